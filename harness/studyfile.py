"""Reading and validating a study file before any cell is built.

A study file is user input like a command-line argument: a malformed, truncated or mistyped file
must fail in one line that names the file, the group, the field and the allowed values (SceneError),
never with a traceback halfway through a study.  `harness.study.load_study` calls these two
functions and then builds cells from a document it can trust.
"""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

from pcverify.harness.catalogue import make_scene
from pcverify.harness.scene import SceneError

GROUP_TABLES = ("scene_params", "solver_params", "sweep")
RESOLUTION_RANGES = {"n": (2, 1000), "refine": (1, 1000)}


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


def check_study_document(doc: dict[str, Any], path: Path, analyses: tuple[str, ...]) -> None:
    """Types and values of every field of every group (scene and solver parameters included)."""
    for key in ("name", "title"):
        if key in doc and not isinstance(doc[key], str):
            raise SceneError(f"study file {path.name}: {key}={_short(doc[key])} is not valid; allowed: text")
    groups = doc.get("group")
    if not isinstance(groups, list) or not groups or not all(isinstance(g, dict) for g in groups):
        raise SceneError(f"study file {path.name}: no [[group]] tables (group={_short(groups)}); allowed: one or "
                         "more [[group]] tables")
    for gi, g in enumerate(groups):
        _check_group(g, f"{path.name} group {gi + 1}", analyses)


def _check_group(g: dict[str, Any], where: str, analyses: tuple[str, ...]) -> None:
    for key in ("id", "title", "analysis", "scene", "probe"):
        if key in g and not isinstance(g[key], str):
            raise SceneError(f"{where}: {key}={_short(g[key])} is not valid; allowed: text")
    if "scene" not in g:
        raise SceneError(f"{where}: scene is missing; allowed: a scene name (see `pcverify scenes`)")
    analysis = g.get("analysis", "table")
    if analysis not in analyses:
        raise SceneError(f"{where}: analysis={analysis!r} is unknown; allowed: one of {', '.join(analyses)}")
    for key in GROUP_TABLES:
        if key in g and not isinstance(g[key], dict):
            raise SceneError(f"{where}: {key}={_short(g[key])} is not valid; allowed: a table {{ key = value, ... }}")
    if "serial" in g and not isinstance(g["serial"], bool):
        raise SceneError(f"{where}: serial={_short(g['serial'])} is not valid; allowed: true/false")
    try:
        make_scene(g["scene"], **g.get("scene_params", {}))
    except SceneError as exc:
        raise SceneError(f"{where}: {exc}") from None
    for key, (low, high) in RESOLUTION_RANGES.items():
        for v in _items(g.get(key, [low]), key, where):
            if isinstance(v, bool) or not isinstance(v, int) or not low <= v <= high:
                raise SceneError(f"{where}: {key}={_short(v)} is not valid; allowed: integer in [{low}, {high}]")
    solvers = _items(g.get("solvers"), "solvers", where)
    for name in solvers:
        if not isinstance(name, str):
            raise SceneError(f"{where}: solvers entry {_short(name)} is not valid; allowed: a solver name (text)")
    sweep = g.get("sweep", {})
    for key, values in sweep.items():
        _items(values, f"sweep.{key}", where)
    _check_solver_params(g, solvers, where, analysis == "stability")


def _check_solver_params(g: dict[str, Any], solvers: list[str], where: str, stability: bool) -> None:
    """Every solver parameter and sweep value against the solver's declared ranges (probe keys apart)."""
    from pcverify.solvers.protocol import effective_params
    from pcverify.solvers.registry import REGISTRY, SolverUnavailable, get_solver

    table = g.get("solver_params", {})
    for key, value in table.items():
        if isinstance(value, dict) and key not in solvers:
            raise SceneError(f"{where}: solver_params.{key} is a per-solver table, but {key!r} is not among the "
                             f"group's solvers; allowed: one of {', '.join(map(str, solvers))}")
    shared = {k: v for k, v in table.items() if not isinstance(v, dict)}
    for name in solvers:
        base = shared | dict(table.get(name, {}))
        variants = [base] + [dict(base, **{k: v}) for k, vals in g.get("sweep", {}).items()
                             for v in (vals if isinstance(vals, list) else [vals])]
        if stability:
            from pcverify.harness.stability import ProbeUnavailable, get_probe

            try:
                probe = get_probe(name)
            except ProbeUnavailable:
                continue  # listed models without a probe (or not landed yet) are skipped with the reason
            if not probe.supports(make_scene(g["scene"], **g.get("scene_params", {})))[0]:
                continue  # skipped with the probe's reason
        if name not in REGISTRY:
            raise SceneError(f"{where}: solver={name!r} is unknown; allowed: one of {', '.join(sorted(REGISTRY))}")
        try:
            solver = get_solver(name)
        except SolverUnavailable:
            continue  # reported as a skipped cell with the import error
        for params in variants:
            try:
                if stability:
                    from pcverify.harness.stability import split_params

                    params, _ = split_params(params)
                effective_params(solver, params)
            except SceneError as exc:
                raise SceneError(f"{where}: {exc}") from None


def _items(value: Any, what: str, where: str) -> list[Any]:
    items = value if isinstance(value, list) else [value]
    if value is None or not items:
        raise SceneError(f"{where}: {what} is missing or empty; allowed: a value or a non-empty list")
    if any(isinstance(v, (list, dict)) for v in items):
        raise SceneError(f"{where}: {what}={_short(value)} is not valid; allowed: a value or a flat list of values")
    return items


def _short(value: Any) -> str:
    text = " ".join(repr(value).split())
    return text if len(text) <= 60 else text[:57] + "..."
