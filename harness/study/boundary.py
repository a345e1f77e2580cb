"""The trust boundary: is what a solver returned an admissible solution for its cell?

A solver, shipped or a plugin, is trusted with its numbers but not with their form.  Before a result is
stored or compared with a reference it must be a `Solution` whose sample sets are the ones the scene asks
for (`scene.sample_sets(n)`, the points `solve` reports at by default), at those points, with one real value
or 3-vector per point (finite when the status is ok), and whose summary, work, resolution and parameters hold real
numbers where numbers belong; the whole of it must be JSON.  Anything else raises `Inadmissible`, whose
message names the solver and the first field at fault: the cell's failed status, never a traceback and
never ok.
"""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np

from pcverify.harness.study.catalogue import get_spec
from pcverify.scene import Resolution, Scene, SceneError, shown
from pcverify.solvers.protocol import STATUSES, Solution, Solver

# A returned point may differ from the asked one by round-off only: 1e-9 of the box's largest extent is
# ~1e6 times the rounding of coordinates computed in float64 (a solver recomputing i * a instead of copying),
# and ~1e-6 of the finest lattice spacing the command line allows (n <= 1000), so a point moved by any
# fraction of a spacing that matters (a quarter bar, half a spacing) is refused.
POINT_TOLERANCE = 1e-9

LABELLED = "a real number (int or float), None, true/false, a text label, or a list of them"
COUNTED = "a real number (int or float) or None"


class Inadmissible(Exception):
    """A solver output that is not an admissible solution for its cell (the message names the solver and
    the field).  Not a SceneError: the input was fine, the output is not."""


def admitted(solution: Any, solver: Solver, scene: Scene, resolution: Resolution) -> dict[str, Any]:
    """The JSON-ready dict of `solution` (`Solution.to_dict`) once every check passes; Inadmissible naming the
    solver and the first field that does not."""
    who = f"solver {solver.name!r} returned"
    if not isinstance(solution, Solution):
        raise Inadmissible(f"{who} a {type(solution).__name__} ({shown(solution)}), not a Solution; allowed: a "
                           "pcverify.Solution")
    _identity(solution, scene, who)
    _samples(solution, scene, resolution, who)
    for part, labels in (("summary", True), ("work", False), ("resolution", False)):
        _scalars(getattr(solution, part), part, labels, who)
    _signs(solution.summary, scene, who)
    h = solution.resolution.get("h")
    if h is not None and not (isinstance(h, (int, float, np.integer, np.floating)) and math.isfinite(h) and h > 0):
        raise Inadmissible(f"{who} resolution['h'] = {shown(h)}; allowed: the grid or lattice spacing, a positive "
                           "number (m)")
    _params(solution.params, solver, who)
    try:
        out = solution.to_dict()
    except Exception as exc:  # noqa: BLE001 - a plugin's own Solution subclass: its failure is the cell's
        raise Inadmissible(f"{who} a Solution whose to_dict raised {type(exc).__name__}: {exc}") from None
    if out["status"] != "ok":  # no field: the record names the scene's quantity, whatever the solver left
        out["quantity"] = scene.quantity
    for key, value in out.items():
        try:
            json.dumps(value, allow_nan=False)
        except (TypeError, ValueError) as exc:
            raise Inadmissible(f"{who} {key} that JSON cannot hold ({type(exc).__name__}: {exc})") from None
    return out


def _signs(summary: dict[str, Any], scene: Scene, who: str) -> None:
    """Each summary scalar whose scene family fixes its sign on this scene has that sign (a plugin that reports
    a compressive reaction as positive is named, with the convention)."""
    try:
        contract = get_spec(scene.name).scalars
    except SceneError:  # a scene no family declares: no contract to hold it to
        return
    for scalar in contract:
        value = summary.get(scalar.name)
        want = scalar.sign(scene) if scalar.sign is not None else 0
        if want and isinstance(value, (int, float)) and math.isfinite(value) and value and np.sign(value) != want:
            have, need = ("positive" if value > 0 else "negative"), ("positive" if want > 0 else "negative")
            raise Inadmissible(f"{who} summary[{scalar.name!r}] = {shown(value)}, {have}; allowed: {need} on this "
                               f"scene ({scalar.description})")


def _identity(solution: Solution, scene: Scene, who: str) -> None:
    """The scalar fields: scene, solver, status, reason, quantity, unknowns, wall time, and the dict fields."""
    if solution.scene != scene.name:
        raise Inadmissible(f"{who} scene={shown(solution.scene)}; the cell's scene is {scene.name!r}")
    for name in ("solver", "reason", "quantity"):
        if not isinstance(getattr(solution, name), str):
            raise Inadmissible(f"{who} {name}={shown(getattr(solution, name))}; allowed: text")
    if solution.status not in STATUSES:
        raise Inadmissible(f"{who} status={shown(solution.status)}; allowed: one of {', '.join(STATUSES)}")
    u = solution.unknowns
    if isinstance(u, (bool, np.bool_)) or not isinstance(u, (int, np.integer)) or u < 0:
        raise Inadmissible(f"{who} unknowns={shown(u)}; allowed: an integer >= 0")
    w = solution.wall_s
    if isinstance(w, (bool, np.bool_)) or not isinstance(w, (int, float, np.integer, np.floating)) \
            or not math.isfinite(w) or w < 0:
        raise Inadmissible(f"{who} wall_s={shown(w)}; allowed: a finite number of seconds >= 0")
    for name in ("params", "resolution", "samples", "summary", "work", "diagnostics"):
        if not isinstance(getattr(solution, name), dict):
            raise Inadmissible(f"{who} {name} of type {type(getattr(solution, name)).__name__}; allowed: a dict")


def _real(value: Any) -> np.ndarray | None:
    """`value` as a float array when it holds real numbers only (no bool, complex, text or objects)."""
    try:
        arr = np.asarray(value)
    except (ValueError, TypeError):  # ragged nesting
        return None
    return arr.astype(float) if arr.dtype.kind in "iuf" else None


def _count(count: int, what: str) -> str:
    return f"{count} {what}" + ("" if count == 1 else "s")


def _samples(solution: Solution, scene: Scene, resolution: Resolution, who: str) -> None:
    """Every asked set, at the asked points, one real value (a temperature) or 3-vector (a displacement, a mode
    shape) per point, finite when ok.  A run that is not ok
    may lack sets (it stopped before it had a field); a modal scene's result is its frequencies, so its sets
    are all there or none."""
    asked = scene.sample_sets(resolution.n)
    samples = solution.samples
    extra = [k for k in samples if k not in asked]
    if extra:
        raise Inadmissible(f"{who} samples[{shown(extra[0])}], a set the scene does not ask for; asked: "
                           f"{', '.join(asked)}")
    missing = [k for k in asked if k not in samples]
    optional = solution.status != "ok" or ("modes" in scene.physics and not samples)
    if missing and not optional:
        what = "no sample sets" if not samples else f"no samples[{missing[0]!r}]"
        raise Inadmissible(f"{who} {what}; the scene asks for {', '.join(asked)}")
    size = float(np.max(scene.box.extent))
    for name, entry in samples.items():
        field = f"samples[{name!r}]"
        want = asked[name]
        if not isinstance(entry, dict):
            raise Inadmissible(f"{who} {field} of type {type(entry).__name__}; allowed: a dict with points "
                               "(k x 3) and values (k)")
        for key in ("points", "values"):
            if key not in entry:
                raise Inadmissible(f"{who} {field} without {key!r}; allowed: a dict with points (k x 3) and "
                                   "values (k)")
        unknown = [k for k in entry if k not in ("points", "values")]
        if unknown:
            raise Inadmissible(f"{who} {field}[{shown(unknown[0])}]; allowed: points and values only")
        points, values = _real(entry["points"]), _real(entry["values"])
        if points is None:
            raise Inadmissible(f"{who} {field}['points'] that are not real numbers; allowed: a (k x 3) array "
                               "of coordinates (m)")
        if values is None:
            raise Inadmissible(f"{who} {field}['values'] that are not real numbers ({_kind(entry['values'])}); "
                               "allowed: one real number or 3-vector per point")
        if points.ndim != 2 or points.shape[1] != 3:
            raise Inadmissible(f"{who} {field}['points'] of shape {points.shape}; allowed: ({len(want)}, 3)")
        if len(points) != len(want):
            raise Inadmissible(f"{who} {field} with {_count(len(points), 'point')}; the scene asks for {len(want)}")
        if values.shape not in ((len(want),), (len(want), 3)):
            raise Inadmissible(f"{who} {field}['values'] of shape {values.shape} for {_count(len(want), 'point')}; "
                               f"allowed: ({len(want)},) or ({len(want)}, 3)")
        if not np.all(np.isfinite(points)):
            raise Inadmissible(f"{who} {field} with non-finite point coordinates")
        off = np.max(np.abs(points - want), axis=1)
        far = np.flatnonzero(off > POINT_TOLERANCE * size)
        if far.size:
            i = int(far[0])
            raise Inadmissible(f"{who} {field} at points other than the scene's: {_count(far.size, 'point')} off, "
                               f"the first (point {i}) by {off[i]:.3g} m from "
                               f"({', '.join(f'{c:.6g}' for c in want[i])}) (tolerance {POINT_TOLERANCE * size:.1g} "
                               "m); allowed: the points of scene.sample_sets(n)")
        bad = np.flatnonzero(~np.all(np.isfinite(values.reshape(len(want), -1)), axis=1))
        if bad.size and solution.status == "ok":
            raise Inadmissible(f"{who} {field} with {_count(bad.size, 'non-finite value')} ({values[bad[0]]} at point "
                               f"{int(bad[0])}) and status ok; allowed: finite values, or a status that is not "
                               "ok with its reason")


def _kind(value: Any) -> str:
    try:
        return f"dtype {np.asarray(value).dtype}"
    except (ValueError, TypeError):
        return "ragged"


def _numeric_text(text: str) -> bool:
    """Whether `text` spells a number ("0.5", "1e3", "nan", "1+2j"): a number sent as text."""
    try:
        complex(text.strip())
    except ValueError:
        return False
    return True


def _value_problem(value: Any, labels: bool) -> str | None:
    """Why `value` is not an admissible scalar (or list of scalars), or None when it is.  `labels`: text is
    allowed (a summary's method names and statuses) unless it spells a number."""
    if value is None or isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(
            value, (bool, np.bool_)):
        return None
    if isinstance(value, (bool, np.bool_)):
        return None if labels else "true/false, not a count"
    if isinstance(value, (complex, np.complexfloating)):
        return "a complex number"
    if isinstance(value, str):
        if not labels:
            return "text"
        return "a number as text" if _numeric_text(value) else None
    if isinstance(value, (list, tuple, np.ndarray)):
        items = value.tolist() if isinstance(value, np.ndarray) else value
        for item in items if isinstance(items, list) else [items]:
            if isinstance(item, (list, tuple, dict)):
                return "a nested container"
            problem = _value_problem(item, labels)
            if problem:
                return f"a list holding {problem}"
        return None
    return f"of type {type(value).__name__}"


def _scalars(values: dict[str, Any], part: str, labels: bool, who: str) -> None:
    """Every value of a summary, work or resolution dict is a real number (or an allowed label)."""
    for key, value in values.items():
        problem = _value_problem(value, labels)
        if problem:
            raise Inadmissible(f"{who} {part}[{shown(key)}] = {shown(value)}, {problem}; allowed: "
                               f"{LABELLED if labels else COUNTED}")


def _params(params: dict[str, Any], solver: Solver, who: str) -> None:
    """The effective parameters: a declared one holds a value its Param accepts, any other a scalar."""
    declared = {p.name: p for p in solver.parameters}
    for key, value in params.items():
        spec = declared.get(key)
        if spec is None:
            problem = _value_problem(value, labels=True)
            if problem:
                raise Inadmissible(f"{who} params[{shown(key)}] = {shown(value)}, {problem}; allowed: {LABELLED}")
            continue
        if value is spec.default:
            continue
        try:
            spec.check(value)
        except SceneError:
            problem = _value_problem(value, labels=True) or "not a value it allows"
            raise Inadmissible(f"{who} params[{key!r}] = {shown(value)}, {problem}; allowed: {spec.allowed()}"
                               ) from None
