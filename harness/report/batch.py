"""Several study reports written at once, after every study has computed: drawing the figures is the slow part
of a report and takes one core, so each report is written in a forked process of its own, at most `processes`
at a time; nothing competes with a study's timed pass, which has run by then."""

from __future__ import annotations

import multiprocessing
import time
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
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
    raised here).  A writer that dies (a signal, a crash of a forked process) never leaves the run waiting: the
    reports it did not write are written here."""
    if processes <= 1 or len(jobs) <= 1:
        return [_write(job, out) for job in jobs]
    _JOBS[:] = jobs
    try:
        with deferred_interrupts():  # the writers are forked here: a signal meanwhile stops us after the forks
            writers = ProcessPoolExecutor(min(processes, len(jobs)), multiprocessing.get_context("fork"),
                                          _writer_start)
            futures = [writers.submit(_write_job, k, out) for k in range(len(jobs))]
        with writers:
            return [_outcome(future, job, out) for future, job in zip(futures, jobs, strict=True)]
    finally:
        _JOBS.clear()


def _outcome(future: Future, job: ReportJob, out: Path) -> float:
    """A forked writer's seconds, or the report written here when its writer died before writing it."""
    try:
        return future.result()
    except BrokenProcessPool:
        return _write(job, out)


def _writer_start() -> None:
    """A forked writer: Ctrl-C and SIGTERM stop it at once (not deferred, as they were while it was forked)."""
    undeferred()
