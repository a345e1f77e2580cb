"""Shared pieces of the red-team tests (tests/test_red_team_*.py): the command line run in this process
(`run`) or in a subprocess (`cli`, where process isolation matters: signals, a crash, the stdout of the
process itself, an import that must not happen in the test process), a guard that turns a hang into a
failure, and a tally of the hostile cases tried, rejected cleanly and accepted correctly.

The subprocess command is `python -m pcverify.harness.cli`; setting PCVERIFY_RED_TEAM_CLI to another command
(e.g. an older installation's `pcverify`) runs the same cases against it - `run` then starts it too - which
is how the cases were shown to fail on the code they were written against.
"""

from __future__ import annotations

import collections
import contextlib
import os
import shlex
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from pcverify.harness.cli import main

ENV = {**os.environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MPLBACKEND": "Agg"}
COMMAND = shlex.split(os.environ.get("PCVERIFY_RED_TEAM_CLI", f"{sys.executable} -m pcverify.harness.cli"))
TALLY: collections.Counter = collections.Counter()


def cli(*args: str, cwd: Path, timeout: float = 300.0, env: dict[str, str] | None = None
        ) -> subprocess.CompletedProcess:
    """Run `pcverify ARGS` in `cwd` (stdout and stderr captured, never raising on the exit code)."""
    return subprocess.run([*COMMAND, *args], cwd=cwd, capture_output=True, text=True, timeout=timeout,
                          env=env or ENV, check=False)


def run(*args: str, cwd: Path, capfd: pytest.CaptureFixture, seconds: float = 300.0
        ) -> subprocess.CompletedProcess:
    """`pcverify ARGS` in `cwd` in this process (no interpreter start-up: seconds saved per case), with what
    `cli` returns: the exit code, stdout and stderr captured at the file descriptors (a worker's lines too).
    A command still running after `seconds` fails the test (Hung).  With PCVERIFY_RED_TEAM_CLI set, `cli`."""
    if "PCVERIFY_RED_TEAM_CLI" in os.environ:
        return cli(*args, cwd=cwd, timeout=seconds)
    capfd.readouterr()
    with contextlib.chdir(cwd), deadline(seconds):
        code = main(list(args))
    out, err = capfd.readouterr()
    return subprocess.CompletedProcess(["pcverify", *args], code, out, err)


class Hung(BaseException):
    """A command that did not finish within its deadline (the bug the hang cases guard against)."""


class deadline:
    """Raise Hung in the main thread after `seconds` (SIGALRM): a hang fails the test instead of the suite."""

    def __init__(self, seconds: float) -> None:
        self.seconds = seconds

    def __enter__(self) -> None:
        def fire(signum, frame):  # noqa: ARG001 - the signal-handler signature
            raise Hung(f"still running after {self.seconds:g} s")

        self.previous = signal.signal(signal.SIGALRM, fire)
        signal.setitimer(signal.ITIMER_REAL, self.seconds)

    def __exit__(self, *exc: object) -> None:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, self.previous)


def popen(*args: str, cwd: Path, env: dict[str, str] | None = None) -> subprocess.Popen:
    """Start `pcverify ARGS` in its own process group (so that a test can signal it and its workers)."""
    return subprocess.Popen([*COMMAND, *args], cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=env or ENV, start_new_session=True)


def processes_with(marker: str) -> list[int]:
    """Pids of the processes whose environment holds `marker` (a study and everything it started)."""
    pids = []
    for proc in Path("/proc").iterdir():
        if not proc.name.isdigit():
            continue
        try:
            if marker.encode() in (proc / "environ").read_bytes():
                pids.append(int(proc.name))
        except OSError:
            continue
    return pids


def one_line_error(out: subprocess.CompletedProcess) -> str:
    """The single `pcverify: error: ...` line of a refused command (asserts exit 2, one line, no traceback)."""
    lines = out.stderr.strip().splitlines()
    assert out.returncode == 2, (out.returncode, out.stderr[-1500:])
    assert len(lines) == 1 and lines[0].startswith("pcverify: error: "), out.stderr[-1500:]
    assert "Traceback" not in out.stderr and len(lines[0]) < 2000
    return lines[0]


def tally(family: str, outcome: str, cases: int = 1) -> None:
    """Count cases: outcome is "rejected" (refused in one line) or "accepted" (ran, correct).  Family names are
    unique across files: one worker may run several red-team files, and each file's tally checks its own."""
    TALLY[f"{family} tried"] += cases
    TALLY[f"{family} {outcome}"] += cases


def check_tally(expected: dict[str, int]) -> None:
    """Print each family's tally and assert that exactly `expected[family]` cases were tried, each either
    rejected cleanly or accepted correctly: a deleted, skipped or silently passing case fails it."""
    for family, cases in expected.items():
        tried, rejected, accepted = (TALLY[f"{family} {k}"] for k in ("tried", "rejected", "accepted"))
        print(f"\n{family}: tried {tried}, rejected cleanly {rejected}, accepted correctly {accepted}")
        assert tried == rejected + accepted == cases, (family, f"tried {tried}", f"expected {cases}")
