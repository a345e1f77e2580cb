"""`pcverify verdict STUDY CLAIM`: one claim judged, the command printed beside every verdict of a report.

The groups (or calibration) the claim reads run through the cache as a study runs them; the claim is judged
on a report written to a temporary folder, so the study's own report is left as it is.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import tempfile
from pathlib import Path

from pcverify.harness.report.calibration_section import calibration_section
from pcverify.harness.report.reproduce import claim_groups, select_groups
from pcverify.harness.report.write import study_verdicts, write_study_report
from pcverify.harness.run.cache import Cache
from pcverify.harness.run.calibration import run_calibration
from pcverify.harness.run.execution import cell_time_limit, execute
from pcverify.harness.run.interrupt import remember_sigint
from pcverify.harness.run.workers import output_to_stderr
from pcverify.harness.study.study import load_study
from pcverify.scene import SceneError, shown


def judge_claim(args: argparse.Namespace) -> int:
    """Judge the claim (one case with --case) and print each verdict's value, target, error, uncertainty and
    tolerance (or the records as JSON).  Exit 1 unless every verdict printed is a pass."""
    with remember_sigint(), cell_time_limit(args.time_limit):
        with output_to_stderr():
            study = load_study(args.study, args.allow_large)
        claims = {c.id: c for c in study.claims}
        if args.claim not in claims:
            raise SceneError(f"claim={shown(args.claim)} is unknown in study {study.name}; allowed: one of "
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
            raise SceneError(f"--case {shown(args.case)} is not a case of claim {claim.id}; allowed: one of "
                             f"{', '.join(repr(c) for c in cases)}")
    if args.json:
        print(json.dumps(records))
    else:
        for r in records:
            print(f"{r['study']}/{r['claim']}" + (f" {r['case']}" if r["case"] else "") + f": {r['verdict']}")
            for key in ("metric", "value", "uncertainty", "target", "target_from", "error", "tolerance", "sense",
                        "reference", "basis", "note", "solver"):
                if r.get(key) not in (None, ""):
                    print(f"  {key:<12} {r[key]!r}" if isinstance(r[key], float) else f"  {key:<12} {r[key]}")
    return 0 if all(r["verdict"] == "pass" for r in records) else 1
