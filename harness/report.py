"""Reports: per-study CSV and Markdown tables, PNG/SVG plots, verdicts (CSV and JSON), and one
self-contained index.html that opens with the summary and the findings.

The report reads study results (or the cache through them); it never runs a solver.  Every verdict
carries the command that reproduces its number; `verdicts.json` beside index.html lists them all.
"""

from __future__ import annotations

import html
import json
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from pcverify.harness import figures, page, verdict
from pcverify.harness.analyses import group_report
from pcverify.harness.findings import findings, summary_lines
from pcverify.harness.provenance import command, provenance
from pcverify.harness.reproduce import study_command, table_group, verdict_commands
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


def _orders(study: Any, tables: dict[str, pd.DataFrame]) -> list[dict[str, Any]]:
    """Observed orders of the study's fits tables: group, solver, params, quantity, order."""
    out = []
    for name, df in tables.items():
        if not name.endswith("-fits") or df.empty or not {"solver", "quantity", "order"} <= set(df.columns):
            continue
        for r in df.dropna(subset=["order"]).itertuples(index=False):
            out.append({"group": table_group(study, name) or name, "solver": str(r.solver),
                        "params": str(getattr(r, "params", "") or ""), "quantity": str(r.quantity),
                        "order": float(r.order)})
    return out


def _lattice_nodes(study: Any, claims: list[verdict.Claim], table: pd.DataFrame) -> list[float]:
    """Lattice nodes (particles) of each verdict whose case is n=K, from its group's scene box."""
    boxes = {g.id: g.cells[0].scene.box for g in study.groups if g.cells}
    by_claim = {c.id: c for c in claims}
    nodes = []
    for claim, case in zip(table["claim"], table["case"], strict=True):
        key, _, value = str(case).partition("=")
        box = boxes.get(table_group(study, by_claim[claim].table) or "")
        if key == "n" and box is not None and value.isdigit():
            nodes.append(float(np.prod(box.lattice_shape(int(value)))))
        else:
            nodes.append(np.nan)
    return nodes


def write_study_report(study: Any, results: list[dict[str, Any]], out: Path, run_command: str | None = None,
                       extra: list[tuple[dict[str, Any], dict[str, pd.DataFrame]]] = ()) -> Path:
    """Write tables, plots, VTU files and verdicts of one study into out/<study>/ and its manifest (with the
    study file, its plugin modules and the command that ran it: this process's, unless `run_command`; and
    `rerun`, the command that reruns it from the cache).  `extra`: sections made elsewhere (a calibration's:
    id, title, figures already drawn) with their tables; their tables are written and available to the
    claims like the groups' tables."""
    folder = out / study.name
    folder.mkdir(parents=True, exist_ok=True)
    manifest: dict[str, Any] = {"name": study.name, "title": study.title, "sections": [], "verdicts": None,
                                "study_file": str(study.path) if study.path else None,
                                "plugins": list(study.plugins), "command": run_command or command(),
                                "rerun": study_command(study, []),
                                "solvers": sorted({c.solver for g in study.groups for c in g.cells}
                                                   | {c.solver for c in getattr(study, "calibrations", [])})}
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
    manifest["orders"] = _orders(study, all_tables)
    if study.claims:
        table = verdict.verdicts(study.name, study.claims, all_tables, verdict_commands(study, results))
        table["nodes"] = _lattice_nodes(study, study.claims, table)
        _write_table(table, folder / "verdicts")
        (folder / "verdicts.json").write_text(json.dumps(verdict.records(table), indent=1))
        manifest["verdicts"] = "verdicts.csv"
    (folder / "manifest.json").write_text(json.dumps(manifest, indent=1))
    return folder


def study_verdicts(out: Path, study: str) -> list[dict[str, Any]]:
    """The verdict records a study's report wrote (from verdicts.csv for a report written before verdicts.json
    existed; empty when the study has no claims)."""
    path = out / study / "verdicts.json"
    if path.exists():
        return json.loads(path.read_text())
    table = _read_csv(path.with_suffix(".csv")) if path.with_suffix(".csv").exists() else pd.DataFrame()
    return verdict.records(table.astype(object).where(table.notna(), None)) if not table.empty else []


def _write_table(df: pd.DataFrame, stem: Path) -> None:
    df.to_csv(stem.with_suffix(".csv"), index=False)
    stem.with_suffix(".md").write_text(_markdown(df))




def _read_csv(path: Path) -> pd.DataFrame:
    try:
        return pd.read_csv(path)
    except pd.errors.EmptyDataError:
        return pd.DataFrame()


def _benchmarks(out: Path) -> list[str]:
    """The benchmark section: history of saved runs and the kernels' cost per pair-step against N."""
    storage = out / "benchmarks"
    runs = figures.benchmark_runs(storage)
    if runs.empty:
        return ["<section id='benchmarks'><h2>Benchmarks</h2><p>No saved benchmark runs under "
                f"{html.escape(str(storage))} (run <code>tox -e bench</code>).</p></section>"]
    folder = out / "benchmark-figures"
    folder.mkdir(exist_ok=True)
    parts = ["<section id='benchmarks'><h2>Benchmarks</h2>"]
    for name, draw in (("history", figures.benchmark_history), ("scaling", figures.benchmark_scaling)):
        if draw(runs, folder / name):
            parts.append(page.figure(folder, "benchmark-figures", f"{name}.png"))
    last = runs[runs["run"] == runs["run"].max()].dropna(axis=1, how="all")
    last.to_csv(folder / "latest.csv", index=False)
    parts.append(page.table_details(last, "benchmark-figures/latest.csv", "benchmarks-latest") + "</section>")
    return parts


def _manifests(out: Path) -> list[tuple[Path, dict[str, Any]]]:
    return [(p.parent, json.loads(p.read_text())) for p in sorted(out.glob("*/manifest.json"))]


def write_index(out: Path) -> Path:
    """One self-contained index.html (images embedded) and verdicts.json: the summary and findings first,
    then the verdicts by claim, every study, benchmarks, provenance."""
    manifests = _manifests(out)
    records = [r for _, man in manifests for r in study_verdicts(out, man["name"])]
    _atomic_write(out / "verdicts.json", json.dumps(records, indent=1))
    prov = provenance([man for _, man in manifests])
    studies = [{"name": m["name"], "title": m["title"], "solvers": m.get("solvers", []), "orders": m.get("orders", [])}
               for _, m in manifests]
    meta = f"generated {prov['generated']} · commit {prov['git commit']} · {len(manifests)} studies"
    body = [page.summary_section(summary_lines(studies, records), records, meta),
            page.findings_section(findings(records)), page.verdicts_section(records)]
    body += [page.study_section(folder, man, records, _read_csv) for folder, man in manifests]
    bench = _benchmarks(out)
    body += bench
    body.append(page.provenance_section(prov))
    index = out / "index.html"
    _atomic_write(index, page.page(page.navigation(manifests, bool(bench)), body))
    return index


def _atomic_write(path: Path, text: str) -> None:
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(text)
    tmp.replace(path)
