"""Replicas with stated coverage: a claim judged on the mean of replicas (uncertainty = "spread") whose true
value lies exactly on its bound passes at most 5 % of the time, for any number of replicas (Student's t)."""

import numpy as np
import pandas as pd
import pytest
from scipy.stats import t as student_t

from pcverify.harness.judge.verdict import verdicts
from pcverify.harness.study.claims import parse_claims

SETS = 4000  # replica sets per case: the pass rate's standard error is sqrt(0.05 x 0.95 / 4000) = 0.34 %


def _pass_rate(values: np.ndarray, tolerance: float, sense: str) -> float:
    """The share of replica sets (rows of `values`) whose claim passes, judged by the harness."""
    sets, n = values.shape
    table = pd.DataFrame({"set": np.repeat(np.arange(sets), n), "bulk": values.ravel()})
    claim = {"id": "c", "text": "t", "table": "replicas", "metric": "bulk", "reference": "theory", "per": "set",
             "aggregate": "mean", "uncertainty": "spread", "sense": sense, "target": 0.0, "tolerance": tolerance}
    found = verdicts("s", parse_claims([claim], "test.toml"), {"replicas": table})
    return float((found["verdict"] == "pass").mean())


@pytest.mark.parametrize("replicas", [3, 5])
@pytest.mark.parametrize("sense", ["at-most", "within"])
def test_a_true_value_on_the_bound_passes_at_most_five_percent_of_the_time(replicas, sense):
    rng = np.random.default_rng(replicas)
    values = rng.normal(0.3, 0.02, (SETS, replicas))  # the true mean 0.3 lies on the bound 0 + 0.3
    rate = _pass_rate(values, 0.3, sense)
    assert rate <= 0.05 + 4.4 * 0.0034, rate  # 4.4 standard errors above 5 %: a false alarm once in 1e5 runs
    assert rate >= 0.05 - 4.4 * 0.0034, rate  # and not a band so wide that nothing passes


def test_one_standard_error_would_pass_a_value_on_its_bound_a_fifth_of_the_time():
    """The band the harness used before: mean +- 1 SE of 3 replicas passes P(T_2 <= -1) = 21 % of such claims."""
    rng = np.random.default_rng(7)
    values = rng.normal(0.3, 0.02, (SETS, 3))
    mean, se = values.mean(axis=1), values.std(axis=1, ddof=1) / np.sqrt(3)
    assert np.mean(mean + se <= 0.3) == pytest.approx(student_t.cdf(-1.0, 2), abs=4.4 * 0.0065)
    assert student_t.cdf(-1.0, 2) == pytest.approx(0.211, abs=1e-3)
