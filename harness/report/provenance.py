"""Provenance of a report: what produced its numbers (versions of pcverify, of its plugins and of the
numerical packages, the git commit, the machine, and the command of each study)."""

from __future__ import annotations

import datetime as dt
import platform
import shlex
import subprocess
import sys
from importlib import metadata
from pathlib import Path
from typing import Any

PACKAGES = ("numpy", "scipy", "numba", "fipy", "scikit-fem", "pyamg", "pandas", "matplotlib")
PLUGIN_GROUPS = ("pcverify.solvers", "pcverify.scenes")


def command() -> str:
    """The command line of this process, as a user would type it (`python -m pcverify.harness.cli` is the
    `pcverify` command)."""
    program = Path(sys.argv[0]).name
    return shlex.join(["pcverify" if program in ("pcverify", "cli.py") else program, *sys.argv[1:]])


def plugin_distributions() -> dict[str, str]:
    """Installed distributions that register pcverify solvers or scenes: name -> version."""
    out = {}
    for group in PLUGIN_GROUPS:
        for ep in metadata.entry_points(group=group):
            if ep.dist is not None:
                out[ep.dist.name] = ep.dist.version
    return dict(sorted(out.items()))


def _version(package: str) -> str:
    try:
        return metadata.version(package)
    except metadata.PackageNotFoundError:
        return "absent"


def source_commit() -> str:
    """The git commit of the checkout this pcverify runs from (not of the working folder), with "+modified"
    when tracked files differ from it; "unknown" for an installed wheel or without git."""
    source = Path(__file__).resolve().parents[1]

    def git(*args: str) -> str:
        return subprocess.run(["git", "-C", str(source), *args], capture_output=True, text=True, timeout=5,
                              check=False).stdout.strip()

    try:
        commit = git("rev-parse", "--short", "HEAD")
        dirty = bool(commit) and bool(git("status", "--porcelain", "--untracked-files=no"))
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return f"{commit}+modified" if dirty else (commit or "unknown")


def provenance(manifests: list[dict[str, Any]] = ()) -> dict[str, str]:
    """Versions, git commit, machine and time for the report's footer, and each study's command and
    plugin modules (from the study manifests)."""
    commit = source_commit()
    info = {"generated": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"), "pcverify": _version("pcverify"),
            "git commit": commit, "machine": f"{platform.node()} {platform.machine()} {platform.processor()}".strip(),
            "python": platform.python_version(), "command": command()}
    plugins = plugin_distributions()
    info["plugin distributions"] = ", ".join(f"{k} {v}" for k, v in plugins.items()) or "none"
    for man in manifests:
        info[f"study {man.get('name')}"] = man.get("command") or "unknown"
        if man.get("plugins"):
            info[f"study {man.get('name')} plugin modules"] = ", ".join(man["plugins"])
    for pkg in PACKAGES:
        info[pkg] = _version(pkg)
    return info
