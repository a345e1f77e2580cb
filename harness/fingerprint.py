"""Code fingerprints: a hash of the source a result depends on, so that a cache entry is recomputed when
that code changes (no hand-bumped versions).

The fingerprint of a class or module is the hash of its module's syntax tree and of every module it
imports from its own top-level package or from pcverify, followed transitively.  Comments and
docstrings are not part of it (they cannot change a result); an edit to anything else is.
"""

from __future__ import annotations

import ast
import hashlib
import importlib.util
import sys
from functools import cache
from pathlib import Path


def _is_docstring(node: ast.stmt) -> bool:
    return isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant) and isinstance(node.value.value, str)


def _strip_docstrings(tree: ast.AST) -> ast.AST:
    for node in ast.walk(tree):
        body = getattr(node, "body", None)
        if isinstance(body, list) and body and isinstance(body[0], ast.stmt) and _is_docstring(body[0]):
            node.body = body[1:] or [ast.Pass()]
    return tree


def _imports(tree: ast.AST, module: str, is_package: bool) -> set[str]:
    """Absolute names of the modules (or module attributes) a syntax tree imports."""
    package = module if is_package else module.rpartition(".")[0]
    out: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")
                parent = ".".join(parts[: len(parts) - node.level + 1])
                base = f"{parent}.{base}" if base else parent
            out.add(base)
            out.update(f"{base}.{a.name}" for a in node.names)
    return out


def _source(module: str) -> tuple[Path, bool] | None:
    """(file, is_package) of an importable module with Python source, else None."""
    found = sys.modules.get(module)
    spec = getattr(found, "__spec__", None)
    if spec is None:
        try:
            spec = importlib.util.find_spec(module)
        except (ImportError, ValueError, AttributeError):
            return None
    origin = getattr(spec, "origin", None)
    if not origin or not origin.endswith(".py"):
        return None
    return Path(origin), spec.submodule_search_locations is not None


@cache
def module_fingerprint(module: str) -> str:
    """Hash of `module`'s code and of the code it imports from its own top-level package or pcverify."""
    roots = {module.split(".")[0], "pcverify"}
    seen: dict[str, str] = {}
    todo = [module]
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        where = _source(name)
        if where is None:
            continue
        path, is_package = where
        tree = ast.parse(path.read_bytes(), filename=str(path))
        seen[name] = hashlib.sha256(ast.dump(_strip_docstrings(tree)).encode()).hexdigest()
        todo.extend(m for m in _imports(tree, name, is_package) if m.split(".")[0] in roots and m not in seen)
    digest = hashlib.sha256("\n".join(f"{k} {v}" for k, v in sorted(seen.items())).encode())
    return digest.hexdigest()[:16]


def code_fingerprint(obj: object) -> str:
    """Fingerprint of the module that defines a class, function or instance."""
    cls = obj if isinstance(obj, type) or callable(obj) else type(obj)
    return module_fingerprint(cls.__module__)
