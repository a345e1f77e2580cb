"""Calibration: fit a solver's free parameters on calibration cells, then judge them on held-out cells.

The search is a space-filling design (`scipy.stats.qmc`) over the free parameters, then bounded Nelder-Mead in
the unit cube from the best design points, until the `budget` of solver runs is spent or the simplex
converges.  Every evaluation is a study cell run through `execution.execute` and its cache, so an interrupted
calibration resumes and a rerun computes nothing.  A run whose status is not ok is a failure of that parameter
set: shown in the trace, penalised, never in an objective, a range or a noise estimate.  After the search: the
objective's noise from replicas at the optimum, the parameter sets within that noise of the best (where the
data cannot tell the parameters apart), a one-at-a-time sensitivity, and the validation cells at the
calibrated values beside the defaults, each row saying whether it was "calibrated on" or "validated on".
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd
from scipy import optimize
from scipy.stats import qmc

from pcverify.harness.judge.metrics import richardson
from pcverify.harness.judge.tables import scalars, spacing, stored_errors, work_counter
from pcverify.harness.run.cache import Cache
from pcverify.harness.run.execution import execute, identify
from pcverify.harness.study.calibspec import CalibCell, Calibration
from pcverify.harness.study.study import Cell, Group, Study
from pcverify.scene import SceneError

PENALTY = 1e6  # objective handed to the local search for a failed parameter set (steers it away; never data)
CALIBRATED, VALIDATED = "calibrated on", "validated on"


class NotCached(RuntimeError):
    """A cell the calibration needs is not in the cache (report rebuilt without computing)."""


class BudgetSpent(RuntimeError):
    """The search's budget of solver runs is used up."""


@dataclass
class Outcome:
    """What a calibration produced: its tables (by name) and counts of solver runs and cache hits."""

    calibration: Calibration
    tables: dict[str, pd.DataFrame]
    runs: int = 0
    hits: int = 0
    best: dict[str, float] = field(default_factory=dict)


class _Evaluator:
    """Runs cells of one calibration through `execute` and keeps the ledger of parameter-set evaluations."""

    def __init__(self, study: Study, cal: Calibration, cache: Cache, jobs: int, compute: bool,
                 rerun: frozenset[str] | None = None, allow_large: bool = False) -> None:
        self.study, self.cal, self.cache, self.jobs, self.compute = study, cal, cache, jobs, compute
        self.rerun, self.allow_large = rerun, allow_large
        self.runs = self.hits = 0
        self.search_runs = 0
        self.ledger: list[dict[str, Any]] = []
        self.memo: dict[tuple, dict[str, Any]] = {}
        self.references: dict[tuple, tuple[float, str]] = {}

    def cell(self, cc: CalibCell, solver: str, params: dict[str, Any], n: int | None = None,
             refine: int | None = None) -> Cell:
        return Cell(self.cal.id, cc.scene, cc.scene_params, solver, cc.n if n is None else n,
                    cc.refine if refine is None else refine, tuple(sorted(params.items())),
                    plugins=self.study.plugins, plugin_folder=self.study.plugin_folder if self.study.plugins else None)

    def run(self, cells: list[Cell]) -> list[dict[str, Any]]:
        """Results of `cells` in order, through the harness's execution path and cache."""
        if not cells:
            return []
        if not self.compute:
            for c in cells:
                if self.cache.load(identify(c).key)[0] is None:
                    raise NotCached(f"calibration {self.cal.id}: {c.describe()} is not cached")
        mini = Study(f"{self.study.name}.{self.cal.id}", self.cal.title,
                     [Group(self.cal.id, self.cal.title, "table", cells)], plugins=self.study.plugins,
                     path=self.study.path)
        results, counts = execute(mini, self.cache, jobs=self.jobs, progress=False, rerun=self.rerun,
                                  allow_large=self.allow_large)
        self.hits += counts["cached"]
        self.runs += counts["done"]
        return results

    # -- references and errors

    def prepare_references(self) -> None:
        """The reference value of every cell with a solver reference (one batch of continuum cells)."""
        wanted: dict[tuple, list[Cell]] = {}
        for cc in (*self.cal.calibrate, *self.cal.validate):
            ref = cc.reference
            if ref is None:
                continue
            key = (cc.key(), cc.metric, ref)
            if key not in wanted:
                wanted[key] = [self.cell(cc, ref.solver, dict(ref.solver_params), n=ref.n or cc.n, refine=r)
                               for r in ref.refine]
        flat = [c for cells in wanted.values() for c in cells]
        results = iter(self.run(flat))
        for key, cells in wanted.items():
            res = [next(results) for _ in cells]
            metric = key[1]
            bad = [r for r in res if r.get("status") != "ok"]
            if bad:
                self.references[key] = (math.nan, f"reference {bad[0].get('status')}: "
                                                               f"{bad[0].get('reason', '')}")
                continue
            values = np.array([scalars(r).get(metric, math.nan) for r in res], dtype=float)
            if len(res) >= 3:
                try:
                    rr = richardson(np.array([spacing(r) for r in res]), values)
                    self.references[key] = (rr.extrapolated, f"Richardson {rr.kind}, order "
                                                                           f"{rr.order:.2f}, GCI {rr.gci_fine:.1e}")
                except ValueError as exc:
                    self.references[key] = (math.nan, f"Richardson undefined ({exc})")
            else:
                self.references[key] = (float(values[0]), "")
        self._check_zero_references()

    def _check_zero_references(self) -> None:
        """A relative error against a reference of exactly 0 is undefined: refused in one line naming the cell,
        before the search spends a run (the cell can say error = "absolute")."""
        for cc in (*self.cal.calibrate, *self.cal.validate):
            if cc.reference is not None and cc.error == "relative" and self.reference(cc) == 0.0:
                raise SceneError(f"calibration {self.cal.id}: cell {cc.describe()} {cc.metric}: its reference "
                                 f"({cc.reference_label()}) is 0, so a relative error is undefined; allowed: "
                                 'error = "absolute" for this cell, or a reference that is not 0')

    def reference(self, cc: CalibCell) -> float:
        if cc.reference is None:
            return math.nan
        return self.references[(cc.key(), cc.metric, cc.reference)][0]

    def error(self, cc: CalibCell, result: dict[str, Any]) -> tuple[float, float]:
        """(value, error) of one cell's result; NaN for a run that is not ok."""
        if result.get("status") != "ok":
            return math.nan, math.nan
        if cc.reference is None:
            e = stored_errors(result).get(cc.metric, math.nan)
            return e, e
        v = scalars(result).get(cc.metric)
        ref = self.reference(cc)
        if v is None or not math.isfinite(ref):
            return math.nan, math.nan
        d = abs(float(v) - ref)
        return float(v), d / abs(ref) if cc.error == "relative" else d

    # -- parameter sets

    def evaluate(self, thetas: list[dict[str, float]], phase: str, fixed: dict[str, Any] | None = None,
                 search: bool = False) -> list[dict[str, Any]]:
        """Ledger rows of parameter sets (objective: RMS of the calibration cells' errors, NaN on failure).
        A set already evaluated under the same fixed parameters is not evaluated (nor counted) again."""
        fixed = dict(self.cal.solver_params) | (fixed or {})
        rows: list[dict[str, Any] | None] = []
        todo = []
        for theta in thetas:
            key = (tuple(sorted(theta.items())), tuple(sorted(fixed.items())))
            rows.append(self.memo.get(key))
            if rows[-1] is None and key not in [k for k, _ in todo]:
                todo.append((key, theta))
        if search and self.search_runs + len(todo) * len(self.cal.calibrate) > self.cal.budget:
            raise BudgetSpent
        cells = [self.cell(cc, self.cal.solver, fixed | theta) for _, theta in todo for cc in self.cal.calibrate]
        results = iter(self.run(cells))
        for key, theta in todo:
            res = [next(results) for _ in self.cal.calibrate]
            errors = [self.error(cc, r)[1] for cc, r in zip(self.cal.calibrate, res, strict=True)]
            failed = [r for r in res if r.get("status") != "ok"]
            status = failed[0].get("status", "failed") if failed else "ok"
            objective = float(np.sqrt(np.mean(np.square(errors)))) if not failed else math.nan
            if not failed and not math.isfinite(objective):
                status = "no-metric"
            work = [work_counter(r) for r in res]
            row = {"evaluation": len(self.ledger) + 1, "phase": phase, **theta, "objective": objective,
                   "status": status, "reason": failed[0].get("reason", "") if failed else "",
                   "wall_s": float(sum(r.get("wall_s") or 0.0 for r in res)),
                   "work": float(sum(w for _, w in work)), "work_kind": work[0][0],
                   **{k: v for k, v in fixed.items() if (k, v) not in self.cal.solver_params}}
            self.ledger.append(row)
            self.memo[key] = row
            if search:
                self.search_runs += len(self.cal.calibrate)
        return [r if r is not None else self.memo[(tuple(sorted(t.items())), tuple(sorted(fixed.items())))]
                for r, t in zip(rows, thetas, strict=True)]


def _design(cal: Calibration) -> np.ndarray:
    """The space-filling design in the unit cube (seeded: the same points every run)."""
    d, m = len(cal.parameters), min(cal.design_points, cal.budget // max(len(cal.calibrate), 1))
    if m < 1:
        return np.zeros((0, d))
    if cal.design == "sobol":
        sampler = qmc.Sobol(d, scramble=True, seed=cal.seed)
        pts = sampler.random_base2(max(int(math.ceil(math.log2(m))), 0))[:m]
    else:
        pts = qmc.LatinHypercube(d, seed=cal.seed).random(m)
    return np.asarray(pts, dtype=float)


def _theta(cal: Calibration, u: np.ndarray) -> dict[str, float]:
    return {p.name: p.from_unit(x) for p, x in zip(cal.parameters, u, strict=True)}


def _unit(cal: Calibration, theta: dict[str, float]) -> np.ndarray:
    return np.array([p.to_unit(theta[p.name]) for p in cal.parameters])


def _local(ev: _Evaluator, cal: Calibration, u0: np.ndarray, share: int) -> None:
    """Bounded Nelder-Mead in the unit cube from u0, for at most `share` solver runs of the search."""
    d = len(u0)
    step = 0.15
    simplex = [u0] + [u0 + np.where(np.arange(d) == i, step if u0[i] + step <= 1 else -step, 0.0) for i in range(d)]
    limit = ev.search_runs + share

    def fun(u: np.ndarray) -> float:
        if ev.search_runs + len(cal.calibrate) > limit:
            raise BudgetSpent
        row = ev.evaluate([_theta(cal, u)], "local", search=True)[0]
        return row["objective"] if row["status"] == "ok" else PENALTY

    try:
        optimize.minimize(fun, u0, method="Nelder-Mead", bounds=[(0.0, 1.0)] * d,
                          options={"initial_simplex": np.clip(np.array(simplex), 0.0, 1.0), "xatol": 1e-3,
                                   "fatol": 0.0, "maxfev": 10 * share + d + 1})
    except BudgetSpent:
        pass


def run_calibration(study: Study, cal: Calibration, cache: Cache, jobs: int = 1, compute: bool = True,
                    rerun: frozenset[str] | None = None, allow_large: bool = False, progress: bool = False) -> Outcome:
    """Search, noise, ranges, sensitivity and validation of one calibration; every run a cached cell.
    `compute` False: read everything from the cache (NotCached if a cell is missing); `rerun` and
    `allow_large` as for `execute` (cells are recomputed once per request); `progress`: one line per phase
    on stderr."""
    ev = _Evaluator(study, cal, cache, jobs, compute, rerun, allow_large)

    def say(phase: str) -> None:
        if progress:
            print(f"calibration {cal.id}: {phase} ({ev.runs} solver runs, {ev.hits} cached so far)", file=sys.stderr)

    say("references")
    ev.prepare_references()
    design = [_theta(cal, u) for u in _design(cal)]
    say(f"{cal.design} design of {len(design)} sets")
    rows = ev.evaluate(design, "design", search=True) if design else []
    say("local search")
    order = sorted((r for r in rows if r["status"] == "ok"), key=lambda r: r["objective"])
    for k, start in enumerate(order[:cal.starts]):
        left = cal.budget - ev.search_runs
        if left < len(cal.calibrate):
            break
        _local(ev, cal, _unit(cal, {p.name: start[p.name] for p in cal.parameters}), left // (cal.starts - k))
    searched = [r for r in ev.ledger if r["status"] == "ok"]
    if not searched:
        return _outcome(ev, cal, None, math.nan, [], [])
    best = min(searched, key=lambda r: (r["objective"], r["evaluation"]))
    theta = {p.name: best[p.name] for p in cal.parameters}
    say("replicas, sensitivity and validation")
    replicas = [ev.evaluate([theta], "replica", fixed={k: v})[0] for k, values in cal.replicas for v in values]
    finite = [best["objective"]] + [r["objective"] for r in replicas if r["status"] == "ok"]
    noise = float(np.std(finite, ddof=1)) if len(finite) >= 2 else 0.0
    sens = _sensitivity(ev, cal, theta)
    return _outcome(ev, cal, best, noise, replicas, sens)


def _sensitivity(ev: _Evaluator, cal: Calibration, theta: dict[str, float]) -> list[dict[str, Any]]:
    """One-at-a-time: each parameter moved by +- sensitivity_step of its (log) range from the optimum."""
    u = _unit(cal, theta)
    thetas, where = [], []
    for i, p in enumerate(cal.parameters):
        for sign in (-1.0, 1.0):
            ui = u.copy()
            ui[i] = min(max(u[i] + sign * cal.sensitivity_step, 0.0), 1.0)
            if ui[i] != u[i]:
                thetas.append(_theta(cal, ui))
                where.append((p.name, sign))
    rows = ev.evaluate(thetas, "sensitivity")
    out = []
    for p in cal.parameters:
        entry: dict[str, Any] = {"parameter": p.name}
        for (name, sign), row in zip(where, rows, strict=True):
            if name == p.name:
                side = "minus" if sign < 0 else "plus"
                entry[f"value_{side}"] = row[p.name]
                entry[f"objective_{side}"] = row["objective"]
                entry[f"status_{side}"] = row["status"]
        out.append(entry)
    return out


def _outcome(ev: _Evaluator, cal: Calibration, best: dict[str, Any] | None, noise: float,
             replicas: list[dict[str, Any]], sens: list[dict[str, Any]]) -> Outcome:
    """The tables of a finished calibration (validation included)."""
    trace = pd.DataFrame(ev.ledger)
    if not trace.empty:
        ok = trace["status"].eq("ok") & trace["phase"].isin(["design", "local"])
        trace["best_so_far"] = trace["objective"].where(ok).cummin().ffill()
    validation, default_summary = _validation(ev, cal, best)
    band = math.nan
    params_rows, ranges = [], {}
    if best is not None:
        band = best["objective"] + max(cal.noise_factor * noise, cal.noise_floor)
        pool = trace[trace["status"].eq("ok") & trace["phase"].isin(["design", "local", "sensitivity"])]
        inside = pool[pool["objective"] <= band]
        for p in cal.parameters:
            ranges[p.name] = (float(inside[p.name].min()), float(inside[p.name].max()))
        sens_by = {s["parameter"]: s for s in sens}
        for p in cal.parameters:
            s = sens_by.get(p.name, {})
            params_rows.append({"parameter": p.name, "role": CALIBRATED, "log": p.log, "low": p.low, "high": p.high,
                                "default": _default(cal, p.name, default_summary), "calibrated": best[p.name],
                                "at_bound": p.to_unit(best[p.name]) <= 1e-9 or p.to_unit(best[p.name]) >= 1 - 1e-9,
                                "range_low": ranges[p.name][0], "range_high": ranges[p.name][1],
                                "sets_in_band": len(inside), "objective_best": best["objective"],
                                "objective_minus": s.get("objective_minus"), "objective_plus": s.get("objective_plus"),
                                "status_minus": s.get("status_minus"), "status_plus": s.get("status_plus"),
                                "value_minus": s.get("value_minus"), "value_plus": s.get("value_plus")})
    noise_rows = [{"replica": ", ".join(f"{k}={v}" for k, v in r.items() if k not in (
        "evaluation", "phase", "objective", "status", "reason", "wall_s", "work", "work_kind")
        and k not in {p.name for p in cal.parameters}), "objective": r["objective"], "status": r["status"],
        "reason": r["reason"], "role": CALIBRATED} for r in replicas]
    held = validation[validation["role"] == VALIDATED]
    matched = held["within_tolerance"].astype(bool)
    fitted = validation[validation["role"] == CALIBRATED]
    summary: dict[str, Any] = {"calibration": cal.id, "solver": cal.solver, "calibrated": "; ".join(
        f"{p.name} = {best[p.name]:.4g} in [{ranges[p.name][0]:.4g}, {ranges[p.name][1]:.4g}]"
        for p in cal.parameters) if best else "no parameter set ran ok"}
    for p in cal.parameters:  # the calibrated values and their ranges, then the numbers, each marked
        summary[f"{p.name} [calibrated on]"] = best[p.name] if best else math.nan
        summary[f"{p.name} range [calibrated on]"] = (f"[{ranges[p.name][0]:.4g}, {ranges[p.name][1]:.4g}]"
                                                      if p.name in ranges else "")
    summary |= {"objective [calibrated on]": best["objective"] if best else math.nan,
                "default objective [calibrated on]": _rms(fitted["default_error"]),
                "replica_mean [calibrated on]": _mean([r["objective"] for r in replicas if r["status"] == "ok"]
                                                      + ([best["objective"]] if best else [])),
                "noise [calibrated on]": noise, "band [calibrated on]": band,
                "tolerance [validated on]": cal.tolerance, "cells [validated on]": len(held),
                "cells_matched [validated on]": int(matched.sum()),
                "cells_not_matched [validated on]": int(len(held) - matched.sum()),
                "max_error_ok_cells [validated on]": _max(held["calibrated_error"]),
                "max_default_error_ok_cells [validated on]": _max(held["default_error"]),
                "evaluations": len(ev.ledger), "search_runs": ev.search_runs, "budget": cal.budget,
                "failed_sets": int((trace["status"] != "ok").sum()) if not trace.empty else 0,
                "solver_runs": ev.runs, "cache_hits": ev.hits,
                "wall_s per search evaluation": _search_cost(trace, "wall_s"),
                "work per search evaluation": _search_cost(trace, "work")}
    tables = {f"{cal.id}-summary": pd.DataFrame([summary]), f"{cal.id}-parameters": pd.DataFrame(params_rows),
              f"{cal.id}-trace": trace, f"{cal.id}-noise": pd.DataFrame(noise_rows),
              f"{cal.id}-validation": validation}
    return Outcome(cal, tables, ev.runs, ev.hits, {p.name: best[p.name] for p in cal.parameters} if best else {})


def _search_cost(trace: pd.DataFrame, column: str) -> float:
    """The mean cost (solver wall time or work) of one evaluation of the search (design and local phases)."""
    if trace.empty:
        return math.nan
    return float(trace.loc[trace["phase"].isin(["design", "local"]), column].mean())


def _rms(errors: pd.Series) -> float:
    """RMS of errors (NaN if any is NaN: a failed run has no error), the objective's own combination."""
    e = pd.to_numeric(errors, errors="coerce").to_numpy(float)
    return float(np.sqrt(np.mean(e * e))) if e.size else math.nan


def _mean(values: list[float]) -> float:
    """Mean objective of the best set and its ok replicas: the best alone is the lowest of many noisy draws
    (optimistic); this is the level a rerun at the calibrated values should expect."""
    return float(np.mean(values)) if values else math.nan


def _max(errors: pd.Series) -> float:
    """Largest finite error (cells whose run is not ok have none; they are counted as not matched)."""
    e = pd.to_numeric(errors, errors="coerce").to_numpy(float)
    e = e[np.isfinite(e)]
    return float(e.max()) if e.size else math.nan


def _default(cal: Calibration, name: str, summary: dict[str, Any]) -> Any:
    """The solver's default of a free parameter; an unset optional one as the default run reports it."""
    value = cal.defaults.get(name)
    if value is None and summary.get(name) is not None:
        return f"{summary[name]:g} (unset: the solver's own)"
    return value


def _validation(ev: _Evaluator, cal: Calibration, best: dict[str, Any] | None
                ) -> tuple[pd.DataFrame, dict[str, Any]]:
    """Every calibration and validation cell at the calibrated values and at the solver's defaults, and the
    summary scalars of the first default run (the effective values of unset parameters)."""
    fixed = dict(cal.solver_params)
    cells = [(CALIBRATED, cc) for cc in cal.calibrate] + [(VALIDATED, cc) for cc in cal.validate]
    theta = {p.name: best[p.name] for p in cal.parameters} if best else None
    batch = [ev.cell(cc, cal.solver, fixed) for _, cc in cells]
    if theta is not None:
        batch += [ev.cell(cc, cal.solver, fixed | theta) for _, cc in cells]
    results = ev.run(batch)
    fitted_runs = {c.key() for c in cal.calibrate}
    rows = []
    for i, (role, cc) in enumerate(cells):
        default = results[i]
        calibrated = results[len(cells) + i] if theta is not None else {"status": "not-run", "wall_s": math.nan}
        dv, de = ev.error(cc, default)
        cv, ce = ev.error(cc, calibrated)
        ref = ev.references.get((cc.key(), cc.metric, cc.reference), (math.nan, ""))
        rows.append({"role": role, "cell": f"{cc.describe()} {cc.metric}", "solver": cal.solver,
                     "scene": cc.scene.name, "n": cc.n,
                     "metric": cc.metric,
                     "error_kind": "field" if cc.reference is None else cc.error, "reference": cc.reference_label(),
                     "reference_value": ref[0], "reference_note": ref[1], "calibrated_value": cv,
                     "calibrated_error": ce, "calibrated_status": calibrated.get("status"),
                     "calibrated_reason": calibrated.get("reason", ""), "calibrated_wall_s": calibrated.get("wall_s"),
                     "default_value": dv, "default_error": de, "default_status": default.get("status"),
                     "default_reason": default.get("reason", ""),
                     "within_tolerance": bool(calibrated.get("status") == "ok" and ce <= cal.tolerance),
                     "shares_calibration_run": role == VALIDATED and cc.key() in fitted_runs})
    return pd.DataFrame(rows), scalars(results[0])
