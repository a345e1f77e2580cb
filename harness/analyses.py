"""The analyses a study group can ask for (`analysis = ...`), as a registry.

An analysis says what its cells compute (a cell task), whether its cells are timed (run serially after
a warm-up), which group options it reads (with their types), and how its cells' results become tables
and figures.  The report and the study loader look analyses up here; a new analysis is one entry.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd

from pcverify.harness import figures, stability, tables
from pcverify.harness.schema import Field
from pcverify.harness.stability import PROBE_KINDS
from pcverify.harness.tasks import SOLVE, TASKS, CellTask

Tables = dict[str, pd.DataFrame]


@dataclass(frozen=True)
class Analysis:
    """One kind of group analysis (see the module docstring)."""

    name: str
    description: str
    tables: Callable[[Any, list[dict[str, Any]], Tables], Tables]
    figures: Callable[[Any, list[dict[str, Any]], Tables, Path], list[str]] = lambda g, res, t, folder: []
    options: tuple[Field, ...] = ()  # the group keys it reads (`schema`: a group's fields by its analysis)
    serial: bool = False
    task: Callable[[dict[str, Any]], CellTask] = field(default=lambda options: SOLVE)


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
    metric = g.options.get("reference_metric", "extrapolated")
    rows = table.dropna(subset=[metric]) if metric in table else table.iloc[0:0]
    unc = rows[f"{metric}_unc"] if f"{metric}_unc" in rows else pd.Series(0.0, index=rows.index)
    kind = rows["kind"] if "kind" in rows else pd.Series("", index=rows.index)
    return {str(q): {"value": float(v), "unc": float(u), "kind": str(k)}
            for q, v, u, k in zip(rows["quantity"], rows[metric], unc, kind, strict=True)}


def _convergence_tables(g: Any, res: list[dict[str, Any]], done: Tables) -> Tables:
    quantities = list(g.options.get("quantities", ["volume_mean", "bulk_median"]))
    levels, fits = tables.convergence(res, quantities, _reference_values(g, done))
    return {f"{g.id}-levels": levels, f"{g.id}-fits": fits}


def _convergence_figures(g: Any, res: list[dict[str, Any]], t: Tables, folder: Path) -> list[str]:
    levels, fits = t[f"{g.id}-levels"], t[f"{g.id}-fits"]
    levels = _ok(levels)
    quantities = list(g.options.get("quantities", ["volume_mean", "bulk_median"]))
    err_cols = [c for c in levels.columns if (c.endswith(".linf") or c.startswith("err.")) and not c.endswith("_unc")]
    drawn = not levels.empty and figures.convergence(levels, err_cols or quantities, folder / g.id, g.title, fits)
    return [f"{g.id}.png"] if drawn else []


def _ok(df: pd.DataFrame) -> pd.DataFrame:
    """The rows of ok cells (tables of measurements keep the others as rows with their status)."""
    return df[df["status"] == "ok"] if "status" in df else df


def _timing_figures(g: Any, res: list[dict[str, Any]], t: Tables, folder: Path) -> list[str]:
    df = _ok(t[f"{g.id}-timing"])
    return [f"{g.id}.png"] if not df.empty and figures.cost(df, folder / g.id, g.title) else []


def _work_precision_tables(g: Any, res: list[dict[str, Any]], done: Tables) -> Tables:
    return {f"{g.id}-work-precision": tables.work_precision(res, g.options.get("error", "nodes.l2"))}


def _work_precision_figures(g: Any, res: list[dict[str, Any]], t: Tables, folder: Path) -> list[str]:
    error = f"err.{g.options.get('error', 'nodes.l2')}"
    df = _ok(t[f"{g.id}-work-precision"]).dropna(subset=[error]) if error in t[f"{g.id}-work-precision"] else None
    return [f"{g.id}.png"] if df is not None and figures.work_precision(df, error, folder / g.id, g.title) else []


def _stability_tables(g: Any, res: list[dict[str, Any]], done: Tables) -> Tables:
    limits, smap = stability.tables(res, g.options.get("probe", "limit"))
    out = {}
    if not limits.empty:
        out[f"{g.id}-limits"] = limits
    if not smap.empty:
        out[f"{g.id}-map"] = smap
    return out


def _stability_figures(g: Any, res: list[dict[str, Any]], t: Tables, folder: Path) -> list[str]:
    drawn = []
    limits = t.get(f"{g.id}-limits")
    if limits is not None:
        limits = _ok(limits)
        meta = {(r["solver"], r["scene"]): {k: r["summary"][k] for k in ("quantity", "theory_label", "x_axis")}
                for r in res if "quantity" in (r.get("summary") or {})
                and r["summary"].get("probe") == "limit"}
        if figures.stability_limits(limits, meta, folder / f"{g.id}-limits", g.title):
            drawn.append(f"{g.id}-limits.png")
    smap = t.get(f"{g.id}-map")
    if smap is not None:
        smap = _ok(smap)
        for (solver, n), part in smap.groupby(["solver", "n"]):
            name = f"{g.id}-map-{solver}-n{n}"
            if figures.stability_map(part, folder / name, f"{g.title}: {solver} n={n}"):
                drawn.append(f"{name}.png")
    return drawn


ANALYSES: dict[str, Analysis] = {a.name: a for a in (
    Analysis("table", "one row per cell: status and every summary scalar", lambda g, res, done: {}),
    Analysis("convergence", "values or errors against h per solver sequence, fitted orders, Richardson and GCI",
             _convergence_tables, _convergence_figures, options=(
                 Field("quantities", "text", "summary quantities to follow (default volume_mean, bulk_median)",
                       shape="list"),
                 Field("reference_table", "text", "an earlier group's fits table whose values are the reference"),
                 Field("reference_metric", "text", "the column of reference_table taken (default extrapolated)"))),
    Analysis("timing", "wall time against unknowns per solver (timed serially after a warm-up)",
             lambda g, res, done: {f"{g.id}-timing": tables.timing(res)}, _timing_figures, serial=True),
    Analysis("work-precision", "error against wall time and work per solver (timed serially after a warm-up)",
             _work_precision_tables, _work_precision_figures, serial=True,
             options=(Field("error", "text", "the error column (default nodes.l2)"),)),
    Analysis("stability", "measured time-step limits (probe = limit) or a stability map (probe = map)",
             _stability_tables, _stability_figures,
             options=(Field("probe", "text", "limit or map (default limit)", choices=PROBE_KINDS),),
             task=lambda options: TASKS[f"stability-{options.get('probe', 'limit')}"]),
)}

def group_report(g: Any, res: list[dict[str, Any]], cells: pd.DataFrame, folder: Path,
                 done: Tables) -> tuple[Tables, list[str]]:
    """Tables and figures of one group (its cells table given), by its analysis and its `figures` list."""
    analysis = ANALYSES[g.analysis]
    out = analysis.tables(g, res, done)
    drawn = analysis.figures(g, res, out, folder)
    out.setdefault(f"{g.id}-cells", cells)
    for kind in g.options.get("figures", []):
        if figures.GROUP_FIGURES[kind](res, folder / f"{g.id}-{kind}", g.title):
            drawn.append(f"{g.id}-{kind}.png")
    return out, drawn
