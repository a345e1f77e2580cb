"""Several study reports written at once, after every study has computed: drawing the figures is the slow part
of a report and takes one core, so each report is written in a forked process of its own, at most `processes`
at a time; nothing competes with a study's timed pass, which has run by then."""

from __future__ import annotations

import multiprocessing
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pcverify.harness.report.calibration_section import calibration_section
from pcverify.harness.report.write import write_study_report
from pcverify.harness.run.interrupt import deferred_interrupts, undeferred


@dataclass
class ReportJob:
    """A computed study: its cells' results and its calibrations' outcomes, to be written into a report."""

    study: Any
    results: list[dict[str, Any]]
    calibrations: list[Any] = field(default_factory=list)


_JOBS: list[ReportJob] = []  # what the forked writers read (inherited, never pickled)


def _write(job: ReportJob, out: Path) -> float:
    t0 = time.perf_counter()
    extra = [calibration_section(outcome, out / job.study.name) for outcome in job.calibrations]
    write_study_report(job.study, job.results, out, extra=extra)
    return time.perf_counter() - t0


def _write_job(k: int, out: Path) -> float:
    return _write(_JOBS[k], out)


def write_reports(jobs: list[ReportJob], out: Path, processes: int = 1) -> list[float]:
    """Write each job's report into out/<study>/ and return the seconds each took: in this process when
    `processes` is 1 or there is one job, else in up to `processes` forked processes (an exception in one is
    raised here)."""
    if processes <= 1 or len(jobs) <= 1:
        return [_write(job, out) for job in jobs]
    _JOBS[:] = jobs
    try:
        with deferred_interrupts():  # the writers are forked here: a signal meanwhile stops us after the forks
            writers = multiprocessing.get_context("fork").Pool(min(processes, len(jobs)), _writer_start)
        with writers:
            return writers.starmap(_write_job, [(k, out) for k in range(len(jobs))], chunksize=1)
    finally:
        _JOBS.clear()


def _writer_start() -> None:
    """A forked writer: Ctrl-C and SIGTERM stop it at once (not deferred, as they were while it was forked)."""
    undeferred()
