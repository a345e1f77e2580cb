"""`pcverify run`: one scene solved by one solver, through the path a study's cells take.

The cell goes through `execution.run_cell` (a worker process with the time limit, BLAS on one thread, the
boundary checks, the compare step), so `run` prints the numbers a study stores for that cell, errors against
the reference included: the command a verdict prints to reproduce its number.
"""

from __future__ import annotations

import argparse
import json
from typing import Any

import numpy as np

from pcverify.harness.run.execution import identify, run_cell
from pcverify.harness.run.limits import check_work
from pcverify.harness.run.progress import working
from pcverify.harness.run.workers import describe_exception, output_to_stderr
from pcverify.harness.study.catalogue import get_spec, make_scene
from pcverify.harness.study.settings import split_settings
from pcverify.harness.study.study import Cell
from pcverify.scene import Resolution, SceneError
from pcverify.solvers.protocol import skipped
from pcverify.solvers.registry import get_solver


def run_one_cell(args: argparse.Namespace) -> int:
    """`pcverify run SCENE --solver NAME`: solve the cell, print its solution (or one JSON object with --json).
    Exit 1 when the cell failed.  What the solver prints goes to stderr; the result's `solver` is the name given
    to --solver."""
    with output_to_stderr():
        spec = get_spec(args.scene)
        resolution = Resolution(args.n, args.refine)
        solver = get_solver(args.solver)
        try:
            scene_vals, solver_vals = split_settings(args.set or [], spec.parameters, solver.parameters)
        except (SceneError, KeyboardInterrupt):
            raise
        except BaseException as exc:  # noqa: BLE001 - a plugin's own Param: one line, never a traceback
            raise SceneError(f"--set: the parameters of solver {args.solver!r} raised {describe_exception(exc)}"
                             ) from None
        scene = make_scene(args.scene, **scene_vals)
        cell = Cell("run", scene, tuple(sorted(scene_vals.items())), args.solver, resolution.n, resolution.refine,
                    tuple(sorted(solver_vals.items())))
        skip = identify(cell).skip  # the parameters check: a bad value is one error line
        if skip is None:
            check_work(solver, scene, resolution, solver_vals, args.allow_large, label=args.solver)
        with working(f"{args.solver} on {scene.name} n={resolution.n} refine={resolution.refine}", not args.json):
            result = run_cell(cell, raise_scene_errors=True, time_limit=args.time_limit)
    # every key of a solution, also for a skipped or failed cell (a public interface: keys are never dropped)
    out = skipped(scene, solver, resolution, "").to_dict() | result
    out["scene_params"] = scene.param_dict
    out["scene_hash"] = scene.content_hash()
    out.setdefault("errors", {})
    code = 1 if out["status"] == "failed" else 0
    if args.json:
        print(json.dumps(out))
        return code
    print_solution(out, scene.name, scene.param_dict, args.solver, resolution)
    return code


def print_solution(out: dict[str, Any], scene: str, scene_params: dict[str, Any], solver: str,
                   resolution: Resolution) -> None:
    """The solution of one cell as text: scene, solver, grid, status, summary, samples and errors."""
    print(f"scene    {scene}  {scene_params}")
    print(f"solver   {solver}  {out['params']}")
    print(f"grid     n={resolution.n} refine={resolution.refine} unknowns={out['unknowns']}  "
          f"wall {out['wall_s']:.3f} s")
    print(f"status   {out['status']}{'  (' + out['reason'] + ')' if out['reason'] else ''}")
    for key, value in out["summary"].items():
        print(f"  {key:<24} {value}")
    for name, s in out["samples"].items():
        v = np.asarray(s["values"], dtype=float)
        span = f"in [{np.nanmin(v):.6g}, {np.nanmax(v):.6g}]" if np.isfinite(v).any() else "not finite"
        print(f"  {name:<24} {v.size} points, {out['quantity']} {span}")
    for name, e in out["errors"].items():
        shown_errors = "  ".join(f"{k} {'n/a' if e.get(k) is None else repr(e[k])}" for k in ("l2", "linf"))
        print(f"  error {name:<18} {shown_errors}  (absolute, against the {e['reference']} reference)")
    for name, e in (out.get("scalar_errors") or {}).items():
        err = "n/a" if e.get("error") is None else f"{e['error']:.4g}"
        print(f"  error {name:<18} {e['value']} against {e['expected']}: relative {err}  ({e['reference']})")
