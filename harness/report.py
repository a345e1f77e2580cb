"""Reports: per-study CSV and Markdown tables, PNG/SVG plots, and one self-contained index.html.

The report reads study results (or the cache through them); it never runs a solver.
"""

from __future__ import annotations

import base64
import html
import json
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from pcverify.harness import figures, verdict
from pcverify.harness.analyses import group_report
from pcverify.harness.provenance import command, provenance
from pcverify.harness.tables import cells_table
from pcverify.harness.vtu import write_vtu


def _markdown(df: pd.DataFrame) -> str:
    if df.empty:
        return "(no rows)\n"
    cols = list(df.columns)
    fmt = lambda v: f"{v:.6g}" if isinstance(v, float) else ("" if v is None else str(v))  # noqa: E731
    lines = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    lines += ["| " + " | ".join(fmt(v) for v in row) + " |" for row in df.itertuples(index=False)]
    return "\n".join(lines) + "\n"


def _vtu_name(r: dict[str, Any]) -> str:
    tag = r.get("cache_key") or "cell"
    return f"{r['group']}-{r['solver']}-n{r['n']}-r{r['refine']}-{tag}.vtu"


def _write_vtus(results: list[dict[str, Any]], folder: Path) -> list[str]:
    """One VTU point cloud per ok cell that sampled the lattice nodes (ParaView)."""
    names = []
    for r in results:
        nodes = (r.get("samples") or {}).get("nodes") if r.get("status") in figures.SHOWN else None
        if nodes is None:
            continue
        values = np.asarray(nodes["values"], dtype=float)
        name = (r.get("quantity") or "value").replace("/", "_over_")
        names.append(f"vtu/{_vtu_name(r)}")
        write_vtu(folder / names[-1], np.asarray(nodes["points"], dtype=float), {name: values})
    return names


def write_study_report(study: Any, results: list[dict[str, Any]], out: Path, run_command: str | None = None,
                       extra: list[tuple[dict[str, Any], dict[str, pd.DataFrame]]] = ()) -> Path:
    """Write tables, plots, VTU files and verdicts of one study into out/<study>/ and its manifest (with the
    study file, its plugin modules and the command that ran it: this process's, unless `run_command`).
    `extra`: sections made elsewhere (a calibration's: id, title, figures already drawn) with their tables;
    their tables are written and available to the claims like the groups' tables."""
    folder = out / study.name
    folder.mkdir(parents=True, exist_ok=True)
    manifest: dict[str, Any] = {"name": study.name, "title": study.title, "sections": [], "verdicts": None,
                                "study_file": str(study.path) if study.path else None,
                                "plugins": list(study.plugins), "command": run_command or command()}
    all_tables: dict[str, pd.DataFrame] = {}
    group_cells = []
    for g in study.groups:
        res = [r for r in results if r.get("group") == g.id]
        group_cells.append(cells_table(res))
        tables, figs = group_report(g, res, group_cells[-1], folder, all_tables)
        skipped = [r for r in res if r.get("status") in ("skipped", "failed")]
        if skipped:
            tables[f"{g.id}-skipped"] = pd.DataFrame(
                [{"solver": r["solver"], "n": r["n"], "refine": r["refine"], "status": r["status"],
                  "reason": r.get("reason", "")} for r in skipped])
        section: dict[str, Any] = {"id": g.id, "title": g.title, "tables": [], "figures": figs, "vtu": []}
        for name, df in tables.items():
            _write_table(df, folder / name)
            if name != f"{g.id}-cells" or g.analysis == "table":
                section["tables"].append(f"{name}.csv")
        if g.options.get("vtu"):
            section["vtu"] = _write_vtus(res, folder)
        all_tables.update(tables)
        manifest["sections"].append(section)
    for meta, tables in extra:
        section = {"id": meta["id"], "title": meta["title"], "tables": [], "figures": list(meta.get("figures", [])),
                   "vtu": []}
        for name, df in tables.items():
            _write_table(df, folder / name)
            section["tables"].append(f"{name}.csv")
        all_tables.update(tables)
        manifest["sections"].append(section)
    cells = pd.concat(group_cells, ignore_index=True) if group_cells else pd.DataFrame()
    cells.to_csv(folder / "cells.csv", index=False)
    if study.claims:
        _write_table(verdict.verdicts(study.name, study.claims, all_tables), folder / "verdicts")
        manifest["verdicts"] = "verdicts.csv"
    (folder / "manifest.json").write_text(json.dumps(manifest, indent=1))
    return folder


def _write_table(df: pd.DataFrame, stem: Path) -> None:
    df.to_csv(stem.with_suffix(".csv"), index=False)
    stem.with_suffix(".md").write_text(_markdown(df))


CSS = ("body{font-family:sans-serif;max-width:1150px;margin:auto}table{border-collapse:collapse;font-size:12px;"
       "margin-bottom:1em}td,th{border:1px solid #ccc;padding:2px 6px}h2{border-bottom:1px solid #888}"
       "img{max-width:100%}.pass{background:#d8f5d0}.fail{background:#f8d0d0}.not-applicable{background:#eee}")


def _html_table(df: pd.DataFrame, table_id: str) -> str:
    if df.empty:
        return f"<table id='{html.escape(table_id)}' class='data'><tr><td>(no rows)</td></tr></table>"
    body = df.to_html(index=False, float_format=lambda v: f"{v:.6g}", na_rep="", classes="data",
                      table_id=table_id, escape=True)
    if "verdict" in df.columns:
        for word in ("pass", "fail", "not-applicable"):
            body = body.replace(f"<td>{word}</td>", f"<td class='{word}'>{word}</td>")
    return f"<div class='scroll'>{body}</div>"


def _read_csv(path: Path) -> pd.DataFrame:
    try:
        return pd.read_csv(path)
    except pd.errors.EmptyDataError:
        return pd.DataFrame()


def _img(path: Path) -> str:
    data = base64.b64encode(path.read_bytes()).decode()
    return f"<img alt='{html.escape(path.name)}' src='data:image/png;base64,{data}'>"


def _benchmarks(out: Path) -> list[str]:
    """The benchmark section: history of saved runs and the kernels' cost per pair-step against N."""
    storage = out / "benchmarks"
    runs = figures.benchmark_runs(storage)
    if runs.empty:
        return ["<h2 id='benchmarks'>Benchmarks</h2><p>No saved benchmark runs under "
                f"{html.escape(str(storage))} (run <code>tox -e bench</code>).</p>"]
    folder = out / "benchmark-figures"
    folder.mkdir(exist_ok=True)
    parts = ["<h2 id='benchmarks'>Benchmarks</h2>"]
    for name, draw in (("history", figures.benchmark_history), ("scaling", figures.benchmark_scaling)):
        if draw(runs, folder / name):
            parts.append(_img(folder / f"{name}.png"))
    last = runs[runs["run"] == runs["run"].max()].dropna(axis=1, how="all")
    parts.append("<p><b>latest run</b></p>" + _html_table(last, "benchmarks-latest"))
    return parts


def write_index(out: Path) -> Path:
    """One self-contained index.html (images embedded): verdicts first, then every study, benchmarks, provenance."""
    manifests = [(p.parent, json.loads(p.read_text())) for p in sorted(out.glob("*/manifest.json"))]
    parts = ["<!doctype html><html lang='en'><head><meta charset='utf-8'><title>pcverify report</title>",
             f"<style>{CSS}</style></head><body><h1>pcverify report</h1>"]
    verdict_tables = [_read_csv(folder / man["verdicts"]) for folder, man in manifests if man.get("verdicts")]
    verdict_tables = [v for v in verdict_tables if not v.empty]
    parts.append("<h2 id='verdicts'>Verdicts</h2><p>Each claim with the kind of reference it stands on, the value, "
                 "its error against the target, the uncertainty of the number, the tolerance and the verdict.</p>")
    if verdict_tables:
        table = pd.concat(verdict_tables, ignore_index=True)
        counts = table["verdict"].value_counts().to_dict()
        parts.append("<p>" + ", ".join(f"{v}: {counts[v]}" for v in sorted(counts)) + "</p>")
        parts.append(_html_table(table, "verdicts-table"))
    else:
        parts.append("<p>No study with claims has results yet.</p>")
    for folder, man in manifests:
        parts.append(f"<h2 id='{html.escape(man['name'])}'>{html.escape(man['title'])}</h2>")
        for sec in man["sections"]:
            parts.append(f"<h3>{html.escape(sec['title'])}</h3>")
            parts += [_img(folder / fig) for fig in sec["figures"]]
            for tab in sec["tables"]:
                parts.append(f"<p><b>{html.escape(tab)}</b></p>")
                parts.append(_html_table(_read_csv(folder / tab), f"{man['name']}-{Path(tab).stem}"))
            if sec.get("vtu"):
                parts.append(f"<p>VTU (ParaView) under {html.escape(str(folder / 'vtu'))}: {len(sec['vtu'])} files</p>")
    parts += _benchmarks(out)
    prov = provenance([man for _, man in manifests])
    parts.append("<h2 id='provenance'>Provenance</h2><table id='provenance-table'>")
    parts += [f"<tr><th>{html.escape(k)}</th><td>{html.escape(v)}</td></tr>" for k, v in prov.items()]
    parts.append("</table></body></html>")
    index = out / "index.html"
    tmp = index.with_suffix(".html.tmp")
    tmp.write_text("\n".join(parts))
    tmp.replace(index)
    return index
