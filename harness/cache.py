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
        """Atomically write one entry."""
        self.root.mkdir(parents=True, exist_ok=True)
        body = json.dumps(result, sort_keys=True)
        doc = {"key": key, "sha256": hashlib.sha256(body.encode()).hexdigest(), "result": result}
        fd, tmp = tempfile.mkstemp(dir=self.root, prefix=f".{key}.", suffix=".tmp")
        try:
            with os.fdopen(fd, "w") as fh:
                json.dump(doc, fh)
                fh.flush()
                os.fsync(fh.fileno())
            os.replace(tmp, self.path(key))
        except BaseException:
            if os.path.exists(tmp):
                os.unlink(tmp)
            raise
