"""`pcverify mutate`: a study's claims run against deliberate defects of the code.

Only the groups the claims read run (a cell no claim reads cannot catch a mutant); the study runs so as
`study --group` runs them (the baseline), then once per mutant in a process of its own on the
mutated code (`run.mutation`); each study gets mutants.json, the kill matrix and a section of its page
(`report.mutation`).  Every mutant's edit is checked before anything runs.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

from pcverify.harness.report.gates import mutant_gate
from pcverify.harness.report.mutation import mutation_document, write_mutation_report
from pcverify.harness.report.reproduce import claimed, select_groups
from pcverify.harness.report.studies import run_study
from pcverify.harness.report.write import write_index
from pcverify.harness.run.cache import Cache
from pcverify.harness.run.execution import cell_time_limit
from pcverify.harness.run.interrupt import remember_sigint
from pcverify.harness.run.mutation import Runner, prepare
from pcverify.harness.run.workers import output_to_stderr
from pcverify.harness.study.mutants import catalogue, select_mutants, solver_packages
from pcverify.harness.study.shipped import study_files
from pcverify.harness.study.study import load_study


def run_mutants(args: argparse.Namespace) -> int:
    """`pcverify mutate STUDY`: the baseline, then every catalogued mutant (or those named by --mutant); a line
    per mutant and the counts (or mutants.json of each study as JSON).  --strict: exit 1 unless every mutant
    run is killed."""
    with remember_sigint(), cell_time_limit(args.time_limit):
        names = sorted(study_files()) if args.name == "default" else [args.name]
        with output_to_stderr():
            whole = [load_study(n, args.allow_large) for n in names]
            found = [catalogue(s.mutants, s.path, solver_packages(s), [c.id for c in s.claims], s.shipped_mutants)
                     for s in whole]
            studies = [claimed(s) for s in whole]
            if args.group:  # one study (the command line checks it)
                studies = [claimed(select_groups(whole[0], args.group))]
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
            judged = {c.id for c in study.claims}  # a report of some groups also keeps the other claims' verdicts
            verdicts = [r for r in baseline["verdicts"] if r["claim"] in judged]
            runner = Runner(study, verdicts, cache, args.time_limit, args.mutant_time_limit, args.allow_large)
            with output_to_stderr():
                outcomes = runner.run(todo, args.jobs, progress=not args.json)
            doc = mutation_document(study.name, verdicts, outcomes, time.perf_counter() - t0)
            doc["baseline"] = {k: baseline.get(k) for k in ("cells", "cached", "done", "failed", "wall_s")}
            where = write_mutation_report(out, study.name, doc)
            docs.append(doc)
            if not args.json:
                print_mutants(doc, where)
        if docs:
            write_index(out)
        if args.json:
            print(json.dumps(docs))
        return mutant_gate(docs, args.strict)


def print_mutants(doc: dict[str, Any], where: Path) -> None:
    """One line per mutant, then the counts and the descriptive claims."""
    width = max(len(o["name"]) for o in doc["mutants"])
    for o in doc["mutants"]:
        about = f"caught by {', '.join(o['caught_by'])}" if o["caught_by"] else o["reason"]
        print(f"  {o['status']:<9} {o['name']:<{width}} {o['wall_s']:7.1f} s  {o['recomputed']:>4} cells run  {about}")
    counts = ", ".join(f"{n} {s}" for s, n in doc["counts"].items())
    descriptive = [c for c, v in doc["claims"].items() if v["descriptive"]]
    print(f"{doc['study']}: {len(doc['mutants'])} mutants: {counts}; descriptive claims (kill no mutant): "
          f"{', '.join(descriptive) or 'none'} -> {where}")
