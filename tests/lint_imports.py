"""Run the import contracts (pyproject.toml, [tool.importlinter]) against the installed layout of the source.

pcverify's folders are installed under one namespace (package-dir mapping), so the source tree itself is
not the importable `pcverify` package that import-linter analyses: this copies pcverify/, harness/,
solvers/ and references/ into pcverify/{.,harness,solvers,references} in a temporary folder and runs
`lint-imports` there.  Used by `tox -e lint` and tests/test_architecture.py.

    python tests/lint_imports.py [--root REPO] [--inject MODULE_FILE:IMPORT_LINE]
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
FOLDERS = {"pcverify": "", "harness": "harness", "solvers": "solvers", "references": "references"}


def installed_layout(root: Path, target: Path) -> Path:
    """Copy the source folders of `root` into target/pcverify as they are installed; returns target."""
    skip = shutil.ignore_patterns("__pycache__", "*.pyc", "studies")
    for folder, inside in FOLDERS.items():
        shutil.copytree(root / folder, target / "pcverify" / inside, ignore=skip, dirs_exist_ok=True)
    return target


def lint_imports(root: Path = REPO, inject: tuple[str, str] | None = None) -> subprocess.CompletedProcess:
    """lint-imports on the installed layout of `root`; `inject` = (file relative to the layout's pcverify/,
    a line appended to it) adds a deliberate violation."""
    with tempfile.TemporaryDirectory(prefix="pcverify-layers-") as tmp:
        where = installed_layout(root, Path(tmp))
        if inject is not None:
            path = where / "pcverify" / inject[0]
            path.write_text(path.read_text() + "\n" + inject[1] + "\n")
        lint = Path(sys.executable).with_name("lint-imports")
        return subprocess.run([str(lint), str(root / "pyproject.toml"), "--no-cache"], cwd=where,
                              capture_output=True, text=True, check=False)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--root", type=Path, default=REPO)
    parser.add_argument("--inject", default=None, help="FILE:LINE, a deliberate violation (for checking the check)")
    args = parser.parse_args()
    inject = tuple(args.inject.split(":", 1)) if args.inject else None
    out = lint_imports(args.root, inject)
    sys.stdout.write(out.stdout)
    sys.stderr.write(out.stderr)
    return out.returncode


if __name__ == "__main__":
    sys.exit(main())
