"""Reproducing a number: the command that prints a verdict's value, and the part of a study it runs.

A value that is one summary scalar or one error of one cell of a solve task is reproduced by `pcverify run
SCENE --solver S --n N [--refine R] [--set KEY=VALUE ...]`, which prints it (the errors against the scene's
reference included); any other (a fit over a sequence of cells, a stability probe, an aggregate over several
cells, a difference from other rows, a scene or solver that only a study file or plugin defines) by
`pcverify verdict NAME CLAIM [--case CASE]`, which runs the groups the claim reads (finished cells read back
from the cache) and prints the verdict's value, target, error, uncertainty and tolerance.
"""

from __future__ import annotations

import dataclasses
import shlex
from typing import Any

import pandas as pd

from pcverify.harness.judge.tables import params_label
from pcverify.harness.judge.verdict import Command
from pcverify.harness.study.catalogue import entries as scene_entries
from pcverify.harness.study.catalogue import get_spec
from pcverify.harness.study.claims import Claim
from pcverify.harness.study.panels import Panel
from pcverify.harness.study.shipped import study_files
from pcverify.harness.study.study import Group, Study
from pcverify.scene import SceneError
from pcverify.solvers.registry import SolverUnavailable, get_solver
from pcverify.solvers.registry import entries as solver_entries


def table_group(study: Study, table: str) -> str | None:
    """The id of the group that writes `table` (tables are named GROUP-KIND; the longest id wins)."""
    ids = [g.id for g in study.groups if table.startswith(f"{g.id}-")]
    return max(ids, key=len) if ids else None


def _needs(study: Study, group: Group) -> set[str]:
    """Groups whose tables `group` reads (its reference_table option)."""
    ref = group.options.get("reference_table")
    found = table_group(study, ref) if isinstance(ref, str) else None
    return {found} if found else set()


def select_groups(study: Study, ids: list[str]) -> Study:
    """The study restricted to the groups (or calibrations) `ids`, the groups they read tables from, and the
    claims that only read the kept groups' or calibrations' tables; an unknown id raises SceneError naming
    the allowed ones."""
    calibrations = [c.id for c in study.calibrations]
    known = [g.id for g in study.groups] + calibrations
    for gid in ids:
        if gid not in known:
            raise SceneError(f"group={gid!r} is unknown in study {study.name}; allowed: one of {', '.join(known)}")
    keep = set(ids) - set(calibrations)
    kept_calibrations = [c for c in study.calibrations if c.id in ids]
    by_id = {g.id: g for g in study.groups}
    while True:
        more = set().union(*(_needs(study, by_id[g]) for g in keep)) - keep
        more |= {table_group(study, c.against_table) for c in study.claims
                 if c.against_table and table_group(study, c.table) in keep} - keep - {None}
        if not more:
            break
        keep |= more

    def kept(claim: Claim) -> bool:
        return all(table_group(study, t) in keep or any(t.startswith(f"{c.id}-") for c in kept_calibrations)
                   for t in (claim.table, claim.against_table or claim.table))

    def whole(panel: Panel) -> bool:  # a panel is redrawn only when every table it reads is recomputed
        return all(table_group(study, t) in keep for r in panel.rows for t in (r.table, r.reference_table) if t)

    return dataclasses.replace(study, groups=[g for g in study.groups if g.id in keep], selected=tuple(ids),
                               claims=[c for c in study.claims if kept(c)], calibrations=kept_calibrations,
                               panels=[p for p in study.panels if whole(p)])


def study_command(study: Study, groups: list[str]) -> str:
    """`pcverify study NAME --group ID ...` (NAME: the shipped name, else the study file's path)."""
    shipped = study_files().get(study.name)
    name = study.name if shipped is not None and study.path is not None and shipped == study.path else str(study.path)
    return " ".join(["pcverify", "study", shlex.quote(name), *(f"--group {shlex.quote(g)}" for g in groups)])


def _text(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    return repr(value) if isinstance(value, float) else str(value)


def _installed(origin: str) -> bool:
    """Whether a name of this origin is known to every `pcverify` process: shipped or an entry point (not
    one registered by a study file or a plugin module that only a study loads)."""
    return origin == "pcverify" or "entry point" in origin


def run_command(result: dict[str, Any]) -> str | None:
    """`pcverify run ...` that recomputes one cell's solve, or None when the command line cannot reach it
    (a scene or solver that only a study file or its plugin modules define)."""
    scene, solver = result["scene"], result["solver"]
    scene_entry, solver_entry = scene_entries().get(scene), solver_entries().get(solver)
    if scene_entry is None or not _installed(scene_entry.origin):
        return None
    if ":" not in solver and (solver_entry is None or not _installed(solver_entry.origin)):
        return None
    try:
        scene_names = {p.name for p in get_spec(scene).parameters}
        solver_names = {p.name for p in get_solver(solver).parameters}
    except (SceneError, SolverUnavailable):
        return None
    parts = ["pcverify", "run", scene, "--solver", solver, "--n", str(result["n"])]
    if int(result.get("refine") or 1) != 1:
        parts += ["--refine", str(result["refine"])]
    for where, params, own, other in (("scene", result.get("scene_params") or {}, scene_names, solver_names),
                                      ("solver", result.get("solver_params") or {}, solver_names, scene_names)):
        for key, value in sorted(params.items()):
            if key not in own:
                return None
            name = f"{where}.{key}" if key in other else key
            parts += ["--set", f"{name}={_text(value)}"]
    return " ".join(shlex.quote(p) for p in parts)


def _one_cell(rows: pd.DataFrame, results: list[dict[str, Any]]) -> dict[str, Any] | None:
    """The result behind `rows` when they are one row of a table that names one solve cell."""
    if len(rows) != 1 or not {"solver", "n"} <= set(rows.columns):
        return None
    row = rows.iloc[0]
    found = [r for r in results if r["solver"] == row["solver"] and int(r["n"]) == int(row["n"])
             and ("refine" not in row or int(r["refine"]) == int(row["refine"]))
             and ("params" not in row or params_label(r, values="resolved" not in row)
                  == (row["params"] if isinstance(row["params"], str) else ""))]
    return found[0] if len(found) == 1 else None


def verdict_command(study: Study, claim: str, case: str = "") -> str:
    """`pcverify verdict NAME CLAIM [--case CASE]` (NAME: the shipped name, else the study file's path)."""
    shipped = study_files().get(study.name)
    name = study.name if shipped is not None and study.path is not None and shipped == study.path else str(study.path)
    parts = ["pcverify", "verdict", name, claim] + (["--case", case] if case else [])
    return " ".join(shlex.quote(p) for p in parts)


def claim_groups(study: Study, claim: Claim) -> list[str]:
    """The groups and calibrations whose tables a claim reads."""
    ids = []
    for table in (claim.table, claim.against_table or claim.table):
        gid = table_group(study, table)
        ids += [gid] if gid else [c.id for c in study.calibrations if table.startswith(f"{c.id}-")]
    return list(dict.fromkeys(ids))


def claimed(study: Study, calibrations: bool = True) -> Study:
    """The study restricted to the groups (and, with `calibrations`, the calibrations) its claims read and those
    these read tables from: a cell outside them cannot move a claim.  The study itself when that is all of it."""
    skip = set() if calibrations else {c.id for c in study.calibrations}
    ids = sorted({g for c in study.claims for g in claim_groups(study, c)} - skip)
    if not ids:
        return dataclasses.replace(study, groups=[], claims=[])
    every = {g.id for g in study.groups} | {c.id for c in study.calibrations} - skip
    part = select_groups(study, ids)
    whole = {g.id for g in part.groups} | {c.id for c in part.calibrations} == every and not skip
    return study if whole and len(part.claims) == len(study.claims) else part


def _printed_by_run(metric: str, result: dict[str, Any]) -> bool:
    """Whether `pcverify run` prints this metric of this cell by its name: a summary scalar, or an error
    `err.SET.NORM` against the scene's reference."""
    value = (result.get("summary") or {}).get(metric)
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return True
    sample, _, norm = metric.removeprefix("err.").rpartition(".")
    return metric.startswith("err.") and norm in ("l2", "linf") and sample in (result.get("errors") or {})


def verdict_commands(study: Study, results: list[dict[str, Any]]) -> Command:
    """The `command` function of `verdict.verdicts` for this study and its results."""
    solve_groups = {g.id for g in study.groups if g.cells and all(c.task.name == "solve" for c in g.cells)}

    def command(claim: Claim, case: str, value_rows: pd.DataFrame, target_rows: pd.DataFrame | None) -> str:
        gid = table_group(study, claim.table)
        if target_rows is None and gid in solve_groups and not value_rows.empty:
            result = _one_cell(value_rows, [r for r in results if r.get("group") == gid])
            text = run_command(result) if result is not None and _printed_by_run(claim.metric, result) else None
            if text:
                return text
        return verdict_command(study, claim.id, case)

    return command
