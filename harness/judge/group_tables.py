"""The tables of a study group, by its analysis (`pcverify.harness.study.analyses`): convergence levels and fits,
timing, work-precision, stability limits and maps.  Pure functions of the group's results and the tables of the
groups before it (a convergence group may take its reference from an earlier group's fits)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pandas as pd

from pcverify.harness.judge import tables
from pcverify.harness.study import stability

Tables = dict[str, pd.DataFrame]


def _reference_values(g: Any, done: Tables) -> dict[str, dict[str, Any]] | None:
    """Reference per quantity from an earlier group's table (option reference_table, e.g. the Richardson fits
    of a converged continuum sequence: its `extrapolated` column by `quantity`), with its uncertainty (the
    `<metric>_unc` column, 0 if the table has none) and its Richardson class (`kind`)."""
    name = g.options.get("reference_table")
    if not name:
        return None
    table = done.get(name)
    if table is None or table.empty:
        return {}
    metric = g.options["reference_metric"]
    rows = table.dropna(subset=[metric]) if metric in table else table.iloc[0:0]
    unc = rows[f"{metric}_unc"] if f"{metric}_unc" in rows else pd.Series(0.0, index=rows.index)
    kind = rows["kind"] if "kind" in rows else pd.Series("", index=rows.index)
    return {str(q): {"value": float(v), "unc": float(u), "kind": str(k)}
            for q, v, u, k in zip(rows["quantity"], rows[metric], unc, kind, strict=True)}


def _convergence_tables(g: Any, res: list[dict[str, Any]], done: Tables) -> Tables:
    quantities = list(g.options["quantities"])
    levels, fits = tables.convergence(res, quantities, _reference_values(g, done),
                                      self_reference=g.options.get("reference") == "self")
    return {f"{g.id}-levels": levels, f"{g.id}-fits": fits}


def _work_precision_tables(g: Any, res: list[dict[str, Any]], done: Tables) -> Tables:
    return {f"{g.id}-work-precision": tables.work_precision(res, g.options["error"])}


def _stability_tables(g: Any, res: list[dict[str, Any]], done: Tables) -> Tables:
    limits, smap = stability.tables(res, g.options["probe"])
    out = {}
    if not limits.empty:
        out[f"{g.id}-limits"] = limits
    if not smap.empty:
        out[f"{g.id}-map"] = smap
    return out


TABLES: dict[str, Callable[[Any, list[dict[str, Any]], Tables], Tables]] = {
    "table": lambda g, res, done: {},
    "convergence": _convergence_tables,
    "timing": lambda g, res, done: {f"{g.id}-timing": tables.timing(res)},
    "work-precision": _work_precision_tables,
    "stability": _stability_tables,
}


def group_tables(g: Any, res: list[dict[str, Any]], done: Tables) -> Tables:
    """The tables of group `g` (its results `res`; `done`: the tables of the groups before it)."""
    return TABLES[g.analysis](g, res, done)
