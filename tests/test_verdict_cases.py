"""A pass must mean something: a claim is judged on all its cases or on none, with its uncertainty.

Each test is a way to get "pass" for something that was never verified: a claim read past a failed, lost or
missing cell, a fit that dropped a level, an uncertainty wider than the tolerance, an oscillatory reference, a
chaotic run judged on one trajectory, a plugin that does not import.  A toy solver with an exactly known error
(T = 1 - z/L + amp h^order sin(pi z / L) on the steady faces bar, so the L-inf error at the nodes is amp h^order
up to the sampling of the sine) stands in for a real method, and a switch makes its run at one n fail.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from pcverify.harness.cli import main
from pcverify.harness.judge.metrics import fit_order
from pcverify.harness.judge.verdict import decide, verdicts
from pcverify.harness.study.claims import parse_claims
from pcverify.solvers.registry import SOLVERS, Entry

TOY = '''
import numpy as np
import pcverify
from pcverify import Param, Solution, effective_params


class PowerLaw:
    """The exact steady profile plus an error amp h^order sin(pi z / L); the run at n = fail_at fails."""

    name = "powerlaw"
    kind = "continuum"
    parameters = (Param("amp", 0.1, "", "error amplitude", low=0.0, high=10.0),
                  Param("order", 2.0, "", "order of the error", low=0.0, high=8.0),
                  Param("fail_at", 0, "", "n whose run reports failed (0: none)", low=0, high=100, kind=int))

    def supports(self, scene):
        return "conduction" in scene.physics, "heat scenes only"

    def solve(self, scene, resolution, samples=None, **params):
        p = effective_params(self, params)
        h = resolution.spacing(scene.box.width)
        length = scene.box.length
        sets = scene.sample_sets(resolution.n) if samples is None else samples
        out = {}
        for k, pts in sets.items():
            pts = np.asarray(pts, float)
            z = pts[:, 2] / length
            out[k] = {"points": pts, "values": 1.0 - z + p["amp"] * h ** p["order"] * np.sin(np.pi * z)}
        nodes = out["nodes"]["values"]
        failed = resolution.n == p["fail_at"]
        return Solution(scene=scene.name, solver=self.name, params=p,
                        resolution={"n": resolution.n, "refine": resolution.refine, "h": h}, samples=out,
                        unknowns=int(nodes.size), wall_s=0.0, status="failed" if failed else "ok",
                        reason="its own check failed" if failed else "",
                        summary={"bulk_median": float(np.median(nodes)), "volume_mean": float(np.mean(nodes))})
'''

HEAD = """
name = "cases"
title = "claims on every case"
plugins = ["pv_toy"]
"""


def _study(tmp_path, monkeypatch, body: str, name: str = "cases.toml"):
    (tmp_path / "pv_toy.py").write_text(TOY)
    monkeypatch.syspath_prepend(str(tmp_path))
    path = tmp_path / name
    path.write_text(HEAD + body)
    return path


def _verdicts(out, study="cases"):
    return {(r["claim"], r["case"]): r for r in json.loads((out / study / "verdicts.json").read_text())}


def _study_json(capsys, *argv) -> tuple[int, list]:
    code = main(["study", *map(str, argv), "--json"])
    return code, json.loads(capsys.readouterr().out.strip().splitlines()[-1])


CELLS = """
[[group]]
id = "faces"
title = "toy on the steady faces bar"
analysis = "table"
scene = "bar-heat-faces"
solvers = ["powerlaw"]
n = [2, 3, 4]
solver_params = { amp = 1e-3, fail_at = 3 }
[[claim]]
id = "small-error"
text = "the error at the nodes is below 1e-5 at every n"
table = "faces-cells"
metric = "bulk_median"
reference = "analytic"
target = 0.5
tolerance = 1e-3
"""


def test_a_failed_cell_fails_its_claim_and_stays_failed_when_read_back(tmp_path, monkeypatch, capsys):
    """On main the n = 3 row (status failed, its numbers present) was read like the others and the claim passed;
    a second run read the failed cell back from the cache and said 0 failed."""
    path = _study(tmp_path, monkeypatch, CELLS)
    out = tmp_path / "reports"
    for run in range(2):
        code, summary = _study_json(capsys, path, "--out", out)
        assert code == 0 and summary[0]["failed"] == 1 and summary[0]["cached"] == 3 * run
        verdict = _verdicts(out)[("small-error", "")]
        assert verdict["verdict"] == "fail" and "n=3 [amp=0.001, fail_at=3] failed (its own check failed)" in (
            verdict["note"]) and verdict["value"] is None
    code = main(["study", str(path), "--out", str(out), "--strict"])
    err = capsys.readouterr().err
    assert code == 1 and "claim fail: cases/small-error" in err and "failed (its own check failed)" in err


FIT = """
[[group]]
id = "conv"
title = "toy convergence at second order"
analysis = "convergence"
scene = "bar-heat-faces"
solvers = ["powerlaw"]
n = [3, 4, 5, 7]
solver_params = { amp = 0.1, order = 2.0, fail_at = FAIL }
[[claim]]
id = "order-two"
text = "the toy converges at second order"
table = "conv-fits"
select = { quantity = "nodes.linf" }
metric = "order"
reference = "analytic"
target = 2.0
tolerance = 0.1
"""


def test_a_fit_that_lost_a_level_is_not_a_pass(tmp_path, monkeypatch, capsys):
    """The fit names its levels; with n = 4 failed the fit over n = 3, 5, 7 still gives order 2, but the claim
    fails naming the lost cell (on main it passed)."""
    whole = _study(tmp_path, monkeypatch, FIT.replace("FAIL", "0"), "whole.toml")
    lost = _study(tmp_path, monkeypatch, FIT.replace("FAIL", "4"), "lost.toml")
    assert _study_json(capsys, whole, "--out", tmp_path / "a")[0] == 0
    good = _verdicts(tmp_path / "a")[("order-two", "")]
    assert good["verdict"] == "pass" and good["basis"] == "fit over n=3, n=4, n=5, n=7"
    assert good["value"] == pytest.approx(2.0, abs=0.05)
    assert _study_json(capsys, lost, "--out", tmp_path / "b")[0] == 0
    bad = _verdicts(tmp_path / "b")[("order-two", "")]
    assert bad["verdict"] == "fail" and "lost n=4 failed" in bad["note"]
    assert bad["basis"] == "fit over n=3, n=5, n=7" and bad["value"] is None  # no number stands for the claim
    fits = pd.read_csv(tmp_path / "b" / "cases" / "conv-fits.csv")
    assert set(fits["missing"]) == {"n=4 failed (its own check failed)"} and set(fits["cells"]) == {4}


PAIR = """
[[group]]
id = "faces"
title = "toy on the steady faces bar"
analysis = "table"
scene = "bar-heat-faces"
solvers = ["powerlaw"]
n = [2, 3]
solver_params = { amp = 10.0 }
[[claim]]
id = "small-bulk-error"
text = "the toy's bulk is 1/2 within 5e-4"
table = "faces-cells"
per = "n"
metric = "bulk_median"
reference = "analytic"
target = 0.5
tolerance = 5e-4
"""


def test_a_report_rebuilt_without_a_cache_entry_never_turns_fail_into_pass(tmp_path, monkeypatch, capsys):
    """The bulk is off by amp h^2 sin(pi z): 8.7e-4 at n = 2 (fails 5e-4), 2.5e-4 at n = 3 (passes).  Deleting
    or corrupting the n = 2 entry must not leave the claim judged on n = 3 alone (on main the rebuilt report
    dropped the row and the claim passed): the report says the cell is missing and its case fails."""
    path = _study(tmp_path, monkeypatch, PAIR)
    out = tmp_path / "reports"
    assert _study_json(capsys, path, "--out", out)[0] == 0
    before = _verdicts(out)
    assert before[("small-bulk-error", "n=2")]["verdict"] == "fail"
    assert before[("small-bulk-error", "n=3")]["verdict"] == "pass"
    n2 = next(r for r in json.loads((out / "cases" / "verdicts.json").read_text()) if r["case"] == "n=2")
    cells = pd.read_csv(out / "cases" / "cells.csv")
    assert n2["value"] == pytest.approx(float(cells[cells["n"] == 2]["bulk_median"].iloc[0]))
    entries = {json.loads(p.read_text())["result"]["n"]: p for p in (out / "cache").glob("*.json")}
    for damage in ("delete", "corrupt"):
        if damage == "delete":
            entries[2].rename(entries[2].with_suffix(".bak"))
        else:
            entries[2].with_suffix(".bak").rename(entries[2])
            entries[2].write_text(entries[2].read_text()[:40])
        assert main(["report", "--out", str(out)]) == 0
        printed = capsys.readouterr().out
        assert "1 cells missing or corrupt" in printed
        after = _verdicts(out)
        assert after[("small-bulk-error", "n=2")]["verdict"] == "fail"
        assert "missing" in after[("small-bulk-error", "n=2")]["note"]
        assert after[("small-bulk-error", "n=3")]["verdict"] == "pass"


def test_a_failed_mca_contact_cell_fails_its_claim(tmp_path, monkeypatch, capsys):
    """The contact relaxation stopped by max_steps with its residual far above tolerance: on main its pressure
    (15 MPa against 70 MPa, read with a tolerance that admits it) fed a passing claim."""
    path = tmp_path / "contact.toml"
    path.write_text("""
name = "contact"
title = "a contact cell cut short"
[[group]]
id = "press"
title = "block-contact-compression, relaxation stopped at 200 steps"
analysis = "table"
scene = "block-contact-compression"
solvers = ["mca"]
n = [4]
solver_params = { max_steps = 200 }
[[claim]]
id = "pressure"
text = "the contact pressure is positive (loose on purpose)"
table = "press-cells"
metric = "contact_pressure_mean"
reference = "analytic"
target = 7e7
tolerance = 1e9
""")
    out = tmp_path / "reports"
    assert _study_json(capsys, path, "--out", out)[0] == 0
    verdict = _verdicts(out, "contact")[("pressure", "")]
    assert verdict["verdict"] == "fail" and "failed (residual" in verdict["note"] and "max_steps 200" in verdict["note"]


def test_a_plugin_that_does_not_import_stops_the_study_with_its_name(tmp_path, monkeypatch, capsys):
    """An entry point, a module:Class and a plugins entry that fail to import: exit 2 with one line naming it
    (on main an entry point's cells were skipped, its claims not applicable and --strict exited 0)."""
    (tmp_path / "pv_broken.py").write_text("raise ImportError('the core library is missing')\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    study = """
name = "broken"
title = "a study of a plugin that does not import"
[[group]]
id = "faces"
title = "faces"
analysis = "table"
scene = "bar-heat-faces"
solvers = ["SOLVER"]
n = [2]
[[claim]]
id = "line"
text = "the line"
table = "faces-cells"
metric = "bulk_median"
reference = "analytic"
target = 0.5
tolerance = 1e-9
"""
    entry = Entry("pv-ep", "pv_broken:Solver", "entry point of pv-broken 1.0")
    monkeypatch.setitem(SOLVERS.__dict__, "entry_points", {"pv-ep": entry})
    for solver, word in (("pv-ep", "pv-ep"), ("pv_broken:Solver", "pv_broken")):
        path = tmp_path / f"{word}.toml"
        path.write_text(study.replace("SOLVER", solver))
        code = main(["study", str(path), "--out", str(tmp_path / "out"), "--strict"])
        err = capsys.readouterr().err
        assert code == 2 and err.count("\n") == 1 and word in err and "the core library is missing" in err
    path = tmp_path / "plugins.toml"
    path.write_text('plugins = ["pv_broken"]\n' + study.replace("SOLVER", "skfem"))
    code = main(["study", str(path), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2 and "plugin 'pv_broken' failed to import" in err


# -- uncertainty: three-valued verdicts ----------------------------------------------------------------------


def _claim(**over):
    base = {"id": "c", "text": "t", "table": "t", "metric": "v", "reference": "paper", "tolerance": 0.02,
            "target": 0.3}
    return parse_claims([base | over], "test.toml")


def test_an_uncertainty_wider_than_the_tolerance_never_passes():
    """0.287 +- 0.107 against 0.3 with tolerance 0.02 passed on main; the band straddles the bound."""
    table = {"t": pd.DataFrame({"v": [0.287], "u": [0.107]})}
    v = verdicts("s", _claim(uncertainty="u"), table)
    assert v["verdict"].item() == "inconclusive" and "straddles" in v["note"].item()
    assert v["uncertainty"].item() == pytest.approx(0.107)
    assert decide(0.287, 0.3, 0.02, "within", 0.005) == "pass"  # 0.013 + 0.005 <= 0.02
    assert decide(0.5, 0.3, 0.02, "within", 0.107) == "fail"  # 0.2 - 0.107 > 0.02: wholly outside
    assert decide(1.85, 2.0, 0.2, "within", 0.06) == "inconclusive"
    assert decide(1.79, 1.8, 0.0, "at-least", 0.0) == "fail" and decide(1.81, 1.8, 0.0, "at-least", 0.02) == (
        "inconclusive")


def test_a_fitted_order_carries_its_standard_error_and_claims_use_it():
    """log e = log C + p log h on four points with +-10 % scatter: the least-squares standard error of p
    (0.082 here, checked against the textbook formula) is the claim's uncertainty; a 0.05 tolerance around 2
    cannot be a pass with it, a 0.2 one is."""
    h = np.array([0.1, 0.05, 0.025, 0.0125])
    e = 3 * h**2 * (1 + 0.1 * np.array([1, -1, 1, -1]))
    fit = fit_order(h, e)
    x, y = np.log(h), np.log(e)
    p, c = np.polyfit(x, y, 1)
    se = math.sqrt(((y - p * x - c) ** 2).sum() / 2 / ((x - x.mean()) ** 2).sum())
    assert fit.order == pytest.approx(p) and fit.order_se == pytest.approx(se) and 0.05 < se < 0.1
    assert math.isnan(fit_order(h[:2], e[:2]).order_se)  # a line through two points has no scatter to measure
    fits = {"t": pd.DataFrame({"v": [fit.order], "v_unc": [fit.order_se]})}
    assert verdicts("s", _claim(target=2.0, tolerance=0.05), fits)["verdict"].item() == "inconclusive"
    assert verdicts("s", _claim(target=2.0, tolerance=0.2), fits)["verdict"].item() == "pass"
    two = {"t": pd.DataFrame({"v": [2.0], "v_unc": [math.nan]})}
    v = verdicts("s", _claim(target=2.0, tolerance=0.2), two)
    assert v["verdict"].item() == "inconclusive" and "uncertainty is unknown" in v["note"].item()


def test_a_suspect_reference_sequence_is_named_and_never_passes():
    """The target comes from a Richardson extrapolation classified oscillatory: the verdict names it."""
    values = pd.DataFrame({"v": [0.301]})
    ref = pd.DataFrame({"quantity": ["bulk"], "extrapolated": [0.3], "extrapolated_unc": [1e-4],
                        "kind": ["oscillatory"]})
    claims = _claim(against_table="ref", against={"quantity": "bulk"}, against_metric="extrapolated")
    v = verdicts("s", claims, {"t": values, "ref": ref})
    assert v["verdict"].item() == "inconclusive" and "target oscillatory" in v["note"].item()
    assert v["uncertainty"].item() == pytest.approx(1e-4)  # the reference's GCI band enters the uncertainty
    ref["kind"] = "monotonic"
    assert verdicts("s", claims, {"t": values, "ref": ref})["verdict"].item() == "pass"


def test_a_chaotic_run_is_judged_on_replicas_or_not_at_all():
    """A run in the defect regime: one trajectory's digits are at best inconclusive; the mean of three
    replicas with its Student-t band is judged; a status the claim does not allow fails it."""
    one = pd.DataFrame({"n": [4], "status": ["defect"], "reason": ["hops"], "v": [0.31]})
    v = verdicts("s", _claim(per="n", statuses=["ok", "defect"]), {"t": one})
    assert v["verdict"].item() == "inconclusive" and "chaotic" in v["note"].item()
    v = verdicts("s", _claim(per="n"), {"t": one})
    assert v["verdict"].item() == "fail" and "n=4 defect (hops)" in v["note"].item()
    three = pd.DataFrame({"n": [4] * 3, "status": ["defect"] * 3, "v": [0.301, 0.299, 0.300]})
    v = verdicts("s", _claim(per="n", statuses=["ok", "defect"], aggregate="mean", uncertainty="spread"),
                 {"t": three})
    t95 = 2.919986  # Student's t, one-sided 95 %, 2 degrees of freedom
    assert v["verdict"].item() == "pass" and v["uncertainty"].item() == pytest.approx(t95 * 0.001 / math.sqrt(3))
    wide = three.assign(v=[0.2, 0.3, 0.4])
    v = verdicts("s", _claim(per="n", statuses=["ok", "defect"], aggregate="mean", uncertainty="spread"),
                 {"t": wide})
    assert v["verdict"].item() == "inconclusive"


def test_a_skipped_case_is_not_applicable_only_where_the_claim_allows_it():
    rows = pd.DataFrame({"solver": ["a", "b"], "status": ["ok", "skipped"], "reason": ["", "no time stepping"],
                         "v": [0.3, math.nan]})
    v = verdicts("s", _claim(per="solver"), {"t": rows})
    assert v["verdict"].tolist() == ["pass", "fail"] and "no time stepping" in v["note"][1]
    v = verdicts("s", _claim(per="solver", allow_skipped=True), {"t": rows})
    assert v["verdict"].tolist() == ["pass", "not-applicable"]
