"""Reports: per-study CSV and Markdown tables, PNG/SVG plots, verdicts (CSV and JSON), and one self-contained
index.html that opens with the summary and the findings; the report never runs a solver.

Several studies may write into one output folder at once: every file is written atomically, index.html and
verdicts.json are rebuilt under a lock, and what the index reads back is checked (a manifest that cannot be
read is skipped with a warning, and only files inside the folder are embedded).
"""

from __future__ import annotations

import html
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from pcverify.harness.judge import verdict
from pcverify.harness.judge.side_by_side import panel_table
from pcverify.harness.judge.tables import cells_table
from pcverify.harness.report import figures, page
from pcverify.harness.report.findings import STATES, findings, summary_lines
from pcverify.harness.report.group_figures import group_report
from pcverify.harness.report.mutation import mutation_section
from pcverify.harness.report.provenance import code_origin, command, provenance
from pcverify.harness.report.reproduce import study_command, table_group, verdict_commands
from pcverify.harness.report.sensitivity import sensitivity_section
from pcverify.harness.report.vtu import write_vtu
from pcverify.harness.run.files import atomic_write, exclusive, read_json, remove_stray_files, safe_stem
from pcverify.harness.study.claims import Claim
from pcverify.scene import is_real
from pcverify.solvers.protocol import model_notes
from pcverify.solvers.registry import SolverUnavailable, get_solver


def _markdown(df: pd.DataFrame) -> str:
    if df.empty:
        return "(no rows)\n"
    cols = list(df.columns)
    fmt = lambda v: f"{v:.6g}" if isinstance(v, float) else ("" if v is None else str(v))  # noqa: E731
    lines = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    lines += ["| " + " | ".join(fmt(v) for v in row) + " |" for row in df.itertuples(index=False)]
    return "\n".join(lines) + "\n"


def _vtu_name(r: dict[str, Any]) -> str:
    """A cell's VTU file name: its group, solver, resolution and key, each a safe stem (a plugin's solver name
    may hold anything)."""
    tag = r.get("cache_key") or "cell"
    return f"{safe_stem(r['group'])}-{safe_stem(r['solver'])}-n{r['n']}-r{r['refine']}-{safe_stem(tag)}.vtu"


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


def _lattice_nodes(study: Any, claims: list[Claim], table: pd.DataFrame) -> list[float]:
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


def solver_notes(names: list[str]) -> dict[str, list[str]]:
    """The model notes of the named solvers that have any (solver -> sentences): what the report shows beside a
    study's numbers, so a reader sees where a solver departs from its source."""
    out = {}
    for name in names:
        try:
            notes = model_notes(get_solver(name))
        except (SolverUnavailable, TypeError) as exc:
            notes = (f"(model notes not available: {exc})",)
        if notes:
            out[name] = list(notes)
    return out


def write_study_report(study: Any, results: list[dict[str, Any]], out: Path, run_command: str | None = None,
                       extra: list[tuple[dict[str, Any], dict[str, pd.DataFrame]]] = ()) -> Path:
    """Write tables, plots, VTU files and verdicts of one study into out/<study>/ and its manifest (the command
    that ran it: this process's, unless `run_command`).  `extra`: sections made elsewhere (a calibration's: id,
    title, figures already drawn) with their tables, which the claims read like the groups' tables."""
    folder = out / study.name
    folder.mkdir(parents=True, exist_ok=True)
    manifest: dict[str, Any] = {"name": study.name, "title": study.title, "sections": [], "verdicts": None,
                                "study_file": str(study.path) if study.path else None,
                                "plugins": list(study.plugins),
                                "plugin_sources": {m: code_origin(m) for m in study.plugins},
                                "command": run_command or command(),
                                "rerun": study_command(study, []),
                                "solvers": sorted({c.solver for g in study.groups for c in g.cells}
                                                   | {c.solver for c in getattr(study, "calibrations", [])})}
    manifest["model_notes"] = solver_notes(manifest["solvers"])
    all_tables: dict[str, pd.DataFrame] = {}
    group_cells = []
    for g in study.groups:
        res = [r for r in results if r.get("group") == g.id]
        group_cells.append(cells_table(res))
        tables, figs = group_report(g, res, group_cells[-1], folder, all_tables)
        skipped = [{"solver": r["solver"], "n": r["n"], "refine": r["refine"], "status": r["status"],
                    "reason": r.get("reason", "")} for r in res if r.get("status") in ("skipped", "failed")]
        skipped += [{"solver": u.solver, "n": "", "refine": "", "status": "not planned",
                     "reason": f"{u.cells} cells: {u.reason}"} for u in getattr(g, "unplanned", [])]
        if skipped:
            tables[f"{g.id}-skipped"] = pd.DataFrame(skipped)
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
    for panel in getattr(study, "panels", []):  # after every group: a panel reads their tables
        _write_table(panel_table(panel, all_tables), folder / panel.id)
        manifest["sections"].append({"id": panel.id, "title": panel.title, "tables": [f"{panel.id}.csv"],
                                     "figures": [], "vtu": [], "open": True})
    cells = pd.concat(group_cells, ignore_index=True) if group_cells else pd.DataFrame()
    manifest["orders"] = _orders(study, all_tables)
    table = None
    if study.claims:
        unplanned = {g.id: {u.solver: u.reason for u in getattr(g, "unplanned", [])} for g in study.groups}
        table = verdict.verdicts(study.name, study.claims, all_tables, verdict_commands(study, results), unplanned)
        table["nodes"] = _lattice_nodes(study, study.claims, table)
    if study.selected:  # --group: the rest of the study's report stays as it was
        manifest, cells, table = _merged(folder, study, manifest, cells, table)
    _write_csv(cells, folder / "cells.csv")
    if table is not None:
        _write_table(table, folder / "verdicts")
        atomic_write(folder / "verdicts.json", json.dumps(verdict.records(table), indent=1))
        manifest["verdicts"] = "verdicts.csv"
    atomic_write(folder / "manifest.json", json.dumps(manifest, indent=1))  # last: it names the files above
    return folder


def _merged(folder: Path, study: Any, manifest: dict[str, Any], cells: pd.DataFrame, table: pd.DataFrame | None
            ) -> tuple[dict[str, Any], pd.DataFrame, pd.DataFrame | None]:
    """A report of some groups merged into the study's report already in `folder`: sections, orders, cells and
    verdicts of the groups and claims just rebuilt replace theirs; every other one is kept as it was."""
    old, why = read_json(folder / "manifest.json")
    if why or _manifest_problem(old, study.name):
        return manifest, cells, table
    new_ids = {sec["id"] for sec in manifest["sections"]}
    fresh = {sec["id"]: sec for sec in manifest["sections"]}
    sections = [fresh.pop(sec["id"], sec) for sec in old.get("sections", [])]
    manifest["sections"] = sections + list(fresh.values())
    manifest["orders"] = [o for o in old.get("orders", []) if o["group"] not in new_ids] + manifest["orders"]
    manifest["solvers"] = sorted(set(manifest["solvers"]) | set(old.get("solvers") or []))
    manifest["model_notes"] = solver_notes(manifest["solvers"])
    manifest["rerun"] = old.get("rerun") or manifest["rerun"]
    previous = _read_csv(folder / "cells.csv") if (folder / "cells.csv").exists() else pd.DataFrame()
    if "group" in previous and not previous.empty:
        cells = pd.concat([previous[~previous["group"].isin(new_ids)], cells], ignore_index=True)
    before = study_verdicts(folder.parent, study.name)
    rebuilt = set() if table is None else set(table["claim"])
    kept = [r for r in before if r["claim"] not in rebuilt]
    if kept:
        table = pd.concat([pd.DataFrame(kept), table], ignore_index=True) if table is not None else pd.DataFrame(kept)
        order = {c: k for k, c in enumerate(dict.fromkeys([r["claim"] for r in before] + list(table["claim"])))}
        table = table.sort_values("claim", key=lambda col: col.map(order), kind="stable").reset_index(drop=True)
    return manifest, cells, table


def study_verdicts(out: Path, study: str) -> list[dict[str, Any]]:
    """The verdict records a study's report wrote (from verdicts.csv for a report written before verdicts.json
    existed; empty when the study has no claims)."""
    path = out / study / "verdicts.json"
    if path.exists():
        doc, why = read_json(path)
        problem = why or _records_problem(doc, study)
        if problem:
            warn(f"{path} {problem}; its verdicts are left out")
            return []
        return doc
    table = _read_csv(path.with_suffix(".csv")) if path.with_suffix(".csv").exists() else pd.DataFrame()
    return verdict.records(table.astype(object).where(table.notna(), None)) if not table.empty else []


# columns a report written by an earlier version lacks
OPTIONAL_VERDICT_COLUMNS = ("basis", "tolerance_basis", "slack")


def _records_problem(doc: Any, study: str) -> str:
    """Why `doc` is not a list of the study's verdict records ("" if it is)."""
    if not isinstance(doc, list) or not all(isinstance(r, dict) for r in doc):
        return "is not a list of verdict records"
    for r in doc:
        missing = [c for c in verdict.VERDICT_COLUMNS if c not in r and c not in OPTIONAL_VERDICT_COLUMNS]
        if missing:
            return f"has a verdict record without {missing[0]}"
        if r["study"] != study or r["verdict"] not in STATES:
            return f"has a verdict record of study {r['study']!r} with verdict {r['verdict']!r}"
    return ""


def warn(message: str) -> None:
    """One line on stderr: something in the output folder was skipped."""
    print(f"pcverify: warning: {' '.join(message.split())[:500]}", file=sys.stderr)


def _write_csv(df: pd.DataFrame, path: Path) -> None:
    atomic_write(path, df.to_csv(index=False))


def _write_table(df: pd.DataFrame, stem: Path) -> None:
    _write_csv(df, stem.with_suffix(".csv"))
    atomic_write(stem.with_suffix(".md"), _markdown(df))


def _read_csv(path: Path) -> pd.DataFrame:
    """A table, empty if the file has no rows; a file that cannot be read as CSV is empty with a warning."""
    try:
        return pd.read_csv(path)
    except pd.errors.EmptyDataError:
        return pd.DataFrame()
    except (OSError, UnicodeDecodeError, pd.errors.ParserError) as exc:
        warn(f"{path} cannot be read as a table ({getattr(exc, 'strerror', None) or type(exc).__name__}); shown empty")
        return pd.DataFrame()


def benchmark_problem(doc: Any) -> str:
    """Why `doc` is not a pytest-benchmark save ("" if it is)."""
    if not isinstance(doc, dict):
        return "is not a JSON object"
    marks = doc.get("benchmarks")
    if not isinstance(marks, list):
        return "has no list of benchmarks"
    for b in marks:
        stats = b.get("stats") if isinstance(b, dict) else None
        if not (isinstance(stats, dict) and is_real(stats.get("mean")) and is_real(stats.get("min"))
                and isinstance(b.get("name"), str)):
            return "has a benchmark without a name and finite mean and min times"
    return ""


def benchmark_runs(storage: Path) -> pd.DataFrame:
    """One row per (saved pytest-benchmark run, benchmark): mean/min seconds and extra_info.  A file that
    cannot be read or is not a pytest-benchmark save is skipped with a warning."""
    rows = []
    for k, file in enumerate(sorted(storage.glob("*/*.json"))):
        doc, why = read_json(file)
        problem = why or benchmark_problem(doc)
        if problem:
            warn(f"{file} {problem}; skipped")
            continue
        commit = doc.get("commit_info")
        commit = str(commit.get("id") or "")[:10] if isinstance(commit, dict) else ""
        for b in doc["benchmarks"]:
            extra = b.get("extra_info") if isinstance(b.get("extra_info"), dict) else {}
            extra = {k2: v for k2, v in extra.items() if isinstance(v, (int, float, str)) and not isinstance(v, bool)}
            rows.append({**extra, "run": k, "saved": file.stem, "datetime": str(doc.get("datetime", "")),
                         "commit": commit, "benchmark": b["name"], "mean_s": b["stats"]["mean"],
                         "min_s": b["stats"]["min"]})
    return pd.DataFrame(rows)


def _benchmarks(out: Path) -> list[str]:
    """The benchmark section: history of saved runs and the kernels' cost per pair-step against N."""
    storage = out / "benchmarks"
    runs = benchmark_runs(storage)
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
    _write_csv(last, folder / "latest.csv")
    parts.append(page.table_details(last, "benchmark-figures/latest.csv", "benchmarks-latest") + "</section>")
    return parts


def manifests(out: Path, quiet: bool = False) -> list[tuple[Path, dict[str, Any]]]:
    """The study manifests under `out` with their folders.  A manifest that cannot be read or is not of the form
    write_study_report writes is skipped, a file it names that is not a file inside `out` is left out, each with
    a warning (none if `quiet`): the report embeds only files inside `out`."""
    root = out.resolve()
    found = []
    for path in sorted(out.glob("*/manifest.json")):
        doc, why = read_json(path)
        problem = why or _manifest_problem(doc, path.parent.name)
        if problem:
            if not quiet:
                warn(f"{path} {problem}; skipped")
            continue
        found.append((path.parent, _files_inside(doc, path, root, quiet)))
    return found


def _listed(value: Any, kind: type = str) -> bool:
    return isinstance(value, list) and all(isinstance(v, kind) for v in value)


def _manifest_problem(doc: Any, folder: str) -> str:
    """Why `doc` is not the manifest of study `folder` ("" if it is)."""
    if not isinstance(doc, dict):
        return "is not a JSON object"
    if doc.get("name") != folder:
        return f"names study {str(doc.get('name'))[:80]!r}, not its folder {folder!r}"
    wrong = [k for k, kind in (("title", str), ("sections", list), ("verdicts", (str, type(None))),
                               ("mutants", (str, type(None))), ("sensitivity", (str, type(None))),
                               ("rerun", (str, type(None))), ("study_file", (str, type(None))),
                               ("command", (str, type(None))))
             if k in doc and not isinstance(doc[k], kind)] + [k for k in ("title", "sections") if k not in doc]
    wrong += [k for k in ("solvers", "plugins") if k in doc and not _listed(doc[k])]
    if not _listed(doc.get("orders", []), dict) or any(
            not isinstance(o.get(k), str) for o in doc.get("orders", []) for k in ("group", "solver", "quantity")) \
            or any(not isinstance(o.get("order"), (int, float)) for o in doc.get("orders", [])):
        wrong.append("orders")
    for sec in doc.get("sections", []) if isinstance(doc.get("sections"), list) else []:
        if not isinstance(sec, dict) or not isinstance(sec.get("id"), str) or not isinstance(sec.get("title"), str) \
                or not all(_listed(sec.get(k, [])) for k in ("figures", "tables", "vtu")):
            wrong.append("sections")
            break
    return f"is not a study manifest (field {wrong[0]})" if wrong else ""


def _files_inside(doc: dict[str, Any], path: Path, root: Path, quiet: bool) -> dict[str, Any]:
    """The manifest without the files it names that are not files inside `root` (each left out with a warning)."""
    def inside(name: str) -> bool:
        target = path.parent / name
        try:
            ok = target.resolve().is_relative_to(root) and target.resolve().is_file()
        except (OSError, RuntimeError, ValueError):  # a symlink loop, a NUL in the name
            ok = False
        if not ok and not quiet:
            warn(f"{path} names {name[:200]!r}, which is not a file inside {root}; not embedded")
        return ok

    doc = {**doc, "sections": [{**sec, "figures": [f for f in sec.get("figures", []) if inside(f)],
                                "tables": [t for t in sec.get("tables", []) if inside(t)]} for sec in doc["sections"]]}
    for key in ("verdicts", "mutants", "sensitivity"):
        if doc.get(key) and not inside(doc[key]):
            doc[key] = None
    return doc


def _extras(folder: Path, man: dict[str, Any]) -> str:
    """The HTML of a study's mutants (`pcverify mutate`) and sensitivity (`pcverify sensitivity`), where its
    manifest names their files."""
    parts = []
    for key, section in (("mutants", mutation_section), ("sensitivity", sensitivity_section)):
        if man.get(key):
            doc, why = read_json(folder / man[key])
            if why:
                warn(f"{folder / man[key]} {why}; its {key} section is left out")
            parts.append(section(folder, man["name"], doc))
    return "".join(parts)


def write_index(out: Path) -> Path:
    """One self-contained index.html (images embedded) and verdicts.json: the summary and findings first,
    then the verdicts by claim, every study, benchmarks, provenance.  One process at a time (a lock file in
    `out`, released by the kernel if its holder dies); the temporary files of dead writers are removed."""
    with exclusive(out / ".index.lock"):
        for pattern in (".*.tmp", "*/.*.tmp", "*/vtu/.*.tmp"):
            remove_stray_files(out, pattern)
        return _write_index(out)


def _write_index(out: Path) -> Path:
    found = manifests(out)
    records = [r for _, man in found for r in study_verdicts(out, man["name"])]
    atomic_write(out / "verdicts.json", json.dumps(records, indent=1))
    prov = provenance([man for _, man in found])
    studies = [{"name": m["name"], "title": m["title"], "solvers": m.get("solvers", []), "orders": m.get("orders", [])}
               for _, m in found]
    meta = f"generated {prov['generated']} · commit {prov['git commit']} · {len(found)} studies"
    body = [page.summary_section(summary_lines(studies, records), records, meta),
            page.findings_section(findings(records)), page.verdicts_section(records)]
    body += [page.study_section(folder, man, records, _read_csv, _extras(folder, man)) for folder, man in found]
    bench = _benchmarks(out)
    body += bench
    body.append(page.provenance_section(prov))
    index = out / "index.html"
    atomic_write(index, page.page(page.navigation(found, bool(bench)), body))
    return index

