"""Verlet lists (cell list, skin, rebuild on demand) and the large-N gather kernel.

Small lattices only (n = 3 ... 8: 63 to 1408 particles).  What is asserted:
- the list holds exactly the pairs a k-d tree finds within r_cut + skin, rows ascending, with and
  without offset groups (the lattice's 16 offsets; none in random order);
- rebuild on demand: not below skin/2 of displacement, yes above; a run that moves particles
  by more than skin/2 rebuilds and still holds every pair within r_cut (brute force);
- the gather force pass equals the fixed-pair-list force (lattice pairs, numpy scatter) to
  round-off, and the run equals the solver's fixed-pair-list kernel to round-off;
- the force pass and the run are bit-identical for 1 and 2 threads and between repeats (n = 8:
  several tiles and slab blocks), with groups and with the residual list only;
- velocity Verlet: energy error second order in dt; blow-up is reported as "unstable".
"""

from __future__ import annotations

import numba
import numpy as np
import pytest
from bench.benchmark_rows import rows_from_benchmark_json
from scipy.spatial import cKDTree

from pcverify.scene import Box, SceneError
from pcverify.solvers.particles.macromolecule import fixes as mm_fixes
from pcverify.solvers.particles.macromolecule import simulate as mm
from pcverify.solvers.particles.macromolecule.codes import FROZEN, PRESCRIBED
from pcverify.solvers.particles.macromolecule.force import SevenRoot, force_array
from pcverify.solvers.particles.macromolecule.large_n.kernel import (
    TILE,
    KernelRun,
    _drift,
    _kick_drift,
    bench_lattice,
    omega_bound,
    pair_forces,
    slab_block,
)
from pcverify.solvers.particles.macromolecule.large_n.neighbours import (
    build_neighbours,
    merge_lists,
    stencil_offsets,
    union_list,
)
from pcverify.solvers.particles.macromolecule.lattice import build_lattice
from pcverify.solvers.particles.macromolecule.modal import free_dofs, hessian, top_frequency

MODEL = SevenRoot(1.0)


def _perturbed(n: int, amp: float = 0.02, seed: int = 1):
    x, a, m = bench_lattice(n)
    rng = np.random.default_rng(seed)
    dx = amp * a * rng.standard_normal(x.shape)
    dx -= dx.mean(axis=0)
    return x, a, m, x + dx


def _numpy_fixed_pair_forces(lat, x, v, delta, model=MODEL):
    """Reference: the solver's fixed pair list (rest r0 <= 2a), scattered with numpy."""
    P = lat.pairs
    d = x[P[:, 1]] - x[P[:, 0]]
    r = np.linalg.norm(d, axis=1)
    e = d / r[:, None]
    g = force_array(r / lat.a, model.coeffs()) + delta * np.einsum("ij,ij->i", v[P[:, 1]] - v[P[:, 0]], e)
    f = np.zeros_like(x)
    np.add.at(f, P[:, 0], g[:, None] * e)
    np.add.at(f, P[:, 1], -g[:, None] * e)
    return f


@pytest.mark.parametrize("groups", [False, True])
def test_list_equals_kdtree_pairs(groups):
    """Residual rows plus the group slots within the radius at build are exactly the k-d tree's pairs;
    with the lattice's groups, the residual holds only pairs of other offsets (0.05a noise brings a
    few sqrt(5) a pairs inside 2.2a)."""
    x_rest, a, _, x = _perturbed(4, amp=0.05)
    offsets = stencil_offsets(x_rest, 2.2 * a) if groups else None
    nl = build_neighbours(x, 2.1 * a, 0.1 * a, offsets)
    ref = cKDTree(x).query_pairs(2.2 * a, output_type="ndarray")
    ref = {tuple(p) for p in np.sort(ref, axis=1)}
    assert {tuple(p) for p in nl.pairs()} == ref
    rows = np.split(nl.index, nl.start[1:-1])
    assert all(np.all(np.diff(r) > 0) for r in rows)  # ascending, no duplicates
    assert nl.index.dtype == np.int32
    i = np.repeat(np.arange(nl.size), np.diff(nl.start))
    assert not np.isin(np.abs(nl.index - i), nl.offsets).any()
    if groups:  # residual: only pairs that are not lattice neighbours at rest (sqrt(5) a and beyond)
        assert len(nl.offsets) == 16 and nl.entries > 0
        assert np.linalg.norm(x_rest[nl.index] - x_rest[i], axis=1).min() > 2.2 * a
    else:
        assert nl.entries == 2 * len(ref)


@pytest.mark.parametrize("n", [4, 8])
def test_union_list_equals_merged_lists(n):
    """The ensemble's one-call union (serial builds below 4096 particles, parallel above) holds exactly
    the rows of K separate lists merged, array for array; K = 5 position sets with 0.03a noise."""
    x, a, _ = bench_lattice(n)
    offsets = stencil_offsets(x, 2.2 * a)
    xk = x[None] + 0.03 * a * np.random.default_rng(n).standard_normal((5, *x.shape))
    ref = merge_lists([build_neighbours(xk[k], 2.1 * a, 0.1 * a, offsets) for k in range(5)])
    got = union_list(xk, 2.1 * a, 0.1 * a, offsets)
    assert ref.entries > 0 and np.array_equal(got.start, ref.start) and np.array_equal(got.index, ref.index)
    assert np.array_equal(got.offsets, offsets) and np.array_equal(got.x_ref, xk[0])


def test_stencil_offsets_are_the_lattice_offsets():
    """Lattice order (x slowest, z fastest): the 16 half-shell offsets di ny nz + dj nz + dk with
    0 < di^2 + dj^2 + dk^2 <= 4; a shuffled order has none."""
    x, a, _ = bench_lattice(5)
    ny, nz = 5, 13
    want = sorted({abs(di * ny * nz + dj * nz + dk) for di in range(-2, 3) for dj in range(-2, 3)
                   for dk in range(-2, 3) if 0 < di * di + dj * dj + dk * dk <= 4})
    assert stencil_offsets(x, 2.2 * a).tolist() == want and len(want) == 16
    assert stencil_offsets(x[np.random.default_rng(0).permutation(len(x))], 2.2 * a).size == 0


def test_rest_lattice_list_is_the_solver_pair_list():
    """r_cut + skin = 2.2a < sqrt(5) a: at rest the list is exactly the solver's pairs (r0 <= 2a)."""
    x, a, _ = bench_lattice(4)
    lat = build_lattice(Box(), 4, 2800.0)
    nl = build_neighbours(x, 2.1 * a, 0.1 * a)
    assert np.array_equal(nl.pairs(), lat.pairs)


def test_rebuild_on_demand_threshold():
    x, a, _ = bench_lattice(3)
    skin = 0.1 * a
    nl = build_neighbours(x, 2.1 * a, skin)
    y = x.copy()
    y[7, 0] += 0.499 * skin
    assert not nl.update(y) and nl.builds == 1
    y[7, 0] = x[7, 0] + 0.501 * skin
    assert nl.update(y) and nl.builds == 2
    assert np.array_equal(nl.x_ref, y)
    assert not nl.update(y)  # displacement now measured from the new build


def test_run_rebuilds_and_list_stays_complete():
    """A tiny skin (0.005a) with 0.02a vibrations forces rebuilds; the list must still hold every
    pair within r_cut, and the forces must equal those of a freshly built list."""
    _, a, m, x0 = _perturbed(3)
    x, _, _ = bench_lattice(3)
    w = omega_bound(MODEL, a, m)
    run = KernelRun.start(x, m, a, MODEL, 0.01 * m * w, 0.2 / w, x0=x0, skin=0.005)
    run.advance(400)
    assert run.status == "ok" and run.nl.builds > 1
    need = {tuple(p) for p in cKDTree(run.x).query_pairs(run.r_cut, output_type="ndarray")}
    assert need <= {tuple(p) for p in run.nl.pairs()}
    fresh = build_neighbours(run.x, 2.1 * a, 0.3 * a, run.nl.offsets)
    f = pair_forces(run.x, run.v, fresh, MODEL, a, run.delta)
    f_run = pair_forces(run.x, run.v, run.nl, MODEL, a, run.delta)
    assert fresh.entries > run.nl.entries  # the wider list holds more residual pairs, all beyond r_cut
    assert np.array_equal(f, f_run)  # same interacting pairs in the same order: bit-identical


@pytest.mark.parametrize("shuffle", [False, True])
def test_force_passes_equal_fixed_pair_list_forces(shuffle):
    """Gather and slab passes against the fixed pair list (numpy scatter, `seven_root.force_x`): the
    pair terms differ in rounding only (root-factor product tree against a running product) and the
    summation order differs, so relative 1e-13 bounds the round-off of ~32 terms of mixed sign
    (observed ~4e-15).  n = 5 in lattice order: the 16 offset groups; a shuffled order has no
    groups: every pair in the residual rows."""
    lat = build_lattice(Box(), 5, 2800.0)
    x, a, m = bench_lattice(5)
    _, _, _, xp = _perturbed(5)
    w = omega_bound(MODEL, a, m)
    v = 0.02 * a * w * np.random.default_rng(2).standard_normal(x.shape)
    delta = 0.02 * m * w
    order = np.random.default_rng(4).permutation(len(x)) if shuffle else np.arange(len(x))
    xs, vs = xp[order], v[order]
    nl = build_neighbours(xs, 2.1 * a, 0.1 * a, stencil_offsets(x[order], 2.2 * a))
    assert (len(nl.offsets) == 16) != shuffle
    ref = _numpy_fixed_pair_forces(lat, xp, v, delta)[order]
    for force_pass in ("gather", "slabs"):
        f = pair_forces(xs, vs, nl, MODEL, a, delta, force_pass=force_pass)
        assert np.abs(f - ref).max() <= 1e-13 * np.abs(ref).max()


@pytest.mark.parametrize("p", [3.0, 2.5])
def test_other_envelope_exponents(p):
    """Envelope (a/r)^p for p != 2 goes through pow (the scalar fallback of the group loops): both passes
    against the numpy reference (`force_x`: repeated multiplication for integer p, pow otherwise) to
    relative 1e-13, as for p = 2."""
    model = SevenRoot(1.0, p=p)
    lat = build_lattice(Box(), 4, 2800.0)
    x, a, m = bench_lattice(4)
    _, _, _, xp = _perturbed(4)
    w = omega_bound(model, a, m)
    v = 0.02 * a * w * np.random.default_rng(5).standard_normal(x.shape)
    nl = build_neighbours(xp, 2.1 * a, 0.1 * a, stencil_offsets(x, 2.2 * a))
    ref = _numpy_fixed_pair_forces(lat, xp, v, 0.02 * m * w, model)
    for force_pass in ("gather", "slabs"):
        f = pair_forces(xp, v, nl, model, a, 0.02 * m * w, force_pass=force_pass)
        assert np.abs(f - ref).max() <= 1e-13 * np.abs(ref).max()


@pytest.mark.parametrize("force_pass", ["slabs", "gather"])
@pytest.mark.parametrize("zeta", [0.0, 0.02])
def test_run_equals_solver_fixed_pair_kernel(zeta, force_pass):
    """Same start (rest positions, velocities v0), same dt, 300 steps: the Verlet-list kernel and the
    solver's fixed-pair-list kernel (integrate.run via macromolecule.simulate) integrate the same
    scheme with the same pairs (checked: no unlisted pair within r_cut), so positions agree to
    round-off: the force sums differ only in order (~1e-16 relative per step), amplified over 300
    steps of a stable vibration; observed 5e-15 a (undamped) and 2e-15 a (damped), bound 1e-11 a."""
    lat = build_lattice(Box(), 3, 2800.0)
    a, m = lat.a, lat.mass
    w = omega_bound(MODEL, a, m)
    dt = 0.2 / w
    delta = zeta * m * w
    # small amplitude: no unlisted pair comes near r_cut (with 0.01 a w the free lattice deforms by
    # 0.2a within 100 steps and an unlisted pair enters 2a: then the two models differ by design)
    v0 = 0.001 * a * w * np.random.default_rng(3).standard_normal(lat.positions.shape)
    v0 -= v0.mean(axis=0)
    N = lat.size
    fx = mm_fixes.Fixes(np.zeros(N, dtype=np.int64), np.zeros((N, 3)), np.zeros(N), np.zeros(N), np.zeros(N))
    ref = mm.simulate(lat, MODEL, fx, delta, dt, 300 * dt, v0=v0)
    run = KernelRun.start(lat.positions, m, a, MODEL, delta, dt, v0=v0, force_pass=force_pass)
    run.advance(ref.steps)
    assert ref.steps == 300 and run.status == "ok"
    assert np.array_equal(cKDTree(run.x).query_pairs(run.r_cut, output_type="ndarray").shape, lat.pairs.shape)
    assert np.abs(run.x - ref.x).max() <= 1e-11 * a


@pytest.mark.parametrize(("n", "force_pass", "groups"), [(5, "slabs", True), (8, "slabs", True), (8, "gather", True),
                                                         (8, "slabs", False)])
def test_thread_count_independent_and_deterministic(n, force_pass, groups):
    """Tiles, slab blocks and row order are fixed by N and the list, never by the thread count: 1 and
    2 threads must give the same bits and rebuild at the same steps (n = 8: three tiles and three slab
    blocks; 0.01a noise with a 0.02a skin rebuilds the list every few steps and leaves residual pairs;
    without groups all pairs are residual; frozen and driven particles; calls of 1, 7 and 92 steps).
    n = 5 (one tile): a displacement count that read stale positions once missed expiries at the
    start of a call on one thread (rebuilt a step late); the rebuild steps must agree."""
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("numba has a single thread here: nothing to compare")
    x, a, m, x0 = _perturbed(n, amp=0.01)
    w = omega_bound(MODEL, a, m)
    kind = np.zeros(len(x), dtype=np.int8)
    kind[[0, 8]], kind[[5, 6]] = FROZEN, PRESCRIBED
    amp = np.zeros((len(x), 3))
    amp[5, 1], amp[6, 1] = 0.02 * a, -0.02 * a
    results = []
    for threads in (1, 2, 2, 1):
        numba.set_num_threads(threads)
        try:
            run = KernelRun.start(x, m, a, MODEL, 0.02 * m * w, 0.2 / w, x0=x0, hotness=True, kind=kind, amp=amp,
                                  omega=0.3 * w, skin=0.02, force_pass=force_pass, groups=groups)
            for steps in (1, 7, 92):
                run.advance(steps)
            assert n < 8 or (len(x) > 2 * TILE and (len(x) // slab_block(run.nl) >= 2 or not groups))
        finally:
            numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
        results.append((run.x.copy(), run.v.copy(), run.hot.copy(), run.potential_energy(), run.nl.history))
    assert len(results[0][4]) > 10  # the list was rebuilt (the steps of the rebuilds are compared too)
    for other in results[1:]:
        assert np.array_equal(results[0][0], other[0])
        assert np.array_equal(results[0][1], other[1])
        assert np.array_equal(results[0][2], other[2])
        assert results[0][3] == other[3]
        assert results[0][4] == other[4]  # expiry counts are exact: the same rebuild steps


@pytest.mark.parametrize("threads", [1, 2])
def test_drift_counts_displaced_slots(threads):
    """The drift passes return exactly the number of slots beyond sqrt(lim2) of x_ref after the drift
    (numpy recount; positions and velocities as numpy computes them, bit for bit).  A version that read
    the positions back through the (3, N) state inside the parallel loop saw stale values (0 or 1
    instead of 3 here, depending on the thread count)."""
    if threads > numba.config.NUMBA_NUM_THREADS:
        pytest.skip("numba has a single thread here")
    rng = np.random.default_rng(7)
    n = 3000
    xs, vs, fs = rng.standard_normal((3, 3, n))
    x_ref = xs.T + 0.01 * rng.standard_normal((n, 3))
    hot = np.zeros(n)
    h, dt, lim2 = 0.3, 0.02, 0.02**2
    for fused in (False, True):
        x, v = xs.copy(), vs.copy()
        numba.set_num_threads(threads)
        try:
            got = (_kick_drift(x, v, fs, x_ref, hot, h, dt, 0.5, lim2) if fused else
                   _drift(x, v, fs, x_ref, h, dt, lim2))
        finally:
            numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
        u = vs + h * fs + (h * fs if fused else 0.0)
        assert np.array_equal(v, u) and np.array_equal(x, xs + dt * u)
        want = int(((((xs + dt * u).T - x_ref) ** 2).sum(axis=1) > lim2).sum())
        assert 0 < want < n and got == want


def test_energy_error_second_order_in_dt():
    """Undamped free lattice: velocity Verlet's energy fluctuation scales as dt^2 (ratio 4 per halving;
    accepted 3.2-4.8 for the anharmonic terms)."""
    x, a, m, x0 = _perturbed(3, amp=0.01)
    w = omega_bound(MODEL, a, m)
    spread = []
    for dt in (0.2 / w, 0.1 / w):
        run = KernelRun.start(x, m, a, MODEL, 0.0, dt, x0=x0)
        e = []
        for _ in range(40):
            run.advance(int(round(2.0 / w / dt)))  # sample every 2/w (same times for both dt)
            e.append(run.kinetic_energy() + run.potential_energy())
        spread.append(np.ptp(e))
    assert 3.2 < spread[0] / spread[1] < 4.8


def test_omega_bound_is_an_upper_bound():
    lat = build_lattice(Box(), 4, 2800.0)
    K = hessian(lat.positions, lat.pairs, MODEL, lat.a)
    w_top = top_frequency(K, lat.mass, free_dofs(np.ones(lat.size, dtype=bool)))
    w_bound = omega_bound(MODEL, lat.a, lat.mass)
    assert w_top <= w_bound <= 1.2 * w_top


def test_blowup_reported_unstable_with_sums_kept():
    """dt at 3x the stability limit 2/omega_max: the run stops early, status unstable, steps kept."""
    x, a, m, x0 = _perturbed(3, amp=0.01)
    w = omega_bound(MODEL, a, m)
    run = KernelRun.start(x, m, a, MODEL, 0.0, 6.0 / w, x0=x0, hotness=True)
    done = run.advance(5000)
    assert run.status == "unstable" and done < 5000 and run.step == done
    assert "NaN" in run.reason or "left" in run.reason


def test_fixes_frozen_and_prescribed():
    """FROZEN stays at rest; PRESCRIBED follows x_rest + amp sin(omega t) exactly."""
    x, a, m, x0 = _perturbed(3, amp=0.01)
    w = omega_bound(MODEL, a, m)
    kind = np.zeros(len(x), dtype=np.int8)
    kind[0], kind[5] = FROZEN, PRESCRIBED
    amp = np.zeros((len(x), 3))
    amp[5, 1] = 0.02 * a
    dt = 0.2 / w
    run = KernelRun.start(x, m, a, MODEL, 0.05 * m * w, dt, x0=x0, kind=kind, amp=amp, omega=0.3 * w)
    run.advance(137)
    assert np.array_equal(run.x[0], x[0]) and not run.v[0].any()
    assert np.allclose(run.x[5], x[5] + amp[5] * np.sin(0.3 * w * 137 * dt), rtol=0, atol=1e-15 * a)


def test_bad_parameters_raise_scene_error():
    x, a, m = bench_lattice(2)
    with pytest.raises(SceneError, match="r_cut"):
        KernelRun.start(x, m, a, MODEL, 0.0, 1e-4, r_cut=1.9)
    with pytest.raises(SceneError, match="skin"):
        KernelRun.start(x, m, a, MODEL, 0.0, 1e-4, skin=0.0)
    with pytest.raises(SceneError, match="dt"):
        KernelRun.start(x, m, a, MODEL, 0.0, -1.0)
    with pytest.raises(SceneError, match="delta"):
        KernelRun.start(x, m, a, MODEL, -1.0, 1e-4)
    with pytest.raises(SceneError, match="force_pass"):
        KernelRun.start(x, m, a, MODEL, 0.0, 1e-4, force_pass="scatter")


def test_rows_from_benchmark_json(tmp_path):
    doc = {"benchmarks": [
        {"name": "b2", "extra_info": {"particles": 203401, "ns_per_pair_step": 9.0, "bytes_per_particle": 300.0,
                                      "threads": 2}},
        {"name": "b1", "extra_info": {"particles": 160, "ns_per_pair_step": 12.5, "bytes_per_particle": 280.0,
                                      "threads": 1}},
        {"name": "other", "extra_info": {"n": 4}},
    ]}
    path = tmp_path / "bench.json"
    path.write_text(__import__("json").dumps(doc))
    rows = rows_from_benchmark_json(path)
    assert [r["N"] for r in rows] == [160, 203401]
    assert rows[0] == {"N": 160, "ns_per_pair_step": 12.5, "bytes_per_particle": 280.0, "threads": 1,
                       "force_pass": "", "name": "b1"}
