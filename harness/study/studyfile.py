"""Reading and checking a study file before any cell is built.

A study file is user input like a command-line argument: a malformed, truncated or mistyped file must
fail in one line that names the file, the group, the field and the allowed values (SceneError), never
with a traceback halfway through a study.  Its keys, types and ranges are declared in `schema` and checked
by its one walk (unknown keys are errors: a misspelt key would otherwise be ignored and the wrong study
run); this module adds what needs other objects: the scenes and the solvers' own parameters.
`pcverify.harness.study.study.load_study` calls these functions, then builds cells from a document it can
trust.
"""

from __future__ import annotations

import itertools
import math
import tomllib
from pathlib import Path
from typing import Any

from pcverify.harness.study.analyses import ANALYSES, REGISTRIES
from pcverify.harness.study.catalogue import get_spec, make_scene
from pcverify.harness.study.expressions import is_expression, resolve, variables
from pcverify.harness.study.schema import GROUP, STUDY, as_list, check, row_where
from pcverify.scene import Scene, SceneError, is_real
from pcverify.solvers.registry import SolverUnavailable, get_solver


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


def check_study_document(doc: dict[str, Any], path: Path) -> dict[str, Any]:
    """Keys, types and values of the whole file against the schema (`schema.STUDY`); a study has groups unless
    it calibrates.  The document back with the schema's defaults filled in (`schema.check`)."""
    where = f"study file {path.name}"
    normal = check(doc, STUDY, where, REGISTRIES)
    if not doc.get("group") and "calibration" not in doc:
        raise SceneError(f"{where}: no [[group]] tables; allowed: one or more [[group]] tables")
    return normal


def check_groups(doc: dict[str, Any], path: Path) -> None:
    """What a group's keys mean, once the study's scenes are known: its scene built with its scene_params (at each
    of its resolutions, where a parameter is an expression of the resolution), and every solver parameter and
    sweep value within the solver's declared ranges (`doc`: as `check_study_document` returns it)."""
    for number, g in enumerate(doc.get("group", []), 1):
        where = row_where(f"study file {path.name}", "group", number, g, GROUP)
        try:
            for n, refine in resolutions(g):
                scene_at(g["scene"], g.get("scene_params", {}), n, refine)
        except SceneError as exc:
            raise SceneError(f"{where}: {exc}") from None
        _check_solver_params(g, as_list(g["solvers"]), where, ANALYSES[g["analysis"]].task(g))
        if "parameter" in as_list(g["figures"]) and "figure_x" not in g:
            raise SceneError(f"{where}: figures = \"parameter\" needs figure_x; allowed: figure_x = a swept solver or "
                             "scene parameter, n, refine or h")


def resolutions(g: dict[str, Any]) -> list[tuple[int, int]]:
    """The (n, refine) pairs of a (normalised) group."""
    return [(int(n), int(r)) for n in as_list(g["n"]) for r in as_list(g["refine"])]


def resolution_names(scene: str, scene_params: dict[str, Any], n: int, refine: int) -> dict[str, float]:
    """What an expression sees at (n, refine) on this scene: n, refine, a (the box's lattice spacing) and h; the
    box is built from the parameters that are not expressions (an extent cannot depend on the resolution)."""
    specs = {p.name: p for p in get_spec(scene).parameters}
    fixed = {k: v for k, v in scene_params.items() if not is_expression(specs.get(k), v)}
    return variables(n, refine, make_scene(scene, **fixed).box.lattice_spacing(n))


def scene_at(scene: str, scene_params: dict[str, Any], n: int, refine: int
             ) -> tuple[Scene, dict[str, Any], dict[str, str]]:
    """The scene at (n, refine), the scene parameters' values there and the expressions among them."""
    names = resolution_names(scene, scene_params, n, refine)
    values, expressions = resolve(scene_params, get_spec(scene).parameters, names)
    given = f" (given as {', '.join(f'{k} = {v!r}' for k, v in expressions.items())} at n={n}, refine={refine})"
    try:
        built = make_scene(scene, **values)
    except SceneError as exc:
        raise SceneError(f"{exc}{given if expressions else ''}") from None
    if expressions:  # a, h and every expression are computed from the box of the parameters that are numbers
        fixed = {k: v for k, v in values.items() if k not in expressions}
        box = make_scene(scene, **fixed).box
        for k in expressions:
            if make_scene(scene, **fixed, **{k: values[k]}).box != box:
                raise SceneError(f"scene parameter {k} = {expressions[k]!r} is an expression of the resolution and "
                                 f"sets the box (at n={n}, refine={refine}), whose spacing a and h every expression "
                                 "is computed from; allowed: a number for a parameter of the box's extent")
    return built, values, expressions


MATERIAL_NAMES = ("density", "conductivity", "heat_capacity", "youngs_modulus", "poisson_ratio")


def target_names(g: dict[str, Any]) -> dict[tuple[int, int], tuple[dict[str, float], dict[str, float]]]:
    """What a claim's target on a group's tables may name at each (n, refine) of the group: (the scalars of the
    scene's reference, asked before any solve; the resolution's names, pi, the scene's numeric parameters, its
    material's constants and the solver parameters every cell of the group shares)."""
    spec, given, out = get_spec(g["scene"]), g.get("scene_params", {}), {}
    shared = _shared_solver_params(g)
    for n, refine in resolutions(g):
        scene, values, _ = scene_at(g["scene"], given, n, refine)
        ref = spec.reference.scalars(scene, {}) if spec.reference and spec.reference.scalars else {}
        names = ({p.name: p.default for p in spec.parameters} | values | {"pi": math.pi}
                 | resolution_names(g["scene"], given, n, refine))
        more = {k: getattr(scene.material, k) for k in MATERIAL_NAMES} | shared  # the scene's names come first
        names |= {k: v for k, v in more.items() if k not in names}
        out[n, refine] = ({k: float(v) for k, v in ref.items() if is_real(v)},
                          {k: float(v) for k, v in names.items() if is_real(v)})
    return out


def _shared_solver_params(g: dict[str, Any]) -> dict[str, Any]:
    """The solver parameters with one value in every cell of the group: each solver's defaults and the group's
    solver_params (flat or by solver), less the swept ones and those on which the group's solvers differ."""
    table, swept, found = g.get("solver_params", {}), set(g.get("sweep", {})), []
    for solver in as_list(g["solvers"]):
        try:
            declared = {p.name: p.default for p in get_solver(solver).parameters}
        except SolverUnavailable:
            return {}
        given = {k: v for k, v in table.items() if not isinstance(v, dict)} | table.get(solver, {})
        found.append({k: v for k, v in (declared | given).items() if k not in swept and not isinstance(v, str)})
    return {k: v for k, v in (found[0] if found else {}).items() if all(k in f and f[k] == v for f in found)}


def solver_params_at(solver: str, params: dict[str, Any], names: dict[str, float]
                     ) -> tuple[dict[str, Any], dict[str, str]]:
    """A solver's parameters at one resolution: expressions replaced by their values (unchanged when the solver
    cannot be loaded: its cells report that)."""
    try:
        specs = get_solver(solver).parameters
    except SolverUnavailable:
        return dict(params), {}
    return resolve(params, specs, names)


def _check_solver_params(g: dict[str, Any], solvers: list[str], where: str, task: Any) -> None:
    """Every solver parameter and sweep value against the solver's declared ranges, through the task's own
    check (a stability cell also takes the probe's parameters)."""
    table = g.get("solver_params", {})
    for key, value in table.items():
        if isinstance(value, dict) and key not in solvers:
            raise SceneError(f"{where}: solver_params.{key} is a per-solver table, but {key!r} is not among the "
                             f"group's solvers; allowed: one of {', '.join(map(str, solvers))}")
    scene_params = g.get("scene_params", {})
    scene = scene_at(g["scene"], scene_params, *resolutions(g)[0])[0]
    for name in solvers:
        base = solver_params_of(table, name)
        raw = [base] + [dict(base, **{k: v}) for k, vals in g.get("sweep", {}).items() for v in as_list(vals)]
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
        for params, (n, refine) in itertools.product(raw, resolutions(g)):
            expressions: dict[str, str] = {}
            try:
                values, expressions = solver_params_at(name, params, resolution_names(g["scene"], scene_params, n,
                                                                                        refine))
                task.check(solver, values)
            except SceneError as exc:
                at = f" (given as {', '.join(f'{k} = {v!r}' for k, v in expressions.items())} at n={n}, " \
                     f"refine={refine})" if expressions else ""
                raise SceneError(f"{where}: {exc}{at}") from None
            except KeyboardInterrupt:
                raise
            except BaseException:  # noqa: BLE001 - a plugin's own check that raises: its cells fail with the reason
                break


def solver_params_of(table: dict[str, Any], solver: str) -> dict[str, Any]:
    """Shared solver parameters plus those under a sub-table named after `solver` (e.g. macromolecule = {...})."""
    shared = {k: v for k, v in table.items() if not isinstance(v, dict)}
    return shared | dict(table.get(solver, {}))
