"""The worker pool's process hygiene: a stop signal never lands inside a fork, and a worker takes its own
signal dispositions (the study's Ctrl-C and SIGTERM stay blocked only for the duration of the fork).

A SIGTERM that arrived while the study's process was forking a worker ran the study's handler inside
logging's at-fork hook, which printed a KeyboardInterrupt traceback and swallowed it (the study then went
on to finish the cell before it stopped).  These tests pin the mechanism that rules that out.
"""

from __future__ import annotations

import os
import signal
import time

import pytest

from pcverify.harness.run import workers
from pcverify.harness.run.interrupt import deferred_interrupts, received, remember_sigint


def _mask() -> set[int]:
    return set(signal.pthread_sigmask(signal.SIG_BLOCK, []))


def test_stop_signals_are_blocked_during_the_fork_and_restored_after(monkeypatch) -> None:
    seen: list[set[int]] = []
    start = workers._FORK.Process.start

    def watched_start(self) -> None:
        seen.append(_mask())
        start(self)

    monkeypatch.setattr(workers._FORK.Process, "start", watched_start)
    before = _mask()
    pool = workers.Pool(world="test")
    try:
        outcome = pool.run_one(_mask, (), time_limit=60.0)
    finally:
        pool.close()
    assert seen and {signal.SIGINT, signal.SIGTERM} <= seen[0]
    assert _mask() == before  # the study's process gets its signals again at once
    assert outcome.kind == "returned"
    assert signal.SIGTERM not in outcome.value and signal.SIGINT not in outcome.value  # the worker's are unblocked


def test_a_worker_dies_by_sigterm_and_the_pool_names_it() -> None:
    """SIGTERM reaches a worker (its mask unblocked, its disposition the default): the task's outcome says so."""
    pool = workers.Pool(world="test")
    try:
        outcome = pool.run_one(signal.raise_signal, (signal.SIGTERM,), time_limit=60.0)
    finally:
        pool.close()
    assert outcome.kind == "died" and "killed by signal 15, SIGTERM" in outcome.reason


def test_a_signal_inside_a_deferring_block_is_raised_when_the_block_ends() -> None:
    """A fork's at-fork hooks run inside `deferred_interrupts`: a SIGTERM there (delivered to any thread) must not
    raise inside them, where Python prints the exception as a traceback and loses it; it stops the study right
    after.  Outside the block the same signal raises at once."""
    with remember_sigint():
        reached = False
        with pytest.raises(KeyboardInterrupt):
            with deferred_interrupts():
                os.kill(os.getpid(), signal.SIGTERM)
                time.sleep(0.2)  # the handler has run by now
                reached = True
        assert reached and received() == signal.SIGTERM
        with pytest.raises(KeyboardInterrupt):
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(5)
