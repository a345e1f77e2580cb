"""Verdicts: each claim of a study judged against the tables the study produced.

A pass must mean something, so a claim is judged on all its cases or on none, and a verdict is three-valued:
pass when the value's whole uncertainty band lies inside the bound, fail when it lies wholly outside,
inconclusive when it straddles it; a value on an oscillatory or divergent Richardson sequence, or on one
chaotic run, is at best inconclusive.  The rules in full, with `per`, `against` and the uncertainties, are in
docs/outputs.md, "What a verdict means".  Each verdict names its solvers, its `basis` and, given a `command`
function, the command that reproduces its number.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pandas as pd
from scipy.stats import t as student_t

from pcverify.harness.judge.cost import cost_at, error_column
from pcverify.harness.study.claims import SPREAD, Claim, bound
from pcverify.harness.study.schema import AGGREGATES as AGGREGATE_NAMES

STATES = ("fail", "inconclusive", "not-applicable", "pass")  # worst first
AGGREGATES = dict(zip(AGGREGATE_NAMES, (np.max, np.min, np.median, np.mean), strict=True))
CHAOTIC = ("defect",)  # statuses of runs whose digits are a property of the arithmetic, not of the model
MIN_REPLICAS = 3
COVERAGE = 0.95  # a replica mean's band is the one-sided Student-t quantile at this level times its standard error
SUSPECT_SEQUENCES = ("oscillatory", "divergent", "scattered")
VERDICT_COLUMNS = ("study", "claim", "statement", "case", "solver", "reference", "metric", "value", "target",
                   "target_from", "error", "uncertainty", "tolerance", "sense", "verdict", "basis", "note", "command",
                   "tolerance_basis", "slack")
LOOSE = 10.0  # a tolerance more than this many times the deviation measured, and not derived, is loose


def select_rows(df: pd.DataFrame, select: dict[str, Any]) -> pd.DataFrame:
    """The rows of `df` whose columns hold the selected values ({ column = value or [values] }); none when a
    selected column is absent."""
    for col, want in select.items():
        if col not in df.columns:
            return df.iloc[0:0]
        wanted = want if isinstance(want, list) else [want]
        df = df[df[col].isin(wanted)]
    return df


def _absent(df: pd.DataFrame, select: dict[str, Any]) -> list[str]:
    """The values a selection names that no row of `df` has ("n=4", ...): every case named must be present."""
    out = []
    for col, want in select.items():
        have = set(df[col].dropna().tolist()) if col in df.columns else set()
        out += [f"{col}={w}" for w in (want if isinstance(want, list) else [want]) if w not in have]
    return out


def _values(df: pd.DataFrame, column: str) -> np.ndarray:
    if column not in df.columns:
        return np.full(len(df), math.nan)
    return pd.to_numeric(df[column], errors="coerce").to_numpy(float)


def _aggregate(values: np.ndarray, how: str) -> float:
    return float(AGGREGATES[how](values)) if values.size and np.all(np.isfinite(values)) else math.nan


def _text(value: Any) -> str:
    return "" if value is None or (isinstance(value, float) and math.isnan(value)) else str(value)


def _label(row: pd.Series) -> str:
    """A row's cell in words: solver, n, refine, params, where the table has them."""
    parts = [f"{k}={row[k]}" for k in ("solver", "n", "refine") if k in row and _text(row[k])
             and not (k == "refine" and _text(row[k]) == "1")]
    for k in ("params", "scene_params"):
        if k in row and _text(row[k]):
            parts.append(f"[{row[k]}]")
    return " ".join(parts) or "a row"


def _problems(rows: pd.DataFrame, claim: Claim) -> tuple[list[str], list[str]]:
    """(why the rows cannot be judged, why they are only skipped): rows whose cells are not of an allowed
    status, rows that lost cells (`missing`), rows of the metric with no finite value."""
    bad, skipped = [], []
    for _, row in rows.iterrows():
        status = _text(row.get("status")) or "ok"
        if status == "skipped" and claim.allow_skipped:
            skipped.append(f"{_label(row)} skipped ({_text(row.get('reason'))})")
        elif status not in claim.statuses:
            reason = _text(row.get("reason"))
            bad.append(f"{_label(row)} {status}" + (f" ({reason})" if reason else ""))
        elif _text(row.get("missing")):
            bad.append(f"{_label(row)} lost {row['missing']}")
    return bad, skipped


def mixed_reference(claim: Claim, rows: pd.DataFrame) -> str:
    """Why the claim's reference kind does not match what its rows stand on ("" when it does): a self-convergence
    number (a solver against its own finest level: metric self.*, or a fit of reference "self") is judged only by
    a claim that says reference = "self", and such a claim only on self-convergence numbers or on a Richardson fit
    of the solver's own sequence."""
    kinds = set(rows["reference"].dropna().astype(str)) if "reference" in rows.columns else set()
    own = claim.metric.startswith("self.") or "self" in kinds
    if claim.reference != "self":
        return (f"its rows are self-convergence (the solver against its own finest level), not a {claim.reference} "
                'reference: the claim must say reference = "self"') if own else ""
    if own or (kinds and kinds <= {"richardson"}):
        return ""
    what = ", ".join(sorted(kinds)) if kinds else "no self-convergence column (self.<set>.<norm>)"
    return f"the claim is on self-convergence, but its rows stand on {what}"


def _suspect(rows: pd.DataFrame) -> list[str]:
    """Richardson sequences the rows stand on that are oscillatory or divergent."""
    out = []
    for col in ("kind", "reference_class"):
        if col in rows.columns:
            out += sorted({str(v) for v in rows[col].dropna() if str(v) in SUSPECT_SEQUENCES})
    return sorted(set(out))


def _uncertainty(rows: pd.DataFrame, spec: float | str, metric: str, values: np.ndarray) -> tuple[float, bool]:
    """(uncertainty, named): the claim's number or column (max over the rows), the band of the mean of the rows
    (`spread`: Student's t at COVERAGE, one-sided, for their number, times the standard error, so a claim
    whose true value lies on its bound passes at most 1 - COVERAGE of the time), else the table's
    `<metric>_unc` column; `named` says the claim or table asks for one, so an unknown value cannot be read as
    zero."""
    if isinstance(spec, str) and spec == SPREAD:
        if values.size < MIN_REPLICAS:
            return math.nan, True
        t = float(student_t.ppf(COVERAGE, values.size - 1))
        return t * float(np.std(values, ddof=1) / math.sqrt(values.size)), True
    if isinstance(spec, str):
        u = _values(rows, spec)
        return (float(np.max(u)) if u.size and np.all(np.isfinite(u)) else math.nan), True
    if math.isfinite(spec):
        return float(spec), True
    if f"{metric}_unc" in rows.columns:
        u = _values(rows, f"{metric}_unc")
        return (float(np.max(u)) if u.size and np.all(np.isfinite(u)) else math.nan), True
    return math.nan, False


def decide(value: float, target: float, tolerance: float, sense: str, uncertainty: float) -> str:
    """pass / fail / inconclusive of a value with an uncertainty band (0 if unknown) against its bound."""
    u = uncertainty if math.isfinite(uncertainty) else 0.0
    if sense == "within":
        miss = abs(value - target) - tolerance
    elif sense == "at-most":
        miss = value - (target + tolerance)
    else:
        miss = (target - tolerance) - value
    if miss + u <= 0:
        return "pass"
    return "fail" if miss - u > 0 else "inconclusive"


def slack(value: float, target: float, tolerance: float, sense: str, uncertainty: float = math.nan) -> float:
    """The tolerance over the far edge of the value's band, the deviation measured in the direction the claim
    bounds plus the uncertainty (a deviation below the round-off of the numbers compared counts as that
    round-off; NaN: a zero tolerance, an at-least claim, whose target is its own bound, or an at-most value
    at or below its target, which the tolerance does not pass).  Above LOOSE, a tenfold worse value would still
    pass."""
    if not (tolerance > 0 and math.isfinite(value) and math.isfinite(target)) or sense == "at-least" or (
            sense == "at-most" and value <= target):
        return math.nan
    deviation = (abs(value - target) if sense == "within" else value - target) + (
        uncertainty if math.isfinite(uncertainty) else 0.0)
    return tolerance / max(deviation, np.finfo(float).eps * max(abs(value), abs(target), tolerance))


def _target(claim: Claim, rows: pd.DataFrame) -> float:
    """A claim's target for a case: its number, or its text's value at the (n, refine) of the case's rows (NaN
    where the rows stand on levels of different values)."""
    if not isinstance(claim.target, str):
        return claim.target
    found = np.array([v for n, refine, v in claim.targets if ("n" not in rows or n in set(rows["n"]))
                      and ("refine" not in rows or refine in set(rows["refine"]))])
    return float(found[0]) if found.size and np.allclose(found, found[0], rtol=1e-12, atol=0.0) else math.nan


# the command that reproduces a verdict's number, from the claim, its case, its value rows and its target rows
Command = Callable[["Claim", str, pd.DataFrame, "pd.DataFrame | None"], str]


def _solvers(rows: pd.DataFrame) -> str:
    return ", ".join(sorted({str(s) for s in rows["solver"].dropna()})) if "solver" in rows else ""


def _basis(rows: pd.DataFrame) -> str:
    """What a value stands on: the levels of a fit, or how many rows were combined."""
    if "used" in rows.columns:
        used = sorted({_text(u) for u in rows["used"] if _text(u)})
        if used:
            return "; ".join(f"fit over {u}" for u in used)
    return f"{len(rows)} rows" if len(rows) > 1 else ""


def _unplanned_of(claim: Claim, unplanned: dict[str, dict[str, str]]) -> dict[str, str]:
    """The solvers (with why) whose cells the group of the claim's table did not plan: its table is named
    `<group id>-...`; the claim's `solver` selection, if any, limits them."""
    groups = [g for g in unplanned if claim.table.startswith(f"{g}-")]
    out = unplanned[max(groups, key=len)] if groups else {}
    want = claim.select.get("solver")
    wanted = None if want is None else set(want if isinstance(want, list) else [want])
    return {s: r for s, r in out.items() if wanted is None or s in wanted}


def judge(study: str, claim: Claim, tables: dict[str, pd.DataFrame], command: Command | None = None,
          unplanned: dict[str, dict[str, str]] | None = None) -> list[dict[str, Any]]:
    """Verdict rows for one claim (one per `per` value).  `unplanned`: per group, the solvers whose cells the
    study did not plan (and why); a claim on them is judged as on skipped cells: not-applicable where the claim
    allows skips and names only such cells (a case of its own with `per = "solver"`), fail otherwise."""
    base = {"study": study, "claim": claim.id, "statement": claim.text, "reference": claim.reference,
            "metric": claim.metric, "tolerance": claim.tolerance, "sense": claim.sense, "basis": "",
            "tolerance_basis": claim.tolerance_basis,
            "target_from": claim.target if isinstance(claim.target, str) else ""}

    def whole(note: str, state: str = "fail", case: str = "") -> list[dict[str, Any]]:
        cmd = command(claim, case, pd.DataFrame(), None) if command else ""
        return [base | {"case": case, "verdict": state, "note": note, "command": cmd}]

    hit = _unplanned_of(claim, unplanned or {})
    if hit:
        skip_state = "not-applicable" if claim.allow_skipped else "fail"
        want = claim.select.get("solver")
        left = [w for w in (want if isinstance(want, list) else [want]) if w not in hit] if want is not None else None
        if claim.per == ("solver",):
            rows = [r for s, why in sorted(hit.items())
                    for r in whole(f"its cells are not planned ({s}: {why})", skip_state, f"solver={s}")]
            if left == []:
                return rows
            narrowed = claim if left is None else dataclasses.replace(claim, select=claim.select | {"solver": left})
            return judge(study, narrowed, tables, command) + rows
        note = "; ".join(f"{s}: {why}" for s, why in sorted(hit.items()))
        if left == []:
            return whole(f"its cells are not planned ({note})", skip_state)
        return whole(f"some of its cells are not planned ({note})")

    df = tables.get(claim.table)
    if df is None or df.empty:
        return whole(f"table {claim.table} has no rows: the claim is judged on nothing")
    missing = [c for c in (claim.metric, *claim.per, *claim.select) if c and c not in df.columns]
    if missing:
        return whole(f"column {missing[0]} is not in table {claim.table} (columns: {', '.join(map(str, df.columns))}"
                     f"{'; per may list several of them' if missing[0] in claim.per else ''})")
    absent = _absent(df, claim.select)
    if absent:
        return whole(f"no row of table {claim.table} has {', '.join(absent)}: a case the claim names is missing")
    rows = select_rows(df, claim.select)
    others = None
    if claim.against or claim.against_table:
        table = tables.get(claim.against_table or claim.table, pd.DataFrame())
        absent = _absent(table, claim.against)
        if absent:
            return whole(f"no row of table {claim.against_table or claim.table} has {', '.join(absent)}: the "
                         "target's rows are missing")
        others = select_rows(table, claim.against)
    per = list(claim.per)
    cases = sorted(tuple(c) for c in rows[per].dropna().drop_duplicates().itertuples(index=False)) if per else []
    return [_judge_case(claim, base, rows, others, case, command) for case in cases or [None]]


def _where(df: pd.DataFrame, values: dict[str, Any]) -> pd.DataFrame:
    """The rows of `df` with every column of `values` at its value."""
    keep = np.ones(len(df), dtype=bool)
    for column, value in values.items():
        keep &= (df[column] == value).to_numpy()
    return df[keep]


def _target_rows(claim: Claim, others: pd.DataFrame, case: dict[str, Any]) -> tuple[pd.DataFrame, str]:
    """The target's rows for a case: `against`'s rows, filtered by each per column the target's table has and
    `against` does not name (so per = "solver" compares each solver with its own rows of the target's table);
    and the filters that left none, named for the note."""
    filters = {c: v for c, v in case.items() if c not in claim.against and c in others.columns}
    ref = _where(others, filters)
    emptied = "" if not ref.empty or others.empty else (
        f" (the target's rows of {claim.against_table or claim.table} filtered by the case's "
        f"{', '.join(f'{c}={v}' for c, v in filters.items())}; name a column in against to keep all its values)")
    return ref, emptied


def _judge_case(claim: Claim, base: dict[str, Any], rows: pd.DataFrame, others: pd.DataFrame | None, case: Any,
                command: Command | None) -> dict[str, Any]:
    at = {} if case is None else dict(zip(claim.per, case, strict=True))
    part = _where(rows, at)
    label = ", ".join(f"{c}={v}" for c, v in at.items())
    ref, emptied = (None, "") if others is None else _target_rows(claim, others, at)
    row = base | {"case": label, "solver": _solvers(part), "basis": _basis(part),
                  "command": command(claim, label, part, ref) if command else ""}
    bad, skipped = _problems(part, claim)
    if ref is not None:
        ref_bad, ref_skipped = _problems(ref, claim)
        bad += [f"target: {b}" for b in ref_bad]
        skipped += ref_skipped
    if bad:
        return row | {"verdict": "fail", "note": "not judged on all its cells: " + "; ".join(bad)}
    mixed = mixed_reference(claim, part)
    if mixed:
        return row | {"verdict": "fail", "note": mixed}
    if skipped and (len(skipped) >= len(part) + (0 if ref is None else len(ref))):
        return row | {"verdict": "not-applicable", "note": "skipped: " + "; ".join(skipped)}
    if skipped:
        return row | {"verdict": "fail", "note": "some of its cells were skipped: " + "; ".join(skipped)}
    if part.empty or (ref is not None and ref.empty):
        return row | {"verdict": "fail", "note": "no rows for this case" + (f" in the target{emptied}"
                                                                             if not part.empty else "")}
    metric = claim.against_metric or claim.metric
    if claim.at_error:
        measured = _cost_case(claim, part, ref, metric)
        if isinstance(measured, str):
            return row | {"verdict": "fail", "note": measured}
        value, value_u, target, target_u = measured
        values, own, ref_named = np.array([value]), True, ref is not None
        if not isinstance(claim.uncertainty, str) and math.isfinite(claim.uncertainty):
            value_u = claim.uncertainty  # the claim's own number replaces the repeats' spread
    else:
        values = _values(part, claim.metric)
        value = _aggregate(values, claim.aggregate)
        target, target_u = _target(claim, part), 0.0
        if ref is not None:
            target = _aggregate(_values(ref, metric), claim.aggregate)
            if f"{metric}_unc" in ref.columns:
                target_u = _aggregate(_values(ref, f"{metric}_unc"), "max")
        if not (math.isfinite(value) and math.isfinite(target)):
            which = claim.metric if not math.isfinite(value) else f"target {metric}"
            return row | {"verdict": "fail", "note": f"no finite {which} in every selected row"}
        value_u, own = _uncertainty(part, claim.uncertainty, claim.metric, values)
        ref_named = ref is not None and f"{metric}_unc" in ref.columns
    named = own or ref_named
    unc = math.hypot(value_u if own else 0.0, target_u if ref_named else 0.0) if named else math.nan
    value = abs(value) if claim.absolute else value
    tolerance = bound(claim, target)
    verdict = decide(value, target, tolerance, claim.sense, unc)
    notes = [] if claim.sense == "within" else [f"{claim.sense} target"]
    if claim.tolerance_rel:
        notes.append(f"tolerance {claim.tolerance_rel:g} x |target|" + (f" + {claim.tolerance:g}" if claim.tolerance
                                                                        else ""))
    if verdict == "inconclusive":
        notes.append("its uncertainty band straddles the bound")
    downgrade = []
    if named and not math.isfinite(unc):
        downgrade.append("its uncertainty is unknown" + (f" (fewer than {MIN_REPLICAS} replicas)"
                                                         if claim.uncertainty == SPREAD else ""))
    chaotic = sorted({str(s) for s in part.get("status", pd.Series(dtype=str)).dropna() if str(s) in CHAOTIC})
    if chaotic and not (claim.uncertainty == SPREAD and values.size >= MIN_REPLICAS):
        downgrade.append(f"it stands on a chaotic run (status {', '.join(chaotic)}): one trajectory's digits, not "
                         f"the mean of {MIN_REPLICAS} or more replicas")
    suspect = _suspect(part) + [f"target {s}" for s in (_suspect(ref) if ref is not None else [])]
    if suspect:
        downgrade.append(f"its reference sequence is {', '.join(suspect)} (Richardson classification)")
    if downgrade and verdict == "pass":
        verdict = "inconclusive"
    notes += downgrade
    if "monotone" in part and not part["monotone"].fillna(True).astype(bool).all():
        notes.append("pre-asymptotic: the errors do not decrease with every refinement, so the fitted order "
                     "is not yet the asymptotic rate")
    return row | {"value": value, "target": target, "error": abs(value - target), "uncertainty": unc,
                  "verdict": verdict, "note": "; ".join(notes),
                  "tolerance": tolerance, "slack": slack(value, target, tolerance, claim.sense, unc)}


def _cost_case(claim: Claim, part: pd.DataFrame, ref: pd.DataFrame | None, metric: str
               ) -> tuple[float, float, float, float] | str:
    """(cost, its uncertainty, target, its uncertainty) of a cost claim's case, or why it has none."""
    column, why = error_column(part, claim.error_metric)
    if why:
        return why
    value, value_u, why = cost_at(part, claim.metric, column, claim.at_error)
    if why:
        return why
    if ref is None:
        return value, value_u, _target(claim, part), 0.0
    target, target_u, why = cost_at(ref, metric, column, claim.at_error) if column in ref else (
        math.nan, math.nan, f"error column {column} is not in the target's table")
    return f"target: {why}" if why else (value, value_u, target, target_u)


def verdicts(study: str, claims: list[Claim], tables: dict[str, pd.DataFrame], command: Command | None = None,
             unplanned: dict[str, dict[str, str]] | None = None) -> pd.DataFrame:
    """All verdict rows of a study, in the fixed column order (`unplanned`: as `judge` takes it)."""
    rows = [r for c in claims for r in judge(study, c, tables, command, unplanned)]
    return pd.DataFrame(rows, columns=list(VERDICT_COLUMNS))


def records(table: pd.DataFrame) -> list[dict[str, Any]]:
    """Verdict rows as JSON-ready records (NaN as None), the form of verdicts.json and `study --json`."""
    def native(v: Any) -> Any:
        v = v.item() if isinstance(v, np.generic) else v
        return None if v is None or (isinstance(v, float) and not math.isfinite(v)) else v

    return [{k: native(v) for k, v in row.items()} for row in table.to_dict("records")]
