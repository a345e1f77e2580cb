"""Run a prepared macromolecule lattice and measure it: hotness, energy balance, hops, status.

`simulate` runs the kernel from rest (or a given state) and turns its sums into per-particle hotness (the
time-mean kinetic energy over the window and its two halves).  `run_status` classifies a run: unstable
(NaN, energy growth, left the bar), defect (broken neighbourhood, hops), failed, non-stationary or ok.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import numba
import numpy as np

from pcverify.solvers.energy import balance_error

from . import codes
from .fixes import Fixes
from .force import SevenRoot
from .kernel import FixArrays, RunOutputs, RunParams, RunState, lattice_arrays, run_any, run_p2
from .lattice import Lattice
from .setup import Setup

N_HISTORY = 400
STOP_DOUBLINGS = 4  # a stationarity stop first compares the halves of the window's first eighth


def window_marks(n_start: int, n_end: int, stop_tol: float) -> np.ndarray:
    """The kernel's window marks: without a stop the midpoint and the end; with one, the window's lengths
    L / 16, L / 8, L / 4, L / 2 and L (L = n_end - n_start), so that each tested window is twice the last."""
    if stop_tol <= 0:
        return np.array([(n_start + n_end) // 2, n_end], dtype=np.int64)
    length = n_end - n_start
    return np.array([n_start + (length >> k) for k in range(STOP_DOUBLINGS, -1, -1)], dtype=np.int64)


@dataclass
class RunResult:
    """Raw kernel output plus the derived per-particle hotness."""

    hot: np.ndarray  # (3, N) mean KE over window, first half, second half (J)
    energy: np.ndarray
    counters: np.ndarray
    history: np.ndarray
    ever: np.ndarray
    x: np.ndarray  # final positions
    v: np.ndarray  # final velocities
    wall_s: float
    steps: int
    cpu_s: float  # CPU seconds of this process inside the kernel (robust on a shared machine)

    @property
    def status_code(self) -> int:
        return int(self.counters[codes.K_STATUS])


def simulate(lat: Lattice, model: SevenRoot, fx: Fixes, delta: float, dt: float, t_end: float, t_start: float = 0.0,
             omega: float = 0.0, v0: np.ndarray | None = None, seed: int = 0, blowup_factor: float = 10.0,
             contact_fraction: float = 0.5, check_every: int | None = None, x0: np.ndarray | None = None,
             stop_tol: float = 0.0) -> RunResult:
    """Run the kernel from rest (or from positions x0 and velocities v0; held particles start on their fix)
    and return averaged hotness and diagnostics.  With `stop_tol` > 0 the averaging window grows by doubling
    from a sixteenth of [t_start, t_end] and the run ends at the first window whose halves agree within
    stop_tol (the mean hotness of every free particle, relative to the hottest free one), or at t_end.

    The kernel is compiled or loaded from numba's cache before the clock starts: wall_s and cpu_s are
    the integration alone."""
    run = run_p2 if float(model.p) == 2.0 else run_any
    N, n_steps = lat.size, int(round(t_end / dt))
    n_start = min(int(round(t_start / dt)), n_steps)
    x = lat.positions + fx.amp * np.sin(fx.phase)[:, None]
    if x0 is not None:
        x[~fx.held] = x0[~fx.held]
    v = np.zeros((N, 3)) if v0 is None else np.array(v0, dtype=float)
    v[fx.held] = 0.0
    cutoff = lat.r0.max() * (1 + 1e-9)
    unlisted = 2.0 * lat.a * (1 + 1e-6) if cutoff < 1.999 * lat.a else math.sqrt(5.0) * lat.a
    e_scale = fx.energy_scale(lat.mass, omega)
    args = (
        RunState(x=x, v=v),
        lattice_arrays(lat.positions, lat.mass, lat.a, lat.pairs, lat.r0, lat.shell, model.basins()),
        FixArrays(kind=np.ascontiguousarray(fx.kind, dtype=np.int64), amp=np.ascontiguousarray(fx.amp, dtype=float),
                  phase=np.ascontiguousarray(fx.phase, dtype=float), gamma=np.ascontiguousarray(fx.gamma, dtype=float),
                  kt=np.ascontiguousarray(fx.kt, dtype=float), omega=float(omega), free_centre=bool(fx.free_centre),
                  seed=int(seed)),
        RunParams(coeffs=model.coeffs(), delta=float(delta), dt=float(dt), n_steps=n_steps, n_start=n_start,
                  n_end=n_steps, check_every=int(check_every or max(1, n_steps // N_HISTORY)),
                  blowup_factor=float(blowup_factor), e_scale=float(e_scale), box_lo=-lat.a * np.ones(3),
                  box_hi=lat.positions.max(axis=0) + lat.a, contact_fraction=float(contact_fraction),
                  cutoff_rest=float(cutoff), skin=float(unlisted - contact_fraction * lat.a),
                  marks=window_marks(n_start, n_steps, stop_tol), stop_tol=float(stop_tol)),
        RunOutputs(hot=np.zeros((3, N)), energy=np.zeros(codes.N_ENERGY),
                   counters=np.zeros(codes.N_COUNTERS, dtype=np.int64),
                   history=np.full((N_HISTORY + 2, codes.N_HISTORY_COLUMNS), np.nan),
                   ever=np.zeros(len(lat.pairs), dtype=np.int8)),
    )
    compiled = run.compile(tuple(numba.typeof(a) for a in args))  # compile or load from the cache: not timed
    t0, c0 = time.perf_counter(), time.process_time()
    rows = compiled(*args)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    out = args[-1]
    counters = out.counters
    steps = np.maximum(counters[[codes.K_HOT_STEPS, codes.K_HALF1, codes.K_HALF2]], 1) * dt
    return RunResult(out.hot / steps[:, None], out.energy, counters, out.history[:rows], out.ever, x, v, wall,
                     int(counters[codes.K_STEPS]), cpu)


def initial_velocities(s: Setup, p: dict[str, Any]) -> np.ndarray | None:
    """The seeded random initial velocities of the free particles (`perturbation` > 0), else None (rest)."""
    if p["perturbation"] == 0:
        return None
    scale = p["perturbation"] * s.lattice.a * 2 * np.pi * s.f_top
    return scale * np.random.default_rng(p["seed"]).standard_normal((s.lattice.size, 3))


def run_setup(s: Setup, p: dict[str, Any], dt: float | None = None, **given: Any) -> RunResult:
    """`simulate` a prepared run with the solver's parameters `p` (at its dt, or at `dt`)."""
    return simulate(s.lattice, s.model, s.fixes, s.delta, dt or s.dt, p["t_end"], p["t_start"],
                    2 * np.pi * p["drive_frequency"], v0=initial_velocities(s, p), seed=p["seed"],
                    blowup_factor=p["blowup_factor"], contact_fraction=p["contact_fraction"], stop_tol=p["stop_tol"],
                    **given)


ENERGY_TOL = 1e-2  # relative energy-balance error above which a run is not integrated (shipped runs: <= 3e-4)


def energy_balance_error(r: RunResult) -> float:
    """|E_end - E_start + dissipated - work in| relative to the largest energy flow (`energy.balance_error`)."""
    e = r.energy
    start, end, diss, drive, bath = e[[codes.E_START, codes.E_END, codes.E_DISS, codes.E_DRIVE, codes.E_BATH]]
    return balance_error(end - start + diss, (drive, bath),
                         max(abs(start), abs(end), abs(drive), abs(bath), diss, 1e-300))


def run_status(run: RunResult, H: np.ndarray, free: np.ndarray, p: dict[str, Any]) -> tuple[str, str, dict]:
    """Status and its reason, first that applies: unstable (blow-up, left the bar), defect (pair list wrong,
    hops), failed (energy balance beyond ENERGY_TOL, or no free kinetic energy), non-stationary, ok; and the
    diagnostic numbers."""
    code = run.status_code
    hmax = H[free].max() if free.any() else 0.0
    stat = float(np.max(np.abs(run.hot[1] - run.hot[2])[free]) / hmax) if hmax > 0 else math.nan
    hops = int(run.counters[codes.K_HOP_EVENTS])
    balance = energy_balance_error(run)
    flags = {
        "energy_check_failed": int(not balance <= ENERGY_TOL),  # the check's own verdict, as a number to judge
        "stationarity": stat, "hops": hops, "hopped_pairs": int(run.counters[codes.K_HOP_PAIRS]),
        "first_hop_step": int(run.counters[codes.K_FIRST_HOP]),
        "stopped_at_step": int(run.counters[codes.K_STOP_STEP]) if code != codes.DONE else -1,
        "stationary_at_step": int(run.counters[codes.K_STATIONARY]),
        "kernel_status": codes.STATUS_TEXT[code],
        "running_integral_linearity": _linearity(run.history),
    }
    if code in (codes.NAN, codes.GROWTH, codes.LEFT_BAR):
        return "unstable", f"{codes.STATUS_TEXT[code]}; stopped at step {run.steps}, sums kept", flags
    if code in (codes.ISOLATED, codes.CONTACT):
        return "defect", (f"{codes.STATUS_TEXT[code]}: the fixed pair list is wrong; run stopped at step "
                          f"{run.steps} (not rebuilt), sums kept"), flags
    if hops:
        return "defect", (f"{flags['hopped_pairs']} pairs left their root interval ({hops} hop events, first at "
                          f"step {flags['first_hop_step']}): lattice defects, chaotic regime"), flags
    if flags["energy_check_failed"]:  # also a balance that cannot be formed (NaN): never ok unchecked
        return "failed", (f"energy balance off by {balance:.3g} of the largest energy flow (tolerance "
                          f"{ENERGY_TOL:g}): the time step does not integrate this run accurately (not a "
                          "blow-up); sums kept"), flags
    if not hmax > 0.0:
        return "failed", (f"no free particle has kinetic energy over the window (hottest free hotness {hmax:.3g}, "
                          f"{int(free.sum())} free particles): relative hotness is undefined"), flags
    if not stat <= p["stationarity_tol"]:
        return "non-stationary", (f"hotness changed by {stat:.3g} (of the hottest free) between the halves of the "
                                  f"window; tolerance {p['stationarity_tol']:g}"), flags
    return "ok", "", flags


def _linearity(history: np.ndarray) -> float:
    """Paper's F 8 check: max deviation of the running integral of total KE from its chord, relative."""
    if history.shape[0] < 3:
        return math.nan
    t, e = history[:, codes.H_T], history[:, codes.H_KIN]
    integ = np.concatenate([[0.0], np.cumsum(0.5 * (e[1:] + e[:-1]) * np.diff(t))])
    chord = integ[0] + (integ[-1] - integ[0]) * (t - t[0]) / (t[-1] - t[0])
    return float(np.max(np.abs(integ - chord)) / abs(integ[-1])) if integ[-1] != 0 else math.nan
