"""Ensemble runs: K replicas in one kernel equal K single runs, bit for bit.

The ensemble and the single runs share one kernel (`large_n.kernel.advance_p2`; a single run is K = 1).
Why bit-identical (not just round-off): each replica performs the single kernel's operations in
the same order (same pair term, tiles and slab blocks counted in particles, the same group slots,
residual rows in ascending j with pairs beyond r_cut skipped rather than added as zeros, drive
amplitude amp * scale formed the same way), and numba compiles without fastmath, so no
reassociation or contraction can differ; vectorised and scalar lanes round alike.  Small lattice
(n = 3: 63 particles, one tile) and n = 8 (1408 particles: three tiles and three slab blocks, so
the tile and block partition of the flat replica index is exercised too).
"""

from __future__ import annotations

import numpy as np
import pytest

from pcverify.scene import SceneError
from pcverify.solvers.particles.macromolecule.codes import FROZEN, GROUP, PRESCRIBED
from pcverify.solvers.particles.macromolecule.force import SevenRoot
from pcverify.solvers.particles.macromolecule.large_n.ensemble import EnsembleRun
from pcverify.solvers.particles.macromolecule.large_n.kernel import (
    TILE,
    KernelRun,
    _pair_sums,
    bench_lattice,
    omega_bound,
)

MODEL = SevenRoot(1.0)
X, A, M = bench_lattice(3)
W = omega_bound(MODEL, A, M)
DT = 0.2 / W


def _fixes():
    kind = np.zeros(len(X), dtype=np.int8)
    kind[[0, 8]] = FROZEN
    kind[[5, 6]] = PRESCRIBED
    amp = np.zeros((len(X), 3))
    amp[5, 1] = 0.02 * A
    amp[6, 1] = -0.02 * A
    return kind, amp


def _single(delta, omega, scale, steps, skin=0.1, force_pass="slabs", groups=True):
    kind, amp = _fixes()
    run = KernelRun.start(X, M, A, MODEL, delta, DT, kind=kind, amp=amp * scale, omega=omega, hotness=True,
                          skin=skin, force_pass=force_pass, groups=groups)
    run.advance(steps)
    return run


@pytest.mark.parametrize(("skin", "force_pass", "groups"), [(0.1, "slabs", True), (0.01, "slabs", True),
                                                           (0.1, "gather", True), (0.01, "slabs", False)])
def test_replicas_bit_identical_to_single_runs(skin, force_pass, groups):
    """Damping, drive amplitude and frequency all differ between replicas; skin 0.01a forces rebuilds
    (the ensemble's shared union list then differs from each single run's own list); without groups
    every pair is in the residual list (the union's extra pairs must change no bit)."""
    deltas = np.array([0.005, 0.02, 0.05]) * M * W
    omegas = np.array([0.25, 0.4, 0.55]) * W
    scales = np.array([1.0, 0.5, 1.5])
    kind, amp = _fixes()
    ens = EnsembleRun.start(X, M, A, MODEL, DT, deltas, omegas, scales, kind=kind, amp=amp, skin=skin,
                            force_pass=force_pass, groups=groups)
    ens.advance(600)
    assert ens.status == "ok" and ens.step == 600
    if skin == 0.01:
        assert ens.nl.builds > 1
    for k in range(3):
        single = _single(deltas[k], omegas[k], scales[k], 600, skin=skin, force_pass=force_pass, groups=groups)
        assert single.status == "ok"
        assert np.array_equal(ens.x[:, k], single.x)
        assert np.array_equal(ens.v[:, k], single.v)
        assert np.array_equal(ens.f[:, k], single.f)
        assert np.array_equal(ens.hot[:, k], single.hot)


@pytest.mark.parametrize("force_pass", ["slabs", "gather"])
def test_replicas_bit_identical_across_tiles_and_blocks(force_pass):
    """n = 8: N = 1408 > 2 TILE, slab blocks of width TILE: replica k of K = 4 (flat tiles of 4 TILE
    slots) against its single run (tiles of TILE), 150 steps of a free lattice started from noise."""
    x, a, m = bench_lattice(8)
    assert len(x) > 2 * TILE
    w = omega_bound(MODEL, a, m)
    x0 = x + 0.003 * a * np.random.default_rng(8).standard_normal(x.shape)
    deltas = np.array([0.0, 0.01, 0.02, 0.04]) * m * w
    ens = EnsembleRun.start(x, m, a, MODEL, 0.2 / w, deltas, 0.0, x0=x0, force_pass=force_pass)
    ens.advance(150)
    for k in range(4):
        single = KernelRun.start(x, m, a, MODEL, deltas[k], 0.2 / w, x0=x0, hotness=True, force_pass=force_pass)
        single.advance(150)
        assert np.array_equal(ens.x[:, k], single.x) and np.array_equal(ens.v[:, k], single.v)
        assert np.array_equal(ens.hot[:, k], single.hot)


def test_replicas_differ_as_their_parameters_say():
    """A guard that the replicas are really different runs: hotness grows with drive amplitude
    (linear regime: mean KE ~ D^2, so doubling D gives ~4x; accepted 3-5x)."""
    kind, amp = _fixes()
    ens = EnsembleRun.start(X, M, A, MODEL, DT, 0.05 * M * W, 0.3 * W, np.array([0.25, 0.5]), kind=kind, amp=amp)
    ens.advance(2000)
    free = kind == 0
    ratio = ens.hotness()[free, 1].sum() / ens.hotness()[free, 0].sum()
    assert 3.0 < ratio < 5.0


def test_unstable_replica_stops_the_ensemble_with_sums_kept():
    """One replica at a huge drive blows up or leaves the bar: status unstable, the reason names it."""
    kind, amp = _fixes()
    big = np.array([1.0, 400.0])  # 0.02a * 400 = 8a stroke: the driven particles leave the lattice
    ens = EnsembleRun.start(X, M, A, MODEL, DT, 0.02 * M * W, 0.3 * W, big, kind=kind, amp=amp)
    done = ens.advance(3000)
    assert ens.status == "unstable" and done < 3000
    assert "[1]" in ens.reason
    assert np.isfinite(ens.hot[:, 0]).all() and ens.hot[:, 0].sum() > 0


def test_bad_replica_parameters_raise_scene_error():
    with pytest.raises(SceneError, match=r"delta\[1\]"):
        EnsembleRun.start(X, M, A, MODEL, DT, np.array([0.0, -1.0]), 1.0)
    with pytest.raises(SceneError, match=r"omega\[0\]"):
        EnsembleRun.start(X, M, A, MODEL, DT, 0.0, np.array([np.nan, 1.0]))


def test_fix_kinds_the_large_n_kernel_does_not_take_are_refused():
    """The large-N kernels share the model's fix kinds (codes.py) but take FREE, FROZEN and PRESCRIBED only:
    a GROUP particle (the red pair's rigid side of the fixed-list kernels) is a one-line SceneError."""
    kind, amp = _fixes()
    kind[3] = GROUP
    with pytest.raises(SceneError, match=r"^kind\[3\]=3 is not allowed; allowed: 0 \(free\), 1 \(frozen\), "
                                         r"2 \(prescribed\)$"):
        KernelRun.start(X, M, A, MODEL, 0.0, DT, kind=kind, amp=amp)
    with pytest.raises(SceneError, match=r"^kind\[3\]=3 is not allowed"):
        EnsembleRun.start(X, M, A, MODEL, DT, 0.0, 1.0, kind=kind, amp=amp)


def _bath_mask():
    """The free particles of the far z face of the n = 3 bench lattice: an absorbing face."""
    return (np.abs(X[:, 2] - X[:, 2].max()) < 1e-9 * A) & (_fixes()[0] == 0)


def test_own_force_scale_exponent_and_bath_bit_identical_to_single_runs():
    """Force scale A, envelope exponent p and the bath rate differ between replicas as well: each replica
    equals its single (K = 1) run bit for bit.  Replica 0 has p = 2: alone it takes the vectorised (a/r)^2
    path, among the others the envelope chosen per pair, which must give the same bits."""
    kind, amp = _fixes()
    bath = _bath_mask()
    stiff = np.array([1.0, 0.7, 1.3, 1.0])
    expo = np.array([2.0, 2.0, 3.0, 1.5])
    gamma = np.array([0.0, 0.5, 0.2, 1.0]) * W
    deltas = np.array([0.01, 0.0, 0.02, 0.005]) * M * W
    omegas = np.array([0.3, 0.45, 0.2, 0.35]) * W
    scales = np.array([1.0, 0.5, 1.5, 0.8])
    ens = EnsembleRun.start(X, M, A, MODEL, DT, deltas, omegas, scales, kind=kind, amp=amp, stiffness=stiff,
                            exponent=expo, bath=bath, gamma=gamma, skin=0.02)
    ens.advance(700)
    assert ens.status == "ok" and ens.nl.builds > 1
    for k in range(4):
        one = EnsembleRun.start(X, M, A, MODEL, DT, deltas[k], omegas[k], scales[k], kind=kind, amp=amp,
                                stiffness=stiff[k], exponent=expo[k], bath=bath, gamma=gamma[k], skin=0.02)
        one.advance(700)
        assert np.array_equal(ens.x[:, k], one.x[:, 0]) and np.array_equal(ens.v[:, k], one.v[:, 0])
        assert np.array_equal(ens.f[:, k], one.f[:, 0]) and np.array_equal(ens.hot[:, k], one.hot[:, 0])


def test_split_advance_equals_one_call():
    """Advancing in chunks (a chunk ends with the closing kick, the next starts with the drift) gives the
    same bits as one call: the checks a heat run makes between chunks change no result."""
    kind, amp = _fixes()
    args = dict(kind=kind, amp=amp, bath=_bath_mask(), gamma=0.3 * W, exponent=2.5)
    one = EnsembleRun.start(X, M, A, MODEL, DT, 0.01 * M * W, 0.3 * W, 1.0, **args)
    one.advance(500)
    chunks = EnsembleRun.start(X, M, A, MODEL, DT, 0.01 * M * W, 0.3 * W, 1.0, **args)
    for n in (1, 99, 150, 250):
        chunks.advance(n)
    assert np.array_equal(one.x, chunks.x) and np.array_equal(one.v, chunks.v) and np.array_equal(one.hot, chunks.hot)


def test_bath_absorbs_and_its_absence_conserves():
    """A free, undamped lattice started from noise keeps its energy KE + U (velocity Verlet: a relative
    drift of order (omega dt)^2 ~ 0.04 at most); with the far face in a 0 K bath at gamma = omega_max / 2
    the same lattice loses most of it (measured 91 % after 4000 steps; asserted: more than half)."""
    x0 = X + 0.01 * A * np.random.default_rng(5).standard_normal(X.shape)
    ens = EnsembleRun.start(X, M, A, MODEL, DT, 0.0, 0.0, x0=x0, bath=_bath_mask(), gamma=np.array([0.0, 0.5 * W]))

    def energy(k: int) -> float:
        c = MODEL.coeffs()
        pot = _pair_sums(np.ascontiguousarray(ens.xs[:, :, k]), ens.nl.offsets, ens.nl.start, ens.nl.index, c, A,
                         ens.r_cut**2)[1]
        return 0.5 * M * float((ens.v[:, k] ** 2).sum()) + pot

    e0 = [energy(0), energy(1)]
    ens.advance(4000)
    assert abs(energy(0) / e0[0] - 1.0) < 0.04
    assert energy(1) < 0.5 * e0[1]


def test_retired_replica_keeps_its_sums_and_the_others_go_on():
    """retire=True: a replica whose drive throws particles out of the lattice is retired at the step its
    single run sees it, with the same sums; the other replica runs to the end, bit-identical to its own
    single run."""
    kind, amp = _fixes()
    big = np.array([1.0, 400.0])
    ens = EnsembleRun.start(X, M, A, MODEL, DT, 0.02 * M * W, 0.3 * W, big, kind=kind, amp=amp, retire=True)
    assert ens.advance(3000) == 3000 and ens.status == "ok"
    assert ens.retired_step[0] == -1 and 0 < ens.retired_step[1] < 3000
    ok = EnsembleRun.start(X, M, A, MODEL, DT, 0.02 * M * W, 0.3 * W, 1.0, kind=kind, amp=amp, retire=True)
    ok.advance(3000)
    assert np.array_equal(ens.replica_hot()[:, 0], ok.replica_hot()[:, 0]) and np.array_equal(ens.x[:, 0], ok.x[:, 0])
    bad = EnsembleRun.start(X, M, A, MODEL, DT, 0.02 * M * W, 0.3 * W, 400.0, kind=kind, amp=amp, retire=True)
    bad.advance(3000)
    assert bad.status == "unstable" and bad.retired_step[0] == ens.retired_step[1]
    assert np.array_equal(bad.replica_hot()[:, 0], ens.replica_hot()[:, 1])
    assert "left the bar" in ens.retired_reason[1] or "NaN" in ens.retired_reason[1]


def test_bad_per_replica_force_parameters_raise_scene_error():
    with pytest.raises(SceneError, match=r"^stiffness\[1\]=0\.0 is out of range; allowed: number in \(0, inf\) N$"):
        EnsembleRun.start(X, M, A, MODEL, DT, 0.0, 1.0, stiffness=np.array([1.0, 0.0]))
    with pytest.raises(SceneError, match=r"^exponent\[0\]=13\.0 is out of range; allowed: number in \[0, 12\]$"):
        EnsembleRun.start(X, M, A, MODEL, DT, 0.0, 1.0, exponent=13.0)
    kind, amp = _fixes()
    with pytest.raises(SceneError, match=r"^bath="):
        EnsembleRun.start(X, M, A, MODEL, DT, 0.0, 1.0, kind=kind, amp=amp, bath=kind == PRESCRIBED)
