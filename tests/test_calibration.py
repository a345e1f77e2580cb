"""Calibration (issue 17): a synthetic solver with a known optimum and added noise is recovered within the
reported ranges; failed sets are failures, never data; the overlap guard and the study-file checks refuse
bad calibrations in one line; a killed calibration resumes and a rerun computes nothing (counted by the
solver itself and by the cache); the same seed gives the same calibration."""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest

from pcverify.harness.report.calibration_section import calibration_section
from pcverify.harness.report.reproduce import select_groups
from pcverify.harness.run.cache import Cache
from pcverify.harness.run.calibration import CALIBRATED, VALIDATED, NotCached, run_calibration
from pcverify.harness.study.study import load_study
from pcverify.scene import SceneError

TESTS = Path(__file__).resolve().parent
sys.path.insert(0, str(TESTS))  # the synthetic solver module is a study plugin
X0, Y0, SIGMA = 0.3, 0.01, 0.002  # calib_synthetic's optimum and the noise the study adds

STUDY = """
name = "calib-synthetic"
plugins = ["calib_synthetic"]

[[calibration]]
id = "quad"
solver = "calib-quadratic"
solver_params = {{ noise = {sigma}, fail_above = 0.8, sleep = {sleep} }}
budget = 40
design_points = 16
seed = 0
replicas = {{ seed = [1, 2, 3, 4, 5] }}
tolerance = 0.05

[[calibration.parameter]]
name = "x"
low = -1.0
high = 1.0

[[calibration.parameter]]
name = "y"
low = 1e-4
high = 1.0
log = true

[[calibration.calibrate]]
scene = "bar-heat-faces"
n = 3
metric = "q"
error = "absolute"
reference = {{ solver = "calib-quadratic", solver_params = {{ x = 0.3, y = 0.01, noise = 0.0 }} }}

[[calibration.validate]]
scene = "bar-heat-faces"
n = {validate_n}
metric = "q"
error = "absolute"
reference = {{ solver = "calib-quadratic", solver_params = {{ x = 0.3, y = 0.01, noise = 0.0 }} }}
"""


def _study(tmp_path: Path, sleep: float = 0.0, validate_n: str = "[4, 6]") -> Path:
    path = tmp_path / "synthetic.toml"
    path.write_text(STUDY.format(sigma=SIGMA, sleep=sleep, validate_n=validate_n))
    return path


@pytest.fixture(scope="module")
def outcome(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("calib")
    study = load_study(str(_study(tmp)))
    return run_calibration(study, study.calibrations[0], Cache(tmp / "cache"))


def test_known_optimum_recovered_within_the_reported_ranges(outcome):
    summary = outcome.tables["quad-summary"].iloc[0]
    params = outcome.tables["quad-parameters"].set_index("parameter")
    for name, truth in (("x", X0), ("y", Y0)):
        assert params.loc[name, "range_low"] <= truth <= params.loc[name, "range_high"], name
    # the objective is |q| with q = dx^2 + 2 dlog10(y)^2 + noise: at the best set, q's deterministic part is at
    # most the band plus the noise of that one run (below 4 sigma: probability 6e-5 for a normal draw)
    slack = summary["band [calibrated on]"] + 4 * SIGMA
    assert abs(params.loc["x", "calibrated"] - X0) <= math.sqrt(slack)
    assert abs(math.log10(params.loc["y", "calibrated"]) - math.log10(Y0)) <= math.sqrt(slack / 2)
    # the band is best + 2 x the replica noise, so it is wider than the noise of one run and the ranges are
    # not a single point
    assert summary["band [calibrated on]"] > summary["objective [calibrated on]"]
    assert params.loc["x", "range_high"] > params.loc["x", "range_low"]
    assert params.loc["y", "range_high"] > params.loc["y", "range_low"]
    assert not params["at_bound"].any()  # the optimum is inside the bounds, not pressed against one


def test_noise_from_replicas_matches_the_added_noise(outcome):
    """The replicas (5 seeds) and the best run estimate the std of |q| at the optimum; for q ~ N(0, sigma)
    that is 0.60 sigma, and a 6-sample standard deviation lies within a factor 3 of it with probability
    above 0.99.  The estimate is deterministic (seeded), so this is one fixed number, not a flaky draw."""
    summary = outcome.tables["quad-summary"].iloc[0]
    noise = summary["noise [calibrated on]"]
    draws = [summary["objective [calibrated on]"], *outcome.tables["quad-noise"]["objective"]]
    assert summary["replica_mean [calibrated on]"] == pytest.approx(sum(draws) / len(draws), rel=1e-12)
    assert 0.6 * SIGMA / 3 <= noise <= 0.6 * SIGMA * 3
    reps = outcome.tables["quad-noise"]
    assert len(reps) == 5 and (reps["status"] == "ok").all()
    assert reps["replica"].str.startswith("seed=").all()


def test_failed_sets_are_failures_not_data(outcome):
    trace = outcome.tables["quad-trace"]
    failed = trace[trace["status"] != "ok"]
    assert len(failed) > 0 and (failed["status"] == "defect").all()  # x > 0.8 fails (Sobol covers [-1, 1])
    assert failed["objective"].isna().all()  # no objective for them, so in no range, band or noise
    assert (failed["x"] > 0.8).all() and (trace.loc[trace["status"] == "ok", "x"] <= 0.8).all()
    assert outcome.tables["quad-summary"].iloc[0]["failed_sets"] == len(failed)


def test_budget_caps_the_search_and_validation_is_marked(outcome):
    summary = outcome.tables["quad-summary"].iloc[0]
    trace = outcome.tables["quad-trace"]
    assert summary["search_runs"] <= 40
    assert trace["phase"].isin(["design", "local"]).sum() == summary["search_runs"]  # one cell per set here
    val = outcome.tables["quad-validation"]
    assert list(val["role"]) == [CALIBRATED, VALIDATED, VALIDATED]
    assert list(val["cell"]) == ["bar-heat-faces n=3 q", "bar-heat-faces n=4 q", "bar-heat-faces n=6 q"]
    # defaults x = 0.5, y = 0.1: q = 0.04 + 2 = 2.04 (+ noise), far outside the tolerance; calibrated: within
    assert (val["default_error"] > 2.0).all()
    assert (val.loc[val["role"] == VALIDATED, "calibrated_error"] < 0.05).all()
    assert summary["cells_not_matched [validated on]"] == 0 and summary["cells_matched [validated on]"] == 2
    assert summary["x [calibrated on]"] == outcome.best["x"]


def test_overlapping_calibration_and_validation_cells_are_refused(tmp_path):
    path = _study(tmp_path, validate_n="[3, 4]")  # n = 3 is the calibration cell
    with pytest.raises(SceneError) as err:
        load_study(str(path))
    message = str(err.value)
    assert "\n" not in message
    assert "overlap" in message and "bar-heat-faces n=3 q" in message and "quad" in message


def test_another_metric_of_a_calibration_run_is_allowed_and_flagged(tmp_path):
    """The shipped MCA calibration validates torsion on the run whose bending it was fitted to: allowed, and
    the validation table says the run is shared."""
    path = _study(tmp_path, validate_n="[3, 4]")
    text = path.read_text()
    head, tail = text.split("[[calibration.validate]]")
    path.write_text(head + "[[calibration.validate]]" + tail.replace('metric = "q"', 'metric = "q_ref"'))
    study = load_study(str(path))
    cal = study.calibrations[0]
    assert [(c.n, c.metric) for c in cal.validate] == [(3, "q_ref"), (4, "q_ref")]
    val = run_calibration(study, cal, Cache(tmp_path / "cache")).tables["quad-validation"]
    assert list(val["shares_calibration_run"]) == [False, True, False]


@pytest.mark.parametrize("change, words", [
    (('name = "x"', 'name = "nope"'), "is not a parameter of solver 'calib-quadratic'"),
    (("low = 1e-4", "low = 0.0"), "log = true"),
    (("budget = 40", "budget = 0"), "budget=0"),
    (('metric = "q"\nerror = "absolute"\nreference = {', 'metric = "nodes.l2"\nerror = "absolute"\nreference = {'),
     "field error against the analytic solution"),
    (("seed = 0", "seeed = 0"),
     "calibration[1] (quad): seeed is not a field of [[calibration]]; allowed: id, title, solver,"),
])
def test_bad_calibration_tables_are_one_line_errors(tmp_path, change, words):
    path = _study(tmp_path)
    path.write_text(path.read_text().replace(*change, 1))
    with pytest.raises(SceneError) as err:
        load_study(str(path))
    assert words in str(err.value) and "\n" not in str(err.value)


def _cli(args: list[str], env: dict[str, str]) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "pcverify.harness.cli", *args], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _lines(path: Path) -> list[str]:
    return path.read_text().splitlines() if path.exists() else []


def test_killed_calibration_resumes_and_a_rerun_computes_nothing(tmp_path):
    """SIGKILL halfway through the search; the rerun solves only what was not stored (no finished solve is
    repeated), and a third run solves nothing; the result equals an uninterrupted run's."""
    study = _study(tmp_path, sleep=0.05)
    log = tmp_path / "solves.log"
    env = {**os.environ, "PYTHONPATH": str(TESTS), "CALIB_SYNTHETIC_LOG": str(log), "OMP_NUM_THREADS": "1",
           "MPLBACKEND": "Agg"}
    args = ["study", str(study), "--out", str(tmp_path / "out")]
    proc = _cli(args, env)
    deadline = time.time() + 120
    while len(_lines(log)) < 20 and proc.poll() is None and time.time() < deadline:
        time.sleep(0.02)
    assert proc.poll() is None, "the calibration finished before it could be killed"
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    first = _lines(log)
    assert len(first) >= 20  # how many more were solved before the kill landed is the machine's load
    entries = len(list((tmp_path / "out" / "cache").glob("*.json")))
    assert entries >= len(first) - 1  # every finished solve was stored (the last may have been killed storing)

    log.unlink()
    second = _cli(args, env)
    _, err = second.communicate(timeout=300)
    assert second.returncode == 0, err[-2000:]
    resumed = _lines(log)
    assert resumed  # the kill landed halfway: the rerun had solves left to do
    assert not set(resumed) & set(first[:-1])  # nothing that was stored is solved again
    assert len(set(resumed)) == len(resumed)  # and nothing twice within the rerun

    log.unlink()
    third = _cli(args + ["--json"], env)
    out, err = third.communicate(timeout=300)
    assert third.returncode == 0, err[-2000:]
    assert _lines(log) == []  # the solver was never called
    summary = pd.read_csv(tmp_path / "out" / "calib-synthetic" / "quad-summary.csv").iloc[0]
    assert summary["solver_runs"] == 0 and summary["cache_hits"] > 0
    assert '"calibration_runs": 0' in out

    fresh = _cli(["study", str(study), "--out", str(tmp_path / "fresh")], {**env, "CALIB_SYNTHETIC_LOG": ""})
    assert fresh.wait(timeout=300) == 0
    once = pd.read_csv(tmp_path / "fresh" / "calib-synthetic" / "quad-trace.csv")
    resumed_trace = pd.read_csv(tmp_path / "out" / "calib-synthetic" / "quad-trace.csv")
    pd.testing.assert_frame_equal(once.drop(columns=["wall_s"]), resumed_trace.drop(columns=["wall_s"]))
    solved = set(first) | set(resumed)  # every cell solved once (the killed one, if any, twice: one line each run)
    assert len(list((tmp_path / "out" / "cache").glob("*.json"))) == len(solved)
    assert summary["cache_hits"] >= len(solved)  # the third run read every one of them back


def test_report_replays_the_calibration_from_the_cache_alone(tmp_path):
    """`pcverify report` reruns the search with compute=False: the same tables from the cached cells, and
    NotCached (nothing computed) when a cell is missing."""
    study = load_study(str(_study(tmp_path)))
    cal = study.calibrations[0]
    with pytest.raises(NotCached):
        run_calibration(study, cal, Cache(tmp_path / "empty"), compute=False)
    assert not (tmp_path / "empty").exists() or not list((tmp_path / "empty").glob("*.json"))
    first = run_calibration(study, cal, Cache(tmp_path / "cache"))
    again = run_calibration(study, cal, Cache(tmp_path / "cache"), compute=False)
    assert again.runs == 0 and again.hits > 0
    for name, table in first.tables.items():
        pd.testing.assert_frame_equal(table.drop(columns=["solver_runs", "cache_hits"], errors="ignore"),
                                      again.tables[name].drop(columns=["solver_runs", "cache_hits"],
                                                              errors="ignore"))


def test_shipped_calibration_study_is_well_formed():
    """The shipped study: five macromolecule parameters on one calibration cell with ten held-out cells, and
    MCA's krot with fifteen (torsion, axial and the third mode of a continuum kind at n = 4 share the fitted run,
    flagged, not refused)."""
    study = load_study("calibration")
    mm, mca = study.calibrations
    assert [p.name for p in mm.parameters] == ["damping_ratio", "drive_amplitude", "drive_frequency", "f_top", "p"]
    assert [(c.scene.name, c.n) for c in mm.calibrate] == [("bar-heat-faces", 4)]
    assert len(mm.validate) == 10 and mm.tolerance == 0.10
    assert [p.name for p in mca.parameters] == ["krot"] and len(mca.validate) == 15 and mca.tolerance == 0.05
    assert {c.key() for c in mca.calibrate} <= {c.key() for c in mca.validate}
    assert not {c.measure() for c in mca.calibrate} & {c.measure() for c in mca.validate}


def test_group_option_selects_a_calibration(tmp_path):
    """`--group ID` takes a calibration id (it reruns that calibration from the cache), unknown ids are named."""
    study = load_study(str(_study(tmp_path)))
    assert select_groups(study, ["quad"]).calibrations == study.calibrations
    with pytest.raises(SceneError) as err:
        select_groups(study, ["nope"])
    assert "allowed: one of quad" in str(err.value)


def test_a_calibration_where_every_set_fails_reports_no_values(tmp_path):
    """Every set a defect (fail_above = -1 < every x of the design): no calibrated values, no ranges, every
    held-out cell not matched; the tables and figures are still written."""
    path = _study(tmp_path)
    path.write_text(path.read_text().replace("fail_above = 0.8", "fail_above = -1.0"))
    study = load_study(str(path))
    outcome = run_calibration(study, study.calibrations[0], Cache(tmp_path / "cache"))
    summary = outcome.tables["quad-summary"].iloc[0]
    assert summary["calibrated"] == "no parameter set ran ok" and math.isnan(summary["objective [calibrated on]"])
    assert summary["cells_not_matched [validated on]"] == 2 and summary["failed_sets"] == summary["evaluations"]
    assert outcome.tables["quad-parameters"].empty and outcome.best == {}
    meta, tables = calibration_section(outcome, tmp_path / "report")
    assert "quad-validation.png" in meta["figures"] and (tmp_path / "report" / "quad-trace.png").exists()
