"""Ctrl-C and SIGTERM during a study must stop it cleanly, and its workers must not outlive it.

A library block with a bare `except:` (FiPy has several) swallows KeyboardInterrupt, so while a study runs
SIGINT and SIGTERM also set INTERRUPTED, and the runner checks it after every finished cell: it stores that
cell, then stops.  A worker exits when the study's process is gone.  SIGTERM is handled for the whole life of
the command: from the command line module's first line (`exit_on_sigterm_at_start_up`: exit 143 at once), then
around every command (`sigterm_interrupts`: KeyboardInterrupt, so locks are released and files written whole or
not at all).  A process started with SIGINT ignored keeps ignoring Ctrl-C, but stops cleanly on SIGTERM.
"""

from __future__ import annotations

import contextlib
import os
import signal
import threading
import time
from collections.abc import Iterator

TERMINATED = 128 + signal.SIGTERM  # the exit code of a command stopped by SIGTERM

INTERRUPTED = threading.Event()
STUDY_PID = "PCVERIFY_STUDY_PID"
_RECEIVED: list[int] = []  # the signal that interrupted the study
_WATCHING: list[int] = []  # the study pid a worker's watchdog follows
_DEFERRING: list[bool] = []  # inside `deferred_interrupts`: a signal is remembered, raised at the block's end


def _interrupt(signum, frame):  # noqa: ARG001 - the signal-handler signature
    """Remember the signal and stop the main thread with KeyboardInterrupt (at the end of a deferring block)."""
    _RECEIVED.append(signum)
    INTERRUPTED.set()
    if not _DEFERRING:
        raise KeyboardInterrupt


@contextlib.contextmanager
def deferred_interrupts() -> Iterator[None]:
    """Within the block Ctrl-C and SIGTERM are only remembered, and KeyboardInterrupt is raised when it ends: for a
    fork, whose at-fork hooks (logging's lock release) would print the exception as a traceback and lose it.
    Blocking the signals is not enough: the kernel may deliver them to another thread of the process (tqdm's
    monitor), and Python then runs the handler in the main thread wherever it is."""
    before = len(_RECEIVED)
    _DEFERRING.append(True)
    try:
        yield
    finally:
        _DEFERRING.pop()
        if len(_RECEIVED) > before and not _DEFERRING:
            raise KeyboardInterrupt


def undeferred() -> None:
    """In a process forked inside `deferred_interrupts`: its signals raise at once again."""
    _DEFERRING.clear()


def _exit_at_start_up(signum, frame):  # noqa: ARG001 - the signal-handler signature
    os.write(2, b"pcverify: terminated (during start-up: nothing was written)\n")
    os._exit(TERMINATED)


def _exit_at_the_end(signum, frame):  # noqa: ARG001 - the signal-handler signature
    os.write(2, b"pcverify: terminated (after the command had ended: what it wrote is complete)\n")
    os._exit(TERMINATED)


def _ours(handler: object) -> bool:
    """Whether SIGTERM's current handler may be replaced: the default action, or one of this module's."""
    return handler in (signal.SIG_DFL, _interrupt, _exit_at_start_up, _exit_at_the_end)


def exit_on_sigterm_at_start_up() -> None:
    """Until a command runs: SIGTERM prints the one "terminated" line and exits 143 (the imports of the
    command line take seconds, and nothing has been written yet).  Only in the main thread, and only over
    the default action."""
    if threading.current_thread() is threading.main_thread() and _ours(signal.getsignal(signal.SIGTERM)):
        signal.signal(signal.SIGTERM, _exit_at_start_up)


@contextlib.contextmanager
def sigterm_interrupts() -> Iterator[None]:
    """Within the block (a whole command), SIGTERM raises KeyboardInterrupt and is remembered (`received`), so
    the command stops cleanly wherever it is: start-up, plugin imports, writing a report.  After it, in the
    command line's process, SIGTERM prints its line and exits 143 (not the silent default death).  A SIGTERM
    handler installed by someone else (a test runner) is left alone."""
    INTERRUPTED.clear()
    _RECEIVED.clear()
    if threading.current_thread() is not threading.main_thread() or not _ours(signal.getsignal(signal.SIGTERM)):
        yield
        return
    previous = signal.signal(signal.SIGTERM, _interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, _exit_at_the_end if previous in (_exit_at_start_up, _exit_at_the_end)
                      else previous)
        INTERRUPTED.clear()


@contextlib.contextmanager
def remember_sigint() -> Iterator[None]:
    """Within the block, SIGINT and SIGTERM raise KeyboardInterrupt and are remembered in INTERRUPTED.  SIGINT
    only where it has Python's default handler: ignored (a background job of sh) or handled by someone else (a
    test runner), it is left alone; SIGTERM still stops the study unless someone else handles it."""
    INTERRUPTED.clear()
    _RECEIVED.clear()
    os.environ[STUDY_PID] = str(os.getpid())  # inherited by the worker processes started from here on
    signals = []
    if threading.current_thread() is threading.main_thread():
        signals = [sig for sig, ours in ((signal.SIGINT, signal.getsignal(signal.SIGINT) is signal.default_int_handler),
                                         (signal.SIGTERM, _ours(signal.getsignal(signal.SIGTERM)))) if ours]
    previous = {sig: signal.signal(sig, _interrupt) for sig in signals}
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
