"""The lattice family: the paper's bar as Arinchev's macromolecule paper sets its particles up (`bar-heat-lattice`),
and the specification of that particle model as an independent reference (docs/physics.md, "The macromolecule
model"; written from the model's definition, never from the solver's code).

The specification: point masses rho V / N at the nodes of the lattice of spacing a = W / (n - 1); every pair
closer than 2a (inclusive) interacts through the seven-root characteristic
    F(x) = A x^-p prod_{i=1..7} (x - x_i) STEP(x; 2s -> 1, 2 -> 0),   x = r / a,  F > 0 attraction,
with the stable roots 1, sqrt 2, sqrt 3, 2 (the simple-cubic shells), one unstable root at the midpoint of each
gap, p = 2, s = 0.9 and MSC.Adams' cubic STEP; A such that the highest natural frequency of the linearised
lattice, the two frozen corners and the two red particles held, is f_top = 50 Hz (the paper's value).  The
reference computes the roots, the force at given separations, the stiffness at the stable roots, A, the particle
count, mass and positions from these statements alone: the Hessian by the product rule at a simple root (no
running product, no finite difference) and a dense eigensolve.  A consistent change of the force law (force and
Hessian together) passes every check of the kernel against itself; it fails these.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from pcverify.references.heat import PLACEMENT, corners
from pcverify.references.shared import DIMENSIONS, T_MAX, box_of, number
from pcverify.scene import ALUMINIUM, Conduction, PointTemperature, Reference, Scalar, Scene, SceneSpec

STABLE_ROOTS = (1.0, math.sqrt(2.0), math.sqrt(3.0), 2.0)  # the four neighbour shells of the simple-cubic lattice
ENVELOPE_P = 2.0  # the envelope (a / r)^p
STEP_S = 0.9  # STEP from 2 s a (value 1) to 2a (value 0)
F_TOP_HZ = 50.0  # the paper's highest natural frequency
FORCE_PROBES = (0.95, 1.1, 1.3, 1.5, 1.65, 1.8, 1.9)  # separations r / a at which the force is compared
DENSE_PARTICLES = 600  # the dense eigensolve of the reference's A: up to this many particles (n <= 6 on the bar)


def probe_name(x: float) -> str:
    """Summary name of the force at r = x a: force_0p95a ... (N)."""
    return "force_" + f"{x:.2f}".replace(".", "p") + "a"


def roots() -> np.ndarray:
    """The seven roots in units of a, ascending: the stable ones and the midpoint of each gap."""
    stable = np.array(STABLE_ROOTS)
    out = np.empty(7)
    out[0::2] = stable
    out[1::2] = 0.5 * (stable[:-1] + stable[1:])
    return out


def step(x: np.ndarray, x0: float, x1: float) -> np.ndarray:
    """MSC.Adams STEP from 1 at x0 to 0 at x1: 1 - D^2 (3 - 2 D), D = (x - x0) / (x1 - x0) clamped to [0, 1]."""
    d = np.clip((np.asarray(x, dtype=float) - x0) / (x1 - x0), 0.0, 1.0)
    return 1.0 - d * d * (3.0 - 2.0 * d)


def force(x: np.ndarray, amplitude: float) -> np.ndarray:
    """F (N) at reduced separations x for the force scale `amplitude` A (N)."""
    x = np.asarray(x, dtype=float)
    prod = np.prod(x[..., None] - roots(), axis=-1)
    return amplitude * x ** (-ENVELOPE_P) * prod * step(x, 2.0 * STEP_S, 2.0)


def root_slope(k: int) -> float:
    """dF/dx at root k (0-based) for A = 1: at a simple root only the root's own factor is differentiated,
    x^-p prod_{i != k} (x_k - x_i) STEP(x_k)."""
    r = roots()
    others = np.delete(r, k)
    return float(r[k] ** (-ENVELOPE_P) * np.prod(r[k] - others) * step(np.array(r[k]), 2.0 * STEP_S, 2.0))


def lattice(scene: Scene, n: int) -> tuple[np.ndarray, float]:
    """(positions (N, 3), spacing a): the nodes of spacing W / (n - 1) filling the box, from the box alone."""
    box = scene.box
    a = box.width / (n - 1)
    counts = [int(round(e / a)) + 1 for e in box.extent]
    axes = [a * np.arange(c) for c in counts]
    grid = np.meshgrid(*axes, indexing="ij")
    return np.stack([g.ravel() for g in grid], axis=1), a


def held(scene: Scene, positions: np.ndarray, a: float) -> np.ndarray:
    """Indices of the held particles: the nodes at the 0 K corners and the red pair, the hot corner and the
    node one spacing below it (above it on the bottom face)."""
    points = []
    for c in scene.constraints:
        point = np.asarray(c.point, dtype=float)
        points.append(point)
        if c.value > 0.0:
            below = point[1] - a >= -1e-9 * a
            points.append(point - np.array([0.0, a if below else -a, 0.0]))
    d = np.linalg.norm(positions[None, :, :] - np.array(points)[:, None, :], axis=2)
    return np.unique(np.argmin(d, axis=1))


def spring_constants(positions: np.ndarray, a: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(i, j, k_ij): every pair within 2a and its radial stiffness dF/dr at rest for A = 1 (N/m)."""
    d = np.linalg.norm(positions[:, None, :] - positions[None, :, :], axis=2) / a
    i, j = np.nonzero(np.triu(d <= 2.0 * (1 + 1e-9), k=1))
    slopes = np.array([root_slope(k) for k in (0, 2, 4, 6)])  # the stable roots
    shell = np.argmin(np.abs(d[i, j][:, None] - np.array(STABLE_ROOTS)[None, :]), axis=1)
    return i, j, slopes[shell] / a


def force_scale(scene: Scene, n: int) -> float:
    """A (N) that puts the held lattice's highest natural frequency at F_TOP_HZ (NaN beyond DENSE_PARTICLES)."""
    pos, a = lattice(scene, n)
    count = pos.shape[0]
    if count > DENSE_PARTICLES:
        return math.nan
    i, j, k = spring_constants(pos, a)
    e = (pos[j] - pos[i]) / np.linalg.norm(pos[j] - pos[i], axis=1)[:, None]
    blocks = k[:, None, None] * e[:, :, None] * e[:, None, :]
    K = np.zeros((count, 3, count, 3))
    np.add.at(K, (i, slice(None), i, slice(None)), blocks)  # index order: (pair, 3, 3) lands on (i, :, i, :)
    np.add.at(K, (j, slice(None), j, slice(None)), blocks)
    np.add.at(K, (i, slice(None), j, slice(None)), -blocks)
    np.add.at(K, (j, slice(None), i, slice(None)), -blocks)
    free = np.setdiff1d(np.arange(count), held(scene, pos, a))
    dofs = (3 * free[:, None] + np.arange(3)[None]).ravel()
    K = K.reshape(3 * count, 3 * count)[np.ix_(dofs, dofs)]
    mass = scene.material.density * scene.box.volume / count
    lam = float(np.linalg.eigvalsh(K)[-1])
    return (2.0 * math.pi * F_TOP_HZ) ** 2 * mass / lam


def spec_scalars(scene: Scene, summary: dict[str, Any]) -> dict[str, float]:
    """The specification's scalars at the resolution n the solver reports (`lattice_n`); {} before a solve."""
    n = number(summary.get("lattice_n"))
    if n is None:
        return {}
    n = int(n)
    pos, a = lattice(scene, n)
    count = pos.shape[0]
    centre = 0.5 * np.asarray(scene.box.extent, dtype=float)
    r = roots()
    out = {"particles": float(count), "lattice_spacing": a,
           "particle_mass": scene.material.density * scene.box.volume / count,
           "lattice_rms_radius": float(np.sqrt(np.mean(np.sum((pos - centre) ** 2, axis=1)))),
           "pairs": float(len(spring_constants(pos, a)[0])), "held_particles": float(len(held(scene, pos, a))),
           "f_top_hz": F_TOP_HZ, "force_root_count": 6.0}
    out |= {f"force_root_{k + 1}": float(r[k]) for k in range(6)}  # the seventh, 2, is where the STEP ends
    A = force_scale(scene, n)
    if math.isfinite(A):
        out["stiffness_A"] = A
        out |= {f"root_stiffness_{k + 1}": A * root_slope(2 * k) / a for k in range(3)}
        out |= {probe_name(x): float(force(np.array(x), A)) for x in FORCE_PROBES}
    return out


def _lattice_scene(p: dict[str, Any]) -> Scene:
    box = box_of(p)
    cons = tuple(PointTemperature(pt, frac * p["t_max"]) for pt, frac in corners(box, p["placement"]))
    return Scene("bar-heat-lattice", LATTICE.description, box, ALUMINIUM, frozenset({"conduction"}), cons,
                 conduction=Conduction(t_max=p["t_max"]), params=tuple(sorted(p.items())))


SCALARS = (
    Scalar("lattice_n", "", "the resolution n the particles were set up at (the reference's lattice follows it)"),
    Scalar("particles", "", "particle count N (the paper: 16, 63, 160 at n = 2, 3, 4)"),
    Scalar("lattice_spacing", "m", "lattice spacing a = W / (n - 1)"),
    Scalar("particle_mass", "kg", "mass of one particle, rho V / N"),
    Scalar("lattice_rms_radius", "m", "rms distance of the particles' rest positions from the box's centre"),
    Scalar("pairs", "", "interacting pairs: every pair within 2a"),
    Scalar("held_particles", "", "particles held in the modal problem (two frozen corners, the red pair)"),
    Scalar("f_top_hz", "Hz", "highest natural frequency of the held, linearised lattice"),
    Scalar("stiffness_A", "N", "force scale A of the seven-root characteristic"),
    Scalar("force_root_count", "", "sign changes of the pair force between 0.9a and 1.99a (not the seventh root, 2a)"),
    *(Scalar(f"force_root_{k}", "a", f"the {k}. root of F(r) in units of a (odd: stable, even: unstable)")
      for k in range(1, 7)),
    *(Scalar(f"root_stiffness_{k}", "N/m", f"dF/dr at the {k}. stable root (positive: stable)") for k in range(1, 4)),
    *(Scalar(probe_name(x), "N", f"pair force at r = {x:g} a (positive: attraction)") for x in FORCE_PROBES),
)

LATTICE = SceneSpec(
    "bar-heat-lattice",
    "The bar-heat-paper corners as the macromolecule paper sets its lattice up: the particle model's force law, "
    "roots, stiffness, top frequency and lattice against its specification (analytic reference)",
    (*DIMENSIONS, PLACEMENT, T_MAX), _lattice_scene, Reference(scalars=spec_scalars, kind="analytic"), SCALARS)
SCENES = (LATTICE,)
