"""Ensemble runs: K replicas of one lattice, each with its own damping, drive amplitude and drive
frequency, integrated in one kernel (parameter sweeps of the macromolecule model).

Replicas share the rest lattice, the fixes (kinds, drive directions, phases), the time step and
one neighbour list: the same offset groups (from the rest lattice) and the union of every
replica's residual list (`neighbours.union_list`), valid for replica k while no particle of k has
moved more than skin/2 from its own build positions; a replica that expires is rebuilt alone and
its list added to the union (`EnsembleRun._rebuild`).  State is (3, N, K), replica innermost: the
flat index i * K + k is a lattice with offsets o * K, so `kernel.advance_p2` runs its contiguous,
vectorised group loops over all replicas at once (K times longer loops, one pass over the tiles,
the damping per slot from a K-periodic vector).

Each replica performs exactly the floating-point operations of a single `kernel.KernelRun` with
its parameters, in the same order (tiles and slab blocks are counted in particles, group slots of
a replica are those of its single run, residual pairs beyond r_cut are skipped, not added as
zeros, drive amplitude amp * scale formed the same way), so every replica is bit-identical to its
single run: the ensemble changes throughput, never results.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pcverify.scene import SceneError

from ..codes import PRESCRIBED
from ..force import SevenRoot
from .kernel import (
    DEFAULT_R_CUT,
    DEFAULT_SKIN,
    FORCE_PASSES,
    LatticeRun,
    check_range,
    initial_state,
    soa_state,
)
from .neighbours import build_neighbours, merge_lists, stencil_offsets, union_list


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
    full_entries: int = 0  # list entries at the last full union (a union of twice that size is rebuilt)

    @classmethod
    def start(cls, x_rest: np.ndarray, mass: float, a: float, model: SevenRoot, dt: float, delta: np.ndarray | float,
              omega: np.ndarray | float, scale: np.ndarray | float = 1.0, replicas: int | None = None,
              kind: np.ndarray | None = None, amp: np.ndarray | None = None, phase: np.ndarray | None = None,
              v0: np.ndarray | None = None, x0: np.ndarray | None = None, r_cut: float = DEFAULT_R_CUT,
              skin: float = DEFAULT_SKIN, force_pass: str = "slabs", groups: bool = True) -> EnsembleRun:
        """Replica k: damping delta[k], drive frequency omega[k] (rad/s), drive amplitude amp * scale[k].

        Scalars broadcast; K is the longest of the three vectors (or `replicas`).  x0, v0 (N, 3) are
        the common initial state of the free particles; force_pass, groups as in KernelRun.start.
        """
        check_range(r_cut, skin, dt)
        if force_pass not in FORCE_PASSES:
            raise SceneError(f"force_pass={force_pass!r} is not allowed; allowed: {', '.join(FORCE_PASSES)}")
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
        offsets = stencil_offsets(x_rest, (r_cut + skin) * a) if groups else None
        run = cls(xs=soa_state(x, k), vs=soa_state(v, k), fs=np.zeros((3, n, k)), x_rest=x_rest, kind=kind, amp=amp,
                  scale=scale, phase=phase, omega=omega, delta=delta, mass=float(mass), a=float(a), dt=float(dt),
                  coeffs=model.coeffs(), nl=build_neighbours(base, r_cut * a, skin * a, offsets), x_ref=x.copy(),
                  hot=np.zeros((n, k)), r_cut=float(r_cut) * a, force_pass=force_pass)
        run._rebuild(-1)
        run.nl.builds, run.nl.history = 1, []
        run._forces()
        return run

    @property
    def replicas(self) -> int:
        return int(self.xs.shape[2])

    def _vectors(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        return self.scale, self.omega, self.delta, self.x_ref.reshape(-1, 3)

    def _rebuild(self, step: int) -> None:
        """Rebuild the lists of the replicas that expired (a particle beyond skin/2 of its own x_ref) and add
        them to the shared list; the others keep their x_ref and their entries.  Stale entries only add
        pairs beyond r_cut, which every force pass skips (no bit changes); the whole union is rebuilt
        at the start and once the list has grown to twice its last full size."""
        x = np.ascontiguousarray(self.x)
        moved = ~(((x - self.x_ref) ** 2).sum(axis=2) <= (0.5 * self.nl.skin) ** 2).all(axis=0)
        builds, history = self.nl.builds, self.nl.history
        if step < 0 or self.nl.entries > 2 * self.full_entries:
            self.nl = union_list(x.transpose(1, 0, 2), self.nl.r_cut, self.nl.skin, self.nl.offsets)
            self.full_entries = max(self.nl.entries, self.size)
            self.x_ref = x
        else:
            fresh = union_list(x[:, moved].transpose(1, 0, 2), self.nl.r_cut, self.nl.skin, self.nl.offsets)
            self.nl = merge_lists([self.nl, fresh])
            self.x_ref[:, moved] = x[:, moved]
        self.nl.builds, self.nl.history = builds + 1, [*history, step]

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

    @property
    def nbytes(self) -> int:
        return int(super().nbytes + self.x_ref.nbytes)
