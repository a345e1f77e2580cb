"""Turn cached cell results into tables: convergence (errors, orders, Richardson/GCI) and timing.

Input is the list of JSON-ready results a study produced; output is pandas DataFrames
that the report writes as CSV, Markdown and plots.  Nothing here runs a solver or evaluates a reference:
the errors are those the compare step stored with each cell (`pcverify.harness.judge.compare`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pandas as pd

from pcverify.harness.judge.metrics import fit_order, richardson, self_convergence
from pcverify.harness.study.catalogue import make_scene


def spacing(result: dict[str, Any]) -> float:
    """h of a cell: the solver's own, else the lattice spacing a / refine of its scene."""
    h = (result.get("resolution") or {}).get("h")
    if h is None:
        box = make_scene(result["scene"], **result.get("scene_params", {})).box
        h = box.width / (result["n"] - 1) / result["refine"]
    return float(h)


def params_label(result: dict[str, Any], values: bool = True) -> str:
    """A cell's solver parameters as the tables write them (column `params`): "k=v, ...", a parameter given as
    an expression of the resolution as "k=v (= EXPR)", or with values=False as "k=EXPR" alone (what a
    convergence sequence has in common: its value changes from level to level)."""
    expressions = result.get("expressions") or {}
    parts = []
    for k, v in sorted((result.get("solver_params") or {}).items()):
        if k not in expressions:
            parts.append(f"{k}={v}")
        else:
            parts.append(f"{k}={v:.6g} (= {expressions[k]})" if values else f"{k}={expressions[k]}")
    return ", ".join(parts)


def scalars(result: dict[str, Any]) -> dict[str, Any]:
    """The scalar summary of a cell, with its lists of frequencies spread: all modes into f1_hz, f2_hz, ..., the
    modes a continuum has (a particle model's rotational modes left out) into fc1_hz, fc2_hz, ..."""
    summary = result.get("summary") or {}
    out = {k: v for k, v in summary.items() if isinstance(v, (int, float)) or v is None}
    for key, prefix in (("frequencies_hz", "f"), ("continuum_frequencies_hz", "fc")):
        out.update({f"{prefix}{k + 1}_hz": f for k, f in enumerate(summary.get(key) or []) if f is not None})
    return out


def cells_table(results: list[dict[str, Any]]) -> pd.DataFrame:
    """One row per cell: identity, cost, status and every summary scalar."""
    rows = []
    for r in results:
        row = {k: r.get(k) for k in ("group", "scene", "solver", "n", "refine", "status", "reason", "unknowns",
                                     "wall_s")}
        row["h"] = spacing(r) if r.get("n") else None
        row["params"] = params_label(r)
        shown = {k.removeprefix("scene."): v for k, v in (r.get("expressions") or {}).items() if k.startswith("scene.")}
        row["scene_params"] = ", ".join(f"{k}={v:.6g} (= {shown[k]})" if k in shown else f"{k}={v}"
                                        for k, v in sorted((r.get("scene_params") or {}).items()))
        row.update(scalars(r))
        for k, v in (r.get("work") or {}).items():
            if isinstance(v, (int, float)):
                row[f"work.{k}"] = v
        if r.get("status") == "ok":
            row.update({f"err.{k}": v for k, v in stored_errors(r).items()})
        for q, e in (r.get("scalar_errors") or {}).items():  # a scalar reference: expected value, relative error
            row[f"ref.{q}"] = math.nan if e.get("expected") is None else float(e["expected"])
            row[f"err.{q}"] = math.nan if e.get("error") is None else float(e["error"])
        rows.append(row)
    return pd.DataFrame(rows)


def stored_errors(result: dict[str, Any]) -> dict[str, float]:
    """The errors the compare step stored with a cell, as columns "<set>.l2" / "<set>.linf" (absolute, against
    the scene's reference; empty when it has none; NaN where an error is not finite)."""
    return {f"{name}.{kind}": math.nan if e.get(kind) is None else float(e[kind])
            for name, e in (result.get("errors") or {}).items() for kind in ("l2", "linf") if kind in e}


def _level_label(n: int, refine: int, refined: bool) -> str:
    return f"n={n}/refine={refine}" if refined else f"n={n}"


def _not_ok(seq: pd.DataFrame, refined: bool) -> str:
    """The cells of a sequence that are not ok, in words ("" if none): what a fit over it lost."""
    lost = seq[seq["status"] != "ok"]
    return "; ".join(f"{_level_label(r.n, r.refine, refined)} {r.status}" + (f" ({r.reason})" if r.reason else "")
                     for r in lost.itertuples())


def convergence(results: list[dict[str, Any]], quantities: list[str],
                reference: dict[str, dict[str, Any]] | None = None, self_reference: bool = False
                ) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(levels, fits): per sequence (solver + params) the values by h, and the fitted orders / GCI.

    Every cell is a level row with its status; only ok levels enter a fit, which names the levels it used
    (`used`) and the cells of its sequence that were not ok (`missing`), so a claim on a fit that lost a cell
    cannot pass.  The fit is of the stored errors against h (an analytic reference; `monotone`: whether they
    decrease with every refinement), of the relative error err.<quantity> against a `reference` per quantity
    (value, uncertainty, Richardson class), or else a three-grid Richardson extrapolation with the GCI of each
    quantity.  With `self_reference` each sample set is also compared with the sequence's own finest level
    (`self_fits`).
    """
    rows = []
    for r in results:
        ok = r.get("status") == "ok"
        row = {"solver": r["solver"], "params": params_label(r, values=False), "n": r["n"], "refine": r["refine"],
               "h": spacing(r), "unknowns": r.get("unknowns"),
               "wall_s": r.get("wall_s"), "status": r.get("status"), "reason": r.get("reason") or ""}
        if r.get("expressions"):
            row["resolved"] = params_label(r)
        row["cpu_s"] = (r.get("cost") or {}).get("cpu_s", np.nan)
        row["cold"] = (r.get("cost") or {}).get("cold", np.nan)  # a first solve: imports and compilation included
        values = scalars(r)
        row.update({q: values.get(q) for q in quantities})
        if ok:
            row.update(stored_errors(r))
        for q, ref in (reference or {}).items():
            if ok and values.get(q) is not None and ref["value"]:
                row[f"err.{q}"] = abs(values[q] - ref["value"]) / abs(ref["value"])
                row[f"err.{q}_unc"] = abs(ref["unc"]) / abs(ref["value"])
                row["reference_class"] = ref["kind"]
        rows.append(row)
    levels = pd.DataFrame(rows)
    fits = []
    if levels.empty:
        return levels, pd.DataFrame()
    if self_reference:
        fits += self_fits(levels, results)
    for (solver, params), whole in levels.groupby(["solver", "params"], sort=False):
        refined = whole["refine"].nunique() > 1 or bool((whole["refine"] != 1).any())
        missing = _not_ok(whole, refined)
        seq = whole[whole["status"] == "ok"].sort_values("h", ascending=False)
        h = seq["h"].to_numpy(float)
        labels = [_level_label(n, k, refined) for n, k in zip(seq["n"], seq["refine"], strict=True)]
        head = {"solver": solver, "params": params, "cells": len(whole), "missing": missing}
        err_cols = [c for c in seq.columns if (c.endswith((".l2", ".linf")) or c.startswith("err."))
                    and not c.endswith("_unc") and not c.startswith("self.")]
        for col in err_cols:
            e = seq[col].to_numpy(float)
            if len(h) >= 2 and np.all(e > 0):
                finest = min(len(h), 4)
                fit = fit_order(h, e, finest=finest)
                kind = "extrapolated" if col.startswith("err.") else "analytic"
                row = head | {"quantity": col, "reference": kind, "levels": len(h), "used": ", ".join(labels[-finest:]),
                              "order": fit.order, "order_unc": fit.order_se, "finest": e[-1], "extrapolated": 0.0,
                              "gci_fine": np.nan, "kind": "error",
                              "monotone": bool(np.all(np.diff(e[-finest:]) < 0))}
                if "reference_class" in seq:
                    row["reference_class"] = seq["reference_class"].iloc[-1]
                fits.append(row)
        if err_cols:
            continue
        for q in quantities:
            f = seq[q].to_numpy(float)
            if len(h) < 3 or not np.all(np.isfinite(f)):
                continue
            used = ", ".join(labels[-3:])
            try:
                rr = richardson(h, f)
            except ValueError as exc:
                fits.append(head | {"quantity": q, "reference": "richardson", "levels": len(h), "used": used,
                                    "kind": f"undefined ({exc})"})
                continue
            fits.append(head | {"quantity": q, "reference": "richardson", "levels": len(h), "used": used,
                                "order": rr.order, "finest": f[-1], "extrapolated": rr.extrapolated,
                                "extrapolated_unc": rr.uncertainty, "gci_fine": rr.gci_fine, "kind": rr.kind,
                                "monotone": rr.kind == "monotonic"})
    return levels, pd.DataFrame(fits)


def self_fits(levels: pd.DataFrame, results: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Self-convergence of every sequence (solver + params, its ok levels coarse to fine): for each sample set all
    its levels have and each norm, the levels' difference from the finest level (written into `levels` as
    self.<set>.<norm>, nan at the finest), from the next finer one (self.<set>.<norm>_next) and a fit of
    reference "self" (`metrics.self_convergence`: the order of the successive differences, the finest level's
    GCI, and its kind: self, or why the sequence is not asymptotic); a set the levels cannot be compared on is
    a fit row whose kind says why."""
    fits = []
    for (solver, params), whole in levels.groupby(["solver", "params"], sort=False):
        refined = whole["refine"].nunique() > 1 or bool((whole["refine"] != 1).any())
        seq = whole[whole["status"] == "ok"].sort_values("h", ascending=False)
        labels = [_level_label(n, k, refined) for n, k in zip(seq["n"], seq["refine"], strict=True)]
        head = {"solver": solver, "params": params, "cells": len(whole), "missing": _not_ok(whole, refined),
                "reference": "self", "levels": len(seq), "used": ", ".join(labels)}
        samples = [results[i].get("samples") or {} for i in seq.index]
        if len(seq) < 2:
            continue
        for name in sorted(set.intersection(*(set(s) for s in samples))):
            fields = [(np.asarray(s[name]["points"], float), np.asarray(s[name]["values"], float)) for s in samples]
            for norm in ("l2", "linf"):
                column = f"self.{name}.{norm}"
                try:
                    sc = self_convergence(seq["h"].to_numpy(float), fields, norm)
                except ValueError as exc:
                    fits.append(head | {"quantity": column, "kind": f"undefined ({exc})"})
                    continue
                levels.loc[seq.index, column] = sc.to_finest
                levels.loc[seq.index, f"{column}_next"] = sc.to_next  # what the order is fitted on
                fits.append(head | {"quantity": column, "order": sc.order, "order_unc": sc.order_se,
                                    "finest": sc.to_next[-2], "extrapolated": np.nan, "gci_fine": sc.gci_fine,
                                    "kind": sc.kind, "monotone": sc.monotone})
    return fits


def _not_ok_row(r: dict[str, Any]) -> dict[str, Any]:
    """The row of a cell that is not ok in a table of measurements: who it is, its status and why."""
    return {"solver": r["solver"], "n": r["n"], "refine": r["refine"], "status": r.get("status"),
            "reason": r.get("reason") or "", "unknowns": np.nan, "wall_s": np.nan}


def cost_columns(result: dict[str, Any]) -> dict[str, Any]:
    """The cost of a cell as the timing tables write it: `cpu_s` (the solve's CPU seconds) and `cpu_s_unc` (the
    range of a timed cell's repeats, max - min; NaN from one solve), `kernel_s` and
    `setup_s` (its time loop or linear solve, and the rest), and for a timed cell its pass (`run`, `machine`,
    `started`), the solves it took (`repeats`: the least CPU time is the cost) and `timing` (how it was timed:
    "serial after warm-up", or "parallel pass" for a cell of an untimed group)."""
    cost = result.get("cost") or {}
    timing = result.get("timing")
    timing = timing if isinstance(timing, dict) else {"kind": timing or "parallel pass"}
    samples = [float(s) for s in timing.get("cpu_s_samples") or []]
    return {"cpu_s": cost.get("cpu_s", np.nan),
            "cpu_s_unc": max(samples) - min(samples) if len(samples) > 1 else np.nan,
            "kernel_s": cost.get("kernel_s", np.nan),
            "setup_s": cost.get("setup_s", np.nan), "cold": cost.get("cold", np.nan),
            "timing": timing.get("kind", "parallel pass"),
            "repeats": timing.get("repeats", 1), "run": timing.get("run", "unknown"),
            "machine": timing.get("machine", "unknown"), "started": timing.get("started", "")}


def timing(results: list[dict[str, Any]]) -> pd.DataFrame:
    """Unknowns against CPU and wall time (and the solver's own parts) per solver; a cell that is not ok is a row
    with its status."""
    rows = [{"solver": r["solver"], "n": r["n"], "refine": r["refine"], "status": "ok", "unknowns": r["unknowns"],
             "wall_s": r["wall_s"], **cost_columns(r),
             **{k: v for k, v in (r.get("work") or {}).items() if k not in ("unknowns", "kernel_s")}}
            if r.get("status") == "ok" else _not_ok_row(r) for r in results]
    df = pd.DataFrame(rows)
    return df.sort_values(["solver", "n", "refine"], kind="stable") if not df.empty else df  # not by a clock


def work_counter(result: dict[str, Any]) -> tuple[str, float]:
    """(name, value) of the work a cell did: pair-steps for particles, unknowns x time steps for grids."""
    work = result.get("work") or {}
    if work.get("pair_steps"):
        return "pair-steps", float(work["pair_steps"])
    steps = max(int(work.get("time_steps") or 1), 1)
    return "unknown-steps", float(result.get("unknowns") or 0) * steps


def work_precision(results: list[dict[str, Any]], error: str = "nodes.l2") -> pd.DataFrame:
    """Error against the reference (stored with the cell) with the wall time and work counter of every ok cell;
    a cell that is not ok is a row with its status (no error: a claim on it cannot pass)."""
    rows = []
    for r in results:
        if r.get("status") != "ok":
            rows.append(_not_ok_row(r))
            continue
        errors = stored_errors(r)
        name, work = work_counter(r)
        rows.append({"solver": r["solver"], "n": r["n"], "refine": r["refine"], "status": "ok",
                     "unknowns": r["unknowns"], "wall_s": r["wall_s"], **cost_columns(r),
                     "work": work, "work_kind": name, f"err.{error}": errors.get(error, np.nan)})
    df = pd.DataFrame(rows)
    return df.sort_values(["solver", "n", "refine"], kind="stable") if not df.empty else df  # not by a clock
