"""Files that several processes share: atomic writes, stray temporary files, and a lock between processes.

`atomic_write` writes to a temporary file in the same folder named for its writer (`.<name>.<pid>.<random>.tmp`),
flushes it and renames it over the target: readers see the old file or the new one, never a half, and a write
that fails leaves the target as it was.  `remove_stray_files` removes the temporary files of dead writers.
`parse_json` treats a document nested too deeply for the parser as invalid JSON, never a RecursionError.
`exclusive` serialises a short critical section between processes with flock(2), which the kernel releases
when its holder dies.  `safe_stem` makes any name (a plugin's solver name, say) a bounded file name.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import json
import os
import re
import socket
import tempfile
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import IO

HOST = socket.gethostname()
UNSAFE = re.compile(r"[^A-Za-z0-9_.+-]+")
STEM_LIMIT = 48  # characters of a name kept in a file name (a file name may have 255 bytes)


def safe_stem(name: str, limit: int = STEM_LIMIT) -> str:
    """`name` as a part of a file name: itself when it is short and only letters, digits and _ . + - (not
    starting with a dot); otherwise those characters of it (others become _), cut to `limit`, and a hash of the
    whole name, so two names never share a stem and no name becomes a path (no separator, no "..")."""
    text = str(name)
    if len(text) <= limit and not UNSAFE.search(text) and not text.startswith(".") and text:
        return text
    kept = UNSAFE.sub("_", text).lstrip(".")[:limit]
    return f"{kept}-{hashlib.sha256(text.encode('utf-8', 'surrogatepass')).hexdigest()[:10]}"


def process_alive(pid: int, host: str = HOST) -> bool:
    """Whether process `pid` on `host` may still run (a process on another host is assumed alive)."""
    if host != HOST:
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # exists, owned by someone else
        return True
    return True


def discard(path: str | os.PathLike | None) -> None:
    """Remove a file (best effort: the folder may be the problem)."""
    if path is not None:
        try:
            os.unlink(path)
        except OSError:
            pass


def atomic_write(path: Path, data: str | bytes | Callable[[IO[bytes]], None], fsync: bool = True) -> Path:
    """Write `data` (text, bytes, or a function that writes to a binary file object) to `path` atomically
    through a unique temporary file beside it.  On any failure the temporary file is removed and the error
    (an OSError names `path`) propagates; `path` is untouched."""
    tmp = None
    try:
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.{os.getpid()}.", suffix=".tmp")
        with os.fdopen(fd, "wb") as fh:
            if callable(data):
                data(fh)
            else:
                fh.write(data.encode() if isinstance(data, str) else data)
            fh.flush()
            if fsync:
                os.fsync(fh.fileno())
        os.chmod(tmp, 0o644)  # mkstemp makes it private; a report is for reading
        os.replace(tmp, path)
    except OSError as exc:
        discard(tmp)
        if exc.filename is None or exc.filename == tmp:
            raise OSError(exc.errno, exc.strerror or str(exc), str(path)) from exc
        raise
    except BaseException:
        discard(tmp)
        raise
    return path


def writer_pid(tmp: Path) -> int | None:
    """The pid in a temporary file's name `.<name>.<pid>.<random>.tmp` (None for another name)."""
    parts = tmp.name.split(".")
    return int(parts[-3]) if len(parts) >= 5 and parts[-3].isdigit() else None


def remove_stray_files(folder: Path, pattern: str = ".*.tmp") -> int:
    """Remove the temporary files in `folder` (matching `pattern`) whose writer has died, and those that do not
    name their writer (left by an older version); returns how many."""
    removed = 0
    for tmp in folder.glob(pattern):
        pid = writer_pid(tmp)
        if pid is None or not process_alive(pid):
            discard(tmp)
            removed += 1
    return removed


def parse_json(text: str | bytes) -> object:
    """`json.loads`, with a document nested too deeply for the parser refused as invalid (ValueError)."""
    try:
        return json.loads(text)
    except RecursionError:
        raise ValueError("nested too deeply to be read") from None


def read_json(path: Path) -> tuple[object, str]:
    """(document, "") or (None, why it cannot be read): a missing, unreadable, empty or invalid file."""
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        return None, f"cannot be read ({getattr(exc, 'strerror', None) or type(exc).__name__})"
    if not text.strip():
        return None, "is empty"
    try:
        return parse_json(text), ""
    except ValueError as exc:
        return None, f"is not valid JSON ({str(exc)[:80]})"


@contextlib.contextmanager
def exclusive(lock: Path, timeout: float = 600.0) -> Iterator[None]:
    """Hold the lock file `lock` (created if missing, never removed) for the block, waiting for another
    holder up to `timeout` seconds.  The holder's pid and host are written into it for whoever looks.
    A folder where no lock file can be made has nothing to share: the block runs unlocked."""
    try:
        fd = os.open(lock, os.O_CREAT | os.O_RDWR, 0o644)
    except OSError:
        yield
        return
    try:
        deadline = time.monotonic() + timeout
        while True:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                if time.monotonic() > deadline:
                    raise TimeoutError(f"{lock} is held by another process for more than {timeout:g} s "
                                       f"({_holder(fd)})") from None
                time.sleep(0.02)
        with contextlib.suppress(OSError):
            os.ftruncate(fd, 0)
            os.pwrite(fd, json.dumps({"pid": os.getpid(), "host": HOST}).encode(), 0)
        yield
    finally:
        os.close(fd)  # releases the flock


def _holder(fd: int) -> str:
    try:
        return os.pread(fd, 200, 0).decode(errors="replace") or "holder unknown"
    except OSError:
        return "holder unknown"
