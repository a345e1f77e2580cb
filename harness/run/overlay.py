"""A mutant's process: one module of a package replaced by an edited copy, the rest of the package as it is.

The process that runs a study on a mutant loads this file by its path, before anything of pcverify is imported
(so it imports nothing of pcverify at its top), and calls `main`.  A finder first on `sys.meta_path` maps the
mutated module's name to the edited copy, so that Python, forked workers, the code fingerprint and numba's
guarded cache all see the mutant.  It imports the mutated module first (one that does not import is `invalid`),
then runs command lines in this process; the outcome is a JSON file for the process that started this one.
"""

from __future__ import annotations

import contextlib
import importlib
import importlib.machinery
import importlib.util
import io
import json
import os
import sys
import threading
import time
from importlib.machinery import ModuleSpec
from typing import Any

INVALID_EXIT = 3  # the mutated module does not import
PARENT_POLL_S = 1.0


class OverlayLoader(importlib.machinery.SourceFileLoader):
    """Loads the edited copy; resources of a package are read from its original folder."""

    def __init__(self, fullname: str, path: str, original: str) -> None:
        super().__init__(fullname, path)
        self.original = original

    def get_resource_reader(self, fullname: str) -> Any:
        return importlib.machinery.SourceFileLoader(fullname, self.original).get_resource_reader(fullname)


class OverlayFinder:
    """A meta-path finder of one module: `module` is loaded from `source` instead of `original`."""

    def __init__(self, module: str, source: str, original: str) -> None:
        self.module, self.source, self.original = module, source, original

    def find_spec(self, fullname: str, path: Any = None, target: Any = None) -> ModuleSpec | None:
        if fullname != self.module:
            return None
        package = os.path.basename(self.original) == "__init__.py"
        return importlib.util.spec_from_file_location(
            fullname, self.source, loader=OverlayLoader(fullname, self.source, self.original),
            submodule_search_locations=[os.path.dirname(self.original)] if package else None)


def install(module: str, source: str, original: str) -> OverlayFinder:
    """Put the overlay of `module` first on sys.meta_path (before it is imported anywhere in this process)."""
    if module in sys.modules:
        raise RuntimeError(f"module {module} was imported before its overlay was installed")
    finder = OverlayFinder(module, source, original)
    sys.meta_path.insert(0, finder)
    return finder


def _describe(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def _die_with(parent: int) -> None:
    """End this process (and, through their own watchdogs, its workers) when the process that started it is
    gone, instead of computing on for nobody."""
    def watch() -> None:
        while True:
            time.sleep(PARENT_POLL_S)
            if os.getppid() != parent:
                os._exit(1)

    threading.Thread(target=watch, daemon=True, name="pcverify-mutant-watchdog").start()


def _command(main: Any, argv: list[str]) -> tuple[int, Any]:
    """(exit code, the JSON it printed or None) of one command run in this process."""
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        try:
            code = main(argv)
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else 1
    try:
        return code, json.loads(out.getvalue())
    except ValueError:
        return code, None


def main(argv: list[str]) -> int:
    """The mutant's process: argv[0] is a JSON file with `module`, `source`, `original`, `sys_path`, `parent`,
    `outcome` (where the outcome is written) and `commands` (command lines run in turn while each exits 0).
    The outcome: `invalid` (why the mutated module does not import) or `results`, per command run its `exit`
    code and the `json` it printed."""
    with open(argv[0], encoding="utf-8") as f:
        job = json.load(f)
    sys.path[:] = job["sys_path"]
    _die_with(job["parent"])
    install(job["module"], job["source"], job["original"])
    outcome: dict[str, Any] = {}
    try:
        importlib.import_module(job["module"])
    except BaseException as exc:  # noqa: BLE001 - whatever the mutated module raises on import makes it invalid
        outcome = {"invalid": f"{job['module']} does not import: {_describe(exc)}"}
    if not outcome:
        cli = importlib.import_module("pcverify.harness.cli")
        outcome["results"] = results = []
        for command in job["commands"]:
            code, printed = _command(cli.main, command)
            results.append({"exit": code, "json": printed})
            if code != 0:
                break
    with open(job["outcome"], "w", encoding="utf-8") as f:
        json.dump(outcome, f)
    return INVALID_EXIT if "invalid" in outcome else int(outcome["results"][-1]["exit"] or 0)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
