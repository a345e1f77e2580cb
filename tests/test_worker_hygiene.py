"""A worker is clean for every task: what one task changed in its process (working folder, environment, signal
handlers, file descriptors 0-2) is put back before the next, and the processes a task started end with it,
whether it returns or is killed at its time limit.  Without this a cell that chdir'd or set a variable changed
the results of the next cell in that worker; a cell that closed its stdout and stderr made the next cells fail
with EBADF (the wrong cells blamed); an outside code started by a timed-out cell kept running after the study;
a helper started without waiting held the study's stderr, so a caller reading it waited for the helper."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from pcverify.harness.run import workers


def _change_state(folder: str) -> int:
    os.chdir(folder)
    os.environ["PCVERIFY_LEAK"] = "from the task before"
    os.environ.pop("HOME", None)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)  # a worker that ignores SIGTERM cannot be stopped by it
    return os.getpid()


def _see_state() -> tuple[int, str, str | None, str | None, bool]:
    return (os.getpid(), os.getcwd(), os.environ.get("PCVERIFY_LEAK"), os.environ.get("HOME"),
            signal.getsignal(signal.SIGTERM) is signal.SIG_IGN)


def _close_output() -> int:
    os.close(1)
    os.close(2)
    return os.getpid()


def _write_output() -> int:
    print("a line on stdout", flush=True)
    print("a line on stderr", file=sys.stderr, flush=True)
    os.write(2, b"a C-level write\n")
    return os.getpid()


def _start_child(record: str) -> int:
    child = subprocess.Popen(["sleep", "120"])  # inherits the worker's stderr, never waited for
    Path(record).write_text(str(child.pid))
    return child.pid


def _start_child_and_hang(record: str) -> None:
    _start_child(record)
    time.sleep(600)


def _alive(pid: int) -> bool:
    """Whether `pid` runs (a zombie, whose descriptors are closed, counts as ended)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


def _wait_ended(pid: int, seconds: float = 10.0) -> bool:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if not _alive(pid):
            return True
        time.sleep(0.05)
    return False


def test_a_task_never_sees_the_working_folder_or_environment_of_the_one_before(tmp_path) -> None:
    pool = workers.Pool(world="hygiene")
    try:
        (_, first), (_, second) = pool.run([(1, _change_state, (str(tmp_path),)), (2, _see_state, ())], 1, 60.0)
    finally:
        pool.close()
    pid, cwd, leak, home, ignores_sigterm = second.value
    assert pid == first.value  # the same worker ran both
    assert (cwd, leak, home, ignores_sigterm) == (os.getcwd(), None, os.environ.get("HOME"), False)


def test_a_task_that_closes_its_output_leaves_the_next_task_its_output() -> None:
    pool = workers.Pool(world="hygiene")
    try:
        outcomes = [o for _, o in pool.run([(1, _close_output, ()), (2, _write_output, ())], 1, 60.0)]
    finally:
        pool.close()
    assert [o.kind for o in outcomes] == ["returned", "returned"], outcomes
    assert outcomes[0].value == outcomes[1].value  # the same worker, its descriptors put back


def test_the_processes_a_task_started_end_with_it(tmp_path) -> None:
    record = tmp_path / "child.pid"
    pool = workers.Pool(world="hygiene")
    try:
        outcome = pool.run_one(_start_child, (str(record),), 60.0)
        assert outcome.kind == "returned"
        assert _wait_ended(outcome.value)  # ended with its task, though its worker lives on
        hung = pool.run_one(_start_child_and_hang, (str(record),), 2.0)
        assert hung.kind == "timed-out"
        assert _wait_ended(int(record.read_text()))  # killed with the worker, not left running
    finally:
        pool.close()


def test_a_caller_reading_the_output_does_not_wait_for_a_tasks_helper(tmp_path) -> None:
    """The study's process (here a script) reads to the end of a pipe that its worker's helper inherited."""
    script = (f"import sys; sys.path.insert(0, {str(Path(__file__).parent)!r})\n"
              "from pcverify.harness.run import workers\nimport test_worker_hygiene as t\n"
              f"pool = workers.Pool(world='hygiene')\nprint(pool.run_one(t._start_child, ({str(tmp_path / 'c')!r},), "
              "60.0).kind)\npool.close()\n")
    t0 = time.monotonic()
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=100, check=False)
    assert done.stdout.strip() == "returned", done.stderr
    assert time.monotonic() - t0 < 60  # not the helper's 120 s
