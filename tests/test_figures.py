"""Figures draw what their legends say: every entry visible, identical series once, legends off the data.

The checks (tests/figure_checks.py) read the description each figure saves beside its PNG; here they are
shown to catch the faults the report once had, and the stability figure is shown to draw every
measured point against its own probe's theory."""

import json

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
import pytest
from figure_checks import problems

from pcverify.harness.report import figures


def _described(fig):
    desc = figures.describe(fig)
    plt.close(fig)
    return desc


def test_checks_catch_a_legend_entry_with_nothing_drawn():
    """The old MCA heat stability figure: one point per series drawn as a dotted line, no marker, so
    the legend listed four series of which nothing was visible."""
    fig, ax = plt.subplots()
    ax.plot([0.0, 0.5], [1.0, 0.6], "k-", label="theory")
    for n, v in ((2, 1.09), (3, 1.02)):
        ax.plot([0.0], [v], ":", label=f"n={n} linear-discrete limit")
    ax.legend()
    found = problems(_described(fig))
    assert len(found) == 2 and all("no visible point" in p for p in found)


def test_checks_catch_duplicates_and_a_legend_over_the_data():
    fig, ax = plt.subplots()
    x = np.linspace(0, 1, 50)
    ax.plot(x, x, "o", label="a")
    ax.plot(x, x * (1 + 1e-12), "-", label="b")  # the same points to round-off
    ax.legend(loc="center")
    found = problems(_described(fig))
    assert any("duplicates 'a'" in p for p in found) and any("legend covers" in p for p in found)


@pytest.mark.filterwarnings("ignore:Data has no positive values")
def test_log_axes_hide_non_positive_points():
    fig, ax = plt.subplots()
    ax.loglog([1.0, 2.0], [0.0, -1.0], "o", label="zero error")
    ax.legend()
    assert "no visible point" in problems(_described(fig))[0]


def test_plot_once_merges_identical_series():
    fig, ax = plt.subplots()
    figures.plot_once(ax, [1, 2, 3], [0.1, 0.2, 0.3], "o-", "skfem")
    figures.plot_once(ax, [1, 2, 3], [0.1, 0.2, 0.3 * (1 + 1e-14)], "o-", "fipy")
    figures.plot_once(ax, [1, 2, 3], [0.1, 0.2, 0.31], "o-", "mca")
    figures.legend_outside(ax)
    desc = _described(fig)
    assert [s["label"] for s in desc["axes"][0]["series"]] == ["skfem = fipy", "mca"]
    assert problems(desc) == []


def _limits(rows):
    base = {"damping": np.nan, "ratio_tol": 1e-3, "runs": 12, "unstable_runs": 6, "undetected": 0,
            "relative_deviation": 0.0, "verdict": "bisected"}
    return pd.DataFrame([base | r for r in rows])


def test_mca_heat_limits_drawn_against_the_gershgorin_step(tmp_path):
    """x = n, theory 1 (the guarantee), every measured limit and every exact 2 / lambda_max drawn."""
    rows = [{"solver": "mca", "scene": "bar-heat-faces", "n": n, "damping_ratio": 0.0, "drive_amplitude": np.nan,
             "safety_theory": 1.0, "measured_safety": m, "linear_safety": lin}
            for n, m, lin in ((2, 1.0918, 1.0909), (3, 1.0234, 1.0228), (4, 1.0104, 1.0102), (6, 1.0039, 1.0037))]
    meta = {("mca", "bar-heat-faces"): {"quantity": "dt / dt_Gershgorin", "theory_label": "Gershgorin guarantee 1",
                                        "x_axis": "n"}}
    assert figures.stability_limits(_limits(rows), meta, tmp_path / "heat", "MCA heat")
    desc = json.loads((tmp_path / "heat.json").read_text())
    assert problems(desc) == []
    series = {s["label"]: s for s in desc["axes"][0]["series"]}
    assert series["measured"]["y"] == [1.0918, 1.0234, 1.0104, 1.0039]
    assert series["measured"]["visible_points"] == 4
    assert series["linear-discrete limit"]["y"] == [1.0909, 1.0228, 1.0102, 1.0037]
    assert series["Gershgorin guarantee 1"]["y"] == [1.0] * 4
    assert desc["axes"][0]["ylabel"] == "limit of dt / dt_Gershgorin" and desc["axes"][0]["xlabel"] == "n"


def test_macromolecule_limits_keep_bounds_and_one_linear_series_per_n(tmp_path):
    """Damping on the x axis; a case with no time-step limit (unstable at every dt) is drawn as such, and
    the linear-discrete limits of two lattices are two series, not one zigzag."""
    rows = []
    for n in (2, 3):
        for z in (0.0, 0.1, 0.3):
            theory = np.sqrt(1 + z * z) - z
            rows.append({"solver": "macromolecule", "scene": "bar-heat-paper", "n": n, "damping_ratio": z,
                         "drive_amplitude": 0.01, "safety_theory": theory, "measured_safety": theory * 0.99,
                         "linear_safety": theory * (0.98 if n == 2 else 0.97)})
    rows[-1] |= {"verdict": "unstable at every dt tried, down to ratio_lo=0.05: not a time-step limit",
                 "measured_safety": 0.05 * rows[-1]["safety_theory"]}
    meta = {("macromolecule", "bar-heat-paper"): {"quantity": "dt omega_max / 2", "x_axis": "damping_ratio",
                                                  "theory_label": "theory sqrt(1+zeta^2) - zeta"}}
    assert figures.stability_limits(_limits(rows), meta, tmp_path / "mm", "macromolecule")
    desc = json.loads((tmp_path / "mm.json").read_text())
    assert problems(desc) == []
    series = {s["label"]: s for s in desc["axes"][0]["series"]}
    assert series["measured n=2, D=0.01 a"]["visible_points"] == 3
    assert series["measured n=3, D=0.01 a"]["visible_points"] == 2
    bound = [s for label, s in series.items() if label.startswith("no time-step limit")]
    assert len(bound) == 1 and bound[0]["visible_points"] == 1
    assert {"linear-discrete limit n=2", "linear-discrete limit n=3"} <= set(series)
    assert series["theory sqrt(1+zeta^2) - zeta"]["y"] == pytest.approx([1.0, np.sqrt(1.01) - 0.1,
                                                                          np.sqrt(1.09) - 0.3])
