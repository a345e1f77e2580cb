"""Result cache: one JSON file per study cell, keyed by a content hash, shared safely between processes.

Writes are atomic (a temporary file named for its writer, fsync, rename), so an interrupted study never
leaves a half-written entry, and temporary files whose writer has died are removed.  An entry that fails
to parse, whose stored key or checksum does not match, or whose result lacks the fields every result
has, is reported as corrupt and recomputed.  A cell being computed holds a lock file (`<key>.lock`, its
holder's pid and host): another process running the same cell waits for the entry instead of computing
it twice, and a lock whose holder has died on this host is taken over.  Takeovers are decided one at a time
under the folder's `.takeover.guard`, so two processes that both found a dead holder cannot both remove a lock
(the second would remove the first's new one) and both compute the cell.
"""

from __future__ import annotations

import hashlib
import json
import os
import time
from pathlib import Path
from typing import Any

from pcverify.harness.files import HOST, atomic_write, discard, exclusive, process_alive, remove_stray_files
from pcverify.solvers.protocol import STATUSES

# the fields every cell result has (identity and status), with their types: an entry without them is corrupt
RESULT_FIELDS: dict[str, type | tuple[type, ...]] = {"status": str, "group": str, "scene": str, "solver": str,
                                                    "n": int, "refine": int}


def cell_key(payload: dict[str, Any]) -> str:
    """Stable content hash of a cell description (scene hash, solver, code fingerprint, resolution, params)."""
    return hashlib.sha256(json.dumps(payload, sort_keys=True, default=str).encode()).hexdigest()[:20]


def schema_problem(result: Any) -> str:
    """Why `result` is not a cell result ("" if it is one)."""
    if not isinstance(result, dict):
        return f"result is a {type(result).__name__}, not a table"
    for name, kind in RESULT_FIELDS.items():
        if name not in result:
            return f"result has no {name}"
        if not isinstance(result[name], kind) or isinstance(result[name], bool):
            return f"result {name} is a {type(result[name]).__name__}"
    if result["status"] not in STATUSES:
        return f"result status {result['status']!r} is not one of {', '.join(STATUSES)}"
    return ""


class CacheWriteError(OSError):
    """An entry could not be written (read-only or full folder): the entries written before are intact."""


class Cache:
    """A folder of `<key>.json` entries and the `<key>.lock` files of cells being computed."""

    def __init__(self, root: str | os.PathLike) -> None:
        self.root = Path(root)
        self.locks: set[str] = set()  # keys this process holds

    def path(self, key: str) -> Path:
        return self.root / f"{key}.json"

    def load(self, key: str) -> tuple[dict[str, Any] | None, str]:
        """(entry, state) with state 'hit', 'miss' or 'corrupt: <why>'."""
        path = self.path(key)
        if not path.exists():
            return None, "miss"
        try:
            doc = json.loads(path.read_text())
            body = json.dumps(doc["result"], sort_keys=True)
            if doc.get("key") != key:
                return None, "corrupt: stored key does not match"
            if doc.get("sha256") != hashlib.sha256(body.encode()).hexdigest():
                return None, "corrupt: checksum mismatch"
        except (OSError, ValueError, KeyError, TypeError) as exc:
            return None, f"corrupt: {type(exc).__name__}"
        problem = schema_problem(doc["result"])
        if problem:
            return None, f"corrupt: {problem}"
        return doc["result"], "hit"

    def store(self, key: str, result: dict[str, Any]) -> None:
        """Atomically write one entry; CacheWriteError (one line) if the folder refuses it."""
        body = json.dumps(result, sort_keys=True)
        doc = {"key": key, "sha256": hashlib.sha256(body.encode()).hexdigest(), "result": result}
        try:
            self.root.mkdir(parents=True, exist_ok=True)
            atomic_write(self.path(key), json.dumps(doc))
        except OSError as exc:
            raise CacheWriteError(f"cannot write cache entry {self.path(key)} ({exc.strerror or exc}); the entries "
                                  "written before are intact: free space or fix permissions, then rerun to resume"
                                  ) from exc

    # -- locks: one process computes a cell, the others wait for its entry

    def _lock_path(self, key: str) -> Path:
        return self.root / f"{key}.lock"

    def holder(self, key: str) -> tuple[int, str] | None:
        """(pid, host) of the live process that holds `key`'s lock, or None (no lock, or its holder died)."""
        try:
            doc = json.loads(self._lock_path(key).read_text())
            pid, host = int(doc["pid"]), str(doc["host"])
        except FileNotFoundError:
            return None
        except (OSError, ValueError, KeyError, TypeError):
            return (0, "?") if self._young(key) else None  # being written right now, or garbage left behind
        return (pid, host) if process_alive(pid, host) else None

    def _young(self, key: str, seconds: float = 10.0) -> bool:
        try:
            return time.time() - self._lock_path(key).stat().st_mtime < seconds
        except OSError:
            return False

    def try_lock(self, key: str) -> bool:
        """Take `key`'s lock (True), or find it held by a live process (False).  A dead holder's lock is
        taken over.  Without a writable folder there is nothing to share: True."""
        if key in self.locks:
            return True
        path = self._lock_path(key)
        for _ in range(2):
            try:
                self.root.mkdir(parents=True, exist_ok=True)
                fd = os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
            except FileExistsError:
                if self.holder(key) is not None:
                    return False
                self._remove_if_dead(key)
                continue
            except OSError:
                return True
            with os.fdopen(fd, "w") as fh:
                json.dump({"pid": os.getpid(), "host": HOST, "since": time.time()}, fh)
            self.locks.add(key)
            return True
        return False

    def _remove_if_dead(self, key: str) -> None:
        """Remove `key`'s lock if its holder has died, deciding again under the takeover guard: the dead
        holder seen before may have been replaced by a live one since."""
        with exclusive(self.root / ".takeover.guard", timeout=60.0):
            if self._lock_path(key).exists() and self.holder(key) is None:
                discard(str(self._lock_path(key)))

    def unlock(self, key: str) -> None:
        if key in self.locks:
            self.locks.discard(key)
            discard(str(self._lock_path(key)))

    def unlock_all(self) -> None:
        for key in list(self.locks):
            self.unlock(key)

    def remove_stray_files(self) -> int:
        """Remove temporary files whose writer has died (a write interrupted by a kill); returns how many."""
        return remove_stray_files(self.root)
