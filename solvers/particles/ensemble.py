"""Ensemble runs: K replicas of one lattice, each with its own damping, drive amplitude and drive
frequency, integrated in one kernel (parameter sweeps of the macromolecule model).

Replicas share the rest lattice, the fixes (kinds, drive directions, phases), the time step and
one neighbour list: the union of every replica's Verlet list (`neighbours.merge_lists`), valid
for replica k while no particle of k has moved more than skin/2 from its own build positions.
State is laid out (N, K, 3) so that the gather over particle i's row reads the K copies of a
neighbour j together: one index load and one cache line serve all replicas.

Each replica performs exactly the floating-point operations of a single `scaling.KernelRun` with
its parameters, in the same order (same pair term, same row order, pairs beyond r_cut skipped,
not added as zeros), so every replica is bit-identical to its single run: the ensemble changes
throughput, never results.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from harness.scene import SceneError

from .neighbours import build_neighbours, dist2, merge_lists
from .scaling import (
    DEFAULT_R_CUT,
    DEFAULT_SKIN,
    DONE,
    EXPIRED,
    PRESCRIBED,
    LatticeRun,
    check_range,
    drift,
    initial_state,
    kick,
    kinetic_dt,
    pair_term,
)
from .seven_root import SevenRoot


@njit(cache=True, parallel=True, error_model="numpy")
def gather_ensemble(x, v, start, index, c, inv_a, rc2, delta, f):
    """f[i, k] = sum over row i of replica k's pair terms (delta[k]); overwrites f."""
    nk = x.shape[1]
    for i in prange(x.shape[0]):
        for k in range(nk):
            f[i, k, 0] = 0.0
            f[i, k, 1] = 0.0
            f[i, k, 2] = 0.0
        for p in range(start[i], start[i + 1]):
            j = index[p]
            for k in range(nk):
                dx = x[j, k, 0] - x[i, k, 0]
                dy = x[j, k, 1] - x[i, k, 1]
                dz = x[j, k, 2] - x[i, k, 2]
                r2 = dx * dx + dy * dy + dz * dz
                if r2 >= rc2:
                    continue
                tx, ty, tz = pair_term(dx, dy, dz, v[j, k, 0] - v[i, k, 0], v[j, k, 1] - v[i, k, 1],
                                       v[j, k, 2] - v[i, k, 2], r2, c, inv_a, delta[k])
                f[i, k, 0] += tx
                f[i, k, 1] += ty
                f[i, k, 2] += tz


@njit(cache=True, parallel=True, error_model="numpy")
def advance_ensemble(x, v, f, x_rest, kind, amp, scale, phase, omega, mass, dt, step0, n_steps, start, index, x_ref,
                     half_skin, c, inv_a, rc2, delta, hot, resume):
    """Velocity-Verlet steps of all replicas (see scaling.advance; amp of replica k = amp * scale[k]).

    Returns (steps completed, status); EXPIRED as in scaling.advance (any replica's particle moved
    more than half_skin from x_ref: rebuild, then resume at the force pass).
    """
    n = x.shape[0]
    nk = x.shape[1]
    lim2 = half_skin * half_skin
    h = 0.5 * dt / mass
    inv_dt = 1.0 / dt
    s = 0  # step loop as scaling.advance (bodies shared); kept twice: (N, K, 3) state, per-replica force pass
    while s < n_steps:
        t0 = (step0 + s) * dt
        t1 = (step0 + s + 1) * dt
        if not resume:
            over = 0
            for i in prange(n):
                for k in range(nk):
                    drift(x, v, f, x_rest, amp, (i, k), i, kind[i], scale[k], omega[k], phase[i], t0, t1, h, dt,
                          inv_dt)
                    if not dist2(x, (i, k), x_ref, (i, k)) <= lim2:
                        over += 1
            if over > 0:
                return s, EXPIRED
        resume = False
        gather_ensemble(x, v, start, index, c, inv_a, rc2, delta, f)
        for i in prange(n):
            for k in range(nk):
                kick(v, f, amp, (i, k), i, kind[i], scale[k], omega[k], phase[i], t1, h)
                hot[i, k] += kinetic_dt(v, (i, k), mass, dt)
        s += 1
    return s, DONE


def _param_vector(name: str, values: np.ndarray | float, k: int, low: float, unit: str) -> np.ndarray:
    out = np.broadcast_to(np.asarray(values, dtype=np.float64), (k,)).copy()
    bad = ~np.isfinite(out) | (out < low)
    if bad.any():
        raise SceneError(f"{name}[{int(np.flatnonzero(bad)[0])}]={out[bad][0]!r} is out of range; allowed: number in "
                         f"[{low:g}, inf) {unit}".rstrip())
    return out


@dataclass(eq=False, kw_only=True)
class EnsembleRun(LatticeRun):
    """K replicas of one lattice advanced together; hot (N, K) holds sum KE dt per replica.

    A replica that becomes non-finite or leaves the bar stops all replicas (status, reason name them)."""

    scale: np.ndarray
    omega: np.ndarray
    delta: np.ndarray
    x_ref: np.ndarray

    @classmethod
    def start(cls, x_rest: np.ndarray, mass: float, a: float, model: SevenRoot, dt: float, delta: np.ndarray | float,
              omega: np.ndarray | float, scale: np.ndarray | float = 1.0, replicas: int | None = None,
              kind: np.ndarray | None = None, amp: np.ndarray | None = None, phase: np.ndarray | None = None,
              v0: np.ndarray | None = None, x0: np.ndarray | None = None, r_cut: float = DEFAULT_R_CUT,
              skin: float = DEFAULT_SKIN) -> EnsembleRun:
        """Replica k: damping delta[k], drive frequency omega[k] (rad/s), drive amplitude amp * scale[k].

        Scalars broadcast; K is the longest of the three vectors (or `replicas`).  x0, v0 (N, 3) are
        the common initial state of the free particles (as in KernelRun.start).
        """
        check_range(r_cut, skin, dt)
        k = replicas or max(np.size(delta), np.size(omega), np.size(scale))
        if k < 1:
            raise SceneError(f"replicas={k!r} is out of range; allowed: integer >= 1")
        delta = _param_vector("delta", delta, k, 0.0, "N s/m")
        omega = _param_vector("omega", omega, k, 0.0, "rad/s")
        scale = _param_vector("scale", scale, k, 0.0, "")
        x_rest, kind, amp, phase, base, vb = initial_state(x_rest, kind, amp, phase, x0, v0)
        n = x_rest.shape[0]
        x = np.repeat(base[:, None, :], k, axis=1)
        v = np.repeat(vb[:, None, :], k, axis=1)
        drv = np.flatnonzero(kind == PRESCRIBED)
        for r in range(k):  # loop over replicas (few), vectorised over particles
            ak = amp[drv] * scale[r]
            x[drv, r] = x_rest[drv] + ak * np.sin(phase[drv])[:, None]
            v[drv, r] = ak * (omega[r] * np.cos(phase[drv]))[:, None]
        run = cls(x=x, v=v, f=np.zeros((n, k, 3)), x_rest=x_rest, kind=kind, amp=amp, scale=scale, phase=phase,
                  omega=omega, delta=delta, mass=float(mass), a=float(a), dt=float(dt), coeffs=model.coeffs(),
                  nl=build_neighbours(base, r_cut * a, skin * a), x_ref=x.copy(), hot=np.zeros((n, k)),
                  r_cut=float(r_cut) * a)
        run._rebuild(-1)
        run.nl.builds, run.nl.history = 1, []
        gather_ensemble(run.x, run.v, run.nl.start, run.nl.index, run.coeffs, 1.0 / run.a, run.r_cut**2, run.delta,
                        run.f)
        return run

    @property
    def replicas(self) -> int:
        return int(self.x.shape[1])

    def _rebuild(self, step: int) -> None:
        """Union of every replica's list at the current positions."""
        lists = [build_neighbours(self.x[:, r], self.nl.r_cut, self.nl.skin) for r in range(self.replicas)]
        merged = merge_lists(lists)
        builds, history = self.nl.builds, self.nl.history
        self.nl = merged
        self.nl.builds, self.nl.history = builds + 1, [*history, step]
        self.x_ref = self.x.copy()

    def _steps(self, n_steps: int, resume: bool) -> tuple[int, int]:
        return advance_ensemble(self.x, self.v, self.f, self.x_rest, self.kind, self.amp, self.scale, self.phase,
                                self.omega, self.mass, self.dt, self.step, n_steps, self.nl.start, self.nl.index,
                                self.x_ref, 0.5 * self.nl.skin, self.coeffs, 1.0 / self.a, self.r_cut**2, self.delta,
                                self.hot, resume)

    def _instability(self, lo: np.ndarray, hi: np.ndarray) -> str:
        bad = ~np.isfinite(self.x).all(axis=(0, 2)) | ~np.isfinite(self.v).all(axis=(0, 2))
        left = ((self.x < lo[None, None]) | (self.x > hi[None, None])).any(axis=(0, 2))
        if not (bad.any() or left.any()):
            return ""
        return (f"NaN/Inf in replicas {np.flatnonzero(bad).tolist()}, a particle more than a outside the bar in "
                f"replicas {np.flatnonzero(left).tolist()} at step {self.step}; all replicas stopped there, sums kept")

    def hotness(self) -> np.ndarray:
        """Time-mean kinetic energy per particle and replica (N, K), J."""
        return self.hot / max(self.step * self.dt, 1e-300)
