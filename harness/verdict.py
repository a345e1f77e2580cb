"""Verdicts: each claim of a study judged against the tables the study produced.

A claim is data in the study file (`[[claim]]`): which table, which rows (`select`), which column
(`metric`), how rows are combined (`aggregate`), the target and tolerance, and the kind of
reference the number stands on (analytic / extrapolated / mesh-dependent / same-grid / theory).
`per` splits a claim into one verdict per value of a column (e.g. per n); `against` takes the
target from other rows (of `against_table`, default the same table; column `against_metric`,
default the metric), matched by the `per` value unless `against` fixes that column itself.
A claim with no usable rows is "not-applicable" with the reason, never a pass.  Each verdict names the
solvers its value comes from and, given a `command` function, the command that reproduces its number.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from pcverify.scene import SceneError, shown

REFERENCE_KINDS = ("analytic", "extrapolated", "mesh-dependent", "same-grid", "theory", "paper")
SENSES = ("within", "at-most", "at-least")
AGGREGATES = {"max": np.max, "min": np.min, "median": np.median, "mean": np.mean}
VERDICT_COLUMNS = ("study", "claim", "statement", "case", "solver", "reference", "metric", "value", "target", "error",
                   "uncertainty", "tolerance", "sense", "verdict", "note", "command")


@dataclass(frozen=True)
class Claim:
    """One checkable statement about a study's results."""

    id: str
    text: str
    table: str
    metric: str
    reference: str
    tolerance: float
    target: float = 0.0
    select: dict[str, Any] = field(default_factory=dict)
    aggregate: str = "max"
    absolute: bool = False  # compare |value| (e.g. signed differences) with the target
    per: str = ""
    against: dict[str, Any] = field(default_factory=dict)
    against_table: str = ""  # default: the claim's own table
    against_metric: str = ""  # default: the claim's metric
    uncertainty: float | str = math.nan  # a number, or a column aggregated like the metric
    sense: str = "within"  # within: |value - target| <= tol; at-most: value <= target + tol; at-least: >= target - tol


FIELD_TYPES = {"id": "text", "text": "text", "table": "text", "metric": "text", "reference": "text", "per": "text",
               "against_table": "text", "against_metric": "text", "aggregate": "text", "sense": "text",
               "tolerance": "number", "target": "number", "absolute": "true/false", "select": "a table",
               "against": "a table", "uncertainty": "a number or a column name"}


def _type_ok(kind: str, value: Any) -> bool:
    number = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
    if kind == "text":
        return isinstance(value, str)
    if kind == "number":
        return number
    if kind == "true/false":
        return isinstance(value, bool)
    if kind == "a table":
        return isinstance(value, dict) and all(
            isinstance(v, (str, int, float, bool)) or (isinstance(v, list) and all(
                isinstance(x, (str, int, float, bool)) for x in v)) for v in value.values())
    return number or isinstance(value, str)


def parse_claims(items: list[dict[str, Any]], where: str) -> list[Claim]:
    """Validate the `[[claim]]` tables of a study file before anything runs; a bad one raises SceneError
    naming the field, its type and the allowed values."""
    claims = []
    known = {f for f in Claim.__dataclass_fields__}
    ids: set[str] = set()
    for k, item in enumerate(items):
        at = f"{where} claim {k + 1}"
        if not isinstance(item, dict):
            raise SceneError(f"{at}: {shown(item)} is not valid; allowed: a [[claim]] table")
        unknown = sorted(set(item) - known)
        if unknown:
            raise SceneError(f"{at}: {unknown[0]} is not a claim field; allowed: {', '.join(sorted(known))}")
        for name in ("id", "text", "table", "metric", "reference", "tolerance"):
            if name not in item:
                raise SceneError(f"{at}: {name} is missing")
        for name, value in item.items():
            if not _type_ok(FIELD_TYPES[name], value):
                raise SceneError(f"{at}: {name}={shown(value)} is not valid; allowed: {FIELD_TYPES[name]}")
        if item["id"] in ids:
            raise SceneError(f"{at}: id={item['id']!r} is used by another claim; allowed: one id per claim")
        ids.add(item["id"])
        if item["reference"] not in REFERENCE_KINDS:
            raise SceneError(f"{at}: reference={item['reference']!r} is not allowed; allowed: "
                             f"{', '.join(REFERENCE_KINDS)}")
        if item.get("sense", "within") not in SENSES:
            raise SceneError(f"{at}: sense={item['sense']!r} is not allowed; allowed: {', '.join(SENSES)}")
        if item.get("aggregate", "max") not in AGGREGATES:
            raise SceneError(f"{at}: aggregate={item['aggregate']!r} is not allowed; allowed: {', '.join(AGGREGATES)}")
        tol = item["tolerance"]
        if isinstance(tol, bool) or not isinstance(tol, (int, float)) or not math.isfinite(tol) or tol < 0:
            raise SceneError(f"{at}: tolerance={tol!r} is out of range; allowed: number in [0, inf)")
        claims.append(Claim(**item))
    return claims


def _rows(df: pd.DataFrame, select: dict[str, Any]) -> pd.DataFrame:
    for col, want in select.items():
        if col not in df.columns:
            return df.iloc[0:0]
        wanted = want if isinstance(want, list) else [want]
        df = df[df[col].isin(wanted)]
    return df


def _aggregate(df: pd.DataFrame, column: str, how: str) -> float:
    if column not in df.columns:
        return math.nan
    values = pd.to_numeric(df[column], errors="coerce").to_numpy(float)
    values = values[np.isfinite(values)]
    return float(AGGREGATES[how](values)) if values.size else math.nan


# the command that reproduces a verdict's number, from the claim, its value rows and its target rows (or None)
Command = Callable[["Claim", pd.DataFrame, "pd.DataFrame | None"], str]


def _solvers(rows: pd.DataFrame) -> str:
    return ", ".join(sorted({str(s) for s in rows["solver"].dropna()})) if "solver" in rows else ""


def judge(study: str, claim: Claim, tables: dict[str, pd.DataFrame], command: Command | None = None
          ) -> list[dict[str, Any]]:
    """Verdict rows for one claim (one per `per` value)."""
    base = {"study": study, "claim": claim.id, "statement": claim.text, "reference": claim.reference,
            "metric": claim.metric, "tolerance": claim.tolerance, "sense": claim.sense}
    df = tables.get(claim.table)
    if df is None or df.empty:
        cmd = command(claim, pd.DataFrame(), None) if command else ""
        return [base | {"case": "", "verdict": "not-applicable", "note": f"table {claim.table} has no rows",
                        "command": cmd}]
    missing = [c for c in (claim.metric, claim.per, *claim.select) if c and c not in df.columns]
    if missing:
        cmd = command(claim, pd.DataFrame(), None) if command else ""
        return [base | {"case": "", "verdict": "not-applicable", "command": cmd,
                        "note": f"column {missing[0]} is not in table {claim.table} (columns: "
                                f"{', '.join(map(str, df.columns))})"}]
    rows = _rows(df, claim.select)
    others = None
    if claim.against or claim.against_table:
        others = _rows(tables.get(claim.against_table or claim.table, pd.DataFrame()), claim.against)
    cases = sorted(rows[claim.per].dropna().unique().tolist()) if claim.per and claim.per in rows else []
    cases = cases or [None]
    out = []
    for case in cases:
        part = rows if case is None else rows[rows[claim.per] == case]
        row = base | {"case": "" if case is None else f"{claim.per}={case}", "solver": _solvers(part)}
        value = _aggregate(part, claim.metric, claim.aggregate)
        target = claim.target
        ref = None
        if others is not None:
            matched = case is None or claim.per in claim.against or claim.per not in others
            ref = others if matched else others[others[claim.per] == case]
            target = _aggregate(ref, claim.against_metric or claim.metric, claim.aggregate)
        row["command"] = command(claim, part, ref) if command else ""
        if not (math.isfinite(value) and math.isfinite(target)):
            reasons = sorted(set(str(r) for r in part.get("reason", pd.Series(dtype=str)).dropna() if r))
            statuses = sorted(set(part.get("status", pd.Series(dtype=str)).dropna()))
            note = f"no finite {claim.metric} in the selected rows"
            note += f" (status {', '.join(statuses)}: {reasons[0]})" if reasons else ""
            out.append(row | {"verdict": "not-applicable", "note": note})
            continue
        if isinstance(claim.uncertainty, str):
            unc = _aggregate(part, claim.uncertainty, "max")
        else:
            unc = float(claim.uncertainty)
        value = abs(value) if claim.absolute else value
        error = abs(value - target)
        ok = {"within": error <= claim.tolerance, "at-most": value <= target + claim.tolerance,
              "at-least": value >= target - claim.tolerance}[claim.sense]
        notes = [] if claim.sense == "within" else [f"{claim.sense} target"]
        if "monotone" in part and not part["monotone"].fillna(True).astype(bool).all():
            notes.append("pre-asymptotic: the errors do not decrease with every refinement, so the fitted order "
                         "is not yet the asymptotic rate")
        out.append(row | {"value": value, "target": target, "error": error, "uncertainty": unc,
                          "verdict": "pass" if ok else "fail", "note": "; ".join(notes)})
    return out


def verdicts(study: str, claims: list[Claim], tables: dict[str, pd.DataFrame], command: Command | None = None
             ) -> pd.DataFrame:
    """All verdict rows of a study, in the fixed column order."""
    rows = [r for c in claims for r in judge(study, c, tables, command)]
    return pd.DataFrame(rows, columns=list(VERDICT_COLUMNS))


def records(table: pd.DataFrame) -> list[dict[str, Any]]:
    """Verdict rows as JSON-ready records (NaN as None), the form of verdicts.json and `study --json`."""
    def native(v: Any) -> Any:
        v = v.item() if isinstance(v, np.generic) else v
        return None if v is None or (isinstance(v, float) and not math.isfinite(v)) else v

    return [{k: native(v) for k, v in row.items()} for row in table.to_dict("records")]
