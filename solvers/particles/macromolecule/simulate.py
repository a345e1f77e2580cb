"""Run a prepared macromolecule lattice and measure it: hotness, energy balance, hops, status.

`simulate` calls a time-stepping kernel (fast, fastmath or the plain reference; the same scheme, equal
to rounding) from rest and turns its sums into per-particle hotness (the time-mean kinetic energy
over the window and its two halves).  `run_status` classifies a run: unstable (NaN, energy growth, a
particle left the bar), defect (broken neighbourhood, pairs hopped to another root), non-stationary
(the halves disagree) or ok.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from pcverify.scene import SceneError

from . import kernel_fast as fk
from . import kernel_reference as ig
from .fixes import Fixes
from .force import SevenRoot
from .lattice import Lattice

N_HISTORY = 400


@dataclass
class RunResult:
    """Raw kernel output plus the derived per-particle hotness."""

    hot: np.ndarray  # (3, N) mean KE over window, first half, second half (J)
    energy: np.ndarray
    counters: np.ndarray
    history: np.ndarray
    ever: np.ndarray
    x: np.ndarray
    wall_s: float
    steps: int
    cpu_s: float = math.nan  # CPU seconds of this process inside the kernel (robust on a shared machine)

    @property
    def status_code(self) -> int:
        return int(self.counters[ig.K_STATUS])


def simulate(lat: Lattice, model: SevenRoot, fx: Fixes, delta: float, dt: float, t_end: float, t_start: float = 0.0,
             omega: float = 0.0, v0: np.ndarray | None = None, seed: int = 0, blowup_factor: float = 10.0,
             contact_fraction: float = 0.5, check_every: int | None = None, kernel: str = "fast") -> RunResult:
    """Run the kernel from rest (or from velocities v0) and return averaged hotness and diagnostics.

    kernel "fast" (`kernel.run`, the default), "fastmath" (the same with its pair loop compiled with
    `kernel.FASTMATH`) or "reference" (`integrate.run`, the plain one): the same scheme, equal to
    rounding."""
    N = lat.size
    n_steps = int(round(t_end / dt))
    n_start = min(int(round(t_start / dt)), n_steps)
    basins = model.basins()
    lo = np.ascontiguousarray(basins[lat.shell, 0])
    hi = np.ascontiguousarray(basins[lat.shell, 1])
    x = lat.positions + fx.amp * np.sin(fx.phase)[:, None]
    v = np.zeros((N, 3)) if v0 is None else np.array(v0, dtype=float)
    v[fx.kind != ig.FREE] = 0.0
    hot = np.zeros((3, N))
    energy = np.zeros(8)
    counters = np.zeros(9, dtype=np.int64)
    history = np.full((N_HISTORY + 2, 6), np.nan)
    ever = np.zeros(len(lat.pairs), dtype=np.int8)
    check = check_every or max(1, n_steps // N_HISTORY)
    ext = lat.positions.max(axis=0)
    cutoff = lat.r0.max() * (1 + 1e-9)
    unlisted = 2.0 * lat.a * (1 + 1e-6) if cutoff < 1.999 * lat.a else math.sqrt(5.0) * lat.a
    skin = unlisted - contact_fraction * lat.a
    held = fx.kind != ig.FREE
    e_scale = 1.5 * fx.kt.sum() + 0.5 * lat.mass * omega**2 * float((fx.amp[held] ** 2).sum())
    pi, pj = lat.pairs[:, 0].copy(), lat.pairs[:, 1].copy()
    box_lo, box_hi = -lat.a * np.ones(3), ext + lat.a
    if kernel == "reference":
        t0, c0 = time.perf_counter(), time.process_time()
        rows = ig.run(x, v, lat.positions, fx.kind, fx.amp, fx.phase, omega, fx.free_centre, lat.mass, fx.gamma,
                      fx.kt, seed, pi, pj, lat.r0, lo, hi, model.coeffs(), lat.a, delta, dt, n_steps, n_start,
                      n_steps, check, blowup_factor, e_scale, box_lo, box_hi, contact_fraction, cutoff, skin, hot,
                      energy, counters, history, ever)
    elif kernel in ("fast", "fastmath"):
        pint = int(model.p) if float(model.p).is_integer() and 0 <= model.p <= 64 else -1
        g_off, g_base, g_lo, g_hi, mask, slot = fk.stencil(lat.pairs, lat.shell, N, basins)
        t0, c0 = time.perf_counter(), time.process_time()
        rows = fk.run(x, v, lat.positions, fx.kind, fx.amp, fx.phase, omega, fx.free_centre, lat.mass, fx.gamma,
                      fx.kt, seed, pi, pj, g_off, g_base, g_lo, g_hi, mask, slot, pint, lat.a, delta, dt, n_steps,
                      n_start, n_steps, check, blowup_factor, e_scale, box_lo, box_hi, contact_fraction, cutoff, skin,
                      model.coeffs(), lat.r0, hot, energy, counters, history, ever, kernel == "fastmath")
    else:
        raise SceneError(f"kernel={kernel!r} is not allowed; allowed: fast, fastmath, reference")
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    steps = np.maximum(counters[[ig.K_HOT_STEPS, ig.K_HALF1, ig.K_HALF2]], 1) * dt
    return RunResult(hot / steps[:, None], energy, counters, history[:rows], ever, x, wall, int(counters[ig.K_STEPS]),
                     cpu)


def energy_balance_error(r: RunResult) -> float:
    """|E_end - E_start + dissipated - work in| relative to the largest energy flow."""
    e = r.energy
    resid = e[ig.E_END] - e[ig.E_START] + e[ig.E_DISS] - e[ig.E_DRIVE] - e[ig.E_BATH]
    scale = max(abs(e[ig.E_START]), abs(e[ig.E_END]), abs(e[ig.E_DRIVE]), abs(e[ig.E_BATH]), e[ig.E_DISS], 1e-300)
    return float(abs(resid) / scale)


def run_status(run: RunResult, H: np.ndarray, free: np.ndarray, p: dict[str, Any]) -> tuple[str, str, dict]:
    """Status ok / non-stationary / defect / unstable, its reason, and the diagnostic numbers."""
    code = run.status_code
    hmax = H[free].max() if free.any() else 0.0
    h1, h2 = run.hot[1], run.hot[2]
    stat = float(np.max(np.abs(h1 - h2)[free]) / hmax) if hmax > 0 else math.nan
    hops = int(run.counters[ig.K_HOP_EVENTS])
    flags = {
        "stationarity": stat,
        "hops": hops, "hopped_pairs": int(run.counters[ig.K_HOP_PAIRS]),
        "first_hop_step": int(run.counters[ig.K_FIRST_HOP]),
        "stopped_at_step": int(run.counters[ig.K_STOP_STEP]) if code != ig.DONE else -1,
        "kernel_status": ig.STATUS_TEXT[code],
        "running_integral_linearity": _linearity(run.history),
    }
    if code in (ig.NAN, ig.GROWTH, ig.LEFT_BAR):
        return "unstable", f"{ig.STATUS_TEXT[code]}; stopped at step {run.steps}, sums kept", flags
    if code in (ig.ISOLATED, ig.CONTACT):
        return "defect", (f"{ig.STATUS_TEXT[code]}: the fixed pair list is wrong; run stopped at step "
                          f"{run.steps} (not rebuilt), sums kept"), flags
    if hops:
        return "defect", (f"{flags['hopped_pairs']} pairs left their root interval ({hops} hop events, first at "
                          f"step {flags['first_hop_step']}): lattice defects, chaotic regime"), flags
    if not stat <= p["stationarity_tol"]:
        return "non-stationary", (f"hotness changed by {stat:.3g} (of the hottest free) between the halves of the "
                                  f"window; tolerance {p['stationarity_tol']:g}"), flags
    return "ok", "", flags


def _linearity(history: np.ndarray) -> float:
    """Paper's Fig. 8 check: max deviation of the running integral of total KE from its chord, relative."""
    if history.shape[0] < 3:
        return math.nan
    t, e = history[:, ig.H_T], history[:, ig.H_KIN]
    integ = np.concatenate([[0.0], np.cumsum(0.5 * (e[1:] + e[:-1]) * np.diff(t))])
    chord = integ[0] + (integ[-1] - integ[0]) * (t - t[0]) / (t[-1] - t[0])
    return float(np.max(np.abs(integ - chord)) / abs(integ[-1])) if integ[-1] != 0 else math.nan
