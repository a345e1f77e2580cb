"""Progress on stderr, on a terminal only: where stderr is a pipe or a log, a display that redraws itself could
not be erased and would stand in front of the one-line error or the result that follows."""

from __future__ import annotations

import contextlib
import sys
import threading
from collections.abc import Iterator
from typing import Any

from tqdm import tqdm


def on_terminal(stream: Any) -> bool:
    """Whether `stream` is a terminal (a closed or replaced stream is not)."""
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError, OSError):
        return False


@contextlib.contextmanager
def working(label: str, enabled: bool = True) -> Iterator[None]:
    """An elapsed-time indicator on stderr for a solve that runs in one call (shown after 2 s), on a terminal
    only."""
    bar = tqdm(total=None, desc=label, bar_format="{desc}: {elapsed} elapsed", delay=2.0,
               disable=not (enabled and on_terminal(sys.stderr)), leave=False)
    done = threading.Event()

    def tick() -> None:
        waited = 0.0
        while not done.wait(0.5):
            waited += 0.5
            if waited >= 2.0:
                bar.refresh()

    thread = threading.Thread(target=tick, daemon=True)
    thread.start()
    try:
        yield
    finally:
        done.set()
        thread.join()
        bar.close()
