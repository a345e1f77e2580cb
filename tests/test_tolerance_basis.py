"""Tolerances tied to what is measured: every shipped claim says where its tolerance comes from, and the report
flags a tolerance that a tenfold worse value would still pass (unless it is derived)."""

import re
import tomllib
from pathlib import Path

import pandas as pd
import pytest

from pcverify.harness.judge.verdict import LOOSE, records, slack, verdicts
from pcverify.harness.report.findings import claim_slack
from pcverify.harness.report.page import verdicts_section
from pcverify.harness.study.claims import parse_claims
from pcverify.scene import SceneError

REPO = Path(__file__).resolve().parents[1]
STUDY_FILES = (sorted((REPO / "harness" / "studies").glob("*.toml")) + sorted((REPO / "examples").glob("*/*.toml")))
TABLE = {"g-cells": pd.DataFrame({"solver": ["a", "a"], "n": [2, 3], "err": [1e-4, 2e-5]})}


def _shipped_claims() -> list[tuple[str, dict]]:
    return [(path.name, claim) for path in STUDY_FILES if not path.name.endswith(".mutants.toml")
            for claim in tomllib.loads(path.read_text()).get("claim", [])]


def test_every_shipped_tolerance_says_whether_it_is_derived_or_measured_and_a_measured_one_is_at_most_ten_fold():
    """A claim with a non-zero tolerance (an at-least claim's target is its own bound) carries its basis; a
    measured basis states its factor, at most 10."""
    unstated, too_loose = [], []
    for name, claim in _shipped_claims():
        if claim.get("tolerance", 0) == 0 or claim.get("sense") == "at-least":
            continue
        basis = claim.get("tolerance_basis", "")
        if not basis:
            unstated.append(f"{name}:{claim['id']}")
        elif basis.startswith("measured:"):
            factors = [float(f) for f in re.findall(r"\(([0-9.e+-]+)[x×]\)", basis)]
            if not factors or max(factors) > LOOSE:
                too_loose.append(f"{name}:{claim['id']}: {basis}")
    assert not unstated, f"claims without a tolerance_basis: {unstated}"
    assert not too_loose, f"measured bases without a factor of at most {LOOSE:g}: {too_loose}"


@pytest.mark.parametrize("value, target, tolerance, sense, u, expected", [
    (1.0e-4, 0.0, 1e-3, "at-most", float("nan"), 10.0),  # tolerance over the value of an at-most claim
    (2.01, 2.0, 0.2, "within", 0.01, 10.0),  # over the deviation plus its uncertainty
    (0.5, 0.0, 0.0, "within", float("nan"), float("nan")),  # a zero tolerance has no slack
    (1.9, 1.5, 0.0, "at-least", float("nan"), float("nan")),  # an at-least claim's target is its bound
])
def test_slack_is_the_tolerance_over_the_far_edge_of_the_band(value, target, tolerance, sense, u, expected):
    got = slack(value, target, tolerance, sense, u)
    assert got == pytest.approx(expected, rel=1e-9, nan_ok=True)


def test_a_value_equal_to_its_target_counts_its_round_off_as_the_deviation():
    assert slack(50.0, 50.0, 1e-6, "within") == pytest.approx(1e-6 / (50.0 * 2.220446049250313e-16))


def _records(tolerance: float, basis: str) -> list[dict]:
    claim = {"id": "c", "text": "t", "table": "g-cells", "metric": "err", "reference": "analytic", "sense": "at-most",
             "per": "n", "tolerance": tolerance} | ({"tolerance_basis": basis} if basis else {})
    return records(verdicts("s", parse_claims([claim], "test.toml"), TABLE))


def test_the_report_flags_a_measured_tolerance_a_tenfold_worse_value_passes_and_not_a_derived_one():
    loose = _records(2e-3, "measured: 1e-4 (20x)")  # the largest value is 1e-4: 20x
    assert [r["slack"] for r in loose] == pytest.approx([20.0, 100.0])
    assert claim_slack(loose) == (pytest.approx(20.0), True)
    page = verdicts_section(loose)
    assert "Loose: s/c." in page and ">loose</span>" in page and "20&times; the largest deviation" in page
    derived = _records(2e-3, "derived: a bound")
    assert claim_slack(derived)[1] is False and "Loose: none." in verdicts_section(derived)
    tight = _records(5e-4, "measured: 1e-4 (5x)")
    assert claim_slack(tight) == (pytest.approx(5.0), False)


def test_a_basis_that_is_neither_derived_nor_measured_is_refused():
    with pytest.raises(SceneError, match="tolerance_basis"):
        _records(1e-3, "because it looked right")
