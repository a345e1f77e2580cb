"""Bond-based peridynamic (nonlocal) heat conduction on the lattice grid of a box.

Each node i exchanges heat with every node j of its family, |x_j - x_i| <= delta (the horizon):
    rho c dT_i/dt = sum_j c_b (T_j - T_i) beta_j V_j,   V_j = h^3,
beta_j the share of j's cell inside the horizon sphere (partial volumes), with one micro-conductivity c_b per
horizon, calibrated on the discrete family so that the sum reproduces k laplacian(T) exactly for a quadratic
field in the bulk: c_b = 2 k / sum_j xi_z^2 beta_j V_j.  As delta -> 0 with m = delta / h fixed
(delta-convergence) the model tends to the classical heat equation; with delta fixed and h -> 0
(m-convergence) it tends to the nonlocal solution, which differs from the classical one by O(delta^2): what
`reference = "self"` measures.

Boundaries: a held face holds its nodes, and the family reaching beyond it sees the odd image of the field,
2 T_face - T(mirror node) (a linear profile through the face is then exact; a constant layer at the face's
temperature, the plain volume constraint, leaves an O(delta) error at the face); an insulated face reflects the
family (mirror nodes, the even image: no flux).  Time: implicit Euler for the first four half steps, then
Crank-Nicolson at the scene's dt (one sparse LU of the free nodes' matrix serves both).
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np
import scipy.sparse as sp
from scipy.interpolate import RegularGridInterpolator
from scipy.sparse.linalg import splu

from pcverify import FaceTemperature, Param, Resolution, Scene, SceneError, Solution, effective_params

AXIS = {"x": 0, "y": 1, "z": 2}
START_HALF_STEPS = 4


class PeridynamicHeat:
    """Nonlocal heat conduction: bond-based peridynamics with a horizon delta (or m spacings)."""

    name = "pd-heat"
    kind = "continuum"
    parameters = (
        Param("delta", None, "m", "horizon (give it, or m); e.g. \"3 * h\" for a fixed ratio", low=0.0, high=1.0,
              low_open=True, optional=True),
        Param("m", None, "", "horizon in grid spacings, delta = m h (give it, or delta)", low=1.0, high=12.0,
              optional=True),
        Param("max_bonds", 20_000_000, "", "largest number of bonds (memory guard)", low=1, high=1e9, kind=int),
    )
    notes = ("A constant micro-conductivity calibrated on the discrete family (not the continuous integral): the "
             "bulk reproduces k laplacian(T) for quadratic fields at every m, so m-convergence measures the "
             "nonlocal model, not the quadrature.",)

    def supports(self, scene: Scene) -> tuple[bool, str]:
        if scene.physics != frozenset({"conduction"}) or scene.conduction.mode != "transient":
            return False, "pd-heat does transient conduction without sources"
        if not scene.constraints or not all(isinstance(c, FaceTemperature) for c in scene.constraints):
            return False, "pd-heat holds whole faces only (volume constraints beyond them)"
        return True, ""

    def solve(self, scene: Scene, resolution: Resolution, samples: dict[str, np.ndarray] | None = None,
              **params: Any) -> Solution:
        t0 = time.perf_counter()
        p = effective_params(self, params)
        if (p["delta"] is None) == (p["m"] is None):
            raise SceneError(f"delta={p['delta']!r}, m={p['m']!r}: give exactly one; allowed: delta in (0, 1] m "
                             "or m in [1, 12]")
        heat = scene.conduction
        shape = tuple((s - 1) * resolution.refine + 1 for s in scene.box.lattice_shape(resolution.n))
        h = resolution.spacing(scene.box.width)
        delta = p["delta"] if p["delta"] is not None else p["m"] * h
        if delta < h * (1 - 1e-9):
            raise SceneError(f"delta={delta:g} m is out of range at h={h:g} m; allowed: delta >= h")
        off, share = family(delta / h)
        nodes = math.prod(shape)
        if nodes * len(off) > p["max_bonds"]:
            raise SceneError(f"{nodes} nodes x {len(off)} bonds is out of range; allowed: at most "
                             f"max_bonds={p['max_bonds']}")
        volume = h**3
        bond = 2.0 * scene.material.conductivity / float(((off[:, 2] * h) ** 2 * share).sum() * volume)
        rates = bond * volume * share / (scene.material.density * scene.material.heat_capacity)
        held_value = {c.face: c.value for c in scene.constraints}
        index = np.indices(shape).reshape(3, -1).T
        held = np.zeros(nodes, dtype=bool)
        fixed = np.zeros(nodes)
        for face, value in held_value.items():
            on = index[:, AXIS[face[0]]] == (0 if face[1] == "0" else shape[AXIS[face[0]]] - 1)
            held |= on
            fixed[on] = value
        rows, cols, vals = [], [], []
        const = np.zeros(nodes)
        for o, rate in zip(off, rates, strict=True):
            target = index + o
            sign = np.ones(nodes)  # -1: the bond reaches the odd image beyond a held face
            for a in range(3):
                last = shape[a] - 1
                for face, beyond in ((f"{'xyz'[a]}0", target[:, a] < 0),
                                     (f"{'xyz'[a]}{'WHL'[a]}", target[:, a] > last)):
                    if face in held_value:  # T(image) = 2 T_face - T(mirror node): a held face is exact for lines
                        sign[beyond] *= -1.0
                        const[beyond] += 2.0 * rate * held_value[face]
                target[:, a] = _fold(target[:, a], last)
            rows.append(np.arange(nodes))
            cols.append(np.ravel_multi_index(target.T, shape))
            vals.append(rate * sign)
        r, c, v = np.concatenate(rows), np.concatenate(cols), np.concatenate(vals)
        a_full = sp.csr_matrix((v, (r, c)), shape=(nodes, nodes)) - sp.diags(np.full(nodes, rates.sum()))
        free = ~held
        a_ff = a_full[free][:, free].tocsc()
        b = (const + a_full[:, held] @ fixed[held])[free]
        temp = np.full(nodes, float(heat.initial_temperature))
        temp[held] = fixed[held]
        steps = round(heat.t_end / heat.dt)
        tk = time.perf_counter()
        eye = sp.identity(int(free.sum()), format="csc")
        implicit = splu((eye - 0.5 * heat.dt * a_ff).tocsc())  # Euler's half step and Crank-Nicolson's left side
        for _ in range(START_HALF_STEPS):
            temp[free] = implicit.solve(temp[free] + 0.5 * heat.dt * b)
        explicit = (eye + 0.5 * heat.dt * a_ff).tocsr()
        for _ in range(steps - START_HALF_STEPS // 2):
            temp[free] = implicit.solve(explicit @ temp[free] + heat.dt * b)
        kernel = time.perf_counter() - tk
        axes = [np.linspace(0.0, e, s) for e, s in zip(scene.box.extent, shape, strict=True)]
        field = RegularGridInterpolator(axes, temp.reshape(shape) / heat.t_max)
        sets = scene.sample_sets(resolution.n) if samples is None else samples
        out = {k: {"points": np.asarray(q, float), "values": field(np.asarray(q, float))} for k, q in sets.items()}
        at_nodes = field(scene.sample_sets(resolution.n)["nodes"])
        summary = {"bulk_median": float(np.median(at_nodes)), "volume_mean": float(temp.mean() / heat.t_max),
                   "delta": delta, "m": delta / h, "family": len(off)}
        return Solution(scene=scene.name, solver=self.name, params=p,
                        resolution={"n": resolution.n, "refine": resolution.refine, "h": h},
                        samples=out, unknowns=int(free.sum()), wall_s=time.perf_counter() - t0, quantity="T/t_max",
                        work={"unknowns": int(free.sum()), "time_steps": steps, "bonds": int(len(r)),
                              "kernel_s": kernel}, summary=summary)


def family(m: float, sub: int = 6) -> tuple[np.ndarray, np.ndarray]:
    """The bonds of a node, as integer offsets (k, 3) in spacings, and the share of each neighbour's cell
    inside the horizon sphere of radius m spacings (partial volumes, from sub^3 points per cell): the sums over
    the family then approximate the nonlocal integrals at every m, not only where cells fit the sphere."""
    reach = int(math.ceil(m + 0.5 * math.sqrt(3.0)))
    grid = np.arange(-reach, reach + 1)
    off = np.stack(np.meshgrid(grid, grid, grid, indexing="ij"), axis=-1).reshape(-1, 3)
    off = off[np.abs(off).sum(axis=1) > 0]
    q = (np.arange(sub) + 0.5) / sub - 0.5
    pts = np.stack(np.meshgrid(q, q, q, indexing="ij"), axis=-1).reshape(-1, 3)
    share = ((((off[:, None, :] + pts[None, :, :]) ** 2).sum(axis=2) <= m * m).mean(axis=1))
    keep = share > 0
    return off[keep], share[keep]


def _fold(i: np.ndarray, last: int) -> np.ndarray:
    """Index i reflected into [0, last] about the end nodes (mirror images, repeated): an insulated face."""
    if last == 0:
        return np.zeros_like(i)
    period = 2 * last
    i = np.mod(i, period)
    return np.where(i > last, period - i, i)
