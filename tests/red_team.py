"""Shared pieces of the red-team tests (tests/test_red_team_*.py): the command line run in a subprocess,
and a tally of the hostile cases tried, rejected cleanly and accepted correctly.

The command is `python -m pcverify.harness.cli`; setting PCVERIFY_RED_TEAM_CLI to another command (e.g.
an older installation's `pcverify`) runs the same cases against it, which is how the cases were shown to
fail on the code they were written against.
"""

from __future__ import annotations

import collections
import os
import shlex
import subprocess
import sys
from pathlib import Path

ENV = {**os.environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MPLBACKEND": "Agg"}
COMMAND = shlex.split(os.environ.get("PCVERIFY_RED_TEAM_CLI", f"{sys.executable} -m pcverify.harness.cli"))
TALLY: collections.Counter = collections.Counter()


def cli(*args: str, cwd: Path, timeout: float = 300.0, env: dict[str, str] | None = None
        ) -> subprocess.CompletedProcess:
    """Run `pcverify ARGS` in `cwd` (stdout and stderr captured, never raising on the exit code)."""
    return subprocess.run([*COMMAND, *args], cwd=cwd, capture_output=True, text=True, timeout=timeout,
                          env=env or ENV, check=False)


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
    """Count cases: outcome is "rejected" (refused in one line) or "accepted" (ran, correct)."""
    TALLY[f"{family} tried"] += cases
    TALLY[f"{family} {outcome}"] += cases
