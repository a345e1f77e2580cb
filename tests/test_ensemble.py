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
