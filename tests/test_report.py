"""Report: verdicts judged from tables, VTU files, figures and the index built from a small study."""

import json
import math
import xml.etree.ElementTree as ET

import numpy as np
import pandas as pd
import pytest

from pcverify.harness.cli import main
from pcverify.harness.verdict import parse_claims, verdicts
from pcverify.harness.vtu import write_vtu
from pcverify.scene import SceneError

TABLES = {
    "g-cells": pd.DataFrame({"solver": ["a", "a", "b", "b"], "n": [2, 3, 2, 3], "err": [1e-3, 2e-4, 5e-2, 1e-2],
                             "bulk": [0.30, 0.32, 0.31, 0.33], "gci": [1e-3, 5e-4, np.nan, np.nan]}),
}


def _claims(**over):
    base = {"id": "c", "text": "t", "table": "g-cells", "metric": "err", "reference": "analytic", "tolerance": 1e-3}
    return parse_claims([base | over], "test.toml")


def test_verdicts_pass_fail_and_not_applicable():
    v = verdicts("s", _claims(select={"solver": "a"}), TABLES)
    assert v["verdict"].tolist() == ["pass"] and v["value"][0] == pytest.approx(1e-3)  # max over n
    v = verdicts("s", _claims(select={"solver": "b"}), TABLES)
    assert v["verdict"].tolist() == ["fail"] and v["error"][0] == pytest.approx(5e-2)
    v = verdicts("s", _claims(select={"solver": "c"}), TABLES)
    assert v["verdict"].tolist() == ["not-applicable"]
    v = verdicts("s", _claims(table="missing"), TABLES)
    assert v["verdict"].tolist() == ["not-applicable"]


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
    assert v.loc["impossible", "verdict"] == "fail" and v.loc["absent", "verdict"] == "not-applicable"
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
    assert html.index("id='verdicts'") < html.index("id='mini'") < html.index("id='provenance'")
    assert html.count("<img ") == 3 and "class='fail'" in html and "command" in html


CHROMIUM = "/usr/bin/chromium"


def _browse(url: str, screenshot=None) -> tuple[list[str], dict]:
    """Load `url` in headless Chromium; return the console errors and what the page holds."""
    import os

    if not os.path.exists(CHROMIUM):
        pytest.skip(f"{CHROMIUM} is absent (Debian package chromium); the browser check needs it")
    sync_api = pytest.importorskip("playwright.sync_api", reason="playwright (test extra) is not installed")
    errors: list[str] = []
    with sync_api.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=["--no-sandbox"])
        page = browser.new_page(viewport={"width": 1200, "height": 900})
        page.on("console", lambda m: errors.append(f"console.{m.type}: {m.text}") if m.type == "error" else None)
        page.on("pageerror", lambda e: errors.append(f"page error: {e}"))
        page.on("requestfailed", lambda r: errors.append(f"request failed: {r.url[:80]}"))
        page.goto(url, wait_until="load")
        held = page.evaluate("""() => ({
            images: Array.from(document.images).map(i => [i.alt, i.complete && i.naturalWidth > 0]),
            tables: Array.from(document.querySelectorAll('table')).map(t => t.id),
            headings: Array.from(document.querySelectorAll('h2')).map(h => h.id)})""")
        if screenshot is not None:
            page.screenshot(path=str(screenshot), full_page=True)
        browser.close()
    return errors, held


def test_index_renders_in_headless_chromium(report, tmp_path):
    """Every table and figure the manifests list is in the page, every image decodes, no browser errors."""
    shot = report / "index-screenshot.png"
    errors, held = _browse((report / "index.html").as_uri(), shot)
    assert errors == []
    manifest = json.loads((report / "mini" / "manifest.json").read_text())
    figures = [f for s in manifest["sections"] for f in s["figures"]]
    assert sorted(alt for alt, _ in held["images"]) == sorted(figures)
    assert all(ok for _, ok in held["images"])
    tables = {f"mini-{t[:-4]}" for s in manifest["sections"] for t in s["tables"]}
    assert tables | {"verdicts-table", "provenance-table"} <= set(held["tables"])
    assert held["headings"][0] == "verdicts" and "provenance" in held["headings"]
    assert shot.stat().st_size > 20_000
    # the same check catches a broken page: a script error and an image that does not decode
    bad = tmp_path / "bad.html"
    bad.write_text("<!doctype html><img alt='x' src='data:image/png;base64,AAAA'><script>nope();</script>")
    errors, held = _browse(bad.as_uri())
    assert any("nope" in e for e in errors) and held["images"] == [["x", False]]


def test_verdict_target_from_another_table():
    tables = TABLES | {"fits": pd.DataFrame({"quantity": ["bulk", "mean"], "extrapolated": [0.32, 0.5]})}
    claims = _claims(metric="bulk", select={"solver": "a"}, per="n", against_table="fits",
                     against={"quantity": "bulk"}, against_metric="extrapolated", tolerance=0.005,
                     reference="extrapolated")
    v = verdicts("s", claims, tables)
    assert v["target"].tolist() == [0.32, 0.32] and v["verdict"].tolist() == ["fail", "pass"]


def test_verdict_with_no_rows_is_not_applicable_even_per_case():
    v = verdicts("s", _claims(select={"solver": "nobody"}, per="n"), TABLES)
    assert v["verdict"].tolist() == ["not-applicable"] and v["case"].tolist() == [""]


def test_verdict_one_sided_claims():
    lower = verdicts("s", _claims(metric="bulk", select={"solver": "a"}, per="n", target=0.31, tolerance=0.0,
                                  sense="at-least", reference="theory"), TABLES)
    assert lower["verdict"].tolist() == ["fail", "pass"]  # 0.30 < 0.31 <= 0.32
    upper = verdicts("s", _claims(metric="bulk", select={"solver": "a"}, per="n", target=0.31, tolerance=0.0,
                                  sense="at-most", reference="theory"), TABLES)
    assert upper["verdict"].tolist() == ["pass", "fail"]
    with pytest.raises(SceneError, match="sense="):
        _claims(sense="sideways")
