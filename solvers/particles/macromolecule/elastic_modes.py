"""The macromolecule lattice scaled to a material, for comparing its eigenfrequencies with MCA's: masses
rho V / N, and A such that the lattice's uniaxial Young's modulus in the bar-compression test (supports on z0
and zL, the force-free 3-2-1 set, reaction on zL over W H) is the material's E; its Poisson's ratio is what its
central forces give (reported).  K phi = omega^2 M phi with the face z0 clamped gives the frequencies.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
from scipy.sparse.linalg import spsolve

from pcverify.scene import Box

from .force import SevenRoot
from .lattice import build_lattice
from .modal import hessian


def _faces(pos: np.ndarray, box: Box) -> dict[str, np.ndarray]:
    ext = box.extent
    out = {}
    for face in ("x0", "xW", "y0", "yH", "z0", "zL"):
        ax = "xyz".index(face[0])
        at = 0.0 if face[1] == "0" else ext[ax]
        out[face] = np.flatnonzero(np.abs(pos[:, ax] - at) <= 1e-9 * ext[ax])
    return out


def uniaxial_constants(k: sp.csr_matrix, pos: np.ndarray, box: Box, strain: float = -1e-3) -> tuple[float, float]:
    """(E_eff, nu_eff) of a lattice with stiffness k (3N) in the bar-compression test (linear solve)."""
    faces = _faces(pos, box)
    n3 = k.shape[0]
    fixed = np.full(n3, np.nan)
    fixed[3 * faces["z0"] + 2] = 0.0
    fixed[3 * faces["zL"] + 2] = strain * box.length
    corner = faces["z0"][np.argmin(np.linalg.norm(pos[faces["z0"], :2], axis=1))]
    side = faces["z0"][np.argmin(np.linalg.norm(pos[faces["z0"], :2] - [box.width, 0.0], axis=1))]
    fixed[3 * corner] = fixed[3 * corner + 1] = fixed[3 * side + 1] = 0.0
    is_fixed = ~np.isnan(fixed)
    u = np.where(is_fixed, fixed, 0.0)
    free = np.flatnonzero(~is_fixed)
    u[free] = spsolve(k[free][:, free].tocsc(), -(k[free][:, np.flatnonzero(is_fixed)] @ u[is_fixed]))
    react = (k @ u)[3 * faces["zL"] + 2].sum()
    e_eff = react / (box.width * box.height) / strain
    up = u.reshape(-1, 3)
    lateral = 0.5 * ((up[faces["xW"], 0].mean() - up[faces["x0"], 0].mean()) / box.width
                     + (up[faces["yH"], 1].mean() - up[faces["y0"], 1].mean()) / box.height)
    return float(e_eff), float(-lateral / strain)


def macromolecule_modes(box: Box, n: int, youngs: float, density: float, modes: int = 6,
                        model: SevenRoot | None = None) -> dict[str, object]:
    """Lowest `modes` frequencies (Hz) of the seven-root lattice scaled to (E, rho), clamped at z0."""
    lat = build_lattice(box, n, density)
    k1 = hessian(lat.positions, lat.pairs, model or SevenRoot(1.0), lat.a).tocsr()
    e1, nu = uniaxial_constants(k1, lat.positions, box)
    scale = youngs / e1
    held = _faces(lat.positions, box)["z0"]
    keep = np.setdiff1d(np.arange(3 * lat.size), (3 * held[:, None] + np.arange(3)).ravel())
    kff = (k1[keep][:, keep] * scale).toarray()
    vals = sla.eigh(kff, eigvals_only=True, subset_by_index=[0, min(modes, kff.shape[0]) - 1]) / lat.mass
    return {"frequencies_hz": np.sqrt(np.clip(vals, 0, None)) / (2 * np.pi), "A": scale, "nu_eff": nu,
            "particles": lat.size}
