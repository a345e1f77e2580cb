"""Progress on stderr: a tqdm bar on a terminal, plain lines anywhere else (a log keeps every frame of a bar):
a line when the work starts, one per tenth of it ("k/N cells") and one when it ends; a solve in one call says
every minute that it still runs.  Notes printed with `tqdm.write` go above a bar, or as plain lines.
"""

from __future__ import annotations

import contextlib
import sys
import threading
import time
from collections.abc import Iterator
from typing import Any

from tqdm import tqdm

STEPS = 10  # lines per run off a terminal: one per tenth of the work to do
STILL_RUNNING_S = 60.0  # off a terminal, a solve in one call says it is still running this often


def on_terminal(stream: Any) -> bool:
    """Whether `stream` is a terminal (a closed or replaced stream is not)."""
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError, OSError):
        return False


class ProgressLines:
    """Progress as plain lines on stderr, with the part of tqdm's interface the harness uses (`update`,
    `set_postfix`, `set_description`, `close`).  `desc` labels every line; the description a bar shows of the
    item in hand is not printed (the lines follow the count)."""

    def __init__(self, total: int, desc: str, unit: str, initial: int = 0) -> None:
        self.total, self.label, self.unit = total, desc, unit
        self.start, self.n = initial, initial
        self.postfix: dict[str, Any] = {}
        self.step = 0  # tenths of the work to do reported so far
        self.t0 = time.monotonic()
        self.closed = False
        if self.n < self.total:  # nothing to do: the line `close` prints is the only one
            self._line("")

    def update(self, n: int = 1) -> None:
        self.n += n
        todo = self.total - self.start
        step = STEPS * (self.n - self.start) // todo if todo > 0 else STEPS
        if step > self.step and self.n < self.total:  # the last line is the one `close` prints
            self.step = step
            self._line("")

    def set_postfix(self, ordered_dict: dict[str, Any] | None = None, refresh: bool = True, **values: Any) -> None:
        """The counts the next line shows, given as tqdm takes them (a mapping, keywords or both)."""
        self.postfix = {**(ordered_dict or {}), **values}

    def set_description(self, text: str) -> None:
        """Ignored: the item in hand, which a bar shows, is no line of its own."""

    def close(self) -> None:
        if self.closed:
            return
        self.closed = True
        self._line(f", {'finished' if self.n >= self.total else 'stopped'} after {time.monotonic() - self.t0:.1f} s")

    def _line(self, tail: str) -> None:
        counts = ", ".join(f"{k} {v}" for k, v in self.postfix.items())
        print(f"{self.label}: {self.n}/{self.total} {self.unit}s" + (f" ({counts})" if counts else "") + tail,
              file=sys.stderr, flush=True)


def progress_bar(total: int, desc: str, unit: str, initial: int = 0, enabled: bool = True) -> Any:
    """A progress display of `total` items (`initial` done already): a tqdm bar on a terminal, `ProgressLines`
    elsewhere, nothing unless `enabled`."""
    if enabled and not on_terminal(sys.stderr):
        return ProgressLines(total, desc, unit, initial)
    return tqdm(total=total, initial=initial, desc=desc, unit=unit, disable=not enabled, dynamic_ncols=True)


@contextlib.contextmanager
def working(label: str, enabled: bool = True) -> Iterator[None]:
    """While a solve runs in one call: on a terminal, the elapsed time (shown after 2 s, erased at the end);
    elsewhere a line each STILL_RUNNING_S that it is still running, never a line that could not be erased and
    would stand in front of the one-line error or the result that follows."""
    terminal = on_terminal(sys.stderr)
    bar = tqdm(total=None, desc=label, bar_format="{desc}: {elapsed} elapsed", delay=2.0,
               disable=not (enabled and terminal), leave=False)
    done = threading.Event()
    t0 = time.monotonic()

    def tick() -> None:
        said = 0
        while not done.wait(0.5):
            waited = time.monotonic() - t0
            if waited >= 2.0:
                bar.refresh()
            if enabled and not terminal and waited >= (said + 1) * STILL_RUNNING_S:
                said += 1
                print(f"{label}: still running after {said * STILL_RUNNING_S:g} s", file=sys.stderr, flush=True)

    thread = threading.Thread(target=tick, daemon=True)
    thread.start()
    try:
        yield
    finally:
        done.set()
        thread.join()
        bar.close()
