"""Reports: per-study CSV and Markdown tables, PNG/SVG plots, and one self-contained index.html.

The report reads study results (or the cache through them); it never runs a solver.
"""

from __future__ import annotations

import argparse
import base64
import datetime as dt
import html
import json
import platform
import subprocess
from importlib import metadata
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pandas as pd  # noqa: E402

from harness import analysis  # noqa: E402

PACKAGES = ("numpy", "scipy", "numba", "fipy", "scikit-fem", "pyamg", "pandas", "matplotlib")


def _markdown(df: pd.DataFrame) -> str:
    if df.empty:
        return "(no rows)\n"
    cols = list(df.columns)
    fmt = lambda v: f"{v:.6g}" if isinstance(v, float) else ("" if v is None else str(v))  # noqa: E731
    lines = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    lines += ["| " + " | ".join(fmt(v) for v in row) + " |" for row in df.itertuples(index=False)]
    return "\n".join(lines) + "\n"


def _plot_convergence(levels: pd.DataFrame, fits: pd.DataFrame, columns: list[str], path: Path, title: str) -> None:
    fig, ax = plt.subplots(figsize=(6, 4))
    for (solver, params), seq in levels.groupby(["solver", "params"], sort=False):
        seq = seq.sort_values("h")
        for col in columns:
            y = seq[col].abs()
            if (y > 0).all():
                ax.loglog(seq["h"], y, "o-", label=f"{solver} {params} {col}".strip())
    ax.set_xlabel("h [m]")
    ax.set_ylabel("error" if any(c.endswith(("l2", "linf")) for c in columns) else "|value|")
    ax.set_title(title, fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    if ax.lines:
        ax.legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(path.with_suffix(".png"), dpi=110)
    fig.savefig(path.with_suffix(".svg"))
    plt.close(fig)


def _plot_timing(df: pd.DataFrame, path: Path, title: str) -> None:
    fig, ax = plt.subplots(figsize=(6, 4))
    for solver, seq in df.groupby("solver"):
        ax.loglog(seq["unknowns"], seq["wall_s"], "o-", label=solver)
    ax.set_xlabel("unknowns")
    ax.set_ylabel("wall time [s]")
    ax.set_title(title, fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path.with_suffix(".png"), dpi=110)
    fig.savefig(path.with_suffix(".svg"))
    plt.close(fig)


def write_study_report(study: Any, results: list[dict[str, Any]], out: Path) -> Path:
    """Write tables and plots of one study into out/<study>/ and a manifest the index reads."""
    folder = out / study.name
    folder.mkdir(parents=True, exist_ok=True)
    manifest: dict[str, Any] = {"name": study.name, "title": study.title, "sections": []}
    by_group = {g.id: [r for r in results if r.get("group") == g.id] for g in study.groups}
    cells = analysis.cells_table(results)
    cells.to_csv(folder / "cells.csv", index=False)
    for g in study.groups:
        res = by_group[g.id]
        section: dict[str, Any] = {"id": g.id, "title": g.title, "tables": [], "figures": []}
        skipped = [r for r in res if r.get("status") in ("skipped", "failed")]
        if g.analysis == "convergence":
            quantities = list(g.options.get("quantities", ["volume_mean", "bulk_median"]))
            levels, fits = analysis.convergence(res, quantities)
            tables = {f"{g.id}-levels": levels, f"{g.id}-fits": fits}
            if not levels.empty:
                err_cols = [c for c in levels.columns if c.endswith(".linf")]
                _plot_convergence(levels, fits, err_cols or quantities, folder / g.id, g.title)
                section["figures"].append(f"{g.id}.png")
        elif g.analysis == "timing":
            df = analysis.timing(res)
            tables = {f"{g.id}-timing": df}
            if not df.empty:
                _plot_timing(df, folder / g.id, g.title)
                section["figures"].append(f"{g.id}.png")
        elif g.analysis == "stability":
            from harness.stability import report_tables

            tables, figures = report_tables(res, folder, g.id, g.title)
            section["figures"] += figures
        else:
            tables = {f"{g.id}-cells": analysis.cells_table(res)}
        if skipped:
            tables[f"{g.id}-skipped"] = pd.DataFrame(
                [{"solver": r["solver"], "n": r["n"], "refine": r["refine"], "status": r["status"],
                  "reason": r.get("reason", "")} for r in skipped])
        for name, df in tables.items():
            df.to_csv(folder / f"{name}.csv", index=False)
            (folder / f"{name}.md").write_text(_markdown(df))
            section["tables"].append(f"{name}.csv")
        manifest["sections"].append(section)
    (folder / "manifest.json").write_text(json.dumps(manifest, indent=1))
    return folder


def provenance() -> dict[str, str]:
    """Package versions, git commit, machine and time, for the report's footer."""
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                                timeout=5, check=False).stdout.strip() or "unknown"
    except (OSError, subprocess.SubprocessError):
        commit = "unknown"
    info = {"generated": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"), "git commit": commit,
            "machine": f"{platform.node()} {platform.machine()} {platform.processor()}".strip(),
            "python": platform.python_version()}
    for pkg in PACKAGES:
        try:
            info[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            info[pkg] = "absent"
    return info


def write_index(out: Path) -> Path:
    """One self-contained index.html (images embedded) over every study folder in `out`."""
    parts = ["<!doctype html><html><head><meta charset='utf-8'><title>pcverify report</title>",
             "<style>body{font-family:sans-serif;max-width:1100px;margin:auto}table{border-collapse:collapse;"
             "font-size:12px}td,th{border:1px solid #ccc;padding:2px 6px}h2{border-bottom:1px solid #888}</style>",
             "</head><body><h1>pcverify report</h1>"]
    for manifest_path in sorted(out.glob("*/manifest.json")):
        man = json.loads(manifest_path.read_text())
        folder = manifest_path.parent
        parts.append(f"<h2>{html.escape(man['title'])}</h2>")
        for sec in man["sections"]:
            parts.append(f"<h3>{html.escape(sec['title'])}</h3>")
            for fig in sec["figures"]:
                data = base64.b64encode((folder / fig).read_bytes()).decode()
                parts.append(f"<img alt='{html.escape(fig)}' src='data:image/png;base64,{data}'>")
            for tab in sec["tables"]:
                parts.append(f"<p><b>{html.escape(tab)}</b></p>")
                try:
                    df = pd.read_csv(folder / tab)
                except pd.errors.EmptyDataError:
                    parts.append("<p>(no rows)</p>")
                    continue
                parts.append(df.to_html(index=False, float_format=lambda v: f"{v:.6g}", na_rep=""))
    prov = provenance()
    parts.append("<h2>Provenance</h2><table>")
    parts += [f"<tr><th>{html.escape(k)}</th><td>{html.escape(v)}</td></tr>" for k, v in prov.items()]
    parts.append("</table></body></html>")
    index = out / "index.html"
    index.write_text("\n".join(parts))
    return index


def report_cli(args: argparse.Namespace) -> int:
    """`pcverify report`: rebuild every study's tables from the cache, then index.html."""
    from harness.cache import Cache
    from harness.study import cached_results, load_study, study_files

    out = Path(args.out)
    cache = Cache(out / "cache")
    rebuilt = []
    for name in sorted(study_files()):
        study = load_study(name)
        results = cached_results(study, cache)
        if results:
            write_study_report(study, results, out)
            rebuilt.append({"study": name, "cells_cached": len(results)})
    index = write_index(out)
    if args.json:
        print(json.dumps({"index": str(index), "studies": rebuilt}))
    else:
        for r in rebuilt:
            print(f"{r['study']}: rebuilt from {r['cells_cached']} cached cells")
        print(f"report: {index}")
    return 0
