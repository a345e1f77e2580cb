"""`pcverify study`: studies run through the cache, their reports written, their verdicts gated.

Every study named is loaded and checked before any runs; each runs its cells and calibrations (cached cells
are read back), and once all have computed their reports are written at once, one process each.  An
interrupted run still writes the reports of the studies that finished.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

from pcverify.harness.report.batch import ReportJob, write_reports
from pcverify.harness.report.gates import verdict_gate
from pcverify.harness.report.reproduce import select_groups
from pcverify.harness.report.write import study_verdicts, write_index
from pcverify.harness.run.cache import Cache
from pcverify.harness.run.calibration import run_calibration
from pcverify.harness.run.execution import cell_time_limit, execute, plan
from pcverify.harness.run.interrupt import remember_sigint
from pcverify.harness.run.workers import output_to_stderr
from pcverify.harness.study.shipped import study_files
from pcverify.harness.study.study import Study, load_study


def run_studies(args: argparse.Namespace) -> int:
    """`pcverify study NAME`: run (or dry-run) one study, or all shipped ones for `default`; print a line per
    study (or a JSON summary); exit 1 under --strict unless every verdict passes."""
    with remember_sigint(), cell_time_limit(args.time_limit):
        names = sorted(study_files()) if args.name == "default" else [args.name]
        with output_to_stderr():  # a plugin's prints, on import or in any cell, never reach stdout
            studies = [load_study(n, args.allow_large) for n in names]  # validate all before running any
        if args.group:  # one study (the command line checks it), restricted to those groups and those they read
            studies = [select_groups(studies[0], args.group)]
        out = Path(args.out)
        cache = Cache(args.cache or out / "cache")
        rerun = None if args.rerun is None else frozenset(args.rerun)
        summary, computed = [], []  # computed: (study, counts, seconds, its report job) of each study run
        for study in studies:
            if args.dry_run:
                summary.append(dry_run(study, cache, rerun, args.json))
                continue
            try:
                counts, seconds, job = compute_study(study, args, cache, rerun)
            except KeyboardInterrupt:
                if computed:  # the studies that finished keep their reports
                    print(f"interrupted: writing the reports of the {len(computed)} studies that finished "
                          "(Ctrl-C again stops now)", file=sys.stderr)
                    with output_to_stderr():
                        write_reports([job for *_, job in computed], out)
                raise
            computed.append((study, counts, seconds, job))
        with output_to_stderr():  # every study computed: the reports at once, one core each
            report_s = write_reports([job for *_, job in computed], out, processes=args.jobs)
        for (study, counts, seconds, _), written_s in zip(computed, report_s, strict=True):
            counts = study_summary(study, counts, seconds + written_s, out)
            summary.append(counts)
            if not args.json:
                calib = (f", calibrations: {counts['calibration_runs']} solver runs, {counts['calibration_cached']} "
                         "cached" if study.calibrations else "")
                not_ok = sum(v for k, v in counts["statuses"].items() if k not in ("ok", "skipped", "failed"))
                print(f"{study.name}: {counts['cells']} cells, {counts['cached']} cached, {counts['done']} run, "
                      f"{counts['failed']} failed, {not_ok} other non-ok, {counts['corrupt']} corrupt entries "
                      f"recomputed{calib} "
                      f"-> {out / study.name}/")
        if not args.dry_run:
            index = write_index(out)
            if not args.json:
                print(f"report: {index}")
        if args.json:
            print(json.dumps(summary))
        return verdict_gate([r for entry in summary for r in entry.get("verdicts", [])], args.strict)


def dry_run(study: Study, cache: Cache, rerun: frozenset[str] | None, as_json: bool) -> dict[str, Any]:
    """`study --dry-run`: what is cached and what would run, printed (unless `as_json`) and returned as the
    study's entry of the JSON summary."""
    with output_to_stderr():
        rows = plan(study, cache, rerun)
    unplanned = [{"group": g.id, "solver": u.solver, "cells": u.cells, "reason": u.reason}
                 for g in study.groups for u in g.unplanned]
    for r in [] if as_json else rows:
        print(f"{r['state']:<8} {r['key']}  {r['cell']}" + (f"  ({r['reason']})" if r["reason"] else ""))
    for u in [] if as_json else unplanned:
        print(f"not planned: group {u['group']}, {u['solver']} ({u['cells']} cells): {u['reason']}")
    for cal in [] if as_json else study.calibrations:  # adaptive: its cells follow from the values
        print(f"calibration {cal.id}: {cal.solver}, search of at most {cal.budget} solver runs, then "
              f"replicas, sensitivity and {len(cal.calibrate) + len(cal.validate)} cells x 2 (cells "
              "depend on the values found; cached ones are read back)")
    return {"study": study.name, "cells": rows, "not_planned": unplanned}


def compute_study(study: Study, args: argparse.Namespace, cache: Cache, rerun: frozenset[str] | None = None
                  ) -> tuple[dict[str, Any], float, ReportJob]:
    """Run one study's cells and calibrations through the cache: its counts, the seconds it took and the job
    that writes its report."""
    t0 = time.perf_counter()
    shown_bar = not args.json and any(g.cells for g in study.groups)  # a calibration-only study: no bar
    with output_to_stderr():
        results, counts = execute(study, cache, jobs=args.jobs, progress=shown_bar,
                                  scheduler=getattr(args, "scheduler", None), rerun=rerun, allow_large=args.allow_large)
        outcomes = [run_calibration(study, cal, cache, jobs=args.jobs, rerun=rerun, allow_large=args.allow_large,
                                    progress=not args.json) for cal in study.calibrations]
    for outcome in outcomes:
        counts["calibration_runs"] = counts.get("calibration_runs", 0) + outcome.runs
        counts["calibration_cached"] = counts.get("calibration_cached", 0) + outcome.hits
    return counts, time.perf_counter() - t0, ReportJob(study, results, outcomes)


def study_summary(study: Study, counts: dict[str, Any], seconds: float, out: Path) -> dict[str, Any]:
    """The summary `study --json` prints for a study whose report is written: counts, wall time, verdicts."""
    return {"study": study.name, **counts, "wall_s": round(seconds, 3), "verdicts": study_verdicts(out, study.name)}


def run_study(study: Study, args: argparse.Namespace, cache: Cache, out: Path, rerun: frozenset[str] | None = None
              ) -> dict[str, Any]:
    """Run one study's cells and calibrations through the cache and write its report: its `study_summary`."""
    counts, seconds, job = compute_study(study, args, cache, rerun)
    with output_to_stderr():
        (written_s,) = write_reports([job], out)
    return study_summary(study, counts, seconds + written_s, out)
