"""Report: verdicts judged from tables, VTU files, figures and the index built from a small study."""

import json
import math
import subprocess
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from figure_checks import report_problems

from pcverify.harness.cli import main
from pcverify.harness.judge.verdict import verdicts
from pcverify.harness.report.provenance import source_commit
from pcverify.harness.report.vtu import write_vtu
from pcverify.harness.study.claims import parse_claims
from pcverify.scene import SceneError
from pcverify.solvers.particles.mca.solver import Mca

REPO = Path(__file__).resolve().parents[1]

TABLES = {
    "g-cells": pd.DataFrame({"solver": ["a", "a", "b", "b"], "n": [2, 3, 2, 3], "err": [1e-3, 2e-4, 5e-2, 1e-2],
                             "bulk": [0.30, 0.32, 0.31, 0.33], "gci": [1e-3, 5e-4, np.nan, np.nan]}),
}


def _claims(**over):
    base = {"id": "c", "text": "t", "table": "g-cells", "metric": "err", "reference": "analytic", "tolerance": 1e-3}
    return parse_claims([base | over], "test.toml")


def test_verdicts_pass_fail_and_nothing_to_judge_fails():
    v = verdicts("s", _claims(select={"solver": "a"}), TABLES)
    assert v["verdict"].tolist() == ["pass"] and v["value"][0] == pytest.approx(1e-3)  # max over n
    v = verdicts("s", _claims(select={"solver": "b"}), TABLES)
    assert v["verdict"].tolist() == ["fail"] and v["error"][0] == pytest.approx(5e-2)
    v = verdicts("s", _claims(select={"solver": "c"}), TABLES)  # a case the claim names is not there
    assert v["verdict"].tolist() == ["fail"] and "solver=c" in v["note"][0]
    v = verdicts("s", _claims(table="missing"), TABLES)
    assert v["verdict"].tolist() == ["fail"] and "has no rows" in v["note"][0]


def test_verdicts_per_case_against_other_rows_and_uncertainty_column():
    claims = _claims(metric="bulk", select={"solver": "a"}, against={"solver": "b"}, per="n", tolerance=0.015,
                     reference="same-grid", uncertainty="gci")
    v = verdicts("s", claims, TABLES)
    assert v["case"].tolist() == ["n=2", "n=3"]
    assert v["error"].tolist() == pytest.approx([0.01, 0.01])
    assert v["uncertainty"].tolist() == pytest.approx([1e-3, 5e-4])
    assert v["verdict"].tolist() == ["pass", "pass"]
    v = verdicts("s", _claims(metric="bulk", target=1 / 3, per="n", tolerance=0.02, reference="paper"), TABLES)
    assert v["verdict"].tolist() == ["fail", "pass"]  # max bulk at n=2 is 0.31: |0.31 - 1/3| > 0.02


@pytest.mark.parametrize("over, word", [({"reference": "magic"}, "reference="), ({"tolerance": -1}, "tolerance="),
                                        ({"aggregate": "sum"}, "aggregate="), ({"colour": 1}, "colour"),
                                        ({"tolerance": math.nan}, "tolerance=")])
def test_bad_claims_name_the_field(over, word):
    with pytest.raises(SceneError, match=word):
        _claims(**over)


def test_vtu_round_trip(tmp_path):
    pts = np.random.default_rng(1).random((7, 3))
    vals = np.linspace(0, 1, 7)
    path = write_vtu(tmp_path / "f.vtu", pts, {"T_over_t_max": vals, "u": pts * 2})
    root = ET.parse(path).getroot()
    piece = root.find("UnstructuredGrid/Piece")
    assert piece.get("NumberOfPoints") == "7" and piece.get("NumberOfCells") == "7"
    arrays = {a.get("Name"): np.array(a.text.split(), float) for a in root.iter("DataArray")}
    assert np.array_equal(arrays["Points"].reshape(-1, 3), pts)  # repr() keeps every bit
    assert np.array_equal(arrays["T_over_t_max"], vals) and np.array_equal(arrays["u"].reshape(-1, 3), 2 * pts)
    assert set(arrays["types"]) == {1.0} and arrays["offsets"][-1] == 7
    with pytest.raises(ValueError, match="field"):
        write_vtu(tmp_path / "g.vtu", pts, {"bad": vals[:3]})


STUDY = """
name = "mini"
title = "mini report study"
[[group]]
id = "paper"
title = "the paper's scene: particles and continuum"
analysis = "table"
scene = "bar-heat-paper"
solvers = ["fipy", "macromolecule"]
n = [2, 3]
solver_params = { macromolecule = { t_end = 1.0 } }
figures = ["edge-profiles", "render-3d"]
vtu = true
[[group]]
id = "faces"
title = "steady faces"
analysis = "table"
scene = "bar-heat-faces"
solvers = ["fipy"]
n = [2, 3]
[[group]]
id = "wp"
title = "transient faces: work-precision"
analysis = "work-precision"
scene = "bar-heat-faces"
scene_params = { mode = "transient", t_end = 0.5, dt = 0.05 }
solvers = ["fipy"]
n = [2, 3, 4]
[[group]]
id = "conv"
title = "transient faces: MCA and FiPy errors against h (the edges' errors equal the nodes' on this 1-D field)"
analysis = "convergence"
scene = "bar-heat-faces"
scene_params = { mode = "transient", t_end = 0.5, dt = 0.05 }
solvers = ["mca", "fipy"]
n = [2, 3, 4]
[[group]]
id = "heat-limit"
title = "MCA explicit heat: measured limit of dt / dt_Gershgorin against the guarantee and 2 / lambda_max"
analysis = "stability"
probe = "limit"
scene = "bar-heat-faces"
scene_params = { mode = "transient", t_end = 1.0, dt = 0.005 }
solvers = ["mca"]
n = [2, 3]
solver_params = { linear = true, ratio_hi = 3.0 }
[[claim]]
id = "exact-line"
text = "FiPy reproduces the steady linear profile"
table = "faces-cells"
select = { solver = "fipy" }
metric = "err.nodes.linf"
reference = "analytic"
tolerance = 1e-9
uncertainty = 1e-12
[[claim]]
id = "impossible"
text = "FiPy's transient error is below 1e-30 (must fail)"
table = "wp-work-precision"
metric = "err.nodes.l2"
reference = "analytic"
tolerance = 1e-30
[[claim]]
id = "too-uncertain"
text = "FiPy's steady profile within 1e-9, with an uncertainty of 1e-8 (inconclusive)"
table = "faces-cells"
select = { solver = "fipy" }
metric = "err.nodes.linf"
reference = "analytic"
tolerance = 1e-9
uncertainty = 1e-8
[[claim]]
id = "absent"
text = "a solver that is not in the study"
table = "faces-cells"
select = { solver = "nobody" }
metric = "bulk_median"
reference = "same-grid"
tolerance = 0.1
"""


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("report")
    path = tmp / "mini.toml"
    path.write_text(STUDY)
    out = tmp / "reports"
    assert main(["study", str(path), "--out", str(out), "--json"]) == 0
    return out


def test_study_report_has_verdicts_figures_and_vtu(report):
    folder = report / "mini"
    v = pd.read_csv(folder / "verdicts.csv").set_index("claim")
    assert v.loc["exact-line", "verdict"] == "pass" and v.loc["exact-line", "value"] < 1e-9
    assert v.loc["impossible", "verdict"] == "fail" and v.loc["absent", "verdict"] == "fail"
    assert v.loc["too-uncertain", "verdict"] == "inconclusive" and "straddles" in v.loc["too-uncertain", "note"]
    assert "solver=nobody" in v.loc["absent", "note"]
    for fig in ("paper-edge-profiles", "paper-render-3d", "wp"):
        assert (folder / f"{fig}.png").stat().st_size > 5000 and (folder / f"{fig}.svg").exists()
    manifest = json.loads((folder / "manifest.json").read_text())
    vtus = manifest["sections"][0]["vtu"]
    assert len(vtus) == 4  # fipy and macromolecule at n = 2, 3
    counts = {int(ET.parse(folder / f).getroot().find("UnstructuredGrid/Piece").get("NumberOfPoints")) for f in vtus}
    assert counts == {16, 63}
    wp = pd.read_csv(folder / "wp-work-precision.csv")
    assert len(wp) == 3 and (wp["timing"] == "serial after warm-up").all()
    assert wp.sort_values("n")["err.nodes.l2"].is_monotonic_decreasing  # finer lattice, smaller error
    paper = pd.read_csv(folder / "paper-cells.csv")
    # completed runs are drawn whatever their diagnostic status; a figure of blown-up runs would prove nothing
    assert set(paper["status"]) <= {"ok", "non-stationary", "defect"}
    html = (report / "index.html").read_text()
    order = [html.index(f"id='{i}'") for i in ("summary", "findings", "verdicts", "mini", "provenance")]
    assert order == sorted(order)
    figs = [f for s in manifest["sections"] for f in s["figures"]]
    assert html.count("<img ") == len(figs) >= 5 and "case fail" in html and "pcverify verdict" in html


def test_model_notes_beside_the_study(report):
    """The MCA's model notes travel with the study that ran it (manifest and page); FiPy has none."""
    manifest = json.loads((report / "mini" / "manifest.json").read_text())
    assert manifest["model_notes"] == {"mca": list(Mca().notes)}
    html = (report / "index.html").read_text()
    assert f"Model notes ({len(Mca().notes)}): where mca departs" in html and "id='mini-model-notes'" in html


def test_every_figure_draws_what_its_legend_lists(report):
    """For every figure in the manifest: each legend entry has a visible point, no series duplicates
    another, no legend covers data (tests/figure_checks.py on the description saved beside it)."""
    found = report_problems(report)
    assert len(found) >= 5 and all(v == [] for v in found.values()), found
    heat = json.loads((report / "mini" / "heat-limit-limits.json").read_text())["axes"][0]
    series = {s["label"]: s for s in heat["series"]}
    assert heat["ylabel"] == "limit of dt / dt_Gershgorin" and series["measured"]["visible_points"] == 2
    limits = pd.read_csv(report / "mini" / "heat-limit-limits.csv")
    assert series["measured"]["y"] == limits.sort_values("n")["measured_safety"].tolist()
    assert series["linear-discrete limit"]["y"] == limits.sort_values("n")["linear_safety"].tolist()
    conv = json.loads((report / "mini" / "conv.json").read_text())["axes"][0]
    labels = [s["label"] for s in conv["series"]]
    # both norms by default (the group sets no `norms`): per solver one L2 and one Linf line
    assert len(labels) == 4 and sum("nodes=front_top_edge=bottom_back_edge.linf" in x for x in labels) == 2
    assert sum("nodes=front_top_edge=bottom_back_edge.l2" in x for x in labels) == 2


CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                 "--disable-component-update", "--no-first-run"]
VIEWPORT = {"width": 1400, "height": 900}
HOLDS = """() => ({
    images: Array.from(document.images).map(i => [i.alt, i.complete && i.naturalWidth > 0]),
    tables: Array.from(document.querySelectorAll('table')).map(t => t.id),
    sections: Array.from(document.querySelectorAll('section')).map(s => s.id),
    summary: document.getElementById('summary') && document.getElementById('summary').getBoundingClientRect().toJSON(),
    width: document.documentElement.scrollWidth})"""
ROWS = """() => Array.from(document.querySelectorAll('#verdicts-table tr.claim'))
    .map(r => [r.dataset.state, !r.hidden])"""


def _browser(p):
    """Debian's chromium through playwright; skipped where it is absent, unless PCVERIFY_REQUIRE_BROWSER
    is set (CI installs it: there the check must run)."""
    import os

    if not os.path.exists(CHROMIUM):
        if os.environ.get("PCVERIFY_REQUIRE_BROWSER"):
            pytest.fail(f"{CHROMIUM} is absent but PCVERIFY_REQUIRE_BROWSER is set")
        pytest.skip(f"{CHROMIUM} is absent (Debian package chromium); the browser check needs it")
    return p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)


def _open(browser, url: str, errors: list[str]):
    page = browser.new_page(viewport=VIEWPORT)
    page.on("console", lambda m: errors.append(f"console.{m.type}: {m.text}") if m.type == "error" else None)
    page.on("pageerror", lambda exc: errors.append(f"page error: {exc}"))
    page.on("requestfailed", lambda r: errors.append(f"request failed: {r.url[:80]}"))
    page.goto(url, wait_until="load")
    return page


def test_index_in_headless_chromium(report, tmp_path):
    """At 1400 x 900: the summary fits the first screen, every figure decodes, nothing is wider than the
    page, the filter hides the passing claims on a click, no browser error; screenshots of the first
    screen and of a study section are saved beside the report."""
    sync_api = pytest.importorskip("playwright.sync_api", reason="playwright (test extra) is not installed")
    errors: list[str] = []
    with sync_api.sync_playwright() as p:
        browser = _browser(p)
        page = _open(browser, (report / "index.html").as_uri(), errors)
        held = page.evaluate(HOLDS)
        page.screenshot(path=str(report / "first-screen.png"))
        rows = page.evaluate(ROWS)
        page.click("#hide-passing")
        hidden = page.evaluate(ROWS)
        page.select_option("#filter-verdict", "inconclusive")
        only_open = page.evaluate(ROWS)
        page.evaluate("document.getElementById('mini').scrollIntoView()")
        page.screenshot(path=str(report / "study-section.png"))
        browser.close()
    assert errors == []
    assert held["sections"][:3] == ["summary", "findings", "verdicts"] and "provenance" in held["sections"]
    assert held["summary"]["top"] >= 0 and held["summary"]["bottom"] <= VIEWPORT["height"]
    assert held["width"] <= VIEWPORT["width"]
    manifest = json.loads((report / "mini" / "manifest.json").read_text())
    figures = [f for s in manifest["sections"] for f in s["figures"]]
    assert sorted(alt for alt, _ in held["images"]) == sorted(figures)
    assert all(ok for _, ok in held["images"])
    assert {"summary-table", "verdicts-table", "provenance-table"} <= set(held["tables"])
    states = [state for state, _ in rows]
    assert all(shown for _, shown in rows) and {"pass", "fail", "inconclusive"} <= set(states)
    assert [shown for _, shown in hidden] == [state != "pass" for state in states]
    assert [shown for _, shown in only_open] == [state == "inconclusive" for state in states]
    for shot in ("first-screen", "study-section"):
        assert (report / f"{shot}.png").stat().st_size > 20_000


def test_browser_check_catches_a_broken_page(tmp_path):
    """The same checks see a script error and an image that does not decode."""
    sync_api = pytest.importorskip("playwright.sync_api", reason="playwright (test extra) is not installed")
    bad = tmp_path / "bad.html"
    bad.write_text("<!doctype html><img alt='x' src='data:image/png;base64,AAAA'><script>nope();</script>")
    errors: list[str] = []
    with sync_api.sync_playwright() as p:
        browser = _browser(p)
        page = _open(browser, bad.as_uri(), errors)
        held = page.evaluate(HOLDS)
        browser.close()
    assert any("nope" in e for e in errors) and held["images"] == [["x", False]]


def test_verdict_target_from_another_table():
    tables = TABLES | {"fits": pd.DataFrame({"quantity": ["bulk", "mean"], "extrapolated": [0.32, 0.5]})}
    claims = _claims(metric="bulk", select={"solver": "a"}, per="n", against_table="fits",
                     against={"quantity": "bulk"}, against_metric="extrapolated", tolerance=0.005,
                     reference="extrapolated")
    v = verdicts("s", claims, tables)
    assert v["target"].tolist() == [0.32, 0.32] and v["verdict"].tolist() == ["fail", "pass"]


def test_verdict_with_no_rows_fails_even_per_case():
    v = verdicts("s", _claims(select={"solver": "nobody"}, per="n"), TABLES)
    assert v["verdict"].tolist() == ["fail"] and v["case"].tolist() == [""]


def test_verdict_one_sided_claims():
    lower = verdicts("s", _claims(metric="bulk", select={"solver": "a"}, per="n", target=0.31, tolerance=0.0,
                                  sense="at-least", reference="theory"), TABLES)
    assert lower["verdict"].tolist() == ["fail", "pass"]  # 0.30 < 0.31 <= 0.32
    upper = verdicts("s", _claims(metric="bulk", select={"solver": "a"}, per="n", target=0.31, tolerance=0.0,
                                  sense="at-most", reference="theory"), TABLES)
    assert upper["verdict"].tolist() == ["pass", "fail"]
    with pytest.raises(SceneError, match="sense="):
        _claims(sense="sideways")


def test_the_provenance_names_the_commit_of_the_running_checkout(tmp_path, monkeypatch):
    """The commit is the checkout's this pcverify runs from, whatever the working folder (a report written
    from outside the repository said 'unknown')."""
    monkeypatch.chdir(tmp_path)
    head = subprocess.run(["git", "-C", str(REPO), "rev-parse", "--short", "HEAD"], capture_output=True,
                          text=True, check=True).stdout.strip()
    assert source_commit().split("+")[0] == head
