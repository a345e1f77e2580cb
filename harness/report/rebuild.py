"""`pcverify report`: every study's tables and page rebuilt from the cache, then the index.

Which study files are rebuilt: the shipped ones, and a file a report's manifest names only where that file
declares the study of the manifest's folder.  A cell missing from the cache is named and its claims fail; so
is a calibration that cannot be replayed from the cache: a rebuilt report never drops a claim in silence.
"""

from __future__ import annotations

import argparse
import itertools
import json
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from pcverify.harness.report.calibration_section import calibration_section
from pcverify.harness.report.write import manifests, warn, write_index, write_study_report
from pcverify.harness.run.cache import Cache
from pcverify.harness.run.calibration import NotCached, run_calibration
from pcverify.harness.run.execution import cached_results
from pcverify.harness.study.calibspec import Calibration
from pcverify.harness.study.shipped import study_files
from pcverify.harness.study.study import Study, declared_name, load_study
from pcverify.scene import SceneError
from pcverify.solvers.registry import SolverUnavailable

CALIBRATION_TABLES = ("summary", "parameters", "trace", "noise", "validation")  # a calibration's tables: ID-NAME


def calibration_not_rebuilt(study: Study, cal: Calibration, why: str) -> tuple[dict[str, Any], dict[str, pd.DataFrame]]:
    """The section of a calibration that `report` cannot replay from the cache (`why`: the cell it lacks): its
    title says so, and every table of it that a claim reads holds only rows that lost that cell, so each such
    claim fails naming it; a report never drops a calibration, or its claims, in silence."""
    lost = f"{why} (calibration {cal.id} not rebuilt: rerun the study)"
    names = {f"{cal.id}-{t}" for t in CALIBRATION_TABLES}
    rows: dict[str, list[dict[str, Any]]] = {f"{cal.id}-not-rebuilt": [{"solver": cal.solver, "missing": lost}]}
    for claim in study.claims:
        reads = [(claim.table, claim.select, claim.metric)]
        if claim.against or claim.against_table:
            reads.append((claim.against_table or claim.table, claim.against, claim.against_metric or claim.metric))
        for table, select, metric in reads:
            if table not in names:
                continue
            keys = list(select)
            for combo in itertools.product(*[v if isinstance(v, list) else [v] for v in select.values()]):
                rows.setdefault(table, []).append({**dict(zip(keys, combo, strict=True)), metric: np.nan,
                                                   **dict.fromkeys(claim.per, np.nan),
                                                   "solver": cal.solver, "missing": lost})
    title = (f"Calibration {cal.id} ({cal.solver}): {cal.title}. NOT REBUILT: {why}; its claims fail. Rerun the "
             "study to compute the missing cells")
    return {"id": cal.id, "title": title, "figures": []}, {name: pd.DataFrame(r) for name, r in rows.items()}


def report_sources(out: Path) -> dict[str, str | None]:
    """The study files `report` rebuilds, with the command that ran each: the shipped ones, and the file each
    manifest under `out` names, only where that file declares the study named by the manifest and its folder
    (a manifest must not make `report` load and run another study file into a study's folder, or replace a
    shipped study): any other is skipped with a warning."""
    shipped = {name: str(path) for name, path in study_files().items()}
    sources: dict[str, str | None] = dict.fromkeys(sorted(shipped.values()))
    for folder, manifest in manifests(out, quiet=True):  # the manifest's name is its folder's (checked there)
        source = manifest.get("study_file")
        if not source:
            continue
        where = f"{folder / 'manifest.json'} names study file {source}"
        try:
            declared = declared_name(Path(source)) if Path(source).is_file() else None
        except (SceneError, OSError, ValueError) as exc:
            warn(f"{where}, which does not load ({exc}); skipped")
            continue
        if declared is None:
            continue  # moved or deleted since: the report stays as it is
        if declared != folder.name:
            warn(f"{where}, which declares study {declared!r}, not {folder.name!r}; not loaded, skipped")
        elif folder.name in shipped:
            if Path(source).resolve() != Path(shipped[folder.name]).resolve():
                warn(f"{where} for the shipped study {folder.name!r}; the shipped file is used, not that one")
            else:
                sources[shipped[folder.name]] = manifest.get("command")
        else:
            sources[source] = manifest.get("command")
    return sources


def rebuild_reports(args: argparse.Namespace) -> int:
    """`pcverify report`: rebuild every study's tables from the cache, then index.html; a line per study
    rebuilt (or a JSON summary)."""
    out = Path(args.out)
    cache = Cache(out / "cache")
    shipped = {str(p) for p in study_files().values()}
    rebuilt = []
    for source, run_command in report_sources(out).items():
        try:
            study = load_study(source)
        except (SceneError, SolverUnavailable, OSError) as exc:
            if source in shipped:
                raise
            warn(f"study file {source} (named by a manifest in {out}) does not load: {exc}; skipped")
            continue
        results = cached_results(study, cache)
        reported = (out / study.name / "manifest.json").exists()
        if not reported and any(r["status"] == "missing" for r in results):
            # not reported here and not whole in the cache (at most a cell another study shares): nothing to rebuild.
            # A study reported before is rebuilt, its missing cells named; a whole one whose folder went, too.
            results = []
        extra, lost = [], []
        for cal in study.calibrations:  # the same search through the cached cells
            try:
                extra.append(calibration_section(run_calibration(study, cal, cache, compute=False), out / study.name))
            except NotCached as exc:
                if reported or results or extra:  # run here before: the report says it is not rebuilt
                    extra.append(calibration_not_rebuilt(study, cal, str(exc)))
                    lost.append(str(exc))
        if results or extra:
            write_study_report(study, results, out, run_command, extra=extra)
            missing = sum(r["status"] == "missing" for r in results)
            rebuilt.append({"study": study.name, "study_file": source, "cells_cached": len(results) - missing,
                            "cells_missing": missing} | ({"calibrations_not_rebuilt": lost} if lost else {}))
    index = write_index(out)
    if args.json:
        print(json.dumps({"index": str(index), "studies": rebuilt}))
    else:
        for r in rebuilt:
            lost = (f"; {r['cells_missing']} cells missing or corrupt in the cache: their claims fail, rerun the study"
                    if r["cells_missing"] else "")
            lost += "".join(f"; {why}: calibration not rebuilt, its claims fail, rerun the study"
                            for why in r.get("calibrations_not_rebuilt", []))
            print(f"{r['study']}: rebuilt from {r['cells_cached']} cached cells{lost}")
        print(f"report: {index}")
    return 0
