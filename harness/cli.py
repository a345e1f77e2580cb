"""Command line `pcverify`: scenes, solvers, run, study, verdict, mutate, report, bench.

Every bad input ends in one line `pcverify: error: ...` naming the parameter and the
allowed range, with exit code 2; never a traceback (unless --debug).
"""

from __future__ import annotations

import sys
from pathlib import Path

from pcverify.harness.run.interrupt import exit_on_sigterm_at_start_up

# the imports below take seconds: as the command (not imported by a test), a SIGTERM meanwhile is the one
# "terminated" line and exit 143, never a silent death
if __name__ == "__main__" or Path(sys.argv[0] if sys.argv else "").name == "pcverify":
    exit_on_sigterm_at_start_up()

import argparse
import contextlib
import dataclasses
import itertools
import json
import os
import re
import signal
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
import pandas as pd
from tqdm import tqdm

from pcverify import __version__
from pcverify.harness.report.batch import ReportJob, write_reports
from pcverify.harness.report.calibration_section import calibration_section
from pcverify.harness.report.mutation import mutation_document, write_mutation_report
from pcverify.harness.report.reproduce import claim_groups, select_groups
from pcverify.harness.report.write import (
    benchmark_problem,
    manifests,
    study_verdicts,
    warn,
    write_index,
    write_study_report,
)
from pcverify.harness.run.cache import Cache
from pcverify.harness.run.calibration import NotCached, run_calibration
from pcverify.harness.run.execution import cached_results, cell_time_limit, execute, identify, plan, run_cell
from pcverify.harness.run.files import read_json
from pcverify.harness.run.interrupt import TERMINATED, check_interrupted, received, remember_sigint, sigterm_interrupts
from pcverify.harness.run.limits import DEFAULT_MUTANT_TIME_LIMIT, DEFAULT_TIME_LIMIT, MAX_TIME_LIMIT, check_work
from pcverify.harness.run.mutation import Runner, prepare
from pcverify.harness.run.workers import describe_exception, output_to_stderr
from pcverify.harness.spec.catalogue import entries as scene_entries
from pcverify.harness.spec.catalogue import get_spec, make_scene
from pcverify.harness.spec.mutants import catalogue, select_mutants, solver_packages
from pcverify.harness.spec.schema import MAX_CELLS
from pcverify.harness.spec.shipped import study_files
from pcverify.harness.spec.study import Cell, declared_name, load_study
from pcverify.scene import Param, Resolution, SceneError, shown
from pcverify.solvers.protocol import model_notes, skipped
from pcverify.solvers.registry import SolverUnavailable, get_solver
from pcverify.solvers.registry import entries as solver_entries

EPILOG = """\
examples:
  pcverify scenes                                   list the scenes and their parameters
  pcverify solvers                                  list the solvers and their parameters
  pcverify run bar-heat-faces --solver skfem --n 4 --json
  pcverify run bar-heat-patch --solver fipy --n 3 --refine 4 --set rho=0.002
  pcverify run bar-heat-faces --solver skfem --set mode=transient --set scheme=crank-nicolson
  pcverify study default                            run the default studies, write reports/
  pcverify study default --dry-run                  show what is cached and what would run
  pcverify study stability --group limit-mca-heat   run one group of a study (from the cache where it can)
  pcverify study my.toml --strict                   exit 1 unless every verdict passes (a CI gate)
  pcverify verdict heat-particles mca-steady-line   judge one claim, print its value (from the cache)
  pcverify mutate my.toml --strict                  run the claims on the study's mutants: exit 1 unless all
                                                    are killed
  pcverify report                                   rebuild reports/index.html from the cache
  pcverify bench                                    benchmarks, saved and compared with the previous run

--set KEY=VALUE goes to the scene if the scene has KEY, else to the solver;
write scene.KEY or solver.KEY when both have it.
"""


class CliError(Exception):
    """A user error: printed as one line, exit code 2."""


class OneLineParser(argparse.ArgumentParser):
    """argparse with usage errors as one line `pcverify: error: ...` (exit 2), like every other error."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, error_line(message) + "\n")


WORD_LIMIT = 240  # characters of one word of an error line: a path fits, a hostile 100 kB name does not


def error_line(message: str) -> str:
    """`pcverify: error: ...` on one line, every word longer than WORD_LIMIT shortened to its start and length."""
    words = [w if len(w) <= WORD_LIMIT else f"{w[:WORD_LIMIT - 20]}...({len(w)} characters){w[-1] * (w[-1] in ';,:')}"
             for w in message.split()]
    return "pcverify: error: " + " ".join(words)


def report_error(message: str) -> None:
    """Print an error line on stderr on a line of its own: open progress bars are closed first."""
    for bar in list(getattr(tqdm, "_instances", ())):
        bar.close()
    print(error_line(message), file=sys.stderr)


def int_in(name: str, low: int, high: int):
    """argparse type: an integer in [low, high], else a one-line error naming it and the range."""

    def convert(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or not low <= value <= high:
            shown = text if len(text) <= 40 else text[:37] + "..."
            shown = shown if shown.strip() and shown.isprintable() else repr(shown)
            raise argparse.ArgumentTypeError(f"{name}={shown} is not valid; allowed: integer in [{low}, {high}]")
        return value

    return convert


def seconds_in(name: str, low: float, high: float):
    """argparse type: a number of seconds in (low, high], else a one-line error naming it and the range."""

    def convert(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = None
        if value is None or not low < value <= high:
            raise argparse.ArgumentTypeError(f"{name}={shown(text)} is not valid; allowed: seconds in "
                                             f"({low:g}, {high:g}]")
        return value

    return convert


def _param_rows(params: tuple[Param, ...]) -> list[dict[str, Any]]:
    return [
        {"name": p.name, "default": p.default, "allowed": p.allowed(), "unit": p.unit, "description": p.description}
        for p in params
    ]


def cmd_scenes(args: argparse.Namespace) -> int:
    rows = []
    for name, entry in scene_entries().items():
        try:
            spec = get_spec(name)
            rows.append({"name": name, "available": True, "origin": entry.origin, "description": spec.description,
                         "parameters": _param_rows(spec.parameters)})
        except SceneError as exc:
            rows.append({"name": name, "available": False, "origin": entry.origin, "reason": str(exc),
                         "parameters": []})
    return _print_entries(rows, args.json, lambda row, origin: f"{row['name']}{origin}\n  {row['description']}",
                          (12, 10))


def cmd_solvers(args: argparse.Namespace) -> int:
    rows = []
    for name, entry in sorted(solver_entries().items()):
        try:
            solver = get_solver(name)
            doc = (type(solver).__doc__ or "").strip()
            rows.append({"name": name, "available": True, "kind": solver.kind, "origin": entry.origin,
                         "description": doc.splitlines()[0] if doc else "",
                         "stability_probe": hasattr(solver, "stability_probe"),
                         "parameters": _param_rows(solver.parameters), "notes": list(model_notes(solver))})
        except (SolverUnavailable, SceneError, TypeError) as exc:
            rows.append({"name": name, "available": False, "origin": entry.origin, "reason": str(exc),
                         "parameters": []})
    return _print_entries(rows, args.json,
                          lambda row, origin: f"{row['name']}  ({row['kind']}) {row['description']}{origin}".rstrip(),
                          (16, 14))


def _print_entries(rows: list[dict[str, Any]], as_json: bool, headline: Callable[[dict[str, Any], str], str],
                   widths: tuple[int, int]) -> int:
    """The `scenes` and `solvers` listings: JSON, or per entry its headline (given the entry and its origin
    note) and a line per parameter (name and default in columns of `widths`); an unavailable entry says why."""
    if as_json:
        print(json.dumps(rows, indent=1))
        return 0
    for row in rows:
        if not row["available"]:
            print(f"{row['name']}  (unavailable: {row['reason']})")
            continue
        print(headline(row, "" if row["origin"] == "pcverify" else f"  [{row['origin']}]"))
        for p in row["parameters"]:
            print(f"    {p['name']:<{widths[0]}} default {p['default']!s:<{widths[1]}} {p['allowed']:<40} "
                  f"{p['description']}")
        if row.get("notes"):
            print("  model notes (departures from the source and choices it leaves open):")
            for k, note in enumerate(row["notes"], 1):
                print(f"    {k}. {note}")
    return 0


def split_settings(settings: list[str], scene_params: tuple[Param, ...], solver_params: tuple[Param, ...]
                   ) -> tuple[dict[str, Any], dict[str, Any]]:
    """Route --set KEY=VALUE to the scene or the solver, parsing each value with its Param spec."""
    scene_spec = {p.name: p for p in scene_params}
    solver_spec = {p.name: p for p in solver_params}
    scene_vals: dict[str, Any] = {}
    solver_vals: dict[str, Any] = {}
    for item in settings:
        if "=" not in item:
            raise CliError(f"--set {shown(item)}: expected KEY=VALUE")
        key, text = item.split("=", 1)
        key = key.strip()
        target = None
        if key.startswith("scene."):
            key, target = key[6:], "scene"
        elif key.startswith("solver."):
            key, target = key[7:], "solver"
        elif key in scene_spec and key in solver_spec:
            raise CliError(f"--set {shown(key)}: both the scene and the solver have it; "
                           f"write scene.{key} or solver.{key}")
        elif key in scene_spec:
            target = "scene"
        elif key in solver_spec:
            target = "solver"
        else:
            known = sorted(set(scene_spec) | set(solver_spec))
            raise CliError(f"--set {shown(key)}: unknown parameter; known: {', '.join(known)}")
        spec = scene_spec if target == "scene" else solver_spec
        if key not in spec:
            raise CliError(f"--set {target}.{shown(key)}: unknown {target} parameter; known: {', '.join(sorted(spec))}")
        (scene_vals if target == "scene" else solver_vals)[key] = spec[key].parse(text)
    return scene_vals, solver_vals


def _isatty(stream: Any) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError, OSError):  # a closed or replaced stream
        return False


@contextlib.contextmanager
def working(label: str, enabled: bool = True) -> Iterator[None]:
    """An elapsed-time indicator on stderr for a solve that runs in one call (shown after 2 s), on a terminal
    only: where stderr is a pipe or a log, the indicator could not be erased and would stand in front of the
    one-line error or the result that follows."""
    bar = tqdm(total=None, desc=label, bar_format="{desc}: {elapsed} elapsed", delay=2.0,
               disable=not (enabled and _isatty(sys.stderr)), leave=False)
    done = threading.Event()

    def tick() -> None:
        waited = 0.0
        while not done.wait(0.5):
            waited += 0.5
            if waited >= 2.0:
                bar.refresh()

    thread = threading.Thread(target=tick, daemon=True)
    thread.start()
    try:
        yield
    finally:
        done.set()
        thread.join()
        bar.close()


def cmd_run(args: argparse.Namespace) -> int:
    """`pcverify run`: one cell through the study's cell path (`execution.run_cell`: a worker process with the
    time limit, BLAS on one thread, the boundary checks, the compare step), so it prints the numbers a study
    stores for that cell, errors against the reference included.  Exit 1 when the cell failed.  What the
    solver prints goes to stderr; the result's `solver` is the name given to --solver."""
    with output_to_stderr():
        spec = get_spec(args.scene)
        resolution = Resolution(args.n, args.refine)
        solver = get_solver(args.solver)
        try:
            scene_vals, solver_vals = split_settings(args.set or [], spec.parameters, solver.parameters)
        except (SceneError, CliError, KeyboardInterrupt):
            raise
        except BaseException as exc:  # noqa: BLE001 - a plugin's own Param: one line, never a traceback
            raise CliError(f"--set: the parameters of solver {args.solver!r} raised {describe_exception(exc)}"
                           ) from None
        scene = make_scene(args.scene, **scene_vals)
        cell = Cell("run", scene, tuple(sorted(scene_vals.items())), args.solver, resolution.n, resolution.refine,
                    tuple(sorted(solver_vals.items())))
        skip = identify(cell).skip  # the parameters check: a bad value is one error line
        if skip is None:
            check_work(solver, scene, resolution, solver_vals, args.allow_large, label=args.solver)
        with working(f"{args.solver} on {scene.name} n={resolution.n} refine={resolution.refine}", not args.json):
            result = run_cell(cell, raise_scene_errors=True, time_limit=args.time_limit)
    # every key of a solution, also for a skipped or failed cell (a public interface: keys are never dropped)
    out = skipped(scene, solver, resolution, "").to_dict() | result
    out["scene_params"] = scene.param_dict
    out["scene_hash"] = scene.content_hash()
    out.setdefault("errors", {})
    code = 1 if out["status"] == "failed" else 0
    if args.json:
        print(json.dumps(out))
        return code
    print(f"scene    {scene.name}  {scene.param_dict}")
    print(f"solver   {args.solver}  {out['params']}")
    print(f"grid     n={resolution.n} refine={resolution.refine} unknowns={out['unknowns']}  "
          f"wall {out['wall_s']:.3f} s")
    print(f"status   {out['status']}{'  (' + out['reason'] + ')' if out['reason'] else ''}")
    for key, value in out["summary"].items():
        print(f"  {key:<24} {value}")
    for name, s in out["samples"].items():
        v = np.asarray(s["values"], dtype=float)
        span = f"in [{np.nanmin(v):.6g}, {np.nanmax(v):.6g}]" if np.isfinite(v).any() else "not finite"
        print(f"  {name:<24} {v.size} points, {out['quantity']} {span}")
    for name, e in out["errors"].items():
        shown_errors = "  ".join(f"{k} {'n/a' if e.get(k) is None else repr(e[k])}" for k in ("l2", "linf"))
        print(f"  error {name:<18} {shown_errors}  (absolute, against the {e['reference']} reference)")
    for name, e in (out.get("scalar_errors") or {}).items():
        err = "n/a" if e.get("error") is None else f"{e['error']:.4g}"
        print(f"  error {name:<18} {e['value']} against {e['expected']}: relative {err}  ({e['reference']})")
    return code


def cmd_study(args: argparse.Namespace) -> int:
    """`pcverify study NAME`: run (or dry-run) one study, or all shipped ones for `default`."""
    with remember_sigint(), cell_time_limit(args.time_limit):
        names = sorted(study_files()) if args.name == "default" else [args.name]
        with output_to_stderr():  # a plugin's prints, on import or in any cell, never reach stdout
            studies = [load_study(n, args.allow_large) for n in names]  # validate all before running any
        studies = selected_groups(studies, args.name, args.group)
        out = Path(args.out)
        cache = Cache(args.cache or out / "cache")
        rerun = None if args.rerun is None else frozenset(args.rerun)
        summary, computed = [], []  # computed: (study, counts, seconds, its report job) of each study run
        for study in studies:
            if args.dry_run:
                with output_to_stderr():
                    rows = plan(study, cache, rerun)
                unplanned = [{"group": g.id, "solver": u.solver, "cells": u.cells, "reason": u.reason}
                             for g in study.groups for u in g.unplanned]
                summary.append({"study": study.name, "cells": rows, "not_planned": unplanned})
                for r in [] if args.json else rows:
                    print(f"{r['state']:<8} {r['key']}  {r['cell']}" + (f"  ({r['reason']})" if r["reason"] else ""))
                for u in [] if args.json else unplanned:
                    print(f"not planned: group {u['group']}, {u['solver']} ({u['cells']} cells): {u['reason']}")
                for cal in [] if args.json else study.calibrations:  # adaptive: its cells follow from the values
                    print(f"calibration {cal.id}: {cal.solver}, search of at most {cal.budget} solver runs, then "
                          f"replicas, sensitivity and {len(cal.calibrate) + len(cal.validate)} cells x 2 (cells "
                          "depend on the values found; cached ones are read back)")
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


def compute_study(study: Any, args: argparse.Namespace, cache: Cache, rerun: frozenset[str] | None = None
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


def study_summary(study: Any, counts: dict[str, Any], seconds: float, out: Path) -> dict[str, Any]:
    """The summary `study --json` prints for a study whose report is written: counts, wall time, verdicts."""
    return {"study": study.name, **counts, "wall_s": round(seconds, 3), "verdicts": study_verdicts(out, study.name)}


def run_study(study: Any, args: argparse.Namespace, cache: Cache, out: Path, rerun: frozenset[str] | None = None
              ) -> dict[str, Any]:
    """Run one study's cells and calibrations through the cache and write its report: its `study_summary`."""
    counts, seconds, job = compute_study(study, args, cache, rerun)
    with output_to_stderr():
        (written_s,) = write_reports([job], out)
    return study_summary(study, counts, seconds + written_s, out)


def selected_groups(studies: list[Any], name: str, groups: list[str] | None) -> list[Any]:
    """`study --group ID ...`: the one study restricted to those groups (and the groups they read)."""
    if not groups:
        return studies
    if name == "default":
        raise CliError("--group needs one study; allowed: a study name or a .toml file, not default")
    return [select_groups(studies[0], groups)]


TIME_LIMIT_HELP = (f"kill a computed cell after SECONDS, failing it with that reason (default {DEFAULT_TIME_LIMIT:g}: "
                   "six times the ten minutes the work limits allow a cell)")
GATE_STATES = ("fail", "inconclusive", "not-applicable")  # what --strict refuses: anything not verified


def verdict_gate(records: list[dict[str, Any]], strict: bool) -> int:
    """Exit code of `study`: with --strict, 1 when any verdict is not a pass (fail, inconclusive or not
    applicable), each listed on stderr with why and the command that reproduces it."""
    bad = [r for r in records if r.get("verdict") in GATE_STATES]
    if not strict or not bad:
        return 0
    for r in bad:
        case = f" {r['case']}" if r.get("case") else ""
        value = "no value" if r.get("value") is None else f"{r['metric']} = {r['value']!r}"
        unc = f" ± {r['uncertainty']!r}" if r.get("uncertainty") is not None else ""
        target = "" if r.get("target") is None else f", target {r['target']!r}"
        why = f"; why: {r['note']}" if r.get("note") else ""
        print(f"pcverify: claim {r['verdict']}: {r['study']}/{r['claim']}{case}: {value}{unc}{target} ({r['sense']}, "
              f"tolerance {r['tolerance']!r}, {r['reference']}){why}; reproduce: {r['command']}", file=sys.stderr)
    counts = ", ".join(f"{sum(r['verdict'] == s for r in bad)} {s}" for s in GATE_STATES)
    print(f"pcverify: {len(bad)} of {len(records)} verdicts are not a pass ({counts}) (--strict)", file=sys.stderr)
    return 1


def cmd_verdict(args: argparse.Namespace) -> int:
    """`pcverify verdict STUDY CLAIM [--case CASE]`: run the groups (or calibration) the claim reads, through
    the cache like a study, judge the claim and print each verdict's value, target, error, uncertainty and
    tolerance.  Exit 1 unless every verdict printed is a pass."""
    with remember_sigint(), cell_time_limit(args.time_limit):
        with output_to_stderr():
            study = load_study(args.study, args.allow_large)
        claims = {c.id: c for c in study.claims}
        if args.claim not in claims:
            raise CliError(f"claim={shown(args.claim)} is unknown in study {study.name}; allowed: one of "
                           f"{', '.join(claims) or '(the study has no claims)'}")
        claim = claims[args.claim]
        part = dataclasses.replace(select_groups(study, claim_groups(study, claim)), claims=[claim], selected=())
        cache = Cache(args.cache or Path(args.out) / "cache")
        with tempfile.TemporaryDirectory(prefix="pcverify-verdict-") as tmp:
            shown_bar = not args.json and any(g.cells for g in part.groups)
            with output_to_stderr():
                results, _ = execute(part, cache, jobs=args.jobs, progress=shown_bar, allow_large=args.allow_large)
                extra = [calibration_section(run_calibration(part, cal, cache, jobs=args.jobs,
                                                             allow_large=args.allow_large, progress=not args.json),
                                             Path(tmp) / study.name)
                         for cal in part.calibrations]
            write_study_report(part, results, Path(tmp), extra=extra)
            records = study_verdicts(Path(tmp), study.name)
    cases = [r["case"] for r in records]
    if args.case is not None:
        records = [r for r in records if r["case"] == args.case]
        if not records:
            raise CliError(f"--case {shown(args.case)} is not a case of claim {claim.id}; allowed: one of "
                           f"{', '.join(repr(c) for c in cases)}")
    if args.json:
        print(json.dumps(records))
    else:
        for r in records:
            print(f"{r['study']}/{r['claim']}" + (f" {r['case']}" if r["case"] else "") + f": {r['verdict']}")
            for key in ("metric", "value", "uncertainty", "target", "error", "tolerance", "sense", "reference",
                        "basis", "note", "solver"):
                if r.get(key) not in (None, ""):
                    print(f"  {key:<12} {r[key]!r}" if isinstance(r[key], float) else f"  {key:<12} {r[key]}")
    return 0 if all(r["verdict"] == "pass" for r in records) else 1


def cmd_mutate(args: argparse.Namespace) -> int:
    """`pcverify mutate STUDY`: the study run as `study` runs it (the baseline), then once per mutant in a process
    of its own on the mutated code (`run.mutation`); writes mutants.json, the kill matrix and the section of the
    study's page.  Every mutant's edit is checked before anything runs.  --strict: exit 1 unless every mutant run
    is killed."""
    with remember_sigint(), cell_time_limit(args.time_limit):
        names = sorted(study_files()) if args.name == "default" else [args.name]
        with output_to_stderr():
            studies = [load_study(n, args.allow_large) for n in names]
            found = [catalogue(s.mutants, s.path, solver_packages(s)) for s in studies]
        if args.mutant and args.name == "default":
            raise CliError("--mutant needs one study; allowed: a study name or a .toml file, not default")
        out = Path(args.out)
        cache = Cache(args.cache or out / "cache")
        chosen = [select_mutants(ms, args.mutant, s.name) for s, ms in zip(studies, found, strict=True)]
        prepared = [[prepare(m, cache.root, s.name) for m in ms] for s, ms in zip(studies, chosen, strict=True)]
        docs = []
        for study, todo in zip(studies, prepared, strict=True):
            if not todo:
                print(f"{study.name}: no catalogued mutants; skipped", file=sys.stderr)
                continue
            t0 = time.perf_counter()
            baseline = run_study(study, args, cache, out)
            runner = Runner(study, baseline["verdicts"], cache, args.time_limit, args.mutant_time_limit,
                            args.allow_large)
            with output_to_stderr():
                outcomes = runner.run(todo, args.jobs, progress=not args.json and _isatty(sys.stderr))
            doc = mutation_document(study.name, baseline["verdicts"], outcomes, time.perf_counter() - t0)
            doc["baseline"] = {k: baseline.get(k) for k in ("cells", "cached", "done", "failed", "wall_s")}
            where = write_mutation_report(out, study.name, doc)
            docs.append(doc)
            if not args.json:
                _print_mutants(doc, where)
        if docs:
            write_index(out)
        if args.json:
            print(json.dumps(docs))
        return mutant_gate(docs, args.strict)


def _print_mutants(doc: dict[str, Any], where: Path) -> None:
    """One line per mutant, then the counts and the descriptive claims."""
    width = max(len(o["name"]) for o in doc["mutants"])
    for o in doc["mutants"]:
        about = f"caught by {', '.join(o['caught_by'])}" if o["caught_by"] else o["reason"]
        print(f"  {o['status']:<9} {o['name']:<{width}} {o['wall_s']:7.1f} s  {o['recomputed']:>4} cells run  {about}")
    counts = ", ".join(f"{n} {s}" for s, n in doc["counts"].items())
    descriptive = [c for c, v in doc["claims"].items() if v["descriptive"]]
    print(f"{doc['study']}: {len(doc['mutants'])} mutants: {counts}; descriptive claims (kill no mutant): "
          f"{', '.join(descriptive) or 'none'} -> {where}")


def mutant_gate(docs: list[dict[str, Any]], strict: bool) -> int:
    """Exit code of `mutate`: with --strict, 1 when a mutant run is not killed (survived, invalid or crashed),
    each listed on stderr with why."""
    bad = [(d["study"], o) for d in docs for o in d["mutants"] if o["status"] != "killed"]
    if not strict or not bad:
        return 0
    for study, o in bad:
        print(f"pcverify: mutant {o['status']}: {study}/{o['name']} ({o['package']}/{o['file']}: {o['breaks']}): "
              f"{o['reason']}", file=sys.stderr)
    total = sum(len(d["mutants"]) for d in docs)
    counts = ", ".join(f"{sum(o['status'] == s for _, o in bad)} {s}" for s in ("survived", "invalid", "crashed"))
    print(f"pcverify: {len(bad)} of {total} mutants are not killed ({counts}) (--strict)", file=sys.stderr)
    return 1


CALIBRATION_TABLES = ("summary", "parameters", "trace", "noise", "validation")  # a calibration's tables: ID-NAME


def calibration_not_rebuilt(study: Any, cal: Any, why: str) -> tuple[dict[str, Any], dict[str, pd.DataFrame]]:
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
                                                   **({claim.per: np.nan} if claim.per else {}),
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


def cmd_report(args: argparse.Namespace) -> int:
    """`pcverify report`: rebuild every study's tables from the cache, then index.html.  A cell missing from the
    cache is named and its claims fail; so is a calibration that cannot be replayed from the cache."""
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


def bench_baseline(storage: Path) -> Path | None:
    """The newest saved benchmark run under `storage` (by run number) that is a pytest-benchmark save: the run
    `bench` compares with.  A file that is not (unreadable, invalid or too deeply nested JSON, another form) is
    skipped with a warning."""
    for file in sorted(storage.glob("*/*.json"), key=lambda f: (f.name, f.parent), reverse=True):
        doc, why = read_json(file)
        problem = why or benchmark_problem(doc)
        if problem:
            warn(f"{file} {problem}; not compared with")
            continue
        return file
    return None


REGRESSION = re.compile(r"Field '(\w+)' has failed (\w+): ([-+0-9.eE]+) > ([-+0-9.eE]+)")


def regression_line(regressions: list[tuple[str, str]], baseline: Path) -> str:
    """pytest-benchmark's regressions (benchmark, failed check) as one line: each benchmark, its field and by
    how much it regressed against the allowed limit, and the saved run compared with."""
    parts = []
    for name, check in regressions or [("(unnamed)", "performance has regressed")]:
        found = REGRESSION.search(check)
        if found and found[2].startswith("Percentage"):
            parts.append(f"{name.split(' (')[0]} {found[1]} +{float(found[3]):.1f} % (allowed: at most "
                         f"+{float(found[4]):g} %)")
        else:
            parts.append(f"{name.split(' (')[0]} {' '.join(check.split())}")
    return f"pcverify: benchmark regression against {baseline.name}: {'; '.join(parts)}"


class BenchmarkRegressions:
    """A pytest plugin that keeps pytest-benchmark's session, to read its regressions for the one-line message."""

    config: Any = None

    def pytest_configure(self, config: Any) -> None:
        self.config = config

    def found(self) -> list[tuple[str, str]]:
        session = getattr(self.config, "_benchmarksession", None)
        return [(str(name), str(check)) for name, check in getattr(session, "performance_regressions", None) or []]


def cmd_bench(args: argparse.Namespace) -> int:
    """Run tests/bench with pytest-benchmark, save under --storage, compare with the previous saved run.  A
    regression is one line naming each benchmark and by how much it regressed, exit 1."""
    import pytest  # optional dependency (the test extra): only `pcverify bench` needs it
    from pytest_benchmark.session import PerformanceRegression  # the same optional dependency

    storage = Path(args.storage).resolve()
    baseline = bench_baseline(storage)
    argv = [args.tests, "--benchmark-enable", "--benchmark-only", f"--benchmark-storage=file://{storage}",
            "--benchmark-autosave", "-p", "no:cacheprovider"]
    if baseline is not None:
        argv += [f"--benchmark-compare={baseline}", f"--benchmark-compare-fail=mean:{args.fail_percent:g}%"]
        print(f"comparing with {baseline.name}; failing on a mean regression beyond {args.fail_percent:g}%")
    else:
        print(f"no previous benchmark run under {storage}: this run becomes the baseline")
    plugin = BenchmarkRegressions()
    try:
        code = int(pytest.main(argv, plugins=[plugin]))
    except PerformanceRegression:
        sys.stdout.flush()
        print(regression_line(plugin.found(), baseline), file=sys.stderr)
        return 1
    check_interrupted()  # pytest turns a SIGTERM into its own exit code: stop like every other command
    return code


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(
        prog="pcverify",
        description="Verify particle methods (macromolecule, MCA) against continuum solvers (FiPy, scikit-fem) "
        "and analytic solutions: run one scene, run studies, write reports.",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"pcverify {__version__}")
    parser.add_argument("--debug", action="store_true", help="show tracebacks instead of one-line errors")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    p = sub.add_parser("scenes", help="list the scene catalogue with parameters (name, default, range, unit)")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.set_defaults(func=cmd_scenes)

    p = sub.add_parser("solvers", help="list the solvers with their parameters")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.set_defaults(func=cmd_solvers)

    p = sub.add_parser("run", help="solve one scene with one solver and print the solution",
                       description="Solve SCENE with --solver at lattice resolution n (one spacing a = width / (n-1) "
                       "on every axis: n x n x (3n-2) nodes on the paper's bar).")
    p.add_argument("scene", help="scene name (see `pcverify scenes`)")
    p.add_argument("--solver", required=True, help="solver name (see `pcverify solvers`) or module:Class of a solver "
                   "that is not installed as a plugin")
    p.add_argument("--n", type=int_in("n", 2, 1000), default=4,
                   help="lattice resolution n >= 2 (default 4: 160 nodes)")
    p.add_argument("--refine", type=int_in("refine", 1, 1000), default=1,
                   help="grid refinement factor of continuum solvers (default 1)")
    p.add_argument("--set", action="append", metavar="KEY=VALUE", help="scene or solver parameter (repeatable)")
    p.add_argument("--allow-large", action="store_true", help="run a solve beyond the work and memory limits")
    p.add_argument("--time-limit", type=seconds_in("time-limit", 0, MAX_TIME_LIMIT), default=DEFAULT_TIME_LIMIT,
                   metavar="SECONDS", help=TIME_LIMIT_HELP)
    p.add_argument("--json", action="store_true", help="one JSON object on stdout")
    p.set_defaults(func=cmd_run)

    p = sub.add_parser("study", help="run a study (a grid of scenes x solvers x resolutions) and write reports/",
                       description="Run the named study (or a TOML file), cache every cell, write tables and plots.")
    p.add_argument("name", help="study name (`default` runs all default studies) or a path to a .toml file")
    p.add_argument("--dry-run", action="store_true", help="list what is cached and what would run; run nothing")
    p.add_argument("--out", default="reports", help="output folder (default reports/)")
    p.add_argument("--cache", default=None, help="cache folder (default OUT/cache)")
    p.add_argument("--jobs", type=int_in("jobs", 1, 256), default=1,
                   help="parallel cells on local cores (default 1)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="hand the cells to a Dask cluster (e.g. tcp://host:8786; needs pcverify[dask])")
    p.add_argument("--allow-large", action="store_true", help=f"run a study of more than {MAX_CELLS} cells, or cells "
                   "beyond the work and memory limits")
    p.add_argument("--time-limit", type=seconds_in("time-limit", 0, MAX_TIME_LIMIT), default=DEFAULT_TIME_LIMIT,
                   metavar="SECONDS", help=TIME_LIMIT_HELP)
    p.add_argument("--rerun", nargs="*", default=None, metavar="SOLVER",
                   help="recompute cached cells: all of them, or those of the named solvers (put it last)")
    p.add_argument("--json", action="store_true", help="print a JSON summary per study with its verdicts (the records "
                   "of verdicts.json; with --dry-run: the plan of every cell), nothing else on stdout")
    p.add_argument("--group", action="append", metavar="ID", help="run only this group of the study (repeatable; "
                   "the groups it reads tables from are included)")
    p.add_argument("--strict", action="store_true", help="exit 1 when any verdict is not a pass (fail, inconclusive or "
                   "not applicable), listing each with why and its reproducing command on stderr (a CI gate)")
    p.set_defaults(func=cmd_study)

    p = sub.add_parser("verdict", help="judge one claim of a study and print its value, target, error, uncertainty",
                       description="Run the groups a claim reads (cached cells are read back), judge the claim and "
                       "print each verdict: the command printed beside every verdict in the report.  Exit 1 unless "
                       "every verdict printed is a pass.")
    p.add_argument("study", help="study name or a path to a .toml file")
    p.add_argument("claim", help="claim id (see the study file)")
    p.add_argument("--case", default=None, help="one case of the claim, as the report writes it (e.g. n=4)")
    p.add_argument("--out", default="reports", help="where the study's cache is (default reports/: reports/cache)")
    p.add_argument("--cache", default=None, help="cache folder (default OUT/cache)")
    p.add_argument("--jobs", type=int_in("jobs", 1, 256), default=1, help="parallel cells on local cores (default 1)")
    p.add_argument("--allow-large", action="store_true", help="run cells beyond the work and memory limits")
    p.add_argument("--time-limit", type=seconds_in("time-limit", 0, MAX_TIME_LIMIT), default=DEFAULT_TIME_LIMIT,
                   metavar="SECONDS", help=TIME_LIMIT_HELP)
    p.add_argument("--json", action="store_true", help="print the verdict records as JSON")
    p.set_defaults(func=cmd_verdict)

    p = sub.add_parser("mutate", help="run a study's claims on deliberate defects of the code: which claims catch "
                       "which mutant", description="Run the study (the baseline), then each of its mutants ([[mutant]] "
                       "tables, STUDY.mutants.toml beside it, plugins' pcverify.mutants entry points) in a process of "
                       "its own on the mutated code; a mutant is killed when a claim that passes on the original does "
                       "not pass on it.  Writes OUT/STUDY/mutants.json, the kill matrix and a section of the report.")
    p.add_argument("name", help="study name (`default`: every shipped study with mutants) or a path to a .toml file")
    p.add_argument("--mutant", action="append", metavar="NAME", help="run only this mutant (repeatable)")
    p.add_argument("--jobs", type=int_in("jobs", 1, 256), default=1,
                   help="mutants run at once, each running its study on one worker, and the baseline's cells run "
                   "at once (default 1)")
    p.add_argument("--out", default="reports", help="output folder (default reports/)")
    p.add_argument("--cache", default=None, help="cache folder (default OUT/cache); mutants keep theirs under "
                   "CACHE/mutants/")
    p.add_argument("--allow-large", action="store_true", help=f"run a study of more than {MAX_CELLS} cells, or cells "
                   "beyond the work and memory limits")
    p.add_argument("--time-limit", type=seconds_in("time-limit", 0, MAX_TIME_LIMIT), default=DEFAULT_TIME_LIMIT,
                   metavar="SECONDS", help=TIME_LIMIT_HELP)
    p.add_argument("--mutant-time-limit", type=seconds_in("mutant-time-limit", 0, MAX_TIME_LIMIT),
                   default=DEFAULT_MUTANT_TIME_LIMIT, metavar="SECONDS", help="stop a mutant's whole run after SECONDS "
                   f"(status crashed; its finished cells are kept; default {DEFAULT_MUTANT_TIME_LIMIT:g})")
    p.add_argument("--json", action="store_true", help="print mutants.json of each study (a list), nothing else on "
                   "stdout")
    p.add_argument("--strict", action="store_true", help="exit 1 when a mutant survives, is invalid or crashed (a "
                   "CI gate)")
    p.set_defaults(func=cmd_mutate)

    p = sub.add_parser("bench", help="run the benchmarks, save them, compare with the previous saved run")
    p.add_argument("--tests", default="tests/bench", help="benchmark folder (default tests/bench)")
    p.add_argument("--storage", default="reports/benchmarks", help="where runs are saved (default reports/benchmarks)")
    p.add_argument("--fail-percent", type=float, default=25.0, help="regression of the mean that fails (default 25)")
    p.set_defaults(func=cmd_bench)

    p = sub.add_parser("report", help="rebuild the tables and reports/index.html from cached results")
    p.add_argument("--out", default="reports", help="output folder (default reports/)")
    p.add_argument("--json", action="store_true", help="print a JSON summary")
    p.set_defaults(func=cmd_report)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # usage errors were printed as one line by OneLineParser; --help exits 0
        if exc.code == 2:
            return 2
        raise
    if not getattr(args, "func", None):
        parser.print_help()
        return 0
    try:
        with sigterm_interrupts():  # SIGTERM anywhere in a command: KeyboardInterrupt, the "terminated" line below
            code = args.func(args)
            sys.stdout.flush()  # here, not at exit: a reader gone by now is the BrokenPipeError below, not a traceback
            return code
    except (SceneError, CliError, SolverUnavailable, FileNotFoundError) as exc:
        if args.debug:
            raise
        report_error(str(exc))
        return 2
    except BrokenPipeError:  # the reader of stdout has gone (`pcverify scenes | head`): not an error of ours
        with contextlib.suppress(OSError):
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # no second error at exit's flush
        return 141  # as a shell reports a process ended by SIGPIPE
    except OSError as exc:  # a read-only or full output folder, a path that is a file, ...
        if args.debug:
            raise
        where = f"{exc.strerror}: {exc.filename}" if exc.filename and exc.strerror else str(exc)
        hint = "; finished cells are kept in the cache, rerun to resume" if args.command == "study" else ""
        report_error(f"{where}{hint if 'rerun' not in where else ''}")
        return 2
    except KeyboardInterrupt:
        if received() == signal.SIGTERM:
            print("\npcverify: terminated (finished cells are kept in the cache)", file=sys.stderr)
            return TERMINATED
        print("\npcverify: interrupted (finished cells are kept in the cache)", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
