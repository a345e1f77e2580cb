"""Benchmarks: the large-N macromolecule kernel (one force + integration step) from N = 160 to ~10^6,
and ensemble throughput (K replicas in one kernel against K single runs).

Lattices n = 4, 16, 41, 70 of the family n x n x (3n-2): N = 160, 11 776, 203 401, 1 019 200;
both force passes (slabs: each pair once; gather: each pair twice), 1 and 2 threads; the list's 16
offset groups (contiguous, vectorised loops), no residual pairs at these amplitudes.
Each timed call advances a fixed number of steps (about 2e6 pair-steps, at least one step) of a
damped lattice started from random displacements of 0.003a rms.  extra_info: particles, pairs, unknowns,
pair_steps per call, threads, ns_per_pair_step (wall, from the benchmark's median when timing is
on, else from the single untimed call), cpu_ns_per_pair_step (process CPU time of one call: less
sensitive to other jobs on the machine, but it counts idle-spinning worker threads),
bytes_per_particle (all arrays of the run, list included; peak_rss_mb is the process's peak, which
includes the set-up's temporaries and everything run before), offset_groups and
list_entries_per_particle (residual entries only).  `benchmark_rows.rows_from_benchmark_json`
turns a saved run into the rows of the ns-per-pair-step-against-N plot.

Run: pytest tests/bench/test_bench_scaling.py --benchmark-enable --benchmark-only
(timings are noisy when other jobs share the cores; the ratios are measured side by side.)
"""

from __future__ import annotations

import resource
import time

import numba
import numpy as np
import pytest

from pcverify.solvers.particles.macromolecule.codes import PRESCRIBED
from pcverify.solvers.particles.macromolecule.force import SevenRoot
from pcverify.solvers.particles.macromolecule.large_n.ensemble import EnsembleRun
from pcverify.solvers.particles.macromolecule.large_n.kernel import KernelRun, bench_lattice, omega_bound

MODEL = SevenRoot(1.0)
SIZES = {4: 160, 16: 11_776, 41: 203_401, 70: 1_019_200}
_RUNS: dict[int, KernelRun] = {}


def lattice_pair_count(n: int) -> int:
    """Pairs with rest distance <= 2a on the n x n x (3n-2) lattice, counted from the offsets."""
    nx, ny, nz = n, n, 3 * n - 2
    total = 0
    for i in range(-2, 3):
        for j in range(-2, 3):
            for k in range(-2, 3):
                if 0 < i * i + j * j + k * k <= 4:
                    total += max(nx - abs(i), 0) * max(ny - abs(j), 0) * max(nz - abs(k), 0)
    return total // 2


def _run(n: int) -> KernelRun:
    """One damped run per lattice, shared by the thread counts (set-up is not timed)."""
    if n not in _RUNS:
        _RUNS.clear()  # keep one large lattice in memory at a time
        x, a, m = bench_lattice(n)
        rng = np.random.default_rng(n)
        dx = 0.003 * a * rng.standard_normal(x.shape)
        dx -= dx.mean(axis=0)
        w = omega_bound(MODEL, a, m)
        _RUNS[n] = KernelRun.start(x, m, a, MODEL, 0.02 * m * w, 0.2 / w, x0=x + dx)
    return _RUNS[n]


@pytest.mark.parametrize("force_pass", ["slabs", "gather"])
@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("n", [4, 16, 41, 70])
def test_bench_kernel_step(benchmark, n: int, threads: int, force_pass: str) -> None:
    if threads > numba.config.NUMBA_NUM_THREADS:
        pytest.skip(f"numba has {numba.config.NUMBA_NUM_THREADS} thread(s) here; {threads} asked")
    if benchmark.disabled and n > 16:
        pytest.skip(f"n={n} ({SIZES[n]} particles) runs only with timing on (--benchmark-enable, tox -e bench): "
                    "it would add minutes to the untimed test suite")
    run = _run(n)
    run.force_pass = force_pass
    pairs = run.pair_count()
    assert run.size == SIZES[n] and pairs == lattice_pair_count(n)
    steps = max(1, int(2e6 // pairs))
    numba.set_num_threads(threads)
    try:
        run.advance(steps)  # warm-up (compilation, caches) outside the timing
        t_cpu, t_wall = time.process_time(), time.perf_counter()
        run.advance(steps)
        cpu, wall = time.process_time() - t_cpu, time.perf_counter() - t_wall
        builds = run.nl.builds
        benchmark.pedantic(run.advance, args=(steps,), rounds=5 if pairs < 5e6 else 3, iterations=1)
    finally:
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    stats = getattr(benchmark, "stats", None)
    median = stats.stats.median if stats is not None else wall
    work = pairs * steps
    benchmark.extra_info.update(
        n=n, particles=run.size, pairs=pairs, unknowns=3 * run.size, steps_per_call=steps, pair_steps=work,
        threads=threads, force_pass=force_pass, slab_block=run.block, ns_per_pair_step=1e9 * median / work,
        cpu_ns_per_pair_step=1e9 * cpu / work,
        bytes_per_particle=run.nbytes / run.size, list_entries_per_particle=run.nl.entries / run.size,
        offset_groups=len(run.nl.offsets),
        list_builds=run.nl.builds, peak_rss_mb=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    )
    assert run.status == "ok"
    assert builds == 1  # 0.003a (rms) vibrations stay below skin/2 = 0.05a (max ~0.03a at 10^6): list kept


def _ensemble_vs_singles(benchmark, n: int, k: int, steps: int, drive: float) -> None:
    """K replicas (damping, drive amplitude and frequency differ) in one kernel against the same K runs one
    after another, same steps, timed side by side (interleaved, best of 3, fresh runs each time) in one
    test; every replica checked bit-identical to its single run.  drive: amplitude of the corner
    particles' drive in units of a (scaled by 0.5 ... 2 over the replicas)."""
    x, a, m = bench_lattice(n)
    w = omega_bound(MODEL, a, m)
    dt = 0.2 / w
    kind = np.zeros(len(x), dtype=np.int8)
    hot = np.flatnonzero(np.linalg.norm(x - x[0], axis=1) < 1.01 * a)  # a corner particle and its neighbours
    kind[hot] = PRESCRIBED
    amp = np.zeros((len(x), 3))
    amp[hot, 1] = drive * a
    deltas = np.linspace(0.01, 0.04, k) * m * w
    omegas = np.linspace(0.2, 0.5, k) * w
    scales = np.linspace(0.5, 2.0, k)

    def make_ensemble() -> EnsembleRun:
        return EnsembleRun.start(x, m, a, MODEL, dt, deltas, omegas, scales, kind=kind, amp=amp)

    def make_singles() -> list[KernelRun]:
        return [KernelRun.start(x, m, a, MODEL, deltas[r], dt, kind=kind, amp=amp * scales[r], omega=omegas[r],
                                hotness=True) for r in range(k)]

    def run_singles(runs: list[KernelRun]) -> None:
        for s in runs:
            s.advance(steps)

    make_ensemble().advance(steps)
    run_singles(make_singles())  # warm-up: compilation outside the timing
    best = {"single": (np.inf, np.inf), "ensemble": (np.inf, np.inf)}
    last = {}
    for _ in range(3):
        for name in best:
            last[name] = make_singles() if name == "single" else make_ensemble()
            c0, t0 = time.process_time(), time.perf_counter()
            if name == "single":
                run_singles(last[name])
            else:
                last[name].advance(steps)
            wall, cpu = time.perf_counter() - t0, time.process_time() - c0
            best[name] = (min(best[name][0], wall), min(best[name][1], cpu))
    ref, ens = last["single"], last["ensemble"]
    benchmark.pedantic(lambda e: e.advance(steps), setup=lambda: ((make_ensemble(),), {}), rounds=3, iterations=1)
    for r in range(k):
        assert np.array_equal(ens.x[:, r], ref[r].x) and np.array_equal(ens.hot[:, r], ref[r].hot)
    (t_single, c_single), (t_ens, c_ens) = best["single"], best["ensemble"]
    work = k * steps * ref[0].pair_count()
    benchmark.extra_info.update(
        n=n, particles=len(x), replicas=k, steps=steps, drive_over_a=drive, pairs=ref[0].pair_count(),
        replica_pair_steps=work, ensemble_s=t_ens, singles_s=t_single,
        speedup_per_replica=t_single / t_ens, cpu_speedup_per_replica=c_single / c_ens,
        ns_per_replica_pair_step_ensemble=1e9 * t_ens / work, ns_per_replica_pair_step_single=1e9 * t_single / work,
        list_builds_ensemble=ens.nl.builds, list_builds_singles=sum(s.nl.builds for s in ref),
        threads=numba.get_num_threads(),
    )


def test_bench_ensemble_throughput(benchmark) -> None:
    """K = 4 replicas at n = 16 (11 776 particles), 20 steps, drive 0.02a (no rebuild).  The single run
    is already vectorised over particles, so the replicas add no SIMD width: the gain is the per-step
    work shared by the replicas (loop set-up, tile and block passes, parallel-region launches)."""
    _ensemble_vs_singles(benchmark, 16, 4, 20, 0.02)


@pytest.mark.parametrize("drive", [0.002, 0.02])
def test_bench_ensemble_paper_lattice(benchmark, drive: float) -> None:
    """K = 16 replicas at the paper's n = 4 (160 particles), 2000 steps: a parameter sweep's regime, where
    a single step is mostly fixed overhead.  drive 0.002a: the list holds for the whole run; 0.02a:
    rebuilds every few tens of steps (the ensemble rebuilds the replicas that expired)."""
    _ensemble_vs_singles(benchmark, 4, 16, 2000, drive)
