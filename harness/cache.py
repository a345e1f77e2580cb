"""Result cache: one JSON file per study cell, keyed by a content hash.

Writes are atomic (temporary file, fsync, rename), so an interrupted study never
leaves a half-written entry; an entry that fails to parse or whose stored key or
checksum does not match is reported as corrupt and recomputed.
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
from pathlib import Path
from typing import Any


def cell_key(payload: dict[str, Any]) -> str:
    """Stable content hash of a cell description (scene hash, solver, version, resolution, params)."""
    return hashlib.sha256(json.dumps(payload, sort_keys=True, default=str).encode()).hexdigest()[:20]


class CacheWriteError(OSError):
    """An entry could not be written (read-only or full folder): the entries written before are intact."""


class Cache:
    """A folder of `<key>.json` entries."""

    def __init__(self, root: str | os.PathLike) -> None:
        self.root = Path(root)

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
        return doc["result"], "hit"

    def store(self, key: str, result: dict[str, Any]) -> None:
        """Atomically write one entry; CacheWriteError (one line) if the folder refuses it."""
        body = json.dumps(result, sort_keys=True)
        doc = {"key": key, "sha256": hashlib.sha256(body.encode()).hexdigest(), "result": result}
        tmp = None
        try:
            self.root.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(dir=self.root, prefix=f".{key}.", suffix=".tmp")
            with os.fdopen(fd, "w") as fh:
                json.dump(doc, fh)
                fh.flush()
                os.fsync(fh.fileno())
            os.replace(tmp, self.path(key))
        except OSError as exc:
            _discard(tmp)
            raise CacheWriteError(f"cannot write cache entry {self.path(key)} ({exc.strerror or exc}); the entries "
                                  "written before are intact: free space or fix permissions, then rerun to resume"
                                  ) from exc
        except BaseException:
            _discard(tmp)
            raise


def _discard(tmp: str | None) -> None:
    """Remove a half-written temporary file (best effort: the folder may be the problem)."""
    if tmp is not None:
        try:
            os.unlink(tmp)
        except OSError:
            pass
