"""Claims in a researcher's words: a tolerance relative to the target, cases over several columns, and a note
that names the filter which left a target without rows."""

import json
import subprocess
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from pcverify.harness.judge.verdict import verdicts
from pcverify.harness.study.claims import parse_claims
from pcverify.scene import SceneError

REPO = Path(__file__).resolve().parents[1]

MODES = {"g-cells": pd.DataFrame({
    "solver": ["lammps", "lammps", "mca", "mca", "skfem", "skfem"],
    "n": [3, 4, 3, 4, 3, 4],
    "f1_hz": [8600.0, 8500.0, 9000.0, 8700.0, 8413.0, 8413.0],
})}


def _verdicts(**claim) -> pd.DataFrame:
    base = {"id": "c", "text": "t", "table": "g-cells", "metric": "f1_hz", "reference": "extrapolated"}
    return verdicts("s", parse_claims([base | claim], "test.toml"), MODES)


def test_a_relative_tolerance_is_a_share_of_the_target():
    """3 % of 8 413 Hz is 252.4 Hz: 8 600 Hz (187 Hz off) passes, 8 700 Hz (287 Hz off) fails."""
    v = _verdicts(select={"solver": "lammps"}, per="n", tolerance_rel=0.03, target=8413.0)
    assert v["tolerance"].tolist() == pytest.approx([0.03 * 8413.0] * 2)
    assert v["verdict"].tolist() == ["pass", "pass"]  # 8 600 and 8 500: 187 and 87 Hz off
    v = _verdicts(select={"solver": "mca"}, per="n", tolerance_rel=0.03, target=8413.0)
    assert v["verdict"].tolist() == ["fail", "fail"]  # 9 000 and 8 700: 587 and 287 Hz off
    assert "tolerance 0.03 x |target|" in v["note"][0]
    v = _verdicts(select={"solver": "mca", "n": 4}, tolerance_rel=0.03, tolerance=40.0, target=8413.0)
    assert v["tolerance"][0] == pytest.approx(292.39) and v["verdict"][0] == "pass"  # the two add up


def test_a_relative_tolerance_against_another_solvers_rows_is_a_share_of_that_value():
    v = _verdicts(select={"solver": ["lammps", "mca"]}, per=["solver", "n"], against={"solver": "skfem"},
                  tolerance_rel=0.03)
    assert v["case"].tolist() == ["solver=lammps, n=3", "solver=lammps, n=4", "solver=mca, n=3", "solver=mca, n=4"]
    assert v["target"].tolist() == pytest.approx([8413.0] * 4)
    assert v["verdict"].tolist() == ["pass", "pass", "fail", "fail"]


def test_a_claim_needs_a_tolerance_of_one_kind():
    with pytest.raises(SceneError, match="tolerance is missing; allowed: a tolerance"):
        _verdicts()


def test_per_over_two_columns_makes_one_case_per_combination_of_values():
    v = _verdicts(per=["solver", "n"], target=8413.0, tolerance=300.0)
    assert len(v) == 6 and v["case"][0] == "solver=lammps, n=3"
    assert dict(zip(v["case"], v["verdict"], strict=True))["solver=mca, n=3"] == "fail"
    v = _verdicts(per=["solver", "cell"], target=8413.0, tolerance=300.0)
    assert v["verdict"].tolist() == ["fail"] and "column cell is not in table g-cells" in v["note"][0]
    assert "per may list several of them" in v["note"][0]


def test_a_target_emptied_by_the_case_filter_says_which_filter_did_it():
    """per = "solver" filters the target's rows by the case's solver too: against the other solver's rows there
    are none, and the note says so and how to keep them (name the column in against)."""
    v = _verdicts(select={"solver": "mca"}, per="solver", against_table="g-cells",
                  against={"n": 4}, tolerance=300.0)
    assert v["verdict"].tolist() == ["pass"]  # the target is mca's own n = 4 row: 8 700 against 9 000
    v = _verdicts(select={"solver": "mca"}, per="solver", against={"n": 4, "solver": "skfem"}, tolerance=300.0)
    assert v["verdict"].tolist() == ["fail"] and v["target"][0] == pytest.approx(8413.0)  # named: kept
    empty = verdicts("s", parse_claims([{"id": "c", "text": "t", "table": "g-cells", "metric": "f1_hz",
                                         "reference": "extrapolated", "select": {"solver": "mca"}, "per": "solver",
                                         "against_table": "other", "tolerance": 1.0}], "t.toml"),
                     MODES | {"other": MODES["g-cells"].query("solver == 'skfem'")})
    assert empty["verdict"].tolist() == ["fail"]
    assert "filtered by the case's solver=mca; name a column in against" in empty["note"][0]


# work-precision rows of two solvers: cost ~ error^-1.5 for both, the particle one 2.5 times dearer
WP = pd.DataFrame({"solver": ["fipy"] * 3 + ["mca"] * 3, "n": [3, 5, 9] * 2,
                   "err.nodes.l2": [1e-2, 2.5e-3, 6.25e-4] * 2,
                   "cpu_s": [0.1, 0.8, 6.4, 0.25, 2.0, 16.0],
                   "cpu_s_unc": [0.01, 0.04, 0.2, 0.02, 0.1, 0.5]})


def _cost(**claim) -> pd.DataFrame:
    base = {"id": "cost", "text": "t", "table": "g-work-precision", "metric": "cpu_s", "reference": "analytic",
            "per": "solver", "at_error": 1e-3, "sense": "at-most"}
    return verdicts("s", parse_claims([base | claim], "test.toml"), {"g-work-precision": WP})


def test_a_cost_claim_reads_the_cpu_seconds_to_reach_an_error_log_log_between_the_levels_that_bracket_it():
    v = _cost(select={"solver": "fipy"}, target=5.0, tolerance=0.0)
    assert v["value"][0] == pytest.approx(0.8 * 2.5 ** 1.5, rel=1e-12)  # exact for a power law: 3.162 s
    w = np.log(0.4) / np.log(0.25)
    assert v["uncertainty"][0] == pytest.approx((1 - w) * 0.04 + w * 0.2)  # the repeats' spread, interpolated
    assert v["verdict"][0] == "pass"  # 3.16 + 0.15 <= 5
    assert _cost(select={"solver": "fipy"}, target=3.0, tolerance=0.0)["verdict"][0] == "fail"
    assert _cost(select={"solver": "fipy"}, target=3.25, tolerance=0.0)["verdict"][0] == "inconclusive"


def test_a_cost_ratio_at_equal_error_is_a_relative_tolerance_on_the_other_solvers_cost():
    """"MCA costs at most 3x FiPy's at equal error" (at most target + 2 x target): 2.5x passes, 2x fails."""
    v = _cost(select={"solver": "mca"}, against={"solver": "fipy"}, tolerance_rel=2.0, uncertainty=0.0)
    assert v["value"][0] / v["target"][0] == pytest.approx(2.5) and v["verdict"][0] == "pass"
    v = _cost(select={"solver": "mca"}, against={"solver": "fipy"}, tolerance_rel=1.0, uncertainty=0.0)
    assert v["verdict"][0] == "fail"


def test_a_cost_is_never_extrapolated_beyond_the_errors_the_levels_reach():
    v = _cost(select={"solver": "fipy"}, at_error=1e-4, target=5.0, tolerance=0.0)
    assert v["verdict"][0] == "fail" and "from 0.000625 to 0.01, not 0.0001" in v["note"][0]
    v = _cost(select={"solver": "fipy"}, error_metric="err.nodes.linf", target=5.0, tolerance=0.0)
    assert "error column err.nodes.linf is not in the table" in v["note"][0]


def test_the_example_study_in_a_researchers_words_runs_and_its_claims_pass(tmp_path):
    """examples/studies/researcher-claims.toml: the second-order line over (solver, n), MCA beside FiPy per n, and
    MCA's CPU time to reach 1e-3 against FiPy's at the same error (measured about 12x less)."""
    out = subprocess.run(["pcverify", "study", str(REPO / "examples" / "studies" / "researcher-claims.toml"),
                          "--out", str(tmp_path), "--jobs", "1"], capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    records = json.loads((tmp_path / "researcher-claims" / "verdicts.json").read_text())
    by = {}
    for r in records:
        by.setdefault(r["claim"], []).append(r)
    assert [r["case"] for r in by["second-order-line"]][:2] == ["solver=fipy, n=3", "solver=fipy, n=4"]
    assert len(by["second-order-line"]) == 8 and len(by["mca-beside-fipy"]) == 4
    cost = by["mca-cost-at-1e-3"][0]
    assert cost["value"] < cost["target"] and cost["uncertainty"] is not None
    assert all(r["verdict"] == "pass" for r in records), [(r["claim"], r["case"], r["note"]) for r in records
                                                          if r["verdict"] != "pass"]
