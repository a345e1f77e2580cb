"""`pcverify scenes` and `pcverify solvers`: the catalogue of scenes and the solvers, with their parameters.

`scenes` reads the scene catalogue only (no solver, no numerical library beyond numpy), so it answers at
once; `solvers` imports each solver to list its parameters and model notes.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable
from typing import Any

from pcverify.harness.study.catalogue import entries as scene_entries
from pcverify.harness.study.catalogue import get_spec
from pcverify.scene import Param, SceneError
from pcverify.solvers.protocol import model_notes
from pcverify.solvers.registry import SolverUnavailable, get_solver
from pcverify.solvers.registry import entries as solver_entries


def _param_rows(params: tuple[Param, ...]) -> list[dict[str, Any]]:
    return [
        {"name": p.name, "default": p.default, "allowed": p.allowed(), "unit": p.unit, "description": p.description}
        for p in params
    ]


def list_scenes(args: argparse.Namespace) -> int:
    """`pcverify scenes [NAME] [--json]`: every scene (or the one named) with its description, parameters and
    reference kind; for one scene also its family's summary scalars and those its reference expects."""
    rows, table = [], scene_entries()
    for name in table if args.scene is None else [get_spec(args.scene).name]:
        try:
            spec = get_spec(name)
            ref = spec.reference
            row = {"name": name, "available": True, "origin": table[name].origin, "description": spec.description,
                   "parameters": _param_rows(spec.parameters), "reference": None if ref is None else ref.kind,
                   "scalars": [{"name": s.name, "unit": s.unit, "description": s.description} for s in spec.scalars]}
            if args.scene is not None:
                row["expected"] = ref.scalars(spec.make(), {}) if ref is not None and ref.scalars is not None else {}
            rows.append(row)
        except SceneError as exc:
            rows.append({"name": name, "available": False, "origin": table[name].origin, "reason": str(exc),
                         "parameters": []})
    return _print_entries(rows, args.json, _scene_lines, (12, 10))


def _scene_lines(row: dict[str, Any], origin: str) -> str:
    lines = [f"{row['name']}{origin}", f"  {row['description']}", f"  reference: {row['reference']}"]
    lines += [f"    expected {k:<30} {v:.9g}" for k, v in row.get("expected", {}).items()]
    lines += [f"  summary scalar {s['name']:<24} [{s['unit'] or '-'}] {s['description']}"
              for s in row["scalars"] if "expected" in row]
    return "\n".join(lines)


def list_solvers(args: argparse.Namespace) -> int:
    """`pcverify solvers [--json]`: every solver, its kind, parameters and model notes."""
    rows = []
    for name, entry in sorted(solver_entries().items()):
        try:
            solver = get_solver(name)
            doc = (type(solver).__doc__ or "").strip()
            rows.append({"name": name, "available": True, "kind": solver.kind, "origin": entry.origin,
                         "description": doc.splitlines()[0] if doc else "",
                         "stability_probe": hasattr(solver, "stability_probe"),
                         "parameters": _param_rows(solver.parameters), "notes": list(model_notes(solver))})
        except (SolverUnavailable, SceneError, TypeError) as exc:
            rows.append({"name": name, "available": False, "origin": entry.origin, "reason": str(exc),
                         "parameters": []})
    return _print_entries(rows, args.json,
                          lambda row, origin: f"{row['name']}  ({row['kind']}) {row['description']}{origin}".rstrip(),
                          (16, 14))


def _print_entries(rows: list[dict[str, Any]], as_json: bool, headline: Callable[[dict[str, Any], str], str],
                   widths: tuple[int, int]) -> int:
    """The `scenes` and `solvers` listings: JSON, or per entry its headline (given the entry and its origin
    note) and a line per parameter (name and default in columns of `widths`); an unavailable entry says why."""
    if as_json:
        print(json.dumps(rows, indent=1))
        return 0
    for row in rows:
        if not row["available"]:
            print(f"{row['name']}  (unavailable: {row['reason']})")
            continue
        print(headline(row, "" if row["origin"] == "pcverify" else f"  [{row['origin']}]"))
        for p in row["parameters"]:
            print(f"    {p['name']:<{widths[0]}} default {p['default']!s:<{widths[1]}} {p['allowed']:<40} "
                  f"{p['description']}")
        if row.get("notes"):
            print("  model notes (departures from the source and choices it leaves open):")
            for k, note in enumerate(row["notes"], 1):
                print(f"    {k}. {note}")
    return 0
