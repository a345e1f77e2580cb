"""Provenance of a report: what produced its numbers (versions of pcverify, of its plugins and of the
numerical packages, the git commit, the machine, and the command of each study)."""

from __future__ import annotations

import datetime as dt
import importlib.util
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
    """Installed distributions that register pcverify solvers or scenes: name -> version, and the git commit of
    the checkout its code is in when it is one (an editable install: "commit abc", "+modified" when it differs)."""
    out = {}
    for group in PLUGIN_GROUPS:
        for ep in metadata.entry_points(group=group):
            if ep.dist is not None and ep.dist.name not in out:
                origin = code_origin(ep.value.partition(":")[0].partition(".")[0])
                commit = next((p for p in origin.split(" · ") if p.startswith("commit ")), "")
                out[ep.dist.name] = f"{ep.dist.version} ({commit})" if commit else ep.dist.version
    return dict(sorted(out.items()))


def _version(package: str) -> str:
    try:
        return metadata.version(package)
    except metadata.PackageNotFoundError:
        return "absent"


def _git_commit(folder: Path, paths: tuple[str, ...] = ("--untracked-files=no",)) -> str:
    """The short commit of the git checkout holding `folder`, with "+modified" when the tracked files (or the
    given paths) differ from it; "" outside git or without git."""

    def git(*args: str) -> str:
        return subprocess.run(["git", "-C", str(folder), *args], capture_output=True, text=True, timeout=5,
                              check=False).stdout.strip()

    try:
        commit = git("rev-parse", "--short", "HEAD")
        dirty = bool(commit) and bool(git("status", "--porcelain", *paths))
    except (OSError, subprocess.SubprocessError):
        return ""
    return f"{commit}+modified" if dirty else commit


def source_commit() -> str:
    """The git commit of the checkout this pcverify runs from (not of the working folder), with "+modified"
    when tracked files differ from it; "unknown" for an installed wheel or without git."""
    return _git_commit(Path(__file__).resolve().parents[1]) or "unknown"


def code_origin(module: str) -> str:
    """Where a plugin's code comes from, for the provenance: its distribution and version when it is installed,
    the git commit of its file's checkout ("+modified" when that file differs from it), and the file itself;
    "not found" when it cannot be located.  Locating a dotted module imports its parent packages (a plugin
    already loaded by the study)."""
    try:
        spec = importlib.util.find_spec(module)
    except (ImportError, ValueError):
        spec = None
    if spec is None or not spec.origin or not Path(spec.origin).exists():
        return "not found"
    path = Path(spec.origin).resolve()
    parts = []
    dists = metadata.packages_distributions().get(module.partition(".")[0], [])
    parts += [f"{d} {_version(d)}" for d in sorted(set(dists))]
    commit = _git_commit(path.parent, ("--untracked-files=all", "--", path.name))
    parts.append(f"commit {commit}" if commit else "not in git")
    parts.append(str(path))
    return " · ".join(parts)


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
            sources = man.get("plugin_sources") or {}
            info[f"study {man.get('name')} plugin modules"] = "; ".join(
                f"{m} ({sources[m]})" if m in sources else m for m in man["plugins"])
    for pkg in PACKAGES:
        info[pkg] = _version(pkg)
    return info
