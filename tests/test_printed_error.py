"""A failed cell says what the solve printed: the last error line a task wrote to its stderr or stdout (C-level
writes included) ends the reason of a task that died, timed out or failed with a generic message.  This is how
a library that prints its error and then aborts (LAMMPS: "ERROR: ..." then SIGABRT) or raises a bare
RuntimeError is diagnosed from the report.  What a worker prints still reaches the study's stderr."""

from __future__ import annotations

import os
import time

import pytest

from pcverify.harness.run import workers
from pcverify.harness.run.execution import _with_printed


def _print_then(line: str, then: str) -> str:
    os.write(1 if then == "stdout" else 2, (line + "\n").encode())
    if then == "abort":
        os.abort()
    if then == "raise":
        raise RuntimeError("Failed to initialize the library")
    if then == "hang":
        time.sleep(60)
    return "done"


@pytest.fixture
def pool():
    p = workers.Pool(world="test-printed")
    yield p
    p.close()


@pytest.mark.parametrize("then, kind", [("abort", "died"), ("raise", "raised"), ("hang", "timed-out"),
                                        ("stdout", "returned")])
def test_the_last_error_line_of_the_task_is_its_outcomes(pool, then, kind, capfd):
    line = "ERROR: Lost atoms: original 162 current 161 (src/thermo.cpp:494)"
    outcome = pool.run_one(_print_then, ("some progress\n" + line + "\nTotal wall time: 0:00:01", then),
                           time_limit=3.0)
    assert outcome.kind == kind
    assert outcome.error_line == line
    if kind == "died":
        assert "SIGABRT" in outcome.reason
    assert line in capfd.readouterr().err  # passed on to the study's stderr as it was printed


def test_an_earlier_tasks_output_is_not_the_next_tasks(pool, capfd):
    first = pool.run_one(_print_then, ("ERROR: from the first task", "stdout"), time_limit=30.0)
    second = pool.run_one(os.abort, (), time_limit=30.0)
    assert first.error_line == "ERROR: from the first task"
    assert second.kind == "died" and second.error_line == ""


def test_a_task_that_prints_no_error_line_has_none(pool):
    outcome = pool.run_one(_print_then, ("all fine, 10 steps", "abort"), time_limit=30.0)
    assert outcome.kind == "died" and outcome.error_line == ""


def test_the_reason_carries_the_line_once():
    assert _with_printed("RuntimeError: generic", "ERROR: bad style") == "RuntimeError: generic; it printed: " \
        "ERROR: bad style"
    assert _with_printed("Exception: ERROR: bad style Last input line: x", "ERROR: bad style") == \
        "Exception: ERROR: bad style Last input line: x"
    assert _with_printed("exit code 1", "") == "exit code 1"
