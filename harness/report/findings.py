"""What a researcher reads first: one summary line per study and solver, and the findings in sentences.

Both are built from verdict records (the rows of verdicts.json) and the observed orders of a study's
fits tables; nothing here reads a solver's output directly.  Failures come first.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Any

from pcverify.harness.judge.verdict import LOOSE, STATES
from pcverify.harness.report.formatting import measured, number, to_float, unit_of

REFERENCE_WORDS = {"analytic": "analytic solution", "extrapolated": "extrapolated continuum",
                   "mesh-dependent": "mesh-dependent continuum", "same-grid": "continuum on the same grid",
                   "theory": "theory", "paper": "the paper",
                   "self": "self-convergence: the solver against its own finest level"}


def severity(record: dict[str, Any]) -> float:
    """How far a verdict is from its bound, in tolerances (larger is worse); for ordering only."""
    value, target, tol = (to_float(record.get(k)) for k in ("value", "target", "tolerance"))
    if not (math.isfinite(value) and math.isfinite(target)):
        return -math.inf
    sense = record.get("sense") or "within"
    miss = {"within": abs(value - target), "at-most": value - target, "at-least": target - value}[sense]
    return miss / tol if tol > 0 else (math.inf if miss > 0 else miss)


def unit(record: dict[str, Any]) -> str:
    return unit_of(str(record.get("metric") or ""))


def value_text(record: dict[str, Any]) -> str:
    """The verdict's value with unit and uncertainty, digits as the uncertainty (or tolerance) supports."""
    return measured(record.get("value"), unit(record), record.get("uncertainty"), record.get("tolerance"))


def target_text(record: dict[str, Any]) -> str:
    """The bound a verdict is judged against: "0.3333", "at least 1.8", "at most 0.01", "70 GPa (reference:E_eff)"
    (a computed target with its source); its tolerance is written apart ("±" is kept for uncertainties)."""
    word = {"within": "", "at-most": "at most ", "at-least": "at least "}[record.get("sense") or "within"]
    source = f" ({record['target_from']})" if record.get("target_from") else ""
    return f"{word}{number(record.get('target'), unit(record), 4)}{source}"


def tolerance_text(record: dict[str, Any]) -> str:
    return f"tolerance {number(record.get('tolerance'), unit(record), 2)}"


def solvers_of(record: dict[str, Any]) -> list[str]:
    """The solvers a verdict is about (its `solver` field lists them comma-separated)."""
    return [s.strip() for s in str(record.get("solver") or "").split(",") if s.strip()]


def state_counts(records: list[dict[str, Any]]) -> dict[str, int]:
    """How many verdicts are in each state."""
    return {s: sum(r["verdict"] == s for r in records) for s in STATES}


def claim_state(rows: list[dict[str, Any]]) -> str:
    """A claim's state: the worst of its verdicts (fail, inconclusive, not-applicable, pass)."""
    return next(s for s in STATES if any(r["verdict"] == s for r in rows))


def claim_slack(rows: list[dict[str, Any]]) -> tuple[float, bool]:
    """A claim's tolerance over the largest deviation any of its judged cases measured (NaN: none has one), and
    whether that makes it loose: above verdict.LOOSE and not derived."""
    found = [to_float(r.get("slack")) for r in rows if r.get("slack") is not None]
    least = min(found) if found else math.nan
    derived = str(rows[0].get("tolerance_basis") or "").startswith("derived:")
    return least, bool(least > LOOSE and not derived)


def by_claim(records: list[dict[str, Any]]) -> dict[tuple[str, str], list[dict[str, Any]]]:
    """The verdict records grouped by (study, claim), in the order they come."""
    claims: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for r in records:
        claims.setdefault((r["study"], r["claim"]), []).append(r)
    return claims


def summary_lines(studies: list[dict[str, Any]], records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One line per study and solver: verdict counts, observed orders, the headline verdict (the one
    farthest from its bound, failures first).  `studies`: name, title, solvers, orders per study."""
    lines = []
    for study in studies:
        mine = [r for r in records if r["study"] == study["name"]]
        unattributed = [r for r in mine if not solvers_of(r)]  # e.g. a claim whose rows are all missing
        for solver in [*study["solvers"], *(["(no rows)"] if unattributed else [])]:
            about = [r for r in mine if solver in solvers_of(r)] if solver != "(no rows)" else unattributed
            counts = state_counts(about)
            orders = [o for o in study.get("orders", []) if o["solver"] == solver]
            judged = sorted(about, key=lambda r: (r["verdict"] != "fail", -severity(r)))
            lines.append({"study": study["name"], "solver": solver, **counts, "orders": orders,
                          "headline": judged[0] if judged else None})
    return sorted(lines, key=lambda x: (-x["fail"], -x["inconclusive"], -x["not-applicable"], -(x["pass"] > 0),
                                        x["study"], x["solver"]))


def orders_text(orders: list[dict[str, Any]], limit: int = 3) -> tuple[str, str]:
    """(short text, full text) of observed orders: "nodes.linf 1.99, ..." and every one with its group."""
    seen: dict[str, list[float]] = {}
    for o in orders:
        seen.setdefault(str(o["quantity"]), []).append(float(o["order"]))
    short = []
    for q, ps in seen.items():
        lo, hi = min(ps), max(ps)
        short.append(f"{q} {lo:.2f}" if math.isclose(lo, hi, abs_tol=5e-3) else f"{q} {lo:.2f}…{hi:.2f}")
    full = "; ".join(f"{o['group']} {o['params'] or ''} {o['quantity']}: {float(o['order']):.3f}".replace("  ", " ")
                     for o in orders)
    text = ", ".join(short[:limit]) + (f" (+{len(short) - limit} more)" if len(short) > limit else "")
    return text, full


def _case_word(case: str) -> tuple[str, str]:
    """("n", "2") from "n=2"; ("", "") for a claim without cases."""
    key, _, value = case.partition("=")
    return (key, value) if value else ("", "")


def _joined(values: Iterable[str]) -> str:
    return " / ".join(values)


def sentence(claim: list[dict[str, Any]]) -> tuple[str, str]:
    """(state, plain sentence) of one claim from its verdict records: what it states, where it holds or
    fails, the values against the target with the reference kind and tolerance."""
    first = claim[0]
    states = [r["verdict"] for r in claim]
    state = claim_state(claim)
    key = _case_word(first.get("case") or "")[0]
    cases = [_case_word(r.get("case") or "")[1] for r in claim]
    if key == "n" and all(r.get("nodes") for r in claim):
        cases = [f"{c} ({int(r['nodes'])} nodes)" for c, r in zip(cases, claim, strict=True)]
    judged = [r for r in claim if r["verdict"] != "not-applicable" and r.get("value") is not None]
    where = ""
    if key and len(claim) > 1:
        failing = [c for c, s in zip(cases, states, strict=True) if s == "fail"]
        open_ = [c for c, s in zip(cases, states, strict=True) if s == "inconclusive"]
        parts = []
        if failing:
            parts.append("fails at every case" if len(failing) == len(claim)
                         else f"fails at {key} = {_joined(failing)}")
        if open_:
            parts.append("is inconclusive at every case" if len(open_) == len(claim)
                         else f"is inconclusive at {key} = {_joined(open_)}")
        where = ", ".join(parts) or "holds at every case judged"
    else:
        where = {"fail": "fails", "pass": "holds", "not-applicable": "is not applicable",
                 "inconclusive": "is inconclusive"}[state]
    text = f"{first['statement'].rstrip('.')}: {where}."
    if judged:
        values = _joined(value_text(r) for r in judged)
        targets = sorted({target_text(r) for r in judged})
        at = f" at {key} = {_joined(c for c, r in zip(cases, claim, strict=True) if r in judged)}" if key else ""
        against = targets[0] if len(targets) == 1 else _joined(target_text(r) for r in judged)
        text += (f" {first.get('metric') or 'value'}{at}: {values}, against {against} ({tolerance_text(first)}; "
                 f"{REFERENCE_WORDS.get(first['reference'], first['reference'])}).")
    missing = [r for r in claim if r["verdict"] == "not-applicable"]
    if missing:
        at = "" if len(claim) == 1 else f" at {len(missing)} cases"
        text += f" Not applicable{at}: {missing[0]['note']}."
    unjudged = [r for r in claim if r["verdict"] != "not-applicable" and r.get("value") is None]
    if unjudged:
        at = "" if len(claim) == 1 else f" at {len(unjudged)} cases"
        text += f" Not judged{at}: {unjudged[0]['note']}."
    return state, text


def findings(records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One finding per claim (study, claim, state, sentence), failures first, then by study."""
    out = []
    for (study, claim), rows in by_claim(records).items():
        state, text = sentence(rows)
        out.append({"study": study, "claim": claim, "state": state, "text": text})
    return sorted(out, key=lambda f: (STATES.index(f["state"]), f["study"]))
