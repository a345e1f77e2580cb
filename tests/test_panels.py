"""Panels: quantities of several solvers side by side, read from the groups' tables, with their reference.

The values a panel shows must be the ones the groups computed (the right table, row and solver), its deviations
(value - reference) / |reference|, and a value it cannot pick (absent, or several rows) shown empty with why."""

import math

import pandas as pd
import pytest

from pcverify.harness.cli import main
from pcverify.harness.judge.side_by_side import panel_table
from pcverify.harness.study.panels import Panel, PanelRow
from pcverify.harness.study.study import load_study

STUDY = """
name = "side"
[[group]]
id = "faces"
scene = "bar-heat-faces"
solvers = ["fipy", "skfem"]
n = [2, 3]

[[group]]
id = "patch"
analysis = "convergence"
scene = "bar-heat-patch"
scene_params = { rho = 0.003 }
solvers = ["fipy"]
n = [2]
refine = [2, 3, 4]

[[panel]]
id = "both"
title = "FiPy and scikit-fem side by side"
solvers = ["fipy", "skfem"]

[[panel.row]]
label = "mean temperature at n = 3 (K)"
table = "faces-cells"
metric = "volume_mean"
select = { n = 3 }
scale = 2.0
reference = 250.0
reference_kind = "analytic"

[[panel.row]]
label = "bulk median against the patch's extrapolation"
table = "faces-cells"
metric = "bulk_median"
select = { n = 2 }
reference_table = "patch-fits"
reference_select = { quantity = "bulk_median" }
reference_kind = "extrapolated"
"""


def _row(**kw) -> PanelRow:
    base = dict(label="q", table="g-cells", metric="x", select={}, scale=1.0, reference=2.0, reference_table=None,
                reference_metric="extrapolated", reference_select={}, reference_kind="analytic")
    return PanelRow(**{**base, **kw})


def test_values_deviations_and_what_cannot_be_picked():
    cells = pd.DataFrame({"solver": ["a", "b", "b", "c"], "n": [4, 4, 4, 4], "x": [3.0, 1.0, 1.5, "bad"]})
    fits = pd.DataFrame({"quantity": ["x"], "extrapolated": [4.0], "extrapolated_unc": [0.25]})
    panel = Panel("p", "p", ("a", "b", "c", "d"), (_row(scale=10.0), _row(reference=None, reference_table="f-fits",
                                                                              reference_select={"quantity": "x"})))
    t = panel_table(panel, {"g-cells": cells, "f-fits": fits}).set_index("quantity", drop=False)
    first, second = t.iloc[0], t.iloc[1]
    assert first["a"] == 30.0 and first["a dev"] == pytest.approx(0.5) and first["reference"] == 20.0
    assert first["reference_unc"] == 0.0
    assert math.isnan(first["b"]) and "b: 2 rows of g-cells" in first["note"]  # never one row picked of two
    assert math.isnan(first["c"]) and "c: x is empty" in first["note"]
    assert math.isnan(first["d"]) and "d: no row of g-cells" in first["note"]
    assert second["a dev"] == pytest.approx(-0.25) and second["reference"] == 4.0
    assert second["reference_unc"] == 0.25 and second["reference_kind"] == "analytic"


def test_a_missing_reference_table_is_said():
    panel = Panel("p", "p", ("a",), (_row(reference=None, reference_table="f-fits"),))
    t = panel_table(panel, {"g-cells": pd.DataFrame({"solver": ["a"], "x": [1.0]})})
    assert math.isnan(t["a dev"][0]) and "reference: no table f-fits" in t["note"][0]


def test_a_study_panel_shows_the_groups_values(tmp_path):
    path = tmp_path / "side.toml"
    path.write_text(STUDY)
    out = tmp_path / "r"
    assert main(["study", str(path), "--out", str(out)]) == 0
    cells = pd.read_csv(out / "side" / "faces-cells.csv")
    fits = pd.read_csv(out / "side" / "patch-fits.csv").set_index("quantity")
    panel = pd.read_csv(out / "side" / "both.csv")
    for solver in ("fipy", "skfem"):
        mean = cells[(cells.solver == solver) & (cells.n == 3)]["volume_mean"].item()
        assert panel[solver][0] == pytest.approx(2.0 * mean, rel=1e-12)
        assert panel[f"{solver} dev"][0] == pytest.approx((mean - 250.0) / 250.0, rel=1e-12)
        median = cells[(cells.solver == solver) & (cells.n == 2)]["bulk_median"].item()
        ref = fits.loc["bulk_median", "extrapolated"]
        assert panel[f"{solver} dev"][1] == pytest.approx((median - ref) / abs(ref), rel=1e-12)
    manifest = (out / "side" / "manifest.json").read_text()
    assert '"both.csv"' in manifest
    html = (out / "index.html").read_text()
    assert "FiPy and scikit-fem side by side" in html
    assert "<details class='table' open><summary><b>both</b>" in html  # a panel is shown, not folded away
    assert "<details class='table'><summary><b>faces-cells</b>" in html


@pytest.mark.parametrize("edit, words", [
    (('table = "faces-cells"\nmetric = "volume_mean"', 'table = "nope-cells"\nmetric = "volume_mean"'),
     ["panel[1] (both)", "table = 'nope-cells' is not a table of this study", "allowed: a group's table"]),
    (('reference = 250.0\n', 'reference = 250.0\nreference_table = "patch-fits"\n'), ["reference", "reference_table"]),
    (('reference_kind = "analytic"', 'reference_kind = "guess"'), ["reference_kind", "allowed"]),
    (('solvers = ["fipy", "skfem"]\n\n[[panel.row]]', 'solvers = []\n\n[[panel.row]]'), ["solvers"]),
])
def test_a_bad_panel_is_one_line_naming_the_field(tmp_path, edit, words):
    path = tmp_path / "side.toml"
    text = STUDY.replace(*edit, 1)
    assert text != STUDY
    path.write_text(text)
    with pytest.raises(Exception) as err:  # noqa: PT011 - the one-line SceneError the CLI prints
        load_study(str(path))
    message = str(err.value)
    assert "\n" not in message and all(w in message for w in words), message
