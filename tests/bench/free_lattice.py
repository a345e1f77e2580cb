"""The free macromolecule lattice of the benchmarks and the LAMMPS cross-check: no fix, A = 1 N, duralumin's
density; its top-frequency bound and a run of the kernel on it (a test helper)."""

from __future__ import annotations

import numpy as np

from pcverify.solvers.particles.macromolecule.fixes import Fixes
from pcverify.solvers.particles.macromolecule.force import STABLE, SevenRoot, force_slope_array
from pcverify.solvers.particles.macromolecule.lattice import Lattice
from pcverify.solvers.particles.macromolecule.simulate import RunResult, simulate

MODEL = SevenRoot(1.0)
DENSITY = 2800.0


def omega_bound(lat: Lattice) -> float:
    """Upper bound on the lattice's highest angular frequency (Gershgorin on the rest Hessian, cheap at any N).

    At rest every pair sits on a root, so its Hessian block is k_s e e^T (k_s = dF/dr of its shell); the
    absolute row sum of a bulk particle's rows is at most 2 sum_s k_s N_s max_c sum_b |e_c e_b|."""
    k = np.abs(force_slope_array(STABLE.copy(), MODEL.coeffs())[1]) / lat.a
    off = np.array([(i, j, m) for i in range(-2, 3) for j in range(-2, 3) for m in range(-2, 3)
                    if 0 < i * i + j * j + m * m <= 4], dtype=float)
    r = np.linalg.norm(off, axis=1)
    e = off / r[:, None]
    ks = k[np.rint(r**2).astype(int) - 1]
    row = np.abs(e[:, :, None] * e[:, None, :]).sum(axis=2)
    return float(np.sqrt(2.0 * (ks[:, None] * row).sum(axis=0).max() / lat.mass))


def free_fixes(size: int) -> Fixes:
    """Every particle free: no drive, no bath."""
    return Fixes(np.zeros(size, dtype=np.int64), np.zeros((size, 3)), np.zeros(size), np.zeros(size), np.zeros(size))


def free_run(lat: Lattice, x0: np.ndarray, steps: int, delta: float, dt: float) -> RunResult:
    """`steps` steps of the free lattice from positions x0 at rest; one check (at the start)."""
    return simulate(lat, MODEL, free_fixes(lat.size), delta, dt, steps * dt, x0=x0, check_every=steps)
