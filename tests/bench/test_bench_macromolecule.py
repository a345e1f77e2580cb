"""Benchmarks of the macromolecule solver: the kernel alone, against its floor, and the paper's three runs.

Timed by pytest-benchmark (`pytest tests/bench -k macromolecule --benchmark-enable --benchmark-only`);
under the default `--benchmark-disable` each runs once.  Kernel timings use CPU time of this process
(time.process_time): the machine is shared, and wall time would count other processes' slices.
extra_info carries nanoseconds per pair-step.
"""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
from numba import njit

from pcverify.harness.study.catalogue import make_scene
from pcverify.scene import Resolution
from pcverify.solvers.particles.macromolecule import codes
from pcverify.solvers.particles.macromolecule import kernel as mk
from pcverify.solvers.particles.macromolecule.force import C_A, C_P, C_ROOTS, C_X0, C_X1, pair_force
from pcverify.solvers.particles.macromolecule.kernel import lattice_arrays
from pcverify.solvers.particles.macromolecule.setup import prepare
from pcverify.solvers.particles.macromolecule.simulate import N_HISTORY, simulate
from pcverify.solvers.particles.macromolecule.solver import Macromolecule
from pcverify.solvers.protocol import effective_params

SOLVER = Macromolecule()
PAPER = make_scene("bar-heat-paper")
KERNEL_STEPS = 2000


def _kernel_case(n: int = 4):
    """bar-heat-paper at n = 4 (N = 160), damping ratio 0.01, D = 0.02 a (no hops), default dt."""
    p = effective_params(SOLVER, {"damping_ratio": 0.01, "drive_amplitude": 0.02})
    s = prepare(PAPER, n, p)
    return s, 2 * np.pi * p["drive_frequency"]


def _run(s, w):
    return simulate(s.lattice, s.model, s.fixes, s.delta, s.dt, KERNEL_STEPS * s.dt, 0.0, w,
                    check_every=_check_every(s))


def _check_every(s) -> int:
    """The check interval of the paper's 15 s run at this time step (`simulate`: n_steps // N_HISTORY; 117
    at n = 4 with the default safety 0.05), so that the 2000 timed steps carry the checks of a real run."""
    return max(1, int(round(15.0 / s.dt)) // N_HISTORY)


@pytest.mark.benchmark(timer=time.process_time)
def test_bench_kernel(benchmark) -> None:
    """2000 steps of the kernel alone at N = 160, damping on, checks as in a 15 s run."""
    s, w = _kernel_case()
    _run(s, w)  # compile outside the timing
    r = benchmark.pedantic(_run, args=(s, w), rounds=5, iterations=1)
    pairs = len(s.lattice.pairs)
    benchmark.extra_info.update(particles=s.lattice.size, pairs=pairs, steps=r.steps, pair_steps=pairs * r.steps,
                                timer="process_time")
    if benchmark.stats is not None:
        benchmark.extra_info["ns_per_pair_step"] = 1e9 * benchmark.stats.stats.min / (pairs * r.steps)
    assert r.steps == KERNEL_STEPS and r.status_code == codes.DONE and r.counters[codes.K_HOP_EVENTS] == 0


@pytest.mark.parametrize("n", [2, 3, 4])
def test_bench_paper_run(benchmark, n: int) -> None:
    """The paper's runs end to end (set-up, modal analysis, kernel, output); kernel_s is the kernel alone.
    When timed, the best of 3 must be under 1 s (issue 3; measured 0.21 / 0.41 / 0.74 s at n = 2 / 3 / 4)."""
    SOLVER.solve(PAPER, Resolution(n), t_end=0.05)  # compile / warm up outside the timing
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
def _floor_group(px, py, pz, vx, vy, vz, o, base, mask, rt, amp_a, p, step_lo, inv_w, a, delta, fsx, fsy, fsz):
    """One stencil group of the kernel's pair loop stripped to the slot forces: the conservative
    force and the radial damping; no dissipation term, hop flag or force accumulation."""
    inv_a = 1.0 / a
    r0, r1, r2, r3, r4, r5, r6 = rt[0], rt[1], rt[2], rt[3], rt[4], rt[5], rt[6]
    for i in range(px.shape[0] - o):
        s, iu, j = np.uint64(base + i), np.uint64(i), np.uint64(i + o)
        m = mask[s]
        dx, dy, dz = px[j] - px[iu], py[j] - py[iu], pz[j] - pz[iu]
        r = math.sqrt(dx * dx + dy * dy + dz * dz)
        ir = 1.0 / r
        ex, ey, ez = dx * ir, dy * ir, dz * ir
        f = pair_force(r * inv_a, a * ir, r0, r1, r2, r3, r4, r5, r6, amp_a, p, step_lo, inv_w, True) * m
        f += delta * ((vx[j] - vx[iu]) * ex + (vy[j] - vy[iu]) * ey + (vz[j] - vz[iu]) * ez) * m
        fsx[s] = f * ex
        fsy[s] = f * ey
        fsz[s] = f * ez


@njit(cache=True, boundscheck=False, error_model="numpy")
def _floor_group_call(px, py, pz, vx, vy, vz, o, base, mask, rt, amp_a, p, step_lo, inv_w, a, delta, fsx, fsy, fsz):
    """`_floor_group` as a function of its own, called once per group (the floor as first measured)."""
    _floor_group(px, py, pz, vx, vy, vz, o, base, mask, rt, amp_a, p, step_lo, inv_w, a, delta, fsx, fsy, fsz)


@njit(cache=True)
def _floor_calls(reps, px, py, pz, vx, vy, vz, g_off, g_base, mask, rt, amp_a, p, step_lo, inv_w, a, delta, fsx, fsy,
                 fsz):
    """The stripped group loop over all groups, a call per group, `reps` times (the floor as first measured)."""
    for _ in range(reps):
        for g in range(g_off.shape[0]):
            _floor_group_call(px, py, pz, vx, vy, vz, g_off[g], g_base[g], mask, rt, amp_a, p, step_lo, inv_w, a,
                              delta, fsx, fsy, fsz)


@njit(cache=True, boundscheck=False, error_model="numpy")
def _floor_inlined(reps, px, py, pz, vx, vy, vz, g_off, g_base, mask, rt, amp_a, p, step_lo, inv_w, a, delta, fsx,
                   fsy, fsz):
    """The same loops inlined into one function, as the kernel inlines its pass (no call per group)."""
    for _ in range(reps):
        for g in range(g_off.shape[0]):
            _floor_group(px, py, pz, vx, vy, vz, g_off[g], g_base[g], mask, rt, amp_a, p, step_lo, inv_w, a, delta,
                         fsx, fsy, fsz)


@njit(cache=True, boundscheck=False, error_model="numpy")
def _floor_accumulated(reps, pos, vel, g_off, g_base, mask, rt, shape, a, delta, fi, fj):
    """The floor's loops with the pass's force accumulation (pair force added to fi[i], subtracted
    from fj[i + o]): the least work a pass that yields per-particle forces does; no dissipation, no hops."""
    px, py, pz = pos
    vx, vy, vz = vel
    fix, fiy, fiz = fi
    fjx, fjy, fjz = fj
    amp_a, p, step_lo, inv_w = shape
    inv_a = 1.0 / a
    r0, r1, r2, r3, r4, r5, r6 = rt[0], rt[1], rt[2], rt[3], rt[4], rt[5], rt[6]
    for _ in range(reps):
        for i in range(px.shape[0]):
            fix[i] = fiy[i] = fiz[i] = fjx[i] = fjy[i] = fjz[i] = 0.0
        for g in range(g_off.shape[0]):
            o, base = g_off[g], g_base[g]
            for i in range(px.shape[0] - o):
                s, iu, j = np.uint64(base + i), np.uint64(i), np.uint64(i + o)
                m = mask[s]
                dx, dy, dz = px[j] - px[iu], py[j] - py[iu], pz[j] - pz[iu]
                r = math.sqrt(dx * dx + dy * dy + dz * dz)
                ir = 1.0 / r
                ex, ey, ez = dx * ir, dy * ir, dz * ir
                f = pair_force(r * inv_a, a * ir, r0, r1, r2, r3, r4, r5, r6, amp_a, p, step_lo, inv_w, True) * m
                f += delta * ((vx[j] - vx[iu]) * ex + (vy[j] - vy[iu]) * ey + (vz[j] - vz[iu]) * ez) * m
                fix[iu] += f * ex
                fiy[iu] += f * ey
                fiz[iu] += f * ez
                fjx[j] -= f * ex
                fjy[j] -= f * ey
                fjz[j] -= f * ez


@njit(cache=True, boundscheck=False, error_model="numpy")
def _pair_passes(reps, pos, vel, lattice, rt, shape, delta, dt, qk, dk, out, ever, counters, fi, fj, f):
    """The kernel's pair pass (forces, damping, dissipation terms, hop flags, accumulation) `reps` times."""
    for k in range(reps):
        mk.pair_pass(pos, vel, lattice, rt, shape, delta, dt, qk, dk, out, ever, k, counters, fi, fj, f, True)


def _accumulated(fs: list[np.ndarray], la, n: int) -> list[np.ndarray]:
    """Slot forces summed per particle in the pass's order: i sides into one vector and i + o sides into
    another, group after group, then added."""
    out = []
    for comp in fs:
        fi, fj = np.zeros(n), np.zeros(n)
        for o, base in zip(la.g_off, la.g_base[:-1], strict=True):
            i = np.arange(n - o)
            fi[i] += comp[base + i]
            fj[i + o] -= comp[base + i]
        out.append(fi + fj)
    return out


@pytest.mark.benchmark(timer=time.process_time)
def test_bench_kernel_floor(benchmark) -> None:
    """The kernel against its floor, side by side at N = 160 (best of 5 CPU time, interleaved): the
    stripped group loop computing only the damped slot forces (a call per group, as the floor was first
    measured, and inlined into one function, as the kernel inlines its pass), the same with the forces
    accumulated per particle, the kernel's full pair pass (that plus the exact dissipation terms and hop
    flags) and its full step (`simulate`, 2000 steps, checks as in a 15 s run).  extra_info: ns per listed
    pair of each and the full step over the floors.  The full pass computes the floor's forces:
    accumulated in the pass's order they are bit-identical."""
    s, w = _kernel_case()
    lat, c = s.lattice, s.model.coeffs()
    la = lattice_arrays(lat.positions, lat.mass, lat.a, lat.pairs, lat.r0, lat.shell, s.model.basins())
    rng = np.random.default_rng(0)
    x = lat.positions + 1e-3 * lat.a * rng.standard_normal(lat.positions.shape)
    v = 1e-3 * rng.standard_normal(lat.positions.shape)
    pos = tuple(np.ascontiguousarray(x[:, d]) for d in range(3))
    vel = tuple(np.ascontiguousarray(v[:, d]) for d in range(3))
    ns, n = la.mask.size, lat.size
    rt = c[C_ROOTS:C_ROOTS + 7].copy()
    shape = (c[C_A], c[C_P], c[C_X0], 1.0 / (c[C_X1] - c[C_X0]))
    floor_args = (*pos, *vel, la.g_off, la.g_base, la.mask, rt, *shape, lat.a, s.delta)
    fs = [np.zeros(ns) for _ in range(3)]
    f = tuple(np.zeros(n) for _ in range(3))
    pass_args = (pos, vel, la, rt, shape, s.delta, s.dt, np.zeros(ns), np.zeros(ns), np.zeros(ns, np.int8),
                 np.zeros(ns, np.int8), np.zeros(codes.N_COUNTERS, np.int64), tuple(np.zeros(n) for _ in range(3)),
                 tuple(np.zeros(n) for _ in range(3)), f)
    _floor_inlined(1, *floor_args, *fs)
    _pair_passes(1, *pass_args)
    assert all(np.array_equal(a, b) for a, b in zip(_accumulated(fs, la, n), f, strict=True))  # the same forces
    _floor_calls(1, *floor_args, *fs)

    def timed(fn):
        def run() -> float:
            c0 = time.process_time()
            fn()
            return time.process_time() - c0
        return run

    acc_args = (pos, vel, la.g_off, la.g_base, la.mask, rt, shape, lat.a, s.delta,
                tuple(np.zeros(n) for _ in range(3)), tuple(np.zeros(n) for _ in range(3)))
    _floor_accumulated(1, *acc_args)
    cases = {"floor_calls": timed(lambda: _floor_calls(KERNEL_STEPS, *floor_args, *fs)),
             "floor_inlined": timed(lambda: _floor_inlined(KERNEL_STEPS, *floor_args, *fs)),
             "floor_accumulated": timed(lambda: _floor_accumulated(KERNEL_STEPS, *acc_args)),
             "full_pass": timed(lambda: _pair_passes(KERNEL_STEPS, *pass_args)),
             "full_step": lambda: _run(s, w).cpu_s}
    cases["full_step"]()
    timed_run = not getattr(benchmark, "disabled", False)  # untimed (the test suite): each case runs once
    best = dict.fromkeys(cases, np.inf)
    for _ in range(5 if timed_run else 1):
        for name, fn in cases.items():
            best[name] = min(best[name], fn())
    benchmark.pedantic(_run, args=(s, w), rounds=1, iterations=1)
    pairs = len(lat.pairs)
    ns_pair = {k: 1e9 * v / (KERNEL_STEPS * pairs) for k, v in best.items()}
    benchmark.extra_info.update(
        ns_per_pair_floor_damped=ns_pair["floor_calls"], ns_per_pair_floor_inlined=ns_pair["floor_inlined"],
        ns_per_pair_floor_accumulated=ns_pair["floor_accumulated"], ns_per_pair_full_pass=ns_pair["full_pass"],
        ns_per_pair_step_full_step=ns_pair["full_step"], full_step_over_floor=best["full_step"] / best["floor_calls"],
        full_step_over_inlined_floor=best["full_step"] / best["floor_inlined"],
        full_step_over_accumulated_floor=best["full_step"] / best["floor_accumulated"], pairs=pairs, slots=ns,
        particles=n)
    if timed_run:  # the full pass does strictly more work on the same slots (a timing: only when timing is on)
        assert best["full_pass"] > best["floor_inlined"]
