"""Ensemble runs: K replicas of one lattice, each with its own damping, drive amplitude, drive
frequency, force scale A, envelope exponent p and absorbing-bath rate, integrated in one kernel
(parameter sweeps and calibrations of the macromolecule model).

Replicas share the rest lattice, the fixes (kinds, drive directions, phases, bath particles), the
roots and STEP of the force, the time step and one neighbour list: the same offset groups (from the
rest lattice) and the union of every replica's residual list (`neighbours.union_list`), valid for
replica k while no particle of k has moved more than skin/2 from its own build positions; a replica
that expires is rebuilt alone and its list added to the union (`EnsembleRun._rebuild`).  State is
(3, N, K), replica innermost: the flat index i * K + k is a lattice with offsets o * K, so
`kernel.advance_p2` runs its contiguous, vectorised group loops over all replicas at once (K times
longer loops, one pass over the tiles, damping, force scale and exponent per slot from K-periodic
vectors).

Each replica performs exactly the floating-point operations of a single `kernel.KernelRun` with
its parameters, in the same order (tiles and slab blocks are counted in particles, group slots of
a replica are those of its single run, residual pairs beyond r_cut are skipped, not added as
zeros, drive amplitude amp * scale formed the same way), so every replica is bit-identical to its
single run: the ensemble changes throughput, never results.  A full union rebuild is made from each
replica's own reference positions (those of replicas that did not expire stay), so a replica's list
expiries fall on the steps of its single run.

`retire=True` makes replicas independent in failure too: a replica that becomes non-finite or
leaves the bar (seen at one of its own list expiries, so at the step its single run sees it) is
retired instead of stopping the others: its sums and step are kept (`retired_step`, `retired_hot`,
`retired_reason`), its slots are put back at rest with its drive off, and the others go on.  A
caller may retire a replica for its own reasons (`retire_replica`, e.g. a lattice defect found at a
check).  The run stops once every replica is retired.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pcverify.scene import SceneError

from ..codes import FREE, PRESCRIBED
from ..force import C_A, C_P, SevenRoot
from .kernel import (
    DEFAULT_R_CUT,
    DEFAULT_SKIN,
    FORCE_PASSES,
    LatticeRun,
    ReplicaParams,
    check_range,
    initial_state,
    soa_state,
)
from .neighbours import build_neighbours, merge_lists, stencil_offsets, union_list


def _param_vector(name: str, values: np.ndarray | float, k: int, low: float, unit: str,
                  high: float = np.inf, low_open: bool = False) -> np.ndarray:
    out = np.broadcast_to(np.asarray(values, dtype=np.float64), (k,)).copy()
    bad = ~np.isfinite(out) | (out < low) | (out > high) | ((out == low) & low_open)
    if bad.any():
        interval = f"{'(' if low_open else '['}{low:g}, {high:g}{']' if np.isfinite(high) else ')'}"
        first = int(np.flatnonzero(bad)[0])
        raise SceneError(f"{name}[{first}]={float(out[first])!r} is out of range; allowed: number in {interval} "
                         f"{unit}".rstrip())
    return out


@dataclass(eq=False, kw_only=True)
class EnsembleRun(LatticeRun):
    """K replicas of one lattice advanced together; hot (N, K) holds sum KE dt per replica.

    A replica that becomes non-finite or leaves the bar stops all replicas (status, reason name them)."""

    scale: np.ndarray
    omega: np.ndarray
    delta: np.ndarray
    amp_a: np.ndarray
    p: np.ndarray
    gamma: np.ndarray
    x_ref: np.ndarray
    full_entries: int = 0  # list entries at the last full union (a union of twice that size is rebuilt)
    retire: bool = False
    retired_step: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))  # -1: running
    retired_hot: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    retired_reason: list[str] = field(default_factory=list)

    @classmethod
    def start(cls, x_rest: np.ndarray, mass: float, a: float, model: SevenRoot, dt: float, delta: np.ndarray | float,
              omega: np.ndarray | float, scale: np.ndarray | float = 1.0, replicas: int | None = None,
              kind: np.ndarray | None = None, amp: np.ndarray | None = None, phase: np.ndarray | None = None,
              v0: np.ndarray | None = None, x0: np.ndarray | None = None, r_cut: float = DEFAULT_R_CUT,
              skin: float = DEFAULT_SKIN, force_pass: str = "slabs", groups: bool = True,
              stiffness: np.ndarray | float | None = None, exponent: np.ndarray | float | None = None,
              bath: np.ndarray | None = None, gamma: np.ndarray | float = 0.0, retire: bool = False) -> EnsembleRun:
        """Replica k: damping delta[k], drive frequency omega[k] (rad/s), drive amplitude amp * scale[k],
        force scale stiffness[k] (N; default the model's A), envelope exponent exponent[k] (default the
        model's p) and bath rate gamma[k] (1/s) of the FREE particles in the boolean mask `bath` (a 0 K
        viscous bath: an absorbing face).  The model gives the roots and the STEP of every replica.

        Scalars broadcast; K is the longest of the vectors (or `replicas`).  x0, v0 (N, 3) are the
        common initial state of the free particles; force_pass, groups as in KernelRun.start; retire as
        in the module docstring.
        """
        check_range(r_cut, skin, dt)
        if force_pass not in FORCE_PASSES:
            raise SceneError(f"force_pass={force_pass!r} is not allowed; allowed: {', '.join(FORCE_PASSES)}")
        coeffs = model.coeffs()
        stiffness = coeffs[C_A] if stiffness is None else stiffness
        exponent = coeffs[C_P] if exponent is None else exponent
        k = replicas or max(np.size(delta), np.size(omega), np.size(scale), np.size(stiffness), np.size(exponent),
                            np.size(gamma))
        if k < 1:
            raise SceneError(f"replicas={k!r} is out of range; allowed: integer >= 1")
        delta = _param_vector("delta", delta, k, 0.0, "N s/m")
        omega = _param_vector("omega", omega, k, 0.0, "rad/s")
        scale = _param_vector("scale", scale, k, 0.0, "")
        amp_a = _param_vector("stiffness", stiffness, k, 0.0, "N", low_open=True)
        p_env = _param_vector("exponent", exponent, k, 0.0, "", high=12.0)
        gamma = _param_vector("gamma", gamma, k, 0.0, "1/s")
        x_rest, kind, amp, phase, base, vb = initial_state(x_rest, kind, amp, phase, x0, v0)
        n = x_rest.shape[0]
        x = np.repeat(base[:, None, :], k, axis=1)
        v = np.repeat(vb[:, None, :], k, axis=1)
        drv = np.flatnonzero(kind == PRESCRIBED)
        for r in range(k):  # loop over replicas (few), vectorised over particles
            ak = amp[drv] * scale[r]
            x[drv, r] = x_rest[drv] + ak * np.sin(phase[drv])[:, None]
            v[drv, r] = ak * (omega[r] * np.cos(phase[drv]))[:, None]
        mask = np.zeros(n, dtype=bool) if bath is None else np.asarray(bath, dtype=bool)
        if mask.shape != (n,) or (mask & (kind != FREE)).any():
            raise SceneError(f"bath={mask.shape} mask is not valid; allowed: a boolean mask of the {n} particles, "
                             "true only for FREE ones")
        offsets = stencil_offsets(x_rest, (r_cut + skin) * a) if groups else None
        run = cls(xs=soa_state(x, k), vs=soa_state(v, k), fs=np.zeros((3, n, k)), x_rest=x_rest, kind=kind, amp=amp,
                  scale=scale, phase=phase, omega=omega, delta=delta, amp_a=amp_a, p=p_env, gamma=gamma,
                  mass=float(mass), a=float(a), dt=float(dt), coeffs=coeffs,
                  nl=build_neighbours(base, r_cut * a, skin * a, offsets), x_ref=x.copy(), hot=np.zeros((n, k)),
                  r_cut=float(r_cut) * a, force_pass=force_pass, bath=np.flatnonzero(mask).astype(np.int64),
                  retire=bool(retire), retired_step=np.full(k, -1, dtype=np.int64), retired_hot=np.zeros((n, k)),
                  retired_reason=[""] * k)
        run._rebuild(-1)
        run.nl.builds, run.nl.history = 1, []
        run._forces()
        return run

    @property
    def replicas(self) -> int:
        return int(self.xs.shape[2])

    def _vectors(self) -> tuple[ReplicaParams, np.ndarray]:
        return ReplicaParams(scale=self.scale, omega=self.omega, delta=self.delta, amp_a=self.amp_a, p=self.p,
                             gamma=self.gamma), self.x_ref.reshape(-1, 3)

    def _moved(self) -> np.ndarray:
        """(K,) whether a particle of replica k is beyond skin/2 of its own x_ref (or not finite)."""
        return ~(((self.x - self.x_ref) ** 2).sum(axis=2) <= (0.5 * self.nl.skin) ** 2).all(axis=0)

    def _rebuild(self, step: int) -> None:
        """Rebuild the lists of the replicas that expired (a particle beyond skin/2 of its own x_ref) and add
        them to the shared list; the others keep their x_ref and their entries.  Stale entries only add
        pairs beyond r_cut, which every force pass skips (no bit changes); the whole union is rebuilt
        at the start and once the list has grown to twice its last full size, from the current positions
        of the replicas that expired and the reference positions of the others."""
        x = np.ascontiguousarray(self.x)
        moved = self._moved()
        builds, history = self.nl.builds, self.nl.history
        if step < 0 or self.nl.entries > 2 * self.full_entries:
            build = x if step < 0 else np.where(moved[None, :, None], x, self.x_ref)
            self.nl = union_list(build.transpose(1, 0, 2), self.nl.r_cut, self.nl.skin, self.nl.offsets)
            self.full_entries = max(self.nl.entries, self.size)
            self.x_ref = np.ascontiguousarray(build)
        else:
            fresh = union_list(x[:, moved].transpose(1, 0, 2), self.nl.r_cut, self.nl.skin, self.nl.offsets)
            self.nl = merge_lists([self.nl, fresh])
            self.x_ref[:, moved] = x[:, moved]
        self.nl.builds, self.nl.history = builds + 1, [*history, step]

    def _instability(self, lo: np.ndarray, hi: np.ndarray) -> str:
        bad = ~np.isfinite(self.x).all(axis=(0, 2)) | ~np.isfinite(self.v).all(axis=(0, 2))
        left = ((self.x < lo[None, None]) | (self.x > hi[None, None])).any(axis=(0, 2))
        if self.retire:  # only replicas at one of their own expiries: the steps their single runs check
            moved = self._moved() & (self.retired_step < 0)
            for k in np.flatnonzero(moved & (bad | left)):
                why = ("NaN/Inf in the state" if bad[k] else
                       "a particle left the bar's neighbourhood (more than a outside)")
                self.retire_replica(int(k), f"{why} at step {self.step}; stopped there, sums kept")
            if (self.retired_step >= 0).all():
                return f"every replica retired (last at step {self.step})"
            return ""
        if not (bad.any() or left.any()):
            return ""
        return (f"NaN/Inf in replicas {np.flatnonzero(bad).tolist()}, a particle more than a outside the bar in "
                f"replicas {np.flatnonzero(left).tolist()} at step {self.step}; all replicas stopped there, sums kept")

    def retire_replica(self, k: int, reason: str) -> None:
        """Keep replica k's sums and step, put its slots back at rest with its drive off (forces zero), so
        the others go on; its later slots are never read (`replica_hot`)."""
        if self.retired_step[k] >= 0:
            return
        self.retired_step[k] = self.step
        self.retired_hot[:, k] = self.hot[:, k]
        self.retired_reason[k] = reason
        self.xs[:, :, k] = self.x_rest.T
        self.vs[:, :, k] = 0.0
        self.fs[:, :, k] = 0.0
        self.scale[k] = 0.0

    def replica_hot(self) -> np.ndarray:
        """(N, K) sums of KE dt: the running sums, or those kept when a replica was retired."""
        return np.where(self.retired_step[None, :] >= 0, self.retired_hot, self.hot)

    def hotness(self) -> np.ndarray:
        """Time-mean kinetic energy per particle and replica (N, K), J."""
        return self.hot / max(self.step * self.dt, 1e-300)

    @property
    def nbytes(self) -> int:
        return int(super().nbytes + self.x_ref.nbytes)
