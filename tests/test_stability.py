"""Stability study, small version: the macromolecule model's measured time-step limit against theory,
every unstable run detected, and the study/report plumbing (probes, skips with reasons, tables, figures).

The full sweep is harness/studies/stability.toml (`pcverify study stability`); here n = 2 and 1 s runs.
"""

from __future__ import annotations

import math

import pandas as pd
import pytest

from pcverify.harness.report.write import write_study_report
from pcverify.harness.run.cache import Cache
from pcverify.harness.run.execution import execute
from pcverify.harness.study.catalogue import make_scene
from pcverify.harness.study.stability import StabilityTask, measure_limit, probe_of, split_params
from pcverify.harness.study.study import load_study
from pcverify.scene import Resolution, SceneError
from pcverify.solvers.registry import get_solver

PAPER = make_scene("bar-heat-paper")
PROBE = probe_of(get_solver("macromolecule"))


@pytest.mark.parametrize("zeta", [0.0, 0.1])
def test_measured_limit_against_theory(zeta: float) -> None:
    """Small drive (D = 0.01a): the bisected limit of dt*omega_max/2 (to 1e-3 of dt_theory, 1 s runs)
    lies within 1.5 % of the linear-discrete limit (spectral radius of the scheme).  Undamped, both equal
    the theory 1 to 1 %.  Damped, the top-mode formula sqrt(1+zeta^2)-zeta is an estimate: measured
    n = 2, zeta = 0.1: 0.886 against 0.905 (the linear-discrete limit is 0.881), so within 3 %."""
    prep = PROBE.prepare(PAPER, Resolution(2), {"damping_ratio": zeta, "drive_amplitude": 0.01, "t_end": 1.0})
    theory = math.sqrt(1 + zeta**2) - zeta
    assert prep.theory_limit == pytest.approx(theory, rel=1e-9)
    lim = measure_limit(PROBE, prep, 0.05, 1.5, 1e-3)
    linear = PROBE.linear_limit(prep)
    assert lim["verdict"] == "bisected" and lim["undetected"] == 0
    assert lim["measured_safety"] == pytest.approx(linear, rel=0.015)
    assert lim["measured_safety"] == pytest.approx(theory, rel=0.01 if zeta == 0 else 0.03)
    if zeta == 0:
        assert linear == pytest.approx(1.0, rel=1e-4)


def test_every_unstable_run_is_detected() -> None:
    """A small map (n = 2): above the linear-discrete limit every run is reported unstable; the
    independent check of the final state (non-finite, a particle more than a from rest, kinetic energy
    beyond blowup_factor times the energy supplied) agrees with the solver's status on every run, so
    no blow-up goes unreported and no stable run is called unstable."""
    rows = []
    for zeta in (0.0, 0.1):
        for D in (0.01, 0.1):
            prep = PROBE.prepare(PAPER, Resolution(2), {"damping_ratio": zeta, "drive_amplitude": D, "t_end": 1.0})
            linear = PROBE.linear_limit(prep) / prep.theory_limit
            for ratio in (0.5, 1.03 * linear, 1.1, 1.5):
                out = PROBE.run(prep, ratio)
                rows.append((zeta, D, ratio, out))
                assert out.blown == (out.status == "unstable"), out
                assert not out.undetected
                if ratio > linear:
                    assert out.status == "unstable" and out.stopped_at_step < out.steps_planned
                    assert "stopped at step" in out.reason
    stable_small = [o for z, D, r, o in rows if r == 0.5 and D == 0.01]
    assert all(o.status != "unstable" and o.steps == o.steps_planned for o in stable_small)


def test_large_drive_is_unstable_at_every_dt() -> None:
    """n = 3, D = 0.1a, undamped: the run blows up even at 5 % of dt_theory, so the bisection reports
    that this is no time-step limit (observed in the study: the drive, not dt, is unstable)."""
    prep = PROBE.prepare(PAPER, Resolution(3), {"damping_ratio": 0.0, "drive_amplitude": 0.1, "t_end": 1.0})
    lim = measure_limit(PROBE, prep, 0.05, 1.5, 1e-2)
    assert lim["verdict"].startswith("unstable at every dt") and lim["runs"] == 1


def test_probe_parameters_are_validated() -> None:
    with pytest.raises(SceneError, match=r"dt_ratio=.*allowed"):
        split_params({"dt_ratio": -1.0})
    with pytest.raises(SceneError, match=r"dt=.*allowed: set dt_ratio"):
        split_params({"dt": 1e-4})
    with pytest.raises(SceneError, match=r"drive_amplitude=.*allowed"):
        StabilityTask("map").run(get_solver("macromolecule"), PAPER, Resolution(2), {"drive_amplitude": 0.5})


STUDY = """
name = "stab-tiny"
[[group]]
id = "limit"
analysis = "stability"
probe = "limit"
scene = "bar-heat-paper"
solvers = ["macromolecule", "mca", "skfem"]
n = [2]
solver_params = { t_end = 0.5, ratio_tol = 0.01, drive_amplitude = 0.01 }
sweep = { damping_ratio = [0.0, 0.2] }
[[group]]
id = "map"
analysis = "stability"
probe = "map"
scene = "bar-heat-paper"
solvers = ["macromolecule"]
n = [2]
solver_params = { t_end = 0.5, damping_ratio = 0.05 }
sweep = { dt_ratio = [0.5, 1.2], drive_amplitude = [0.01, 0.05] }
"""


def test_stability_study_and_report(tmp_path) -> None:
    """The study runs probe cells, does not plan the models without a probe (skfem) or whose scene has no time
    stepping (MCA's steady heat), with the reason one line each, and the report writes the limit table, the map
    table and their figures."""
    path = tmp_path / "stab.toml"
    path.write_text(STUDY)
    study = load_study(str(path))
    results, counts = execute(study, Cache(tmp_path / "cache"), progress=False)
    assert counts["cells"] == 6 and counts["failed"] == 0  # the macromolecule's 2 limits and 4 map runs
    unplanned = {u.solver: u for u in study.groups[0].unplanned}
    assert set(unplanned) == {"mca", "skfem"} and all(u.cells == 2 for u in unplanned.values())
    assert "no stability probe" in unplanned["skfem"].reason
    assert "steady mca heat is a direct solve" in unplanned["mca"].reason
    folder = write_study_report(study, results, tmp_path / "out")
    skipped = pd.read_csv(folder / "limit-skipped.csv")
    assert skipped[["solver", "status"]].values.tolist() == [["mca", "not planned"], ["skfem", "not planned"]]
    limits = pd.read_csv(folder / "limit-limits.csv")
    assert set(limits["solver"]) == {"macromolecule"} and (limits["status"] == "ok").all()
    assert list(limits["damping_ratio"]) == [0.0, 0.2]
    theory = [1.0, math.sqrt(1.04) - 0.2]
    assert limits["safety_theory"].tolist() == pytest.approx(theory, rel=1e-9)
    assert (abs(limits["relative_deviation"]) < 0.06).all()  # ratio_tol 0.01, 0.5 s runs
    smap = pd.read_csv(folder / "map-map.csv")
    assert set(smap[smap["dt_ratio"] == 1.2]["run_status"]) == {"unstable"}
    assert not smap["undetected"].any()
    assert (folder / "limit-limits.png").exists() and (folder / "map-map-macromolecule-n2.png").exists()


def test_unknown_probe_kind_is_a_study_error(tmp_path) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(STUDY.replace('probe = "map"', 'probe = "sweep"'))
    with pytest.raises(SceneError, match=r"probe='sweep' is not valid; allowed: one of limit, map"):
        load_study(str(path))
    assert PROBE.theory.startswith("velocity Verlet")


def test_mca_limit_respects_its_gershgorin_guarantee() -> None:
    """MCA (n = 2, bar-compression): dt = cfl * 2 / omega_G with omega_G >= omega_max, so every cfl <= 1
    is stable and the measured limit is >= 1 (measured 1.137); above it the run stops as unstable with
    the step in the reason, and heat scenes are skipped with the reason (heat_cfl <= 1 by range)."""
    probe = probe_of(get_solver("mca"))
    scene = make_scene("bar-compression")
    prep = probe.prepare(scene, Resolution(2), {})
    lim = measure_limit(probe, prep, 0.05, 4.0, 1e-2)
    assert lim["verdict"] == "bisected" and lim["undetected"] == 0
    assert 1.0 <= lim["measured_safety"] < 4.0
    above = probe.run(prep, 2.0)
    assert above.status == "unstable" and "step" in above.reason
    assert not probe.supports(make_scene("bar-heat-faces"))[0]


def test_mca_heat_limit_is_the_exact_forward_euler_limit() -> None:
    """Forward Euler on the automata: the bisected limit equals 2 / lambda_max(C^-1 L) (a linear scheme, so
    to the bisection resolution) and is at least the Gershgorin step the solver uses (ratio 1)."""
    probe = probe_of(get_solver("mca"))
    scene = make_scene("bar-heat-faces", mode="transient", t_end=1.0, dt=0.005)
    assert probe.supports(scene) == (True, "")
    prep = probe.prepare(scene, Resolution(3), {})
    exact = probe.linear_limit(prep)
    lim = measure_limit(probe, prep, 0.5, 3.0, 1e-3)
    assert lim["verdict"] == "bisected" and exact >= 1.0
    assert abs(lim["measured_ratio"] - exact) <= 2e-3
