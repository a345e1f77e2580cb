"""The summary lines and the findings sentences are generated from verdict records, failures first."""

import math

from pcverify.harness.report.findings import findings, orders_text, sentence, severity, summary_lines


def _record(claim, case, solver, value, target, verdict, **over):
    return {"study": "s", "claim": claim, "statement": f"statement of {claim}", "case": case, "solver": solver,
            "reference": "paper", "metric": "bulk_median", "value": value, "target": target,
            "error": abs(value - target), "uncertainty": None, "tolerance": 0.05, "sense": "within",
            "verdict": verdict, "note": "", "command": "", "nodes": None} | over


RECORDS = [
    _record("third", "n=2", "macromolecule", 0.159, 1 / 3, "fail", nodes=16),
    _record("third", "n=3", "macromolecule", 0.098, 1 / 3, "fail", nodes=63),
    _record("third", "n=4", "macromolecule", 0.31, 1 / 3, "pass", nodes=160),
    _record("line", "", "mca", 1e-15, 0.0, "pass", metric="err.nodes.linf", tolerance=1e-9, reference="analytic"),
    _record("order", "", "mca", 1.2, 1.0, "pass", metric="order", tolerance=0.0, sense="at-least"),
]


def test_sentence_says_where_a_claim_fails_with_values_and_reference():
    state, text = sentence(RECORDS[:3])
    assert state == "fail"
    assert text.startswith("statement of third: fails at n = 2 (16 nodes) / 3 (63 nodes).")
    assert "bulk_median at n = 2 (16 nodes) / 3 (63 nodes) / 4 (160 nodes): 0.159 / 0.098 / 0.310" in text
    assert "against 0.3333 (tolerance 0.050; the paper)" in text
    state, text = sentence(RECORDS[3:4])
    assert state == "pass" and "holds" in text and ": 1.0 × 10⁻¹⁵," in text and "; analytic solution)" in text


def test_findings_and_summary_put_failures_first():
    found = findings(RECORDS)
    assert [f["claim"] for f in found] == ["third", "line", "order"]
    lines = summary_lines([{"name": "s", "title": "t", "solvers": ["mca", "macromolecule", "fipy"],
                            "orders": [{"group": "g", "solver": "mca", "params": "", "quantity": "nodes.l2",
                                        "order": 1.98}]}], RECORDS)
    assert [(x["solver"], x["fail"], x["pass"]) for x in lines] == [("macromolecule", 2, 1), ("mca", 0, 2),
                                                                   ("fipy", 0, 0)]
    assert lines[0]["headline"]["case"] == "n=3"  # the failure farthest from its bound
    assert orders_text(lines[1]["orders"])[0] == "nodes.l2 1.98" and lines[2]["headline"] is None


def test_severity_in_tolerances_by_sense():
    assert severity(RECORDS[1]) == (1 / 3 - 0.098) / 0.05
    assert severity(RECORDS[4]) < 0  # above its at-least bound: no miss
    assert severity(_record("x", "", "a", 0.5, 1.0, "fail", sense="at-least", tolerance=0.0)) == math.inf
    assert severity(_record("x", "", "a", math.nan, 1.0, "not-applicable")) == -math.inf
