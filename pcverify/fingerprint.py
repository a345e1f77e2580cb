"""Code fingerprints: a hash of all the code a result depends on, so that a cached result or a compiled
kernel is redone when that code changes (no hand-bumped versions).

A module's fingerprint covers its source closure: every module it reaches by import, transitively and
across packages, with the parent packages' `__init__.py` that Python runs first.  Modules outside
site-packages (the product, a plugin, a local library it subclasses) count by their syntax tree without
docstrings; a module of an installed distribution by the distribution's name and version; the standard
library by Python's version.  pcverify and the module's own top-level package always count by source,
even when installed.  Names are resolved with the import system's finders, never by importing them.
"""

from __future__ import annotations

import ast
import hashlib
import importlib.util
import os
import platform
import sys
import time
from functools import cache
from importlib import metadata
from importlib.machinery import ModuleSpec
from pathlib import Path, PurePath

ALWAYS_SOURCE = "pcverify"  # hashed by source wherever it is installed
INSTALLED = frozenset({"site-packages", "dist-packages"})  # folders of installed third-party distributions
RACY_NS = 2_000_000_000  # a file changed this recently is not trusted by its stat alone: another edit may keep it


def _is_docstring(node: ast.AST) -> bool:
    return isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant) and isinstance(node.value.value, str)


def _summary(tree: ast.AST, module: str, is_package: bool) -> tuple[str, frozenset[str]]:
    """(hash of the syntax tree without docstrings, absolute names of the modules or module attributes it
    imports anywhere) of one module's syntax tree; strips the docstrings off the tree."""
    package = module if is_package else module.rpartition(".")[0]
    imports: set[str] = set()
    for node in ast.walk(tree):
        body = getattr(node, "body", None)
        if isinstance(body, list) and body and _is_docstring(body[0]):
            node.body = body[1:] or [ast.Pass()]
        if isinstance(node, ast.Import):
            imports.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")
                if node.level > len(parts):
                    continue  # beyond the top-level package: Python refuses it too
                parent = ".".join(parts[: len(parts) - node.level + 1])
                base = f"{parent}.{base}" if base else parent
            imports.add(base)
            imports.update(f"{base}.{a.name}" for a in node.names if a.name != "*")
    return hashlib.sha256(ast.dump(tree).encode()).hexdigest(), frozenset(imports)


_SUMMARIES: dict[tuple[str, str, bool], tuple[str, frozenset[str]]] = {}  # (sha256 of the bytes, module, is_package)


def _read(path: str, module: str, is_package: bool) -> tuple[str, frozenset[str]] | None:
    """(hash, imported names) of one file as it is now: Python source by its syntax tree without docstrings,
    anything else (an extension module) by its bytes; None if it cannot be read.  Parsed once per content."""
    try:
        data = Path(path).read_bytes()
    except OSError:
        return None
    key = (hashlib.sha256(data).hexdigest(), module, is_package)
    if key not in _SUMMARIES:
        try:
            summary = _summary(ast.parse(data, filename=path), module, is_package) if path.endswith(".py") else None
        except (SyntaxError, ValueError):
            summary = None
        _SUMMARIES[key] = summary or (key[0], frozenset())
    return _SUMMARIES[key]


def find_spec(name: str, memo: dict[str, ModuleSpec | None] | None = None) -> ModuleSpec | None:
    """The spec of module `name` as `import name` would find it, without importing anything: a loaded
    module's own spec, else each finder of sys.meta_path asked with the parent package's search path
    (found the same way).  None if it is not found."""
    memo = {} if memo is None else memo
    if name in memo:
        return memo[name]
    memo[name] = spec = _find_spec(name, memo)
    return spec


def _find_spec(name: str, memo: dict[str, ModuleSpec | None]) -> ModuleSpec | None:
    if name in sys.modules:
        module = sys.modules[name]
        spec = getattr(module, "__spec__", None)
        if spec is None and isinstance(getattr(module, "__file__", None), str):  # a script run as __main__
            spec = importlib.util.spec_from_file_location(name, module.__file__)
        return spec
    parent = name.rpartition(".")[0]
    path = None
    if parent:
        loaded = sys.modules.get(parent)
        path = getattr(loaded, "__path__", None) if loaded is not None else None
        if path is None:
            parent_spec = find_spec(parent, memo)
            path = None if parent_spec is None else parent_spec.submodule_search_locations
        if path is None:
            return None  # the parent is not a package: `name` is an attribute, not a module
        path = list(path)
    for finder in list(sys.meta_path):
        find = getattr(finder, "find_spec", None)
        if find is None:
            continue
        try:
            spec = find(name, path)
        except (ImportError, OSError, ValueError, AttributeError, TypeError):
            continue  # a finder that cannot look for this name does not have it
        if spec is not None:
            return spec
    return None


def _origin(spec: ModuleSpec) -> str | None:
    """The file a spec loads from, if it is one (not a namespace package, built-in or frozen module)."""
    origin = spec.origin
    return origin if spec.has_location and isinstance(origin, str) and os.path.isfile(origin) else None


def installed(origin: str) -> bool:
    """Whether a file lies in an installed distribution's folder (a module there counts by its version)."""
    return not INSTALLED.isdisjoint(PurePath(origin).parts)


def _provides(dist: metadata.Distribution, top: str) -> bool:
    declared = dist.read_text("top_level.txt")
    if declared is not None:
        return top in declared.split()
    return any(PurePath(f).parts[0] in (top, f"{top}.py") for f in dist.files or ())


@cache
def _distributions(top: str) -> dict[str, str]:
    """{"dist:NAME": version} of the installed distributions that provide top-level package `top` (the one
    named like it if it does, else all that list it: scanning every distribution costs 0.1 s).  Once per
    process, which runs the versions it imported first."""
    try:
        named = metadata.distribution(top)
    except metadata.PackageNotFoundError:
        named = None
    if named is not None and _provides(named, top):
        found = [named]
    else:
        found = []
        for name in sorted(set(_packages_distributions().get(top, ()))):
            try:
                found.append(metadata.distribution(name))
            except metadata.PackageNotFoundError:
                continue
    return {f"dist:{d.metadata['Name']}": d.version for d in found}


@cache
def _packages_distributions() -> dict[str, list[str]]:
    return metadata.packages_distributions()


def _stat(path: str) -> tuple[int, int, int, int] | None:
    try:
        st = os.stat(path)
    except OSError:
        return None
    return st.st_mtime_ns, st.st_ctime_ns, st.st_size, st.st_ino


# module -> (where it was looked up, the files and folders read with their stat, the closure)
_CLOSURES: dict[str, tuple[tuple, dict[str, tuple[int, int, int, int] | None], dict[str, str]]] = {}


def _environment() -> tuple:
    return tuple(sys.path), tuple(id(f) for f in sys.meta_path)


def _memoised(module: str) -> dict[str, str] | None:
    """The closure found before, if no file or folder it looked at has changed since (nor sys.path)."""
    found = _CLOSURES.get(module)
    if found is None or found[0] != _environment():
        return None
    return found[2] if all(_stat(p) == st for p, st in found[1].items()) else None


def _memoise(module: str, read: list[str], closure: dict[str, str]) -> None:
    """Remember a closure with the stat of each file read, of its folder and of the folders on sys.path
    (which change when a module is added or removed there), unless one changed so recently that another
    edit may keep its stat."""
    watched = [*read, *(os.path.dirname(f) for f in read), *(p or os.curdir for p in sys.path)]
    stats = {p: _stat(p) for p in watched}
    recent = time.time_ns() - RACY_NS
    if all(st is None or max(st[0], st[1]) < recent for st in stats.values()):
        _CLOSURES[module] = (_environment(), stats, closure)


def source_closure(module: str) -> dict[str, str]:
    """What `module`'s fingerprint covers: {module name: hash of its source} for every module it reaches by
    import (and their parent packages), {"dist:NAME": version} for an installed distribution it reaches,
    and {"python": version}."""
    memoised = _memoised(module)
    if memoised is not None:
        return dict(memoised)
    roots = {ALWAYS_SOURCE, module.partition(".")[0]}
    out = {"python": platform.python_version()}
    memo: dict[str, ModuleSpec | None] = {}
    installed_tops: dict[str, dict[str, str]] = {}  # top-level name -> its distributions ({}: not installed)
    read: list[str] = []
    seen: set[str] = set()
    todo = [module]
    while todo:
        name = todo.pop()
        if name in seen or not name:
            continue
        seen.add(name)
        top = name.partition(".")[0]
        if top not in roots and top in sys.stdlib_module_names:
            continue
        if top not in roots and top not in installed_tops:
            spec = find_spec(top, memo)
            origin = None if spec is None else _origin(spec)
            installed_tops[top] = _distributions(top) if origin and installed(origin) else {}
        if installed_tops.get(top):
            out.update(installed_tops[top])
            continue
        if "." in name:
            todo.append(name.rpartition(".")[0])  # Python runs the parent packages first
        spec = find_spec(name, memo)
        origin = None if spec is None else _origin(spec)
        if origin is None:
            continue
        if top not in roots and installed(origin) and _distributions(top):
            out.update(_distributions(top))  # a module of a namespace package inside an installed distribution
            continue
        # relative imports resolve against the spec's name (pkg.mod for `python -m pkg.mod`, not __main__)
        summary = _read(origin, spec.name or name, spec.submodule_search_locations is not None)
        if summary is None:
            continue
        read.append(origin)
        out[name], imports = summary
        todo.extend(imports - seen)
    _memoise(module, read, out)
    return dict(out)


def module_fingerprint(module: str) -> str:
    """Hash of `module`'s source closure (see source_closure): it changes when any code the module reaches
    by import changes, or an installed distribution it uses changes version."""
    closure = source_closure(module)
    return hashlib.sha256("\n".join(f"{k} {v}" for k, v in sorted(closure.items())).encode()).hexdigest()[:16]


def code_fingerprint(obj: object) -> str:
    """Fingerprint of the module that defines a class, function or instance."""
    cls = obj if isinstance(obj, type) or callable(obj) else type(obj)
    return module_fingerprint(cls.__module__)
