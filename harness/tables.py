"""Turn cached cell results into tables: convergence (errors, orders, Richardson/GCI) and timing.

Input is the list of JSON-ready results a study produced; output is pandas DataFrames
that the report writes as CSV, Markdown and plots.  Nothing here runs a solver or evaluates a reference:
the errors are those the compare step stored with each cell (`pcverify.harness.compare`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pandas as pd

from pcverify.harness.catalogue import make_scene
from pcverify.harness.metrics import observed_order, richardson


def spacing(result: dict[str, Any]) -> float:
    """h of a cell: the solver's own, else the lattice spacing a / refine of its scene."""
    h = (result.get("resolution") or {}).get("h")
    if h is None:
        box = make_scene(result["scene"], **result.get("scene_params", {})).box
        h = box.width / (result["n"] - 1) / result["refine"]
    return float(h)


def scalars(result: dict[str, Any]) -> dict[str, Any]:
    """The scalar summary of a cell, with a list of frequencies spread into f1_hz, f2_hz, ..."""
    summary = result.get("summary") or {}
    out = {k: v for k, v in summary.items() if isinstance(v, (int, float)) or v is None}
    out.update({f"f{k + 1}_hz": f for k, f in enumerate(summary.get("frequencies_hz") or []) if f is not None})
    return out


def cells_table(results: list[dict[str, Any]]) -> pd.DataFrame:
    """One row per cell: identity, cost, status and every summary scalar."""
    rows = []
    for r in results:
        row = {k: r.get(k) for k in ("group", "scene", "solver", "n", "refine", "status", "reason", "unknowns",
                                     "wall_s")}
        row["h"] = spacing(r) if r.get("n") else None
        row["params"] = ", ".join(f"{k}={v}" for k, v in sorted((r.get("solver_params") or {}).items()))
        row["scene_params"] = ", ".join(f"{k}={v}" for k, v in sorted((r.get("scene_params") or {}).items()))
        row.update(scalars(r))
        for k, v in (r.get("work") or {}).items():
            if isinstance(v, (int, float)):
                row[f"work.{k}"] = v
        if r.get("status") == "ok":
            row.update({f"err.{k}": v for k, v in stored_errors(r).items()})
        rows.append(row)
    return pd.DataFrame(rows)


def stored_errors(result: dict[str, Any]) -> dict[str, float]:
    """The errors the compare step stored with a cell, as columns "<set>.l2" / "<set>.linf" (absolute, against
    the scene's reference; empty when it has none; NaN where an error is not finite)."""
    return {f"{name}.{kind}": math.nan if e.get(kind) is None else float(e[kind])
            for name, e in (result.get("errors") or {}).items() for kind in ("l2", "linf") if kind in e}


def convergence(results: list[dict[str, Any]], quantities: list[str],
                reference: dict[str, float] | None = None) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(levels, fits): per sequence (solver + params) the values by h, and the fitted orders / GCI.

    With an analytic reference the fit is of the error (L2 and Linf per sample set) against h (`monotone`
    says whether the fitted errors decrease with every refinement; if not, the order is pre-asymptotic);
    with a `reference` value per quantity (e.g. an extrapolated continuum result) of the relative
    error err.<quantity>; without either, three-grid Richardson extrapolation with the GCI on
    each summary quantity.
    """
    ok = [r for r in results if r.get("status") == "ok"]
    rows = []
    for r in ok:
        row = {"solver": r["solver"], "params": ", ".join(f"{k}={v}" for k, v in sorted(r["solver_params"].items())),
               "n": r["n"], "refine": r["refine"], "h": spacing(r), "unknowns": r["unknowns"],
               "wall_s": r["wall_s"]}
        values = scalars(r)
        row.update({q: values.get(q) for q in quantities})
        row.update(stored_errors(r))
        for q, ref in (reference or {}).items():
            if values.get(q) is not None and ref:
                row[f"err.{q}"] = abs(values[q] - ref) / abs(ref)
        rows.append(row)
    levels = pd.DataFrame(rows)
    fits = []
    if levels.empty:
        return levels, pd.DataFrame()
    for (solver, params), seq in levels.groupby(["solver", "params"], sort=False):
        seq = seq.sort_values("h", ascending=False)
        h = seq["h"].to_numpy(float)
        err_cols = [c for c in seq.columns if c.endswith((".l2", ".linf")) or c.startswith("err.")]
        for col in err_cols:
            e = seq[col].to_numpy(float)
            if len(h) >= 2 and np.all(e > 0):
                finest = min(len(h), 4)
                p, _ = observed_order(h, e, finest=finest)
                kind = "extrapolated" if col.startswith("err.") else "analytic"
                fits.append({"solver": solver, "params": params, "quantity": col, "reference": kind,
                             "levels": len(h), "order": p, "finest": e[-1], "extrapolated": 0.0,
                             "gci_fine": np.nan, "kind": "error",
                             "monotone": bool(np.all(np.diff(e[-finest:]) < 0))})
        if err_cols:
            continue
        for q in quantities:
            f = seq[q].to_numpy(float)
            if len(h) < 3 or not np.all(np.isfinite(f)):
                continue
            try:
                rr = richardson(h, f)
            except ValueError as exc:
                fits.append({"solver": solver, "params": params, "quantity": q, "reference": "richardson",
                             "levels": len(h), "kind": f"undefined ({exc})"})
                continue
            fits.append({"solver": solver, "params": params, "quantity": q, "reference": "richardson",
                         "levels": len(h), "order": rr.order, "finest": f[-1], "extrapolated": rr.extrapolated,
                         "gci_fine": rr.gci_fine, "kind": rr.kind, "monotone": rr.kind == "monotonic"})
    return levels, pd.DataFrame(fits)


def timing(results: list[dict[str, Any]]) -> pd.DataFrame:
    """Unknowns against wall time (and its parts) per solver."""
    rows = [{"solver": r["solver"], "n": r["n"], "refine": r["refine"], "unknowns": r["unknowns"],
             "wall_s": r["wall_s"], **{k: v for k, v in (r.get("work") or {}).items() if k != "unknowns"}}
            for r in results if r.get("status") == "ok"]
    df = pd.DataFrame(rows)
    return df.sort_values(["solver", "unknowns"]) if not df.empty else df


def work_counter(result: dict[str, Any]) -> tuple[str, float]:
    """(name, value) of the work a cell did: pair-steps for particles, unknowns x time steps for grids."""
    work = result.get("work") or {}
    if work.get("pair_steps"):
        return "pair-steps", float(work["pair_steps"])
    steps = max(int(work.get("time_steps") or 1), 1)
    return "unknown-steps", float(result.get("unknowns") or 0) * steps


def work_precision(results: list[dict[str, Any]], error: str = "nodes.l2") -> pd.DataFrame:
    """Error against the reference (stored with the cell) with the wall time and work counter of every ok
    cell."""
    rows = []
    for r in results:
        if r.get("status") != "ok":
            continue
        errors = stored_errors(r)
        if error not in errors:
            continue
        name, work = work_counter(r)
        rows.append({"solver": r["solver"], "n": r["n"], "refine": r["refine"], "unknowns": r["unknowns"],
                     "wall_s": r["wall_s"], "kernel_s": (r.get("summary") or {}).get("kernel_s"),
                     "work": work, "work_kind": name, f"err.{error}": errors[error],
                     "timing": r.get("timing", "parallel pass")})
    df = pd.DataFrame(rows)
    return df.sort_values(["solver", "wall_s"]) if not df.empty else df
