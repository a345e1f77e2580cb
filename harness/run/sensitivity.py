"""Which claim sees which input: each model input of a study's cells scaled by (1 + step) where a cell has it,
the study's claims judged again, and per input the claims whose values moved.

An input is a real number a solver is handed: a leaf of a cell's scene value (its box, material constants,
held values, loads, by path: `heat-manufactured:material.conductivity`), the box's size at fixed shape
(`heat-manufactured:box`) or a number parameter its solver declares (`mca:cfl`).  Only the solver sees the
perturbed value (a `Perturbed` task hands it a perturbed copy): the reference, the claims' targets and the
tables' columns keep the study's values, so a perturbation is the defect "the solver reads this input `step`
off", and a claim that sees it would see that defect.  The rules of "moved" and "inert" are in
docs/sensitivity.md.
"""

from __future__ import annotations

import dataclasses
import fnmatch
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from pcverify.harness.judge.group_tables import group_tables
from pcverify.harness.judge.tables import cells_table
from pcverify.harness.judge.verdict import records, verdicts
from pcverify.harness.run.cache import Cache
from pcverify.harness.run.execution import execute, identify
from pcverify.harness.run.perturbation import Perturbed
from pcverify.harness.run.progress import progress_bar
from pcverify.harness.study.study import Cell, Study
from pcverify.scene import SceneError, shown
from pcverify.solvers.registry import SolverUnavailable, get_solver

STEP = 1e-2  # default relative step
MAX_STEP = 0.5
ROUND_OFF = 1e-9  # a move below this share of the value is round-off
TOLERANCE_SHARE = 1e-3  # a move below this share of the claim's tolerance (or bound) is one it could never notice
ROUND_OFF_BASIS = "derived: round-off"  # a tolerance so based bounds round-off: a move within it is round-off
NOT_SOLVER_INPUTS = ("name", "description", "params", "physics")  # a scene's labels and provenance
BOX = "box"  # the input that scales the whole box (its size at fixed shape: a lattice fits it as before)
OUTPUTS = ("status", "samples", "summary")  # what a cell's result says of the physics (`output_change`)
TIMINGS = ("wall_s", "kernel_s", "kernel_wall_s", "kernel_cpu_s", "assembly_s", "solve_s", "postprocess_s",
           "calibrated_wall_s", "cpu_s", "setup_s", "heat_kernel_s", "eigensolve_s", "lammps_wall_s",
           "lammps_cpu_s")  # seconds measured by a clock: not physics


@dataclass(frozen=True)
class Input:
    """One model input: `name` is "OWNER:PATH"; `kind` scene (OWNER a scene, PATH a leaf of its value) or solver
    (OWNER a solver, PATH its parameter)."""

    kind: str
    owner: str
    path: str

    @property
    def name(self) -> str:
        return f"{self.owner}:{self.path}"


def scene_leaves(obj: Any, path: str = "") -> dict[str, float]:
    """The real numbers of a scene value by path (`material.conductivity`, `constraints[0].value`): every field
    of its parts, tuples by index; labels, integers, flags and text are not inputs a relative step can scale."""
    if dataclasses.is_dataclass(obj):
        out: dict[str, float] = {}
        for f in dataclasses.fields(obj):
            if f.name not in NOT_SOLVER_INPUTS and f.init:
                out |= scene_leaves(getattr(obj, f.name), f"{path}.{f.name}" if path else f.name)
        return out
    if isinstance(obj, tuple):
        return {k: v for i, item in enumerate(obj) for k, v in scene_leaves(item, f"{path}[{i}]").items()}
    return {path: float(obj)} if isinstance(obj, (float, np.floating)) and math.isfinite(obj) else {}


def _replaced(obj: Any, parts: list[str], value: float) -> Any:
    """`obj` with the leaf at `parts` (field names and "[i]") set to `value` (each part validated anew); the
    path `box` scales the whole box to the width `value`."""
    head, *rest = parts
    if parts == [BOX]:
        return dataclasses.replace(obj, box=dataclasses.replace(obj.box, **{
            k: v * value / obj.box.width for k, v in scene_leaves(obj.box).items()}))
    if head.startswith("["):
        i = int(head[1:-1])
        return obj[:i] + (_replaced(obj[i], rest, value) if rest else value,) + obj[i + 1:]
    return dataclasses.replace(obj, **{head: _replaced(getattr(obj, head), rest, value) if rest else value})


def _split(path: str) -> list[str]:
    return [p for part in path.split(".") for p in part.replace("[", ".[").split(".") if p]


def solver_numbers(cell: Cell) -> dict[str, float]:
    """The number parameters the cell's solver declares, at their values in the cell (unset ones left out: the
    solver's own rule decides them)."""
    try:
        params = get_solver(cell.solver).parameters
    except SolverUnavailable:
        return {}
    given = dict(cell.solver_params)
    values = {p.name: given.get(p.name, p.default) for p in params if p.kind is float}
    return {k: float(v) for k, v in values.items() if isinstance(v, (int, float)) and not isinstance(v, bool)}


def inputs_of(cell: Cell) -> dict[Input, float]:
    """Every input of a cell that is solved, with its value there."""
    if identify(cell).skip is not None:
        return {}
    leaves = {BOX: cell.scene.box.width} | scene_leaves(cell.scene)
    scene = {Input("scene", cell.scene.name, k): v for k, v in leaves.items()}
    return scene | {Input("solver", cell.solver, k): v for k, v in solver_numbers(cell).items()}


def perturbed_cell(cell: Cell, values: dict[Input, float], item: Input, step: float
                   ) -> tuple[Cell | None, float, str]:
    """(the cell with `item` scaled by 1 + step, or by 1 - step where 1 + step leaves its range; the factor
    used) or (None, nan, why not): the cell does not have it (`values`: its inputs), it is zero or not finite,
    or neither factor is in its range."""
    value = values.get(item)
    if value is None:
        return None, math.nan, "not in this cell"
    if value == 0 or not math.isfinite(value):
        return None, math.nan, f"{value:g}: a relative step leaves it"
    why = ""
    for factor in (1 + step, 1 - step):
        label = f"{item.name} x {factor!r}"
        try:
            if item.kind == "scene":
                task = Perturbed(cell.task, label, scene=_replaced(cell.scene, _split(item.path), value * factor))
            else:
                task = Perturbed(cell.task, label, param=item.path, value=value * factor, original=value)
                task.check(get_solver(cell.solver), dict(cell.solver_params))
            return dataclasses.replace(cell, task=task), factor, ""
        except (SceneError, TypeError, ValueError) as exc:
            why = " ".join(str(exc).split())
    return None, math.nan, f"out of range both ways ({why})"


def study_inputs(study: Study) -> list[Input]:
    """Every input of the study's solved cells, in the order the cells first have them."""
    return list(dict.fromkeys(i for g in study.groups for c in g.cells for i in inputs_of(c)))


def select_inputs(found: list[Input], patterns: list[str] | None, study: str) -> list[Input]:
    """The inputs whose name matches one of `patterns` (exact names or fnmatch globs; all when None), one-line
    SceneError for a pattern that matches none."""
    if not patterns:
        return found
    for pattern in patterns:
        if not any(fnmatch.fnmatchcase(i.name, pattern) for i in found):
            known = ", ".join(i.name for i in found[:12]) + (", ..." if len(found) > 12 else "")
            raise SceneError(f"--input {shown(pattern)} matches no input of study {study}; allowed: an input name or "
                             f"a glob pattern ({known})")
    return [i for i in found if any(fnmatch.fnmatchcase(i.name, p) for p in patterns)]


def judged(study: Study, results: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The verdict records of the study's claims on `results` (tables built as the report builds them, without
    figures or calibrations)."""
    tables: dict[str, Any] = {}
    for g in study.groups:
        res = [r for r in results if r.get("group") == g.id]
        tables |= group_tables(g, res, tables)
        tables.setdefault(f"{g.id}-cells", cells_table(res))
    unplanned = {g.id: {u.solver: u.reason for u in g.unplanned} for g in study.groups}
    return records(verdicts(study.name, study.claims, tables, unplanned=unplanned)) if study.claims else []


def _number(value: Any) -> float:
    return float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else math.nan


def _finite(value: float) -> float | None:
    return value if math.isfinite(value) else None


def case_change(before: dict[str, Any], after: dict[str, Any] | None) -> dict[str, Any]:
    """How one claim case changed: its values, the change, the scale it is held against (the larger uncertainty,
    ROUND_OFF of the value, TOLERANCE_SHARE of the tolerance, or of the target where the tolerance is 0, or the
    whole tolerance where it bounds round-off), `moved` (the change exceeds that scale, or the value appeared or
    vanished) and `verdict_changed`."""
    after = after or {}
    vb, vp = _number(before.get("value")), _number(after.get("value"))
    unc = [u for u in (_number(before.get("uncertainty")), _number(after.get("uncertainty"))) if math.isfinite(u)]
    bound = abs(_number(before.get("tolerance")) or _number(before.get("target")))  # a tolerance 0: the target bounds
    share = 1.0 if str(before.get("tolerance_basis") or "").startswith(ROUND_OFF_BASIS) else TOLERANCE_SHARE
    scale = max([*unc, ROUND_OFF * max(abs(vb), abs(vp)) if math.isfinite(vb + vp) else 0.0,
                 share * bound if math.isfinite(bound) else 0.0])
    delta = vp - vb
    moved = abs(delta) > scale if math.isfinite(delta) else math.isfinite(vb) != math.isfinite(vp)
    return {"case": before.get("case") or "", "before": _finite(vb), "after": _finite(vp), "delta": _finite(delta),
            "relative": _finite(delta / vb if vb else math.nan), "scale": scale, "moved": bool(moved),
            "verdict_before": before.get("verdict"), "verdict_after": after.get("verdict", "missing"),
            "verdict_changed": before.get("verdict") != after.get("verdict", "missing")}


def claim_changes(baseline: list[dict[str, Any]], perturbed: list[dict[str, Any]]) -> dict[str, list[dict[str, Any]]]:
    """Per claim of the baseline, the change of each of its cases (`case_change`)."""
    after = {(r["claim"], r.get("case") or ""): r for r in perturbed}
    out: dict[str, list[dict[str, Any]]] = {}
    for r in baseline:
        out.setdefault(r["claim"], []).append(case_change(r, after.get((r["claim"], r.get("case") or ""))))
    return out


def _numbers(obj: Any) -> list[float]:
    """The numbers of a result's part in order (dicts by key, lists by index; None as NaN), timings left out."""
    if isinstance(obj, dict):
        return [x for k in sorted(obj, key=str) if k not in TIMINGS for x in _numbers(obj[k])]
    if isinstance(obj, (list, tuple)):
        return [x for v in obj for x in _numbers(v)]
    return [math.nan] if obj is None else [] if isinstance(obj, (bool, str)) else [_number(obj)]


def _parts(obj: Any, path: str) -> dict[str, list[float]]:
    """A result's numbers by part: each number outside a list, and each list (a sampled field, a history) whole,
    keyed by its dotted path (timings left out)."""
    if isinstance(obj, dict):
        return {k: v for key in sorted(obj, key=str) if key not in TIMINGS
                for k, v in _parts(obj[key], f"{path}.{key}").items()}
    numbers = _numbers(obj)
    return {path: numbers} if numbers else {}


def _result_parts(result: dict[str, Any]) -> dict[str, list[float]]:
    """The parts (`_parts`) of a cell result's samples and summary."""
    return _parts({k: result[k] for k in OUTPUTS[1:] if result.get(k) is not None}, "")


def part_scales(results: list[dict[str, Any]]) -> dict[str, float]:
    """Each part's largest magnitude over the study's baseline cells (the scale a change of it is held against)."""
    scales: dict[str, float] = {}
    for r in results:
        for name, numbers in _result_parts(r).items():
            size = float(np.nanmax(np.abs(np.array(numbers, float)), initial=0.0))
            scales[name] = max(scales.get(name, 0.0), size)
    return scales


def output_change(before: dict[str, Any], after: dict[str, Any], scales: dict[str, float] | None = None
                  ) -> dict[str, float]:
    """How far each part of a cell's result moved (its samples and summary: a number, or a list such as a sampled
    field or a history), relative to that part's largest magnitude over the study (`scales`, `part_scales`; at
    least its own): a small quantity (a Poisson ratio beside a modulus) is not measured against a large one, and a
    value that is round-off of 0 in one cell (the pair-only MCA's Poisson ratio, 1e-14) against the same quantity
    elsewhere.  {"status": inf} when the status changed; inf for a part whose shape changed or that appeared or
    vanished; parts that did not move are left out."""
    if before.get("status") != after.get("status"):
        return {"status": math.inf}
    pa, pb = _result_parts(before), _result_parts(after)
    out = {}
    for name in sorted(set(pa) | set(pb)):
        a, b = (np.array(p.get(name, []), float) for p in (pa, pb))
        if a.shape != b.shape or not np.array_equal(np.isnan(a), np.isnan(b)):
            out[name.lstrip(".")] = math.inf
            continue
        diff = float(np.nan_to_num(np.abs(b - a), nan=0.0).max(initial=0.0))
        size = max(float(np.nanmax(np.abs(a), initial=0.0)), (scales or {}).get(name, 0.0))
        if diff > 0:
            out[name.lstrip(".")] = diff / size if size > 0 else diff
    return out


def moved_parts(changes: list[dict[str, float]], count: int = 3) -> dict[str, float | str]:
    """The `count` parts that moved most beyond round-off over a perturbation's cells, with their largest change
    ("inf" for a status or a shape that changed: JSON has no infinity)."""
    most: dict[str, float] = {}
    for cell in changes:
        for name, change in cell.items():
            most[name] = max(most.get(name, 0.0), change)
    ranked = sorted(((c, n) for n, c in most.items() if c > ROUND_OFF), reverse=True)[:count]
    return {n: _finite(c) if math.isfinite(c) else "inf" for c, n in ranked}


def not_run(result: dict[str, Any]) -> bool:
    """Whether a cell's solver refused to run it: skipped, or failed before its solve ended (a scene or parameter
    check, an exception), which leaves no cost.  A solve that ran and reported a failed status (an energy
    balance missed near a stability limit) is an outcome of the input, judged like any other."""
    return result.get("status") == "skipped" or (result.get("status") == "failed" and "cost" not in result)


def perturb(study: Study, results: list[dict[str, Any]], baseline: list[dict[str, Any]], item: Input, step: float,
            cache: Cache, jobs: int, found: list[dict[Input, float]], scales: dict[str, float]) -> dict[str, Any]:
    """One input perturbed in every cell that has it (`found`: each cell's inputs): those cells run through
    `cache` (the baseline's `results` stand for the others), the claims judged and compared with `baseline`,
    each part of a result held against its `scales` (`part_scales` of `results`)."""
    cells = [c for g in study.groups for c in g.cells]
    made = [perturbed_cell(c, values, item, step) for c, values in zip(cells, found, strict=True)]
    todo = [i for i, (cell, _, _) in enumerate(made) if cell is not None]
    reasons = sorted({why for cell, _, why in made if cell is None and why != "not in this cell"})
    entry: dict[str, Any] = {"input": item.name, "kind": item.kind, "owner": item.owner, "path": item.path,
                             "cells": len(todo), "factor": made[todo[0]][1] if todo else None}
    if not todo:
        return entry | {"status": "not perturbed", "reason": "; ".join(reasons), "changed_cells": 0, "claims": {}}
    part = dataclasses.replace(study, groups=[dataclasses.replace(study.groups[0], cells=[made[i][0] for i in todo])])
    ran, counts = execute(part, cache, jobs=jobs, progress=False)
    mixed = list(results)
    for i, res in zip(todo, ran, strict=True):
        mixed[i] = res
    refused = [(mixed[i]["status"], mixed[i].get("reason")) for i in todo
               if not_run(mixed[i]) and mixed[i]["status"] != results[i].get("status")]
    if refused:  # the solver refuses the value (a box that no longer fits the lattice, a held value it cannot do)
        return entry | {"status": "refused", "reason": f"{len(refused)} of {len(todo)} cells {refused[0][0]}: "
                        f"{' '.join(str(refused[0][1]).split())[:300]}", "changed_cells": 0, "claims": {}}
    changes = [output_change(results[i], mixed[i], scales) for i in todo]
    moves = [max(c.values(), default=0.0) for c in changes]
    claims = claim_changes(baseline, judged(study, mixed))
    return entry | {"status": "perturbed", "reason": "; ".join(reasons),
                    "changed_cells": sum(m > ROUND_OFF for m in moves), "largest_change": _finite(max(moves)),
                    "moved_parts": moved_parts(changes),
                    "failed_cells": counts["failed"], "computed_cells": counts["done"], "claims": claims}


def sensitivity(study: Study, results: list[dict[str, Any]], baseline: list[dict[str, Any]], items: list[Input],
                step: float, cache: Cache, jobs: int, progress: bool,
                done: Callable[[dict[str, Any]], None] = lambda e: None) -> list[dict[str, Any]]:
    """Every input of `items` perturbed in turn (`perturb`), a progress bar over the inputs."""
    found = [inputs_of(c) for g in study.groups for c in g.cells]
    scales = part_scales(results)
    bar = progress_bar(len(items), f"{study.name}: sensitivity", "input", enabled=progress)
    out = []
    try:
        for item in items:
            bar.set_description(f"{study.name}: {item.name}"[:70])
            out.append(perturb(study, results, baseline, item, step, cache, jobs, found, scales))
            done(out[-1])
            bar.update(1)
    finally:
        bar.close()
    return out
