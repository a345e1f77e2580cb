"""The figures of a study group, by its analysis (`pcverify.harness.study.analyses`), and the group's part of a
report: its tables (`pcverify.harness.judge.group_tables`) and figures, with the figures its `figures` list asks
for by name."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import pandas as pd

from pcverify.harness.judge.group_tables import Tables, group_tables
from pcverify.harness.report import figures


def _convergence_figures(g: Any, res: list[dict[str, Any]], t: Tables, folder: Path) -> list[str]:
    levels, fits = t[f"{g.id}-levels"], t[f"{g.id}-fits"]
    levels = _ok(levels)
    quantities = list(g.options["quantities"])
    norms = tuple(f".{n}" for n in g.options["norms"])
    err_cols = [c for c in levels.columns if (c.endswith(norms) or c.startswith("err.")) and not c.endswith("_unc")]
    drawn = not levels.empty and figures.convergence(levels, err_cols or quantities, folder / g.id, g.title, fits)
    return [f"{g.id}.png"] if drawn else []


def _ok(df: pd.DataFrame) -> pd.DataFrame:
    """The rows of ok cells (tables of measurements keep the others as rows with their status)."""
    return df[df["status"] == "ok"] if "status" in df else df


def _timing_figures(g: Any, res: list[dict[str, Any]], t: Tables, folder: Path) -> list[str]:
    df = _ok(t[f"{g.id}-timing"])
    drawn = not df.empty and figures.cost(df, folder / g.id, g.title, bool(g.options.get("mix_runs")))
    return [f"{g.id}.png"] if drawn else []


def _work_precision_figures(g: Any, res: list[dict[str, Any]], t: Tables, folder: Path) -> list[str]:
    error = f"err.{g.options['error']}"
    df = _ok(t[f"{g.id}-work-precision"]).dropna(subset=[error]) if error in t[f"{g.id}-work-precision"] else None
    beside = []
    for other in g.options.get("beside", []):
        table = t.get(f"{other}-work-precision")
        if table is not None and error in table:
            beside.append((str(other), _ok(table).dropna(subset=[error])))
    drawn = df is not None and figures.work_precision(df, error, folder / g.id, g.title,
                                                      bool(g.options.get("mix_runs")), beside)
    return [f"{g.id}.png"] if drawn else []


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


FIGURES: dict[str, Callable[[Any, list[dict[str, Any]], Tables, Path], list[str]]] = {
    "table": lambda g, res, t, folder: [],
    "convergence": _convergence_figures,
    "timing": _timing_figures,
    "work-precision": _work_precision_figures,
    "stability": _stability_figures,
}


def group_report(g: Any, res: list[dict[str, Any]], cells: pd.DataFrame, folder: Path,
                 done: Tables) -> tuple[Tables, list[str]]:
    """Tables and figures of one group (its cells table given), by its analysis and its `figures` list."""
    out = group_tables(g, res, done)
    drawn = FIGURES[g.analysis](g, res, done | out, folder)  # a figure may draw earlier groups' tables beside
    out.setdefault(f"{g.id}-cells", cells)
    for kind in g.options["figures"]:
        if kind == "parameter":
            x = g.options["figure_x"]
            ys = g.options["figure_y"]
            ys = [ys] if isinstance(ys, str) else list(ys)
            if figures.parameter_figure(res, folder / f"{g.id}-{x}", f"{g.title}: against {x}", x, ys):
                drawn.append(f"{g.id}-{x}.png")
        elif figures.GROUP_FIGURES[kind](res, folder / f"{g.id}-{kind}", g.title):
            drawn.append(f"{g.id}-{kind}.png")
    return out, drawn
