"""Ensemble runs: K replicas in one kernel equal K single runs, bit for bit.

The single runs use the gather force pass, which the ensemble kernel shares.
Why bit-identical (not just round-off): each replica performs the single kernel's operations in
the same order (same pair term, rows in ascending j, pairs beyond r_cut skipped rather than added
as zeros, drive amplitude amp * scale formed the same way), and numba compiles without fastmath,
so no reassociation or contraction can differ.  Small lattice (n = 3: 63 particles).
"""

from __future__ import annotations

import numpy as np
import pytest

from harness.scene import SceneError
from solvers.particles.ensemble import EnsembleRun
from solvers.particles.scaling import FROZEN, PRESCRIBED, KernelRun, bench_lattice, omega_bound
from solvers.particles.seven_root import SevenRoot

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


def _single(delta, omega, scale, steps, skin=0.1):
    kind, amp = _fixes()
    run = KernelRun.start(X, M, A, MODEL, delta, DT, kind=kind, amp=amp * scale, omega=omega, hotness=True,
                          skin=skin, force_pass="gather")
    run.advance(steps)
    return run


@pytest.mark.parametrize("skin", [0.1, 0.01])
def test_replicas_bit_identical_to_single_runs(skin):
    """Damping, drive amplitude and frequency all differ between replicas; skin 0.01a forces rebuilds
    (the ensemble's shared union list then differs from each single run's own list)."""
    deltas = np.array([0.005, 0.02, 0.05]) * M * W
    omegas = np.array([0.25, 0.4, 0.55]) * W
    scales = np.array([1.0, 0.5, 1.5])
    kind, amp = _fixes()
    ens = EnsembleRun.start(X, M, A, MODEL, DT, deltas, omegas, scales, kind=kind, amp=amp, skin=skin)
    ens.advance(600)
    assert ens.status == "ok" and ens.step == 600
    if skin == 0.01:
        assert ens.nl.builds > 1
    for k in range(3):
        single = _single(deltas[k], omegas[k], scales[k], 600, skin=skin)
        assert single.status == "ok"
        assert np.array_equal(ens.x[:, k], single.x)
        assert np.array_equal(ens.v[:, k], single.v)
        assert np.array_equal(ens.f[:, k], single.f)
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
