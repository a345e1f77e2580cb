"""Mutants: named, small, deliberate defects of a solver's source, as data, that `pcverify mutate` runs a
study's claims on (a claim that passes on the original and not on a mutant has caught it).

A mutant is a `[[mutant]]` table (`schema.MUTANT`): the top-level `package` whose file it edits (default
pcverify), the `file` relative to that package's folder (pcverify's installed layout, e.g.
solvers/particles/mca/contact.py), the edit (`find` and `replace`, `find` occurring exactly `count` times, or a
unified `diff`) and `breaks`, the sentence saying what physics or numerics it breaks.  A study's mutants come
from its own `[[mutant]]` tables, from `<study>.mutants.toml` beside the study file (only `[[mutant]]` tables),
and from the entry point group `pcverify.mutants` (a plugin's object: mutant tables, or the path of such a
file, or a function returning either; offered to the studies that run a solver of the mutant's package).

A file is named by its module, resolved with the import system's finders without importing it, so a mutant
never reaches outside its package: an absolute path, `..`, another extension or a module that is not there
is one error line naming the mutant.
"""

from __future__ import annotations

import ast
import dataclasses
import hashlib
import json
import re
from collections.abc import Iterable
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path, PurePosixPath
from typing import Any

from pcverify.fingerprint import find_spec, installed, source_closure
from pcverify.harness.study.schema import MUTANT, Field, Table, check, row_where
from pcverify.harness.study.shipped import BESIDE, study_files
from pcverify.harness.study.studyfile import read_study_document
from pcverify.scene import SceneError, shown
from pcverify.solvers.registry import SolverUnavailable, get_solver

ENTRY_POINTS = "pcverify.mutants"
MUTANTS_FILE = Table("a mutants file", (Field("mutant", "tables", table=MUTANT, min_items=0),))
IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
HUNK = re.compile(r"@@ -(\d+)(?:,(\d+))? \+(\d+)(?:,(\d+))? @@")


class MutantError(SceneError):
    """A mutant that cannot be applied: one line naming it, its file and why."""


@dataclass(frozen=True)
class Mutant:
    """One deliberate defect: `file` of `package` edited by find/replace (`count` occurrences) or by `diff`."""

    name: str
    file: str
    breaks: str
    package: str = "pcverify"
    find: str | None = None
    replace: str | None = None
    count: int = 1
    diff: str | None = None
    expect: tuple[str, ...] = ()
    origin: str = ""  # where it is declared: a study file, a mutants file, an entry point

    @property
    def label(self) -> str:
        return f"mutant {self.name!r} ({self.origin})" if self.origin else f"mutant {self.name!r}"

    def module(self) -> str:
        """The dotted name of the module the file is (a package's `__init__.py`: the package)."""
        parts = PurePosixPath(self.file).parts
        if (not self.file or "\\" in self.file or self.file.startswith("/") or not self.file.endswith(".py")
                or not all(IDENTIFIER.fullmatch(p) for p in (*parts[:-1], parts[-1][:-3]))):
            raise MutantError(f"{self.label}: file={shown(self.file)} is not valid; allowed: a relative path of a .py "
                              f"module inside package {self.package!r} (folders and module names are Python names: "
                              "no '..', no absolute path)")
        names = [self.package, *parts[:-1]] + ([] if parts[-1] == "__init__.py" else [parts[-1][:-3]])
        return ".".join(names)

    def path(self) -> Path:
        """The original file, as `import` would find it (MutantError if the package or the module is not there)."""
        top = find_spec(self.package) if IDENTIFIER.fullmatch(self.package) else None
        if top is None or top.submodule_search_locations is None:
            raise MutantError(f"{self.label}: package={shown(self.package)} is not an importable package; allowed: "
                              "the top-level package of a solver (pcverify, or a plugin's)")
        spec = find_spec(self.module())
        origin = Path(spec.origin) if spec is not None and spec.has_location and isinstance(spec.origin, str) else None
        if origin is None or not origin.is_file() or origin.name != PurePosixPath(self.file).name:
            raise MutantError(f"{self.label}: file={shown(self.file)} is not a module of package {self.package!r}; "
                              "allowed: a relative path of a .py file inside the package")
        return origin

    def edited(self) -> tuple[str, str]:
        """(original source, edited source); MutantError when the edit does not apply as declared."""
        path = self.path()
        try:
            source = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise MutantError(f"{self.label}: {self.file} cannot be read ({exc}); allowed: a UTF-8 Python file"
                              ) from None
        if self.diff is not None:
            edited = apply_diff(source, self.diff, f"{self.label}: diff")
        else:
            found = source.count(self.find)
            if found != self.count:
                raise MutantError(f"{self.label}: find={shown(self.find)} occurs {found} times in {self.package}/"
                                  f"{self.file}; allowed: exactly count={self.count}")
            edited = source.replace(self.find, self.replace)
        if edited == source:
            raise MutantError(f"{self.label}: the edit leaves {self.package}/{self.file} unchanged; allowed: a "
                              "replacement that differs from the text it replaces")
        return source, edited

    def identity(self, edited: str) -> str:
        """A hash of the definition and of the edited source: names the mutant's cache folder, so an edit of
        the mutant or of the file starts a new one."""
        data = json.dumps([self.name, self.package, self.file, self.find, self.replace, self.count, self.diff, edited])
        return hashlib.sha256(data.encode()).hexdigest()[:12]

    def seedable(self) -> bool:
        """Whether a cell key covers every code this mutant can change (the solver's closure, the task, the compare
        step, the scene's content): then a cell whose key it leaves unchanged computes the same result, and the
        baseline's entries may be reused.  Not so for pcverify's own top-level modules (the fingerprint, the
        numba guard), nor the harness outside judge and report (how cells run and studies are read), nor a module
        of an installed distribution (a key counts it by the distribution's version, which the edit leaves)."""
        module = self.module()
        if self.package != "pcverify":
            return not installed(str(self.path()))
        return module.startswith(("pcverify.solvers.", "pcverify.references.", "pcverify.scene.",
                                  "pcverify.harness.judge.", "pcverify.harness.report.")) or module in (
            "pcverify.solvers", "pcverify.references", "pcverify.scene")

    def changes_code(self, source: str, edited: str) -> bool:
        """Whether the edit changes the module's syntax tree without docstrings (what the code fingerprint and
        Python run), not only comments, layout or docstrings."""
        return _code(source) != _code(edited)


def _code(source: str) -> str:
    try:
        tree = ast.parse(source)
    except SyntaxError:
        return f"not Python: {hashlib.sha256(source.encode()).hexdigest()}"
    for node in ast.walk(tree):
        body = getattr(node, "body", None)
        first = body[0] if isinstance(body, list) and body else None
        if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant) and isinstance(first.value.value, str):
            node.body = body[1:] or [ast.Pass()]
    return ast.dump(tree)


def apply_diff(source: str, diff: str, where: str) -> str:
    """`source` with the hunks of a unified diff applied (header lines before the first hunk are ignored); a hunk
    is matched at its line, else at the one other place it fits nearest to it.  MutantError naming the hunk."""
    lines = source.splitlines()
    hunks: list[tuple[int, list[str], list[str]]] = []
    for line in diff.splitlines():
        head = HUNK.match(line)
        if head:
            hunks.append((int(head[1]), [], []))
        elif hunks and line.startswith((" ", "-", "+")):
            kind, text = line[0], line[1:]
            if kind in " -":
                hunks[-1][1].append(text)
            if kind in " +":
                hunks[-1][2].append(text)
        elif hunks and line == "":
            hunks[-1][1].append("")
            hunks[-1][2].append("")
        elif hunks and not line.startswith("\\"):  # "\ No newline at end of file"
            raise MutantError(f"{where}: line {shown(line)} is not part of a hunk; allowed: a unified diff (lines "
                              "starting with ' ', '-', '+' after an @@ header)")
    if not hunks:
        raise MutantError(f"{where} has no hunk; allowed: a unified diff with @@ -line,count +line,count @@ headers")
    out: list[str] = []
    pos = 0
    for number, (start, old, new) in enumerate(hunks, 1):
        fits = [i for i in range(pos, len(lines) - len(old) + 1) if lines[i:i + len(old)] == old]
        if not fits:
            raise MutantError(f"{where}: hunk {number} (@@ -{start}) does not match the file; allowed: a diff against "
                              "the file as it is")
        at = min(fits, key=lambda i: abs(i - (start - 1)))
        out += lines[pos:at] + new
        pos = at + len(old)
    out += lines[pos:]
    return "\n".join(out) + ("\n" if source.endswith("\n") else "")


def parse_mutants(items: list[dict[str, Any]], where: str, table: str = "mutant") -> list[Mutant]:
    """`[[mutant]]` tables (checked against `schema.MUTANT`) as mutants; `where` names their source."""
    check({table: items}, Table(where, (Field(table, "tables", table=MUTANT, min_items=0),)), where)
    out = []
    for number, item in enumerate(items, 1):
        at = row_where(where, table, number, item, MUTANT)
        if "find" in item and "replace" not in item:
            raise SceneError(f"{at}: replace is missing; allowed: the text that replaces find")
        extra = [k for k in ("replace", "count") if k in item and "diff" in item]
        if extra:
            raise SceneError(f"{at}: {extra[0]} is given with diff; allowed: find, replace and count, or diff alone")
        expect = item.get("expect", [])
        out.append(Mutant(**item | {"expect": tuple([expect] if isinstance(expect, str) else expect),
                                    "origin": where}))
    return out


def beside_file(study_path: Path) -> Path:
    """The mutants file of a study file: `<stem>.mutants.toml` in the same folder."""
    return study_path.with_name(study_path.stem + BESIDE)


def read_mutants_file(path: Path) -> list[Mutant]:
    """The `[[mutant]]` tables of a mutants file (nothing else is allowed in it)."""
    doc = read_study_document(path)
    where = f"mutants file {path}"
    check(doc, MUTANTS_FILE, where)
    return parse_mutants(doc.get("mutant", []), where)


def entry_point_mutants(packages: Iterable[str]) -> list[Mutant]:
    """The mutants plugins ship through the entry point group `pcverify.mutants` whose package is one of
    `packages` (those of the study's solvers).  An entry point's object is a list of mutant tables, the path of a
    mutants file (relative: to its module's folder), or a function returning one of these."""
    wanted = set(packages)
    out = []
    for ep in sorted(metadata.entry_points(group=ENTRY_POINTS), key=lambda e: (e.name, e.value)):
        where = f"entry point {ep.name} = {ep.value!r} of group {ENTRY_POINTS}"
        try:
            value = ep.load()
            value = value() if callable(value) else value
        except KeyboardInterrupt:
            raise
        except BaseException as exc:  # noqa: BLE001 - a plugin's own error (SystemExit too), shown as one line
            raise SceneError(f"{where} failed to load: {type(exc).__name__}: {' '.join(str(exc).split())}") from None
        if isinstance(value, (str, Path)):
            path = Path(value)
            if not path.is_absolute():
                spec = find_spec(ep.module)
                path = Path(spec.origin).parent / path if spec is not None and spec.origin else path
            found = read_mutants_file(path)
        elif isinstance(value, (list, tuple)):
            found = parse_mutants(list(value), where)
        else:
            raise SceneError(f"{where}: {shown(value)} is not valid; allowed: a list of mutant tables, the path of a "
                             "mutants file, or a function returning one")
        out += [m for m in found if m.package in wanted]
    return out


def shipped_catalogue(solvers: Iterable[str]) -> list[Mutant]:
    """The mutants the shipped studies catalogue (their `[[mutant]]` tables and mutants files) that edit a module
    one of the shipped `solvers` reaches by import, offered to another study (its `shipped_mutants`): each named
    `<shipped study>.<name>`, its `expect` dropped (it names that study's claims); one of each definition."""
    reached = set().union(*(source_closure(type(get_solver(name)).__module__) for name in solvers))
    out: dict[tuple[Any, ...], Mutant] = {}
    for study, path in sorted(study_files().items()):
        found = parse_mutants(read_study_document(path).get("mutant", []), f"study file {path.name}")
        found += read_mutants_file(beside_file(path)) if beside_file(path).is_file() else []
        for m in found:
            if m.package == "pcverify" and m.module() in reached:  # a module the solver reaches by import
                key = (m.package, m.file, m.find, m.replace, m.count, m.diff)
                out.setdefault(key, dataclasses.replace(m, name=f"{study}.{m.name}", expect=(),
                                                        origin=f"the shipped catalogue of {study} ({m.origin})"))
    return list(out.values())


def catalogue(declared: list[Mutant], study_path: Path | None, packages: Iterable[str],
              claims: Iterable[str] | None = None, shipped: Iterable[str] = ()) -> list[Mutant]:
    """Every mutant of a study: its `[[mutant]]` tables (`declared`), its mutants file, the shipped catalogues'
    mutants of the `shipped` solvers (`shipped_catalogue`), the plugins' entry points; a name declared twice is an
    error naming both places.  With the study's `claims`, an `expect` of its own mutants (tables and file) that
    names no claim of it is an error (a plugin's entry-point mutants may expect the claims of the plugin's own
    study)."""
    found = list(declared)
    if study_path is not None and beside_file(study_path).is_file():
        found += read_mutants_file(beside_file(study_path))
    if claims is not None:
        known = set(claims)
        for m in found:
            unknown = [c for c in m.expect if c not in known]
            if unknown:
                raise SceneError(f"mutant {m.name!r} ({m.origin}): expect = {unknown[0]!r} is not a claim of the "
                                 f"study; allowed: one of {', '.join(sorted(known)) or '(the study has no claims)'}")
    found += shipped_catalogue(shipped)
    found += entry_point_mutants(packages)
    seen: dict[str, Mutant] = {}
    for m in found:
        if m.name in seen:
            raise SceneError(f"mutant name {m.name!r} is declared twice: in {seen[m.name].origin} and in {m.origin}; "
                             "allowed: one mutant per name")
        seen[m.name] = m
    return found


def solver_packages(study: Any) -> set[str]:
    """The top-level packages of the solvers a study runs and of its plugin modules: the packages whose mutants
    the plugins' entry points offer it."""
    names = {c.solver for g in study.groups for c in g.cells} | {c.solver for c in study.calibrations}
    out = {p.partition(".")[0] for p in study.plugins}
    for name in sorted(names):
        try:
            out.add(type(get_solver(name)).__module__.partition(".")[0])
        except (SolverUnavailable, SceneError):
            continue
    return out


def select_mutants(mutants: list[Mutant], names: list[str] | None, study: str) -> list[Mutant]:
    """The mutants `--mutant NAME ...` names (all without names); an unknown name is one line listing the known."""
    if not names:
        return mutants
    known = {m.name: m for m in mutants}
    for name in names:
        if name not in known:
            raise SceneError(f"--mutant {shown(name)} is not a mutant of study {study}; allowed: one of "
                             f"{', '.join(known) or '(the study has no mutants)'}")
    return [known[n] for n in dict.fromkeys(names)]
