"""Progress on stderr: plain lines where stderr is not a terminal (a log, a CI job), the tqdm bar on a terminal.

Before, `pcverify study` drew its bar into a pipe too: the log of a clean `tox -e verify` was a few lines of
text inside megabytes of carriage-return frames.
"""

from __future__ import annotations

import fcntl
import os
import pty
import re
import struct
import subprocess
import sys
import termios
import time
from pathlib import Path

import pytest

from pcverify.harness.run import progress

TESTS = Path(__file__).resolve().parent
STUDY = """name = "progress-lines"
plugins = ["calib_synthetic"]
[[group]]
id = "g"
scene = "bar-heat-faces"
solvers = ["calib-quadratic"]
n = [2, 3]
sweep = { seed = [0, 1, 2, 3, 4, 5, 6, 7, 8, 9] }
"""  # 20 cells of the synthetic solver: a few seconds


@pytest.fixture(scope="module")
def work(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("progress")
    (folder / "study.toml").write_text(STUDY)
    return folder


def _study(work: Path, stderr: int) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(TESTS), os.environ.get("PYTHONPATH", "")])}
    return subprocess.Popen([sys.executable, "-m", "pcverify.harness.cli", "study", "study.toml", "--out", "out"],
                            cwd=work, env=env, stdout=subprocess.DEVNULL, stderr=stderr)


def _counts(err: str) -> list[int]:
    return [int(m[1]) for m in re.finditer(r"^progress-lines: (\d+)/20 cells", err, re.MULTILINE)]


def test_a_study_into_a_pipe_reports_progress_in_plain_lines(work: Path) -> None:
    """A line when the cells start, one per tenth of the 20 cells (2 cells), one when they are done; no frame."""
    proc = _study(work, subprocess.PIPE)
    err = proc.communicate(timeout=600)[1].decode()
    assert proc.returncode == 0, err[-1500:]
    assert "\r" not in err and "|" not in err, err[-1500:]
    assert _counts(err) == list(range(0, 21, 2)), err
    assert re.search(r"^progress-lines: 20/20 cells \(done 20, cached 0, failed 0\), finished after [0-9.]+ s$", err,
                     re.MULTILINE), err
    again = _study(work, subprocess.PIPE)  # every cell cached: the one line that says so
    err = again.communicate(timeout=600)[1].decode()
    assert again.returncode == 0 and _counts(err) == [20] and "finished" in err, err


def test_a_study_on_a_terminal_draws_the_bar(work: Path) -> None:
    """The same study (cached) with stderr a terminal: tqdm's bar, redrawn with carriage returns."""
    leader, follower = pty.openpty()
    fcntl.ioctl(follower, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))  # rows, columns: a bar fits
    proc = _study(work, follower)
    os.close(follower)
    chunks = []
    while True:
        try:
            data = os.read(leader, 4096)
        except OSError:  # EIO: every process holding the terminal has exited
            break
        if not data:
            break
        chunks.append(data)
    os.close(leader)
    err = b"".join(chunks).decode(errors="replace")
    assert proc.wait(timeout=600) == 0, err[-1500:]
    assert "\r" in err and "20/20" in err and "100%" in err, err[-1500:]


def test_a_long_solve_off_a_terminal_says_it_is_still_running(monkeypatch, capsys) -> None:
    """`run`'s elapsed-time display off a terminal: a plain line every STILL_RUNNING_S (here 0.5 s), never a
    frame to erase."""
    monkeypatch.setattr(progress, "STILL_RUNNING_S", 0.5)
    with progress.working("skfem on bar-heat-faces n=4 refine=1"):
        time.sleep(1.8)
    err = capsys.readouterr().err
    lines = err.splitlines()
    assert "\r" not in err and "elapsed" not in err, err
    assert lines[:2] == ["skfem on bar-heat-faces n=4 refine=1: still running after 0.5 s",
                         "skfem on bar-heat-faces n=4 refine=1: still running after 1 s"], err


def test_the_plain_lines_take_the_counts_as_tqdm_takes_them(capsys) -> None:
    """Off a terminal the bar is ProgressLines, on one tqdm: a caller may give the counts as a mapping, as
    keywords or both, and both must take them (a mapping once crashed `pcverify mutate` into a pipe)."""
    tqdm = pytest.importorskip("tqdm")
    lines = progress.ProgressLines(4, "mutants", "mutant")
    with open(os.devnull, "w") as sink:
        bar = tqdm.tqdm(total=4, file=sink)
        for call in (lambda b: b.set_postfix({"killed": 1}), lambda b: b.set_postfix(killed=2),
                     lambda b: b.set_postfix({"killed": 3}, survived=1)):
            call(lines)
            call(bar)
            lines.update(1)
        bar.close()
    lines.close()
    err = capsys.readouterr().err
    assert "(killed 3, survived 1)" in err.splitlines()[-1] and "(killed 1)" in err
