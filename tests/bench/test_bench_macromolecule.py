"""Benchmarks of the macromolecule solver: the time-stepping kernel alone, and the paper's three runs.

Timed by pytest-benchmark (`pytest tests/bench -k macromolecule --benchmark-enable --benchmark-only`);
under the default `--benchmark-disable` each runs once.  Kernel timings use CPU time of this process
(time.process_time): the machine is shared, and wall time would count other processes' slices.
extra_info carries nanoseconds per pair-step; the fast/reference ratio is measured side by side in
one test (interleaved repetitions, best of each), so it does not depend on the load of the moment.
"""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
from numba import njit

from pcverify.harness.catalogue import make_scene
from pcverify.scene import Resolution
from pcverify.solvers.particles.macromolecule import kernel_fast as fk
from pcverify.solvers.particles.macromolecule import kernel_reference as ig
from pcverify.solvers.particles.macromolecule.force import C_A, C_P, C_ROOTS, C_X0, C_X1, force_tree
from pcverify.solvers.particles.macromolecule.setup import prepare
from pcverify.solvers.particles.macromolecule.simulate import simulate
from pcverify.solvers.particles.macromolecule.solver import Macromolecule
from pcverify.solvers.protocol import effective_params

SOLVER = Macromolecule()
PAPER = make_scene("bar-heat-paper")
KERNEL_STEPS = 2000
CHECK_EVERY = 59  # what a 15 s run at n = 4 uses (n_steps // 400)


def _kernel_case(n: int = 4):
    """bar-heat-paper at n = 4 (N = 160), damping ratio 0.01, D = 0.02 a (no hops), default dt."""
    p = effective_params(SOLVER, {"damping_ratio": 0.01, "drive_amplitude": 0.02})
    s = prepare(PAPER, n, p)
    return s, 2 * np.pi * p["drive_frequency"]


def _run(s, w, kernel: str):
    return simulate(s.lattice, s.model, s.fixes, s.delta, s.dt, KERNEL_STEPS * s.dt, 0.0, w,
                    check_every=CHECK_EVERY, kernel=kernel)


@pytest.mark.benchmark(timer=time.process_time)
@pytest.mark.parametrize("kernel", ["fast", "fastmath", "reference"])
def test_bench_kernel(benchmark, kernel: str) -> None:
    """2000 steps of the kernel alone at N = 160, damping on."""
    s, w = _kernel_case()
    _run(s, w, kernel)  # compile outside the timing
    r = benchmark.pedantic(_run, args=(s, w, kernel), rounds=5, iterations=1)
    pairs = len(s.lattice.pairs)
    benchmark.extra_info.update(kernel=kernel, particles=s.lattice.size, pairs=pairs, steps=r.steps,
                                pair_steps=pairs * r.steps, timer="process_time")
    if benchmark.stats is not None:
        benchmark.extra_info["ns_per_pair_step"] = 1e9 * benchmark.stats.stats.min / (pairs * r.steps)
    assert r.steps == KERNEL_STEPS and r.status_code == ig.DONE and r.counters[ig.K_HOP_EVENTS] == 0


@pytest.mark.benchmark(timer=time.process_time)
def test_bench_kernel_ratio(benchmark) -> None:
    """fast, fastmath and reference kernels in one test: best-of-5 CPU time of each, interleaved.

    extra_info: ns per pair-step of each, the fast/reference speed-up, the fastmath/fast speed-up
    and the largest relative hotness difference of fastmath from the exact fast kernel."""
    s, w = _kernel_case()
    pairs = len(s.lattice.pairs)
    best = {"fast": np.inf, "fastmath": np.inf, "reference": np.inf}
    runs = {}
    for k in best:
        _run(s, w, k)
    for _ in range(5):
        for k in best:
            t0 = time.process_time()
            runs[k] = _run(s, w, k)
            best[k] = min(best[k], time.process_time() - t0)
    benchmark.pedantic(_run, args=(s, w, "fast"), rounds=1, iterations=1)
    ns = {k: 1e9 * v / (pairs * KERNEL_STEPS) for k, v in best.items()}
    h = {k: r.hot[0] for k, r in runs.items()}
    fastmath_dev = float(np.max(np.abs(h["fastmath"] - h["fast"])) / h["fast"].max())
    benchmark.extra_info.update(ns_per_pair_step_fast=ns["fast"], ns_per_pair_step_reference=ns["reference"],
                                ns_per_pair_step_fastmath=ns["fastmath"], speedup=best["reference"] / best["fast"],
                                fastmath_speedup=best["fast"] / best["fastmath"],
                                fastmath_max_rel_hotness_dev=fastmath_dev, particles=s.lattice.size, pairs=pairs)
    # all three integrate the same run: equal to rounding
    for k in ("fast", "fastmath"):
        assert np.max(np.abs(h[k] - h["reference"])) <= 1e-10 * h["reference"].max()


@pytest.mark.parametrize("n", [2, 3, 4])
def test_bench_paper_run(benchmark, n: int) -> None:
    """The paper's runs end to end (set-up, modal analysis, kernel, output); kernel_s is the kernel alone.
    When timed, the best of 3 must be under 1 s (issue 3; measured 0.21 / 0.41 / 0.74 s at n = 2 / 3 / 4)."""
    SOLVER.solve(PAPER, Resolution(n), t_end=0.01)  # compile / warm up outside the timing
    sol = benchmark.pedantic(SOLVER.solve, args=(PAPER, Resolution(n)), kwargs={"drive_amplitude": 0.05,
                             "drive_frequency": 50.0, "t_end": 15.0}, rounds=3, iterations=1)
    kernel, cpu = sol.summary["kernel_s"], sol.summary["kernel_cpu_s"]
    benchmark.extra_info.update(
        n=n, particles=sol.summary["particles"], pairs=sol.summary["pairs"], time_steps=sol.work["time_steps"],
        pair_steps=sol.work["pair_steps"], kernel_s=kernel, kernel_cpu_s=cpu, solve_s=sol.wall_s,
        ns_per_pair_step=1e9 * kernel / sol.work["pair_steps"], ns_per_pair_step_cpu=1e9 * cpu / sol.work["pair_steps"],
        status=sol.status,
    )
    assert sol.work["time_steps"] == sol.summary["steps"] == round(15.0 / sol.summary["dt"])
    if benchmark.stats is not None:  # timed (tox -e bench): issue 3's "each paper run under 1 s", best of 3
        assert benchmark.stats.stats.min < 1.0


@njit(inline="always")
def _floor_group(px, py, pz, vx, vy, vz, o, base, mask, rt, amp_a, p, step_lo, inv_w, a, delta, fsx, fsy, fsz,
                 damped):
    """One stencil group of `kernel._group` stripped to the slot forces: the conservative force and,
    if `damped`, the radial damping; no dissipation term, hop flag or scatter."""
    inv_a = 1.0 / a
    r0, r1, r2, r3, r4, r5, r6 = rt[0], rt[1], rt[2], rt[3], rt[4], rt[5], rt[6]
    for i in range(px.shape[0] - o):
        s, iu, j = fk._slot(base, i, o)
        m = mask[s]
        dx, dy, dz = px[j] - px[iu], py[j] - py[iu], pz[j] - pz[iu]
        r = math.sqrt(dx * dx + dy * dy + dz * dz)
        ir = 1.0 / r
        ex, ey, ez = dx * ir, dy * ir, dz * ir
        f = force_tree(r * inv_a, a * ir, r0, r1, r2, r3, r4, r5, r6, amp_a, p, step_lo, inv_w, True) * m
        if damped:
            f += delta * ((vx[j] - vx[iu]) * ex + (vy[j] - vy[iu]) * ey + (vz[j] - vz[iu]) * ez) * m
        fsx[s] = f * ex
        fsy[s] = f * ey
        fsz[s] = f * ez


@njit(cache=True, boundscheck=False, error_model="numpy")
def _floor_conservative(px, py, pz, vx, vy, vz, o, base, mask, rt, amp_a, p, step_lo, inv_w, a, delta, fsx, fsy,
                        fsz):
    """`_floor_group` without damping (a function of its own per variant, as in kernel.py, so it vectorises)."""
    _floor_group(px, py, pz, vx, vy, vz, o, base, mask, rt, amp_a, p, step_lo, inv_w, a, delta, fsx, fsy, fsz,
                 False)


@njit(cache=True, boundscheck=False, error_model="numpy")
def _floor_damped(px, py, pz, vx, vy, vz, o, base, mask, rt, amp_a, p, step_lo, inv_w, a, delta, fsx, fsy, fsz):
    """`_floor_group` with the radial damping."""
    _floor_group(px, py, pz, vx, vy, vz, o, base, mask, rt, amp_a, p, step_lo, inv_w, a, delta, fsx, fsy, fsz,
                 True)


@njit(cache=True)
def _floor_passes(reps, damped, px, py, pz, vx, vy, vz, g_off, g_base, mask, rt, amp_a, p, step_lo, inv_w, a, delta,
                  fsx, fsy, fsz):
    """The stripped group loop over all groups, `reps` times: the floor of the kernel's pair work."""
    for _ in range(reps):
        for g in range(g_off.shape[0]):
            if damped:
                _floor_damped(px, py, pz, vx, vy, vz, g_off[g], g_base[g], mask, rt, amp_a, p, step_lo, inv_w, a,
                              delta, fsx, fsy, fsz)
            else:
                _floor_conservative(px, py, pz, vx, vy, vz, g_off[g], g_base[g], mask, rt, amp_a, p, step_lo, inv_w,
                                    a, delta, fsx, fsy, fsz)


@njit(cache=True)
def _pair_passes(reps, px, py, pz, vx, vy, vz, g_off, g_base, g_lo, g_hi, mask, rt, amp_a, p, step_lo, inv_w, a,
                 delta, dt, qk, fsx, fsy, fsz, dk, out, ever, counters, fx, fy, fz):
    """`kernel.pair_pass` (forces, damping, dissipation terms, hop flags, scatter) `reps` times."""
    for k in range(reps):
        fk.pair_pass(px, py, pz, vx, vy, vz, g_off, g_base, g_lo, g_hi, mask, rt, amp_a, 2, p, step_lo, inv_w, a,
                     delta, dt, qk, fsx, fsy, fsz, dk, out, ever, k, counters, fx, fy, fz, False)


@pytest.mark.benchmark(timer=time.process_time)
def test_bench_kernel_floor(benchmark) -> None:
    """The kernel's full pair pass against its floor, side by side at N = 160 (best of 5 CPU time,
    interleaved): the same group loop computing only the slot forces, conservative alone and with the
    radial damping (no dissipation term, hop flag, scatter or integration).  extra_info: ns per listed
    pair of each; what the 3 ns per pair-step target of issue 7 is up against.  They compute the same
    forces: the full pass's slot forces are bit-identical to the damped floor loop's."""
    s, _ = _kernel_case()
    lat, c = s.lattice, s.model.coeffs()
    g_off, g_base, g_lo, g_hi, mask, _ = fk.stencil(lat.pairs, lat.shell, lat.size, s.model.basins())
    rng = np.random.default_rng(0)
    x = lat.positions + 1e-3 * lat.a * rng.standard_normal(lat.positions.shape)
    v = 1e-3 * rng.standard_normal(lat.positions.shape)
    px, py, pz = (np.ascontiguousarray(x[:, d]) for d in range(3))
    vx, vy, vz = (np.ascontiguousarray(v[:, d]) for d in range(3))
    ns = mask.size
    rt, coeffs = c[C_ROOTS:C_ROOTS + 7].copy(), (c[C_A], c[C_P], c[C_X0], 1.0 / (c[C_X1] - c[C_X0]), lat.a)
    floor = [np.zeros(ns) for _ in range(3)]
    delta = s.delta
    full = [np.zeros(ns) for _ in range(5)] + [np.zeros(ns, np.int8), np.zeros(ns, np.int8),
                                                np.zeros(9, np.int64)] + [np.zeros(lat.size) for _ in range(3)]

    def run_conservative(reps: int) -> None:
        _floor_passes(reps, False, px, py, pz, vx, vy, vz, g_off, g_base, mask, rt, *coeffs, delta, *floor)

    def run_damped(reps: int) -> None:
        _floor_passes(reps, True, px, py, pz, vx, vy, vz, g_off, g_base, mask, rt, *coeffs, delta, *floor)

    def run_full(reps: int) -> None:
        _pair_passes(reps, px, py, pz, vx, vy, vz, g_off, g_base, g_lo, g_hi, mask, rt, *coeffs, delta, s.dt,
                     *full)

    run_damped(1)
    run_full(1)
    assert all(np.array_equal(floor[d], full[1 + d]) for d in range(3))  # the same slot forces
    run_conservative(1)
    best = {"conservative": np.inf, "damped": np.inf, "full": np.inf}
    for _ in range(5):
        for name, fn in (("conservative", run_conservative), ("damped", run_damped), ("full", run_full)):
            t0 = time.process_time()
            fn(KERNEL_STEPS)
            best[name] = min(best[name], time.process_time() - t0)
    benchmark.pedantic(run_full, args=(KERNEL_STEPS,), rounds=1, iterations=1)
    pairs = len(lat.pairs)
    ns_pair = {k: 1e9 * v / (KERNEL_STEPS * pairs) for k, v in best.items()}
    benchmark.extra_info.update(ns_per_pair_floor_conservative=ns_pair["conservative"],
                                ns_per_pair_floor_damped=ns_pair["damped"], ns_per_pair_full_pass=ns_pair["full"],
                                pairs=pairs, slots=ns, particles=lat.size)
    assert best["full"] > best["damped"]  # the full pass does strictly more work on the same slots
