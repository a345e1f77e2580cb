"""Reading and checking a study file before any cell is built.

A study file is user input like a command-line argument: a malformed, truncated or mistyped file must
fail in one line that names the file, the group, the field and the allowed values (SceneError), never
with a traceback halfway through a study.  Unknown keys are errors (a misspelt key would otherwise be
ignored and the wrong study run), and so are duplicate group ids and names that could not be file
names.  `pcverify.harness.study.load_study` calls these functions, then builds cells from a document
it can trust.
"""

from __future__ import annotations

import re
import tomllib
from pathlib import Path
from typing import Any

from pcverify.harness.analyses import ANALYSES, allowed_group_keys
from pcverify.harness.catalogue import make_scene
from pcverify.harness.figures import GROUP_FIGURES
from pcverify.scene import SceneError, shown
from pcverify.solvers.registry import SolverUnavailable, get_solver

TOP_KEYS = {"name": "study name (letters, digits, . _ -)", "title": "title (text)",
            "plugins": "list of module names imported in every worker", "scene": "[[scene]] tables",
            "group": "[[group]] tables", "claim": "[[claim]] tables",
            "calibration": "[[calibration]] tables (pcverify.harness.calibspec)"}
GROUP_TABLES = ("scene_params", "solver_params", "sweep")
RESOLUTION_RANGES = {"n": (2, 1000), "refine": (1, 1000)}
SAFE_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]{0,79}$")


def read_study_document(path: Path) -> dict[str, Any]:
    """Parse the TOML of a study file; unreadable, binary or invalid files raise SceneError."""
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise SceneError(f"study file {path}: not UTF-8 text ({exc.reason} at byte {exc.start}); allowed: a TOML "
                         "text file") from None
    except OSError as exc:
        raise SceneError(f"study file {path}: cannot be read ({exc.strerror or type(exc).__name__}); allowed: a "
                         "readable .toml file") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"study file {path}: not valid TOML ({' '.join(str(exc).split())})") from None
    except RecursionError:
        raise SceneError(f"study file {path}: nested too deeply to be read; allowed: a study file of [[group]], "
                         "[[claim]] and [[scene]] tables") from None


def safe_name(value: Any, what: str, where: str) -> str:
    """A name that becomes a file or folder name: letters, digits, '.', '_', '-', not starting with a dot."""
    if not isinstance(value, str) or not SAFE_NAME.match(value) or value in (".", ".."):
        raise SceneError(f"{where}: {what}={shown(value)} is not valid; allowed: 1 to 80 letters, digits, '.', '_' "
                         "or '-', starting with a letter or digit")
    return value


def check_study_document(doc: dict[str, Any], path: Path) -> None:
    """Keys, types and values of the whole file (scene and solver parameters included)."""
    where = f"study file {path.name}"
    unknown = sorted(set(doc) - set(TOP_KEYS))
    if unknown:
        raise SceneError(f"{where}: {unknown[0]} is not a study field; allowed: {', '.join(TOP_KEYS)}")
    if "name" in doc:
        safe_name(doc["name"], "name", where)
    if "title" in doc and not isinstance(doc["title"], str):
        raise SceneError(f"{where}: title={shown(doc['title'])} is not valid; allowed: text")
    for key in ("scene", "claim"):
        if key in doc and not (isinstance(doc[key], list) and all(isinstance(t, dict) for t in doc[key])):
            raise SceneError(f"{where}: {key}={shown(doc[key])} is not valid; allowed: [[{key}]] tables")
    groups = doc.get("group", [] if "calibration" in doc else None)  # a calibration study may have no groups
    if not isinstance(groups, list) or not (groups or "calibration" in doc) or not all(isinstance(g, dict)
                                                                                     for g in groups):
        raise SceneError(f"{where}: no [[group]] tables (group={shown(groups)}); allowed: one or more [[group]] "
                         "tables")
    ids: dict[str, int] = {}
    for gi, g in enumerate(groups):
        at = f"{path.name} group {gi + 1}"
        _check_group(g, at)
        gid = g.get("id", f"group{gi + 1}")
        if gid in ids:
            raise SceneError(f"{at}: id={gid!r} is already group {ids[gid] + 1}'s; allowed: a different id per group")
        ids[gid] = gi


def _check_group(g: dict[str, Any], where: str) -> None:
    analysis = g.get("analysis", "table")
    if not isinstance(analysis, str) or analysis not in ANALYSES:
        raise SceneError(f"{where}: analysis={shown(analysis)} is unknown; allowed: one of {', '.join(ANALYSES)}")
    allowed = allowed_group_keys(analysis)
    unknown = sorted(set(g) - set(allowed))
    if unknown:
        raise SceneError(f"{where}: {unknown[0]} is not a field of a {analysis} group; allowed: "
                         f"{', '.join(allowed)}")
    if "id" in g:
        safe_name(g["id"], "id", where)
    if "title" in g and not isinstance(g["title"], str):
        raise SceneError(f"{where}: title={shown(g['title'])} is not valid; allowed: text")
    if "scene" not in g or not isinstance(g["scene"], str):
        raise SceneError(f"{where}: scene={shown(g.get('scene'))} is not valid; allowed: a scene name (see "
                         "`pcverify scenes`)")
    for key in GROUP_TABLES:
        if key in g and not isinstance(g[key], dict):
            raise SceneError(f"{where}: {key}={shown(g[key])} is not valid; allowed: a table {{ key = value, ... }}")
    for key in ("serial", "vtu"):
        if key in g and not isinstance(g[key], bool):
            raise SceneError(f"{where}: {key}={shown(g[key])} is not valid; allowed: true/false")
    for option in ANALYSES[analysis].options:
        if option.name in g:
            option.check(g[option.name], where)
    for kind in values_of(g.get("figures", []), "figures", where, allow_empty=True):
        if kind not in GROUP_FIGURES:
            raise SceneError(f"{where}: figures entry {shown(kind)} is unknown; allowed: {', '.join(GROUP_FIGURES)}")
    try:
        make_scene(g["scene"], **g.get("scene_params", {}))
    except SceneError as exc:
        raise SceneError(f"{where}: {exc}") from None
    for key, (low, high) in RESOLUTION_RANGES.items():
        for v in values_of(g.get(key, [low]), key, where):
            if isinstance(v, bool) or not isinstance(v, int) or not low <= v <= high:
                raise SceneError(f"{where}: {key}={shown(v)} is not valid; allowed: integer in [{low}, {high}]")
    solvers = values_of(g.get("solvers"), "solvers", where)
    for name in solvers:
        if not isinstance(name, str):
            raise SceneError(f"{where}: solvers entry {shown(name)} is not valid; allowed: a solver name (text)")
    for key, values in g.get("sweep", {}).items():
        values_of(values, f"sweep.{key}", where)
    _check_solver_params(g, solvers, where, ANALYSES[analysis].task(g))


def _check_solver_params(g: dict[str, Any], solvers: list[str], where: str, task: Any) -> None:
    """Every solver parameter and sweep value against the solver's declared ranges, through the task's own
    check (a stability cell also takes the probe's parameters)."""
    table = g.get("solver_params", {})
    for key, value in table.items():
        if isinstance(value, dict) and key not in solvers:
            raise SceneError(f"{where}: solver_params.{key} is a per-solver table, but {key!r} is not among the "
                             f"group's solvers; allowed: one of {', '.join(map(str, solvers))}")
    scene = make_scene(g["scene"], **g.get("scene_params", {}))
    for name in solvers:
        base = solver_params_of(table, name)
        variants = [base] + [dict(base, **{k: v}) for k, vals in g.get("sweep", {}).items()
                             for v in values_of(vals, f"sweep.{k}", where)]
        try:
            solver = get_solver(name)
        except SolverUnavailable:
            continue  # reported as a skipped cell with the import error
        except SceneError as exc:
            raise SceneError(f"{where}: {exc}") from None
        try:
            if not task.supports(solver, scene)[0]:
                continue  # skipped with the reason (a probe-less solver in a stability group, a scene it cannot do)
        except KeyboardInterrupt:
            raise
        except BaseException:  # noqa: BLE001 - a plugin's supports that raises: its cells fail with the reason
            continue
        for params in variants:
            try:
                task.check(solver, params)
            except SceneError as exc:
                raise SceneError(f"{where}: {exc}") from None
            except KeyboardInterrupt:
                raise
            except BaseException:  # noqa: BLE001 - a plugin's own check that raises: its cells fail with the reason
                break


def solver_params_of(table: dict[str, Any], solver: str) -> dict[str, Any]:
    """Shared solver parameters plus those under a sub-table named after `solver` (e.g. macromolecule = {...})."""
    shared = {k: v for k, v in table.items() if not isinstance(v, dict)}
    return shared | dict(table.get(solver, {}))


def values_of(value: Any, what: str, where: str, allow_empty: bool = False) -> list[Any]:
    """A value or a flat list of values as a list (a string is one value, never its characters)."""
    items = value if isinstance(value, list) else [value]
    if value is None or (not items and not allow_empty):
        raise SceneError(f"{where}: {what} is missing or empty; allowed: a value or a non-empty list")
    if any(isinstance(v, (list, dict)) for v in items):
        raise SceneError(f"{where}: {what}={shown(value)} is not valid; allowed: a value or a flat list of values")
    return items
