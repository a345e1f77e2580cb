"""Ctrl-C and SIGTERM during a study must stop it cleanly, and its workers must not outlive it.

Python raises KeyboardInterrupt wherever the main thread happens to be; inside a library block with a
bare `except:` (FiPy evaluates its variables under several) the exception is swallowed and the study
would run on to the end.  While a study runs, SIGINT and SIGTERM therefore also set INTERRUPTED (and
remember which signal came), and the runner checks it after every finished cell: it stores that cell,
then stops with KeyboardInterrupt.  A worker process watches the study's process and exits when it is
gone (killed with SIGKILL, say), instead of computing on for minutes.
"""

from __future__ import annotations

import contextlib
import os
import signal
import threading
import time
from collections.abc import Iterator

INTERRUPTED = threading.Event()
STUDY_PID = "PCVERIFY_STUDY_PID"
_RECEIVED: list[int] = []  # the signal that interrupted the study
_WATCHING: list[int] = []  # the study pid a worker's watchdog follows


@contextlib.contextmanager
def remember_sigint() -> Iterator[None]:
    """Within the block, SIGINT and SIGTERM raise KeyboardInterrupt and are remembered in INTERRUPTED."""
    INTERRUPTED.clear()
    _RECEIVED.clear()
    os.environ[STUDY_PID] = str(os.getpid())  # inherited by the worker processes started from here on
    if threading.current_thread() is not threading.main_thread() or \
            signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
        try:
            yield  # SIGINT ignored or handled by someone else (e.g. a test runner): leave it alone
        finally:
            INTERRUPTED.clear()
        return

    def handler(signum, frame):  # noqa: ARG001 - the signal-handler signature
        _RECEIVED.append(signum)
        INTERRUPTED.set()
        raise KeyboardInterrupt

    previous = {sig: signal.signal(sig, handler) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)
        INTERRUPTED.clear()  # the interrupt is handled by whoever catches it; later studies start clean


def received() -> int:
    """The signal that stopped the study (SIGINT if none was recorded: a plain KeyboardInterrupt)."""
    return _RECEIVED[-1] if _RECEIVED else signal.SIGINT


def check_interrupted() -> None:
    """Raise KeyboardInterrupt if a SIGINT or SIGTERM arrived (even one a library swallowed)."""
    if INTERRUPTED.is_set():
        raise KeyboardInterrupt


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _watch(pid: int, period: float) -> None:
    parent = os.getppid()
    # the study is gone when it no longer exists, or when this worker has been handed to another parent
    # (a killed study is a zombie until its own parent reaps it, but its children are re-parented at once)
    while _alive(pid) and os.getppid() == parent:
        time.sleep(period)
    os._exit(1)  # nobody will read this worker's result


def ignore_sigint_in_worker(period: float = 1.0) -> None:
    """In a worker process of a study: leave Ctrl-C to the study's own process, which stops the study and
    its workers (an interrupted worker would only print a traceback on the shared terminal), and exit
    when the study's process has died.  No-op in the study's process and in threads."""
    parent = os.environ.get(STUDY_PID)
    if not parent or parent == str(os.getpid()) or threading.current_thread() is not threading.main_thread():
        return
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if not _WATCHING:
        _WATCHING.append(int(parent))
        threading.Thread(target=_watch, args=(int(parent), period), daemon=True, name="pcverify-watchdog").start()
