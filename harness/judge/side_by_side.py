"""The table of a panel: per quantity, each solver's value, its deviation from the reference, and the reference.

Values are read from the tables the groups wrote (`Tables`), never computed here.  A solver whose rows are
absent (its cells skipped, say) shows an empty value; one whose selection matches several rows shows none and
says how many, since picking one would hide the choice.
"""

from __future__ import annotations

import math
from typing import Any

import pandas as pd

from pcverify.harness.judge.verdict import select_rows
from pcverify.harness.study.panels import Panel, PanelRow

Tables = dict[str, pd.DataFrame]


def _one(tables: Tables, table: str, select: dict[str, Any], metric: str) -> tuple[float, str]:
    """The single value of `metric` in the rows of `table` that `select` picks, or NaN and why not."""
    df = tables.get(table)
    if df is None:
        return math.nan, f"no table {table}"
    if metric not in df.columns:
        return math.nan, f"no column {metric} in {table}"
    rows = select_rows(df, select)
    if len(rows) != 1:
        return math.nan, f"{len(rows)} rows of {table}" if len(rows) else f"no row of {table}"
    value = pd.to_numeric(rows[metric], errors="coerce").iloc[0]
    return (float(value), "") if pd.notna(value) else (math.nan, f"{metric} is empty")


def _reference(row: PanelRow, tables: Tables) -> tuple[float, float, str]:
    """The reference value, its uncertainty (the table's <metric>_unc column; 0 for a number) and why it is
    missing."""
    if row.reference is not None:
        return row.reference, 0.0, ""
    value, why = _one(tables, str(row.reference_table), row.reference_select, row.reference_metric)
    unc, _ = _one(tables, str(row.reference_table), row.reference_select, f"{row.reference_metric}_unc")
    return value, unc, why


def panel_table(panel: Panel, tables: Tables) -> pd.DataFrame:
    """One row per quantity: `<solver>` (scaled value) and `<solver> dev` ((value - ref) / |ref|) per solver, then
    `reference`, `reference_unc`, `reference_kind`, `source` (table and column) and `note` (why a value is
    missing)."""
    records = []
    for row in panel.rows:
        ref, unc, ref_why = _reference(row, tables)
        rec: dict[str, Any] = {"quantity": row.label}
        notes = [f"reference: {ref_why}"] if ref_why else []
        for solver in panel.solvers:
            value, why = _one(tables, row.table, {**row.select, "solver": solver}, row.metric)
            rec[solver] = value * row.scale
            rec[f"{solver} dev"] = (value - ref) / abs(ref) if math.isfinite(ref) and ref != 0 else math.nan
            if why:
                notes.append(f"{solver}: {why}")
        rec["reference"] = ref * row.scale
        rec["reference_unc"] = unc * row.scale
        rec["reference_kind"] = row.reference_kind
        rec["source"] = f"{row.table}: {row.metric}"
        rec["note"] = "; ".join(notes)
        records.append(rec)
    return pd.DataFrame(records)
