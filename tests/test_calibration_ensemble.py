"""The macromolecule solver's ensemble path (kernel = "ensemble", `solve_batch`): K parameter sets of one
scene in one kernel call give the Solutions their own solves give, and agree with the fixed-list kernel."""

from __future__ import annotations

import numpy as np
import pytest

from pcverify.harness.catalogue import make_scene
from pcverify.scene import Resolution, SceneError
from pcverify.solvers.registry import get_solver

BASE = dict(hot_face="driven", face_drive_direction="z", kernel="ensemble", t_end=3.0, dt=2e-4)
SETS = [BASE | dict(damping_ratio=d, drive_amplitude=a, p=p)
        for d, a, p in [(0.01, 0.02, 2.0), (0.03, 0.01, 3.0), (0.005, 0.03, 1.0)]]


@pytest.fixture(scope="module")
def runs():
    solver, scene = get_solver("macromolecule"), make_scene("bar-heat-faces")
    batch = solver.solve_batch(scene, Resolution(3), SETS)
    single = [solver.solve(scene, Resolution(3), **s) for s in SETS]
    fast = [solver.solve(scene, Resolution(3), **(s | {"kernel": "fast"})) for s in SETS]
    return batch, single, fast


def _nodes(sol) -> np.ndarray:
    return np.asarray(sol.samples["nodes"]["values"], dtype=float)


def test_batch_equals_single_solves_bit_for_bit(runs):
    batch, single, _ = runs
    assert len(batch) == len(SETS)
    for b, s in zip(batch, single, strict=True):
        assert b.status == s.status
        np.testing.assert_array_equal(_nodes(b), _nodes(s))
        assert b.summary["bulk_median"] == s.summary["bulk_median"]


def test_ensemble_agrees_with_fixed_list_kernel(runs):
    """Same scheme but for where the bath acts (full step) and when hotness is read (after the closing half
    kick): measured differences 9e-4 in relative hotness over 3 s (15 000 steps); 5e-3 bounds them with room,
    and is 100 times below the hotness levels compared (0.3 - 0.5).  The ensemble kernel keeps no energy
    accounts, so under the rule that no run is ok unchecked (simulate.run_status: the energy balance must be
    formed and within 1e-2) its runs are never ok: status failed, the reason naming the balance."""
    batch, _, fast = runs
    assert [f.status for f in fast] == ["ok", "ok", "non-stationary"]
    for b, f in zip(batch, fast, strict=True):
        assert b.status == "failed" and "energy balance off by nan" in b.reason
        if f.status == "ok":
            assert np.abs(_nodes(b) - _nodes(f)).max() < 5e-3
    assert len({round(b.summary["bulk_median"], 3) for b in batch}) == 3  # the sets really differ


def test_a_set_the_ensemble_cannot_run_gets_the_error_its_solve_raises():
    """A Langevin hot face (the default) is not for the ensemble kernel: its entry in the batch is the
    SceneError that its own `solve` raises, word for word, and the other set still runs."""
    solver, scene = get_solver("macromolecule"), make_scene("bar-heat-faces")
    langevin = dict(kernel="ensemble", t_end=0.05, dt=2e-4)
    with pytest.raises(SceneError) as alone:
        solver.solve(scene, Resolution(2), **langevin)
    batch = solver.solve_batch(scene, Resolution(2), [langevin, SETS[0] | {"t_end": 0.05}])
    assert isinstance(batch[0], SceneError) and str(batch[0]) == str(alone.value)
    assert "Langevin" in str(batch[0]) and np.isfinite(batch[1].summary["bulk_median"])
