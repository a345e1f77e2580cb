"""Heat runs of the macromolecule solver on the ensemble kernel: K parameter sets of one scene in one call.

`run_heat` takes the prepared runs (`setup.Setup`) of K parameter sets that share the lattice, the fix
kinds and phases, the roots and STEP of the force, the time step and the run length, and integrates
them as replicas of one `EnsembleRun` (each replica bit-identical to the same set run alone, K = 1).
Per replica: force scale A (from its f_top), envelope exponent p, pair damping delta (from its damping
ratio), drive frequency and amplitude, and the rate of its absorbing face.  The ensemble kernel takes
FREE, FROZEN and PRESCRIBED particles and 0 K baths: the hot face driven, the red pair shared
symmetrically (drive_sharing = "symmetric"), absorbing or frozen far faces; not the red pair's free
centre (GROUP) and not a Langevin (noisy) hot face, which `ensemble_problem` names.

Each replica gives what `simulate.simulate` gives for the fixed-list kernels (a `RunResult`: hotness over
the window and its two halves, counters, a coarse history), measured by checks between chunks of steps
at the same steps for every K: every `check_every` steps (n_steps / 400) the pairs of the rest lattice
are checked against their root intervals and the particles against the bar's neighbourhood.  A replica
with a pair out of its interval (a lattice defect) or a particle out of the bar is retired there with
its sums kept; one that goes non-finite is retired at the step it does.  Differences to the fixed-list
kernels: velocity Verlet with a Verlet list (pairs may change partners in a defect; the fixed list
would break), hotness from v_n after the closing half kick, hops seen at the checks only (a pair out of
its interval for less than check_every steps can be missed), no energy accounting (energy balance
NaN, so `simulate.run_status`, which lets no run be ok unchecked, calls every ensemble run failed), and
the bath applied at the full step.  In a run without defects the two integrate the same
scheme to round-off (tests/test_calibration_ensemble.py compares them).
"""

from __future__ import annotations

import time
from typing import Any

import numba
import numpy as np

from pcverify.scene import SceneError

from ..codes import (
    DONE,
    FREE,
    FROZEN,
    K_FIRST_HOP,
    K_HALF1,
    K_HALF2,
    K_HOP_EVENTS,
    K_HOP_PAIRS,
    K_HOT_STEPS,
    K_STATUS,
    K_STEPS,
    K_STOP_STEP,
    LEFT_BAR,
    N_COUNTERS,
    N_ENERGY,
    N_HISTORY_COLUMNS,
    NAN,
    PRESCRIBED,
)
from ..fixes import make_fixes
from ..force import C_A, C_P
from ..setup import Setup
from ..simulate import N_HISTORY, RunResult
from .ensemble import EnsembleRun

ENSEMBLE = "ensemble"  # the solver's kernel name for this path
PER_REPLICA = ("f_top", "stiffness", "p", "delta", "damping_ratio", "drive_amplitude", "drive_frequency",
               "face_gamma")  # solver parameters a replica may have of its own; every other one is shared


def ensemble_problem(setup: Setup, p: dict[str, Any]) -> str:
    """Why the ensemble kernel cannot run this prepared run ("" if it can)."""
    fx = setup.fixes
    other = sorted(set(np.unique(fx.kind).tolist()) - {FREE, FROZEN, PRESCRIBED})
    if other:
        return ("the red pair's free centre (drive_sharing = free-centre) is a rigid group; the ensemble kernel "
                "takes FREE, FROZEN and PRESCRIBED particles: use drive_sharing = symmetric")
    if (fx.kt > 0).any():
        return "a Langevin (noisy) hot face; the ensemble kernel takes 0 K baths only: use hot_face = driven"
    if p["dt_check"]:
        return "dt_check reruns at dt / 2; run it with a fixed-list kernel"
    return ""


def require_ensemble(setup: Setup, p: dict[str, Any]) -> None:
    """Raise the SceneError naming why the ensemble kernel cannot run this prepared run, if it cannot."""
    why = ensemble_problem(setup, p)
    if why:
        raise SceneError(f"kernel={ENSEMBLE!r} cannot run this scene: {why}")


def shared_key(p: dict[str, Any]) -> tuple:
    """The parameters replicas of one ensemble must share (everything but PER_REPLICA)."""
    return tuple(sorted((k, v) for k, v in p.items() if k not in PER_REPLICA))


def run_heat(scene: Any, setups: list[Setup], params: list[dict[str, Any]], threads: int = 1) -> list[RunResult]:
    """Integrate K prepared runs (one scene, one lattice) as replicas of one ensemble; one RunResult each.

    wall_s and cpu_s of each are the ensemble's divided by K.  `threads`: numba threads of the kernel
    (results do not depend on it; 1 keeps parallel cells from oversubscribing the cores)."""
    k = len(setups)
    if k == 0:
        return []
    s0, p0 = setups[0], params[0]
    for s, p in zip(setups, params, strict=True):
        require_ensemble(s, p)
        if s.dt != s0.dt or shared_key(p) != shared_key(p0) or s.lattice.size != s0.lattice.size:
            raise SceneError("kernel='ensemble': replicas must share the time step and every parameter but "
                             f"{', '.join(PER_REPLICA)}; give dt explicitly to run different f_top together")
    lat = s0.lattice
    unit = make_fixes(scene, lat, p0 | {"drive_amplitude": 1.0}, omega_top=1.0)  # stroke a: amp = unit * D
    bath = (s0.fixes.gamma > 0) & (s0.fixes.kind == FREE)
    gamma = np.array([float(s.fixes.gamma[bath].max()) if bath.any() else 0.0 for s in setups])
    coeffs = [s.model.coeffs() for s in setups]
    dt = s0.dt
    n_steps = int(round(p0["t_end"] / dt))
    n_start = min(int(round(p0["t_start"] / dt)), n_steps)
    n_mid = (n_start + n_steps) // 2
    every = max(1, n_steps // N_HISTORY)
    stops = sorted(set(range(every, n_steps, every)) | {n_start, n_mid, n_steps} - {0})
    previous = numba.get_num_threads()
    numba.set_num_threads(max(1, min(threads, numba.config.NUMBA_NUM_THREADS)))
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        run = EnsembleRun.start(
            lat.positions, lat.mass, lat.a, s0.model, dt, np.array([s.delta for s in setups]),
            np.array([2 * np.pi * p["drive_frequency"] for p in params]),
            np.array([p["drive_amplitude"] for p in params]), kind=s0.fixes.kind, amp=unit.amp, phase=s0.fixes.phase,
            stiffness=np.array([c[C_A] for c in coeffs]), exponent=np.array([c[C_P] for c in coeffs]), bath=bath,
            gamma=gamma, retire=True)
        checks = _Checks(lat, s0.model.basins(), k, dt)
        checks.record(run, 0)
        marks: dict[int, np.ndarray] = {0: run.replica_hot().copy()}
        for stop in stops:
            if run.status == "ok":
                run.advance(stop - run.step)
            checks.check(run)
            checks.record(run, stop)
            if stop in (n_start, n_mid):
                marks[stop] = run.replica_hot().copy()
            if (run.retired_step >= 0).all():
                break
    finally:
        numba.set_num_threads(previous)
    wall, cpu = (time.perf_counter() - t0) / k, (time.process_time() - c0) / k
    end_hot = run.replica_hot()
    out = []
    for r in range(k):
        end = int(run.retired_step[r]) if run.retired_step[r] >= 0 else run.step
        at = {m: h[:, r] for m, h in marks.items()}
        start = at.get(n_start, end_hot[:, r]) if end >= n_start else end_hot[:, r]
        mid = at.get(n_mid, end_hot[:, r]) if end >= n_mid else end_hot[:, r]
        spans = np.array([max(end - n_start, 0), max(min(end, n_mid) - n_start, 0), max(end - max(n_mid, n_start), 0)])
        sums = np.stack([end_hot[:, r] - start, mid - start, end_hot[:, r] - mid])
        counters = checks.counters(r)
        counters[K_STEPS] = end
        counters[K_HOT_STEPS], counters[K_HALF1], counters[K_HALF2] = spans
        if counters[K_STATUS] != DONE:
            counters[K_STOP_STEP] = end
        out.append(RunResult(hot=sums / (np.maximum(spans, 1) * dt)[:, None], energy=np.full(N_ENERGY, np.nan),
                             counters=counters, history=checks.history(r), ever=checks.ever[:, r].astype(np.int8),
                             x=np.ascontiguousarray(run.x[:, r]), wall_s=wall, steps=end, cpu_s=cpu))
    return out


class _Checks:
    """The checks between chunks, per replica: pairs of the rest lattice against their root intervals,
    particles against the bar's neighbourhood, a history row (t, kinetic energy)."""

    def __init__(self, lat: Any, basins: np.ndarray, k: int, dt: float) -> None:
        self.pairs, self.a, self.mass = lat.pairs, lat.a, lat.mass
        self.lo, self.hi = basins[lat.shell, 0], basins[lat.shell, 1]
        self.box = (lat.positions.min(axis=0) - lat.a, lat.positions.max(axis=0) + lat.a)
        self.ever = np.zeros((len(lat.pairs), k), dtype=bool)
        self.events = np.zeros(k, dtype=np.int64)
        self.first = np.full(k, -1, dtype=np.int64)
        self.code = np.full(k, DONE, dtype=np.int64)
        self.rows: list[tuple[int, np.ndarray]] = []
        self.dt = dt

    def check(self, run: EnsembleRun) -> None:
        live = run.retired_step < 0
        x = run.x  # (N, K, 3)
        d = x[self.pairs[:, 1]] - x[self.pairs[:, 0]]
        xr = np.sqrt((d * d).sum(axis=2)) / self.a  # (P, K)
        out = ~((xr >= self.lo[:, None]) & (xr < self.hi[:, None])) & live[None, :]
        bad = ~np.isfinite(x).all(axis=(0, 2)) | ~np.isfinite(run.v).all(axis=(0, 2))
        left = ((x < self.box[0]) | (x > self.box[1])).any(axis=(0, 2))
        self.ever |= out
        self.events += out.sum(axis=0)
        hopped = out.any(axis=0) & ~bad
        self.first[hopped & (self.first < 0)] = run.step
        for r in np.flatnonzero(live):
            if bad[r] or left[r]:
                self.code[r] = NAN if bad[r] else LEFT_BAR
                why = ("NaN/Inf in the state" if bad[r] else
                       "a particle left the bar's neighbourhood (more than a outside)")
                run.retire_replica(int(r), f"{why} at step {run.step}; stopped there, sums kept")
            elif hopped[r]:
                run.retire_replica(int(r), f"{int(out[:, r].sum())} pairs out of their root interval at step "
                                           f"{run.step}: a lattice defect; stopped there, sums kept")
        for r in np.flatnonzero(~live & (self.code == DONE)):  # retired by the kernel (non-finite or left the bar)
            self.code[r] = NAN if "NaN" in run.retired_reason[r] else LEFT_BAR

    def record(self, run: EnsembleRun, step: int) -> None:
        ke = 0.5 * self.mass * (run.v**2).sum(axis=(0, 2))
        self.rows.append((step, np.where(run.retired_step < 0, ke, np.nan)))

    def counters(self, r: int) -> np.ndarray:
        c = np.zeros(N_COUNTERS, dtype=np.int64)
        c[K_HOP_EVENTS] = self.events[r]
        c[K_HOP_PAIRS] = int(self.ever[:, r].sum())
        c[K_FIRST_HOP] = self.first[r]
        c[K_STATUS] = self.code[r]
        c[K_STOP_STEP] = -1
        return c

    def history(self, r: int) -> np.ndarray:
        rows = np.full((len(self.rows), N_HISTORY_COLUMNS), np.nan)
        for i, (step, ke) in enumerate(self.rows):
            rows[i, 0] = step * self.dt
            rows[i, 1] = ke[r]
        return rows[np.isfinite(rows[:, 1])]
