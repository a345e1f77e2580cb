"""`pcverify sensitivity`: which claim of a study sees which model input.

The study runs as `study` runs it (the baseline, its report written), then each input is scaled in every cell
of the groups its claims read that has it (`run.sensitivity`; an input only other groups have is *unread*; the
perturbed cells are cached under CACHE/sensitivity/STUDY/, never among the study's entries) and the claims are
judged again; the study gets sensitivity.json, the matrix and a section of its page (`report.sensitivity`).  Bad
input (an unknown --input) is one line before anything runs.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

from pcverify.harness.report.reproduce import claimed
from pcverify.harness.report.sensitivity import sensitivity_document, write_sensitivity_report
from pcverify.harness.report.studies import run_study
from pcverify.harness.report.write import write_index
from pcverify.harness.run.cache import Cache
from pcverify.harness.run.execution import cell_time_limit, execute
from pcverify.harness.run.interrupt import remember_sigint
from pcverify.harness.run.sensitivity import Input, inputs_of, judged, select_inputs, sensitivity, study_inputs
from pcverify.harness.run.workers import output_to_stderr
from pcverify.harness.study.study import Study, load_study


def run_sensitivity(args: argparse.Namespace) -> int:
    """`pcverify sensitivity STUDY`: the baseline, then every input (or those --input names) perturbed; a line per
    input and the blind spots (or sensitivity.json as JSON).  --strict: exit 1 when an input is a blind spot or a
    claim is out of reach."""
    with remember_sigint(), cell_time_limit(args.time_limit):
        with output_to_stderr():
            study = load_study(args.name, args.allow_large)
            items = select_inputs(study_inputs(study), args.input, study.name)
            read = claimed(study, calibrations=False)
            inside = set(study_inputs(read))
        out = Path(args.out)
        cache = Cache(args.cache or out / "cache")
        t0 = time.perf_counter()
        run_study(study, args, cache, out)
        with output_to_stderr():
            results, _ = execute(read, cache, jobs=args.jobs, progress=False)  # read back from the cache
            baseline = judged(read, results)
            entries = sensitivity(read, results, baseline, [i for i in items if i in inside], args.step,
                                  Cache(cache.root / "sensitivity" / study.name), args.jobs, progress=not args.json)
        entries += [unread(study, read, i) for i in items if i not in inside]
        claims = [c.id for c in read.claims]
        doc = sensitivity_document(study.name, args.step, claims, entries, time.perf_counter() - t0,
                                   [c.id for c in study.claims if c.id not in claims])
        where = write_sensitivity_report(out, study.name, doc)
        write_index(out)
        if args.json:
            print(json.dumps(doc))
        else:
            print_sensitivity(doc, where)
        return 1 if args.strict and (doc["blind_spots"] or doc["claims_not_reached"]) else 0


def unread(study: Study, read: Study, item: Input) -> dict[str, Any]:
    """The entry of an input that only cells of groups no claim reads have: a blind spot, not run."""
    claimed_ids = {g.id for g in read.groups}
    groups = sorted({g.id for g in study.groups if g.id not in claimed_ids for c in g.cells if item in inputs_of(c)})
    return {"input": item.name, "kind": item.kind, "owner": item.owner, "path": item.path, "status": "unread",
            "reason": f"only in groups no claim reads: {', '.join(groups)}", "cells": 0, "changed_cells": 0,
            "claims": {}}


def print_sensitivity(doc: dict[str, Any], where: Path) -> None:
    """One line per input (the claims that see it, or why none does), then the counts."""
    width = max((len(x["input"]) for x in doc["inputs"]), default=0)
    blind = {b["input"]: b["why"] for b in doc["blind_spots"]}
    for x in doc["inputs"]:
        about = (x["reason"] if x["status"] != "perturbed" else blind.get(x["input"])
                 or f"seen by {', '.join(x['seen_by'])}")
        state = "blind" if x["input"] in blind else "seen" if x["status"] == "perturbed" else x["status"]
        print(f"  {state:<13} {x['input']:<{width}} {x['cells']:>4} cells {x['changed_cells']:>4} changed  {about}")
    n = doc["counts"]
    if doc["claims_seeing_nothing"]:
        print(f"  claims no perturbed input moves: {', '.join(doc['claims_seeing_nothing'])}")
    if doc["claims_not_reached"]:
        print(f"  claims no perturbation reaches (they read a calibration's runs, which sensitivity does not "
              f"perturb): {', '.join(doc['claims_not_reached'])}")
    print(f"{doc['study']}: {n['inputs']} inputs, {n['perturbed']} perturbed by 1 + {doc['step']:g}: {n['seen']} seen, "
          f"{n['blind']} blind spots, in {doc['wall_s']:.0f} s -> {where}")
