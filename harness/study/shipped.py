"""The study files shipped with the package, by name, and the file a study name or a path names.

Apart from the rest of `spec` (the study file's checks import the analyses and their tables), so that the
command line checks a study name at once, before it imports what runs a study.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from pcverify.scene import SceneError

BESIDE = ".mutants.toml"  # <study-stem>.mutants.toml beside a study file


def study_files() -> dict[str, Path]:
    """The study files shipped with the package, by name (not the mutants files beside them)."""
    folder = resources.files("pcverify.harness") / "studies"
    return {Path(str(p)).stem: Path(str(p)) for p in folder.iterdir()
            if str(p).endswith(".toml") and not str(p).endswith(BESIDE)}


def study_path(name_or_path: str) -> Path:
    """The file of a shipped study name or of a path (SceneError if neither)."""
    shipped = study_files()
    path = shipped.get(name_or_path, Path(name_or_path))
    if not path.is_file():
        raise SceneError(f"study={name_or_path!r} is unknown; allowed: one of {', '.join(sorted(shipped))} "
                         "or a path to a .toml file")
    return path
