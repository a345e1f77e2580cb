"""Result cache: one JSON file per study cell, keyed by a content hash, shared safely between processes.

Writes are atomic, so an interrupted study never leaves a half-written entry; an entry that fails to parse or
whose key, checksum or fields do not match is reported as corrupt and recomputed, and one whose solve read a file
or imported a module that has changed since (`dependencies`) is stale and recomputed.  A cell being computed holds
a lock file that other processes wait on, taken over when its holder died or after STALE_LOCK_S (docs/outputs.md,
"The cache"), one takeover at a time under the folder's `.takeover.guard`.  Every caller follows one protocol:
`claim` a cell, `release` it with its entry, or `wait` for its holder's.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from tqdm import tqdm

from pcverify.harness.run.dependencies import stale
from pcverify.harness.run.files import (
    HOST,
    atomic_write,
    discard,
    exclusive,
    parse_json,
    process_alive,
    remove_stray_files,
)
from pcverify.scene import SceneError
from pcverify.solvers.protocol import STATUSES

CELL_TIME_LIMIT_S = 3600.0  # the default time limit of one cell
STALE_LOCK_S = 2 * CELL_TIME_LIMIT_S  # a lock older than this is taken over, whoever it names
WAIT_FIRST_NOTICE_S = 10.0  # a wait this long is said (a shorter one is another process finishing the cell)
WAIT_NOTICE_S = 60.0  # then again this often

# the fields every cell result has (identity and status), with their types: an entry without them is corrupt
CLAIMED, HELD = "claimed", "held"  # what `Cache.claim` answers when it does not give an entry back

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


def folder_problem(root: Path) -> str:
    """Why `root` cannot be the cache folder ("" if it is one, or can be made): it, or a folder above it, is a
    file, or it cannot be examined."""
    for path in (root, *root.parents):
        try:
            if path.is_dir():
                return ""
            if path.exists():
                return "it is a file" if path == root else f"{path}, a folder above it, is a file"
        except OSError as exc:  # a name too long, a loop of symlinks
            return f"it cannot be examined ({exc.strerror or type(exc).__name__})"
    return ""


def _age(seconds: float) -> str:
    """A duration for people: 45 s, 12 min, 3.0 h, 7.0 days."""
    if seconds < 120:
        return f"{seconds:.0f} s"
    if seconds < 7200:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h" if seconds < 172800 else f"{seconds / 86400:.1f} days"


class Cache:
    """A folder of `<key>.json` entries and the `<key>.lock` files of cells being computed."""

    def __init__(self, root: str | os.PathLike) -> None:
        """A cache in the folder `root` (made when the first entry is stored); SceneError (one line) if `root`
        or a folder above it is a file."""
        self.root = Path(root)
        problem = folder_problem(self.root)
        if problem:
            raise SceneError(f"cache folder {self.root} cannot be used: {problem}; allowed: a folder, or a path where "
                             "one can be made (--cache DIR; default OUT/cache)")
        self.locks: set[str] = set()  # keys this process holds
        self.stale_after = STALE_LOCK_S  # raised by a study whose cell time limit is longer than the default
        self._told: dict[str, float] = {}  # when this process next says it waits for a key's lock

    def path(self, key: str) -> Path:
        return self.root / f"{key}.json"

    def load(self, key: str) -> tuple[dict[str, Any] | None, str]:
        """(entry, state) with state 'hit', 'miss' or 'corrupt: <why>'."""
        path = self.path(key)
        if not path.exists():
            return None, "miss"
        try:
            text = path.read_text()
        except (OSError, UnicodeDecodeError) as exc:
            return None, f"corrupt: {type(exc).__name__}"
        try:
            doc = parse_json(text)
        except ValueError as exc:
            return None, f"corrupt: not valid JSON ({' '.join(str(exc).split())[:80]})"
        try:
            body = json.dumps(doc["result"], sort_keys=True)
            if doc.get("key") != key:
                return None, "corrupt: stored key does not match"
            if doc.get("sha256") != hashlib.sha256(body.encode()).hexdigest():
                return None, "corrupt: checksum mismatch"
        except (OSError, ValueError, KeyError, TypeError, RecursionError) as exc:
            return None, f"corrupt: {type(exc).__name__}"
        problem = schema_problem(doc["result"])
        if problem:
            return None, f"corrupt: {problem}"
        why = stale(doc["result"].get("depends"))
        if why:
            return None, f"stale: {why}"
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

    def lock_state(self, key: str) -> tuple[str, dict[str, Any]]:
        """(state, lock) of `key`'s lock: state 'free' (no lock), 'held' (by a live process, or being written
        right now), 'dead' (its holder died on this host), 'stale' (older than `stale_after`, whatever it
        names) or 'garbage' (unreadable, and not being written: left behind); lock holds `pid`, `host` and
        `age` (seconds) where known."""
        path = self._lock_path(key)
        try:
            text = path.read_text()
            written = path.stat().st_mtime
        except FileNotFoundError:
            return "free", {}
        except OSError:
            text, written = "", self._mtime(path)
        now = time.time()
        try:
            doc = parse_json(text)
            pid, host = int(doc["pid"]), str(doc["host"])
            since = float(doc.get("since", written))
            if not 0 < pid < 2**31:
                raise ValueError("not a process id")
        except (ValueError, KeyError, TypeError, AttributeError, OverflowError):
            return ("held" if now - written < 10.0 else "garbage"), {"age": now - written}
        # a `since` in the future (or not a number) does not keep a lock young
        age = max(now - since if math.isfinite(since) else 0.0, now - written)
        lock = {"pid": pid, "host": host, "age": age}
        if host == HOST and not process_alive(pid, host):
            return "dead", lock
        return ("stale" if age > self.stale_after else "held"), lock

    @staticmethod
    def _mtime(path: Path) -> float:
        try:
            return path.stat().st_mtime
        except OSError:
            return 0.0

    def holder(self, key: str) -> tuple[int, str] | None:
        """(pid, host) of the live process that holds `key`'s lock ((0, "?") for a lock being written), or None:
        no lock, or one that may be taken over (its holder died, it is stale, or it is garbage)."""
        state, lock = self.lock_state(key)
        if state != "held":
            return None
        return lock.get("pid", 0), lock.get("host", "?")

    def describe_lock(self, key: str) -> str:
        """The lock of `key` in words: file, holder (pid, host) and age, and when it would be taken over."""
        state, lock = self.lock_state(key)
        if state == "free":
            return f"cell lock {self._lock_path(key)} is free"
        who = f"pid {lock['pid']} on host {lock['host']}" if "pid" in lock else "a holder not named in it"
        when = "when its holder dies, or " if lock.get("host") == HOST else ""
        return (f"cell lock {self._lock_path(key)} is held by {who} for {_age(lock['age'])} (taken over {when}once "
                f"it is older than {_age(self.stale_after)}: twice the cell time limit)")

    def tell_waiting(self, key: str) -> None:
        """Called while this process waits for `key`'s lock: once the wait has lasted WAIT_FIRST_NOTICE_S, say on
        stderr which lock, whose and how old, and again every WAIT_NOTICE_S."""
        now = time.monotonic()
        next_notice = self._told.setdefault(key, now + WAIT_FIRST_NOTICE_S)
        if now >= next_notice:
            self._told[key] = now + WAIT_NOTICE_S
            tqdm.write(f"pcverify: waiting for another process: {self.describe_lock(key)}", file=sys.stderr)

    def try_lock(self, key: str) -> bool:
        """Take `key`'s lock (True), or find it held by a live process (False).  A dead holder's, a stale or a
        garbage lock is taken over (a stale one with a warning); one that cannot be removed is CacheWriteError.
        Without a writable folder there is nothing to share: True."""
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
            self.locks.add(key)  # before writing it: an interrupt from here on still removes it
            with os.fdopen(fd, "w") as fh:
                json.dump({"pid": os.getpid(), "host": HOST, "since": time.time()}, fh)
            return True
        if self.holder(key) is None:
            raise CacheWriteError(f"cannot take over cell lock {path} (it is not held by a live process, and it "
                                  "cannot be removed): remove it by hand, then rerun")
        return False

    def _remove_if_dead(self, key: str) -> None:
        """Remove `key`'s lock if it may be taken over, deciding again under the takeover guard: the dead or
        stale holder seen before may have been replaced by a live one since."""
        with exclusive(self.root / ".takeover.guard", timeout=60.0):
            state, lock = self.lock_state(key)
            if state in ("dead", "stale", "garbage"):
                if state == "stale":
                    tqdm.write(f"pcverify: warning: cell lock {self._lock_path(key)} of pid {lock['pid']} on host "
                               f"{lock['host']} is {_age(lock['age'])} old, older than {_age(self.stale_after)} (twice "
                               "the cell time limit): stale, taken over", file=sys.stderr)
                discard(str(self._lock_path(key)))

    # -- the protocol every caller follows: claim, compute and release; or wait for the holder's entry

    def claim(self, key: str, reuse: bool = True) -> dict[str, Any] | str:
        """Claim `key` to compute it: CLAIMED (this process holds its lock now), HELD (a live process holds it:
        `wait` for its entry), or the entry itself when, `reuse` allowing, it was stored since it was looked up
        (read again once the lock is taken, then released: a cell is never computed twice)."""
        if not self.try_lock(key):
            return HELD
        if reuse and (entry := self.load(key)[0]) is not None:
            self.unlock(key)
            return entry
        return CLAIMED

    def release(self, key: str, result: dict[str, Any]) -> None:
        """Store the entry of a claimed `key`, then give up its lock."""
        self.store(key, result)
        self.unlock(key)

    def wait(self, key: str, poll: float = 0.5, between: Callable[[], None] = lambda: None
             ) -> dict[str, Any] | None:
        """The entry of `key` once its holder stores it; None if the holder let go without storing it (it died
        or failed): this process then holds the claim and computes it.  `between` runs between polls (the
        caller's interrupt check); a wait that lasts is said on stderr (`tell_waiting`)."""
        while True:
            entry, _ = self.load(key)
            if entry is not None:
                return entry
            if self.holder(key) is None:
                entry, _ = self.load(key)  # stored just before the lock went
                if entry is None:
                    claim = self.claim(key)  # a process that took the lock and let it go may have stored it
                    if claim == CLAIMED:
                        return None
                    entry = claim if isinstance(claim, dict) else None
                if entry is not None:
                    return entry
            between()
            self.tell_waiting(key)  # which lock, its holder and its age, once a minute
            time.sleep(poll)

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
