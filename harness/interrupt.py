"""Ctrl-C during a study must not be lost.

Python raises KeyboardInterrupt wherever the main thread happens to be; inside a library block with a
bare `except:` (FiPy evaluates its variables under several) the exception is swallowed and the study
would run on to the end.  While a study runs, SIGINT therefore also sets INTERRUPTED, and the runner
checks it after every finished cell: it stores that cell, then stops with KeyboardInterrupt.
"""

from __future__ import annotations

import contextlib
import os
import signal
import threading
from collections.abc import Iterator

INTERRUPTED = threading.Event()
STUDY_PID = "PCVERIFY_STUDY_PID"


@contextlib.contextmanager
def remember_sigint() -> Iterator[None]:
    """Within the block, SIGINT raises KeyboardInterrupt as usual and is also remembered in INTERRUPTED."""
    INTERRUPTED.clear()
    os.environ[STUDY_PID] = str(os.getpid())  # inherited by the worker processes started from here on
    if threading.current_thread() is not threading.main_thread() or \
            signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
        try:
            yield  # SIGINT ignored or handled by someone else (e.g. a test runner): leave it alone
        finally:
            INTERRUPTED.clear()
        return

    def handler(signum, frame):  # noqa: ARG001 - the signal-handler signature
        INTERRUPTED.set()
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGINT, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        INTERRUPTED.clear()  # the interrupt is handled by whoever catches it; later studies start clean


def check_interrupted() -> None:
    """Raise KeyboardInterrupt if a SIGINT arrived (even one a library swallowed)."""
    if INTERRUPTED.is_set():
        raise KeyboardInterrupt


def ignore_sigint_in_worker() -> None:
    """In a worker process of a study: leave Ctrl-C to the study's own process, which stops the study and
    its workers.  An interrupted worker would only print a traceback on the shared terminal (e.g. from
    numba's object-cache callback, seen in the tests).  No-op in the study's process and in threads."""
    parent = os.environ.get(STUDY_PID)
    if parent and parent != str(os.getpid()) and threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
