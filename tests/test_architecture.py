"""The house rules, checked: the layer contracts of pyproject.toml (import-linter) hold, a deliberate
violation breaks them, and no project module imports inside a function (except an optional dependency,
with a comment saying so)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest
from lint_imports import REPO, lint_imports

SOURCES = ("pcverify", "harness", "solvers", "references")


def test_import_contracts_hold() -> None:
    out = lint_imports()
    assert out.returncode == 0, out.stdout + out.stderr
    assert "0 broken" in out.stdout


@pytest.mark.parametrize("where, line, contract", [
    ("solvers/particles/mca/heat.py", "from pcverify.harness.study import study", "Data flows one way"),
    ("harness/report/write.py", "from pcverify.solvers.particles.macromolecule import solver",
     "The harness reaches solvers only through the registry"),
    ("references/shared.py", "import pcverify.solvers.registry", "Data flows one way"),
    ("scene/geometry.py", "from pcverify.harness.run import cache", "Data flows one way"),
    ("fingerprint.py", "from pcverify.scene import params", "Data flows one way"),
    ("harness/study/study.py", "from pcverify.harness.run import cache", "Harness layers"),
    ("harness/judge/verdict.py", "from pcverify.harness.report import figures", "Harness layers"),
    ("harness/run/cache.py", "from pcverify.harness.run import execution", "Inside the run package"),
    ("harness/study/schema.py", "from pcverify.harness.study import study", "Inside the study package"),
    ("solvers/particles/mca/automata.py", "from pcverify.solvers.particles.macromolecule import lattice",
     "Particle models and continuum solvers do not import each other"),
])
def test_a_deliberately_wrong_import_breaks_a_contract(where: str, line: str, contract: str) -> None:
    out = lint_imports(inject=(where, line))
    assert out.returncode != 0
    text = " ".join(out.stdout.split())  # import-linter wraps long contract names
    broken = [segment.split(" KEPT ")[-1] for segment in text.split(" BROKEN")[:-1]]
    assert any(contract in name for name in broken), text[-800:]


def _function_imports(path: Path) -> list[str]:
    """Imports of project modules (pcverify, or relative) inside functions, and any import inside a function
    whose line does not say it is an optional dependency or deferred in the start-up module (which every Python
    of the environment imports: its own imports wait until LAMMPS is imported)."""
    source = path.read_text()
    lines = source.splitlines()
    bad = []
    for node in ast.walk(ast.parse(source)):
        if not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            continue
        for inner in ast.walk(node):
            if isinstance(inner, (ast.Import, ast.ImportFrom)):
                names = [inner.module or ""] if isinstance(inner, ast.ImportFrom) else [a.name for a in inner.names]
                project = (isinstance(inner, ast.ImportFrom) and inner.level > 0) or any(
                    n.split(".")[0] == "pcverify" for n in names)
                optional = any(mark in lines[inner.lineno - 1] for mark in ("optional dependency", "start-up"))
                if project or not optional:
                    bad.append(f"{path.relative_to(REPO)}:{inner.lineno}: {lines[inner.lineno - 1].strip()}")
    return bad


def test_imports_sit_at_the_top() -> None:
    bad = [b for folder in SOURCES for path in sorted((REPO / folder).rglob("*.py")) for b in _function_imports(path)]
    assert not bad, "\n".join(bad)

