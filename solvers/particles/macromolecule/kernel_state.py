"""What every fixed-pair-list kernel takes: five structures numba accepts (typed named tuples of arrays
and scalars), so that all kernels share one signature

    run(state: RunState, lattice: LatticeArrays, fixes: FixArrays, params: RunParams, out: RunOutputs) -> int

(the number of history rows written).  `LatticeArrays` carries the pair list twice: as a list with each
pair's root interval (the reference kernel) and laid out as a lattice stencil (the fast kernels, see
`stencil`).  Arrays must be C-contiguous with the dtypes built here (float64, int64, int8), so that one
compiled signature (and its cache entry) serves every run.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


class RunState(NamedTuple):
    """Positions at t = 0 (N, 3), overwritten with the final positions, and the initial velocities (N, 3)."""

    x: np.ndarray
    v0: np.ndarray


class LatticeArrays(NamedTuple):
    """Rest positions, particle mass, spacing and the fixed pair list: as pairs (i < j, rest distance,
    root interval [lo, hi) in units of a) and as a stencil (groups of equal index offset and rest shell:
    offset, first slot, root interval, rest distance; per slot a 0/1 mask and the rest distance; each pair's slot)."""

    x_rest: np.ndarray
    mass: float
    a: float
    pi: np.ndarray
    pj: np.ndarray
    r0: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    g_off: np.ndarray
    g_base: np.ndarray
    g_lo: np.ndarray
    g_hi: np.ndarray
    g_r0: np.ndarray
    mask: np.ndarray
    r0s: np.ndarray
    slot: np.ndarray


class FixArrays(NamedTuple):
    """Per-particle fixes (codes.FREE ... GROUP), drive amplitudes (N, 3) and phases, Langevin friction rate
    and kT, the drive's angular frequency, whether the red pair's centre moves freely, the RNG seed."""

    kind: np.ndarray
    amp: np.ndarray
    phase: np.ndarray
    gamma: np.ndarray
    kt: np.ndarray
    omega: float
    free_centre: bool
    seed: int


class RunParams(NamedTuple):
    """Force coefficients (force.SevenRoot.coeffs), radial damping, time step; steps to run and the
    hotness window [n_start, n_end); check interval and blow-up rule (kinetic energy above blowup_factor
    times the energy supplied, e_scale the drives' and baths' energy scale); the bar's neighbourhood
    box; the neighbourhood check (contact fraction of a, largest listed rest distance, skin)."""

    coeffs: np.ndarray
    delta: float
    dt: float
    n_steps: int
    n_start: int
    n_end: int
    check_every: int
    blowup_factor: float
    e_scale: float
    box_lo: np.ndarray
    box_hi: np.ndarray
    contact_fraction: float
    cutoff_rest: float
    skin: float


class RunOutputs(NamedTuple):
    """Filled by the kernel: hot (3, N) sums of KE dt over the window and its halves; energy (codes.E_*);
    counters (codes.K_*); history (rows, codes.H_*); ever (P,) 1 for pairs that ever left their interval."""

    hot: np.ndarray
    energy: np.ndarray
    counters: np.ndarray
    history: np.ndarray
    ever: np.ndarray


def stencil(pairs: np.ndarray, shell: np.ndarray, n: int, basins: np.ndarray) -> tuple[np.ndarray, ...]:
    """Pair list as groups of equal index offset o = j - i and rest shell (a lattice stencil).

    Group g covers the slots i = 0 .. n - o - 1 (pair (i, i + o)) at slots base_g + i, so every
    access in the pair loop is contiguous and the loop vectorises; slots that are not listed
    pairs (lattice edges) have mask 0 and contribute exactly nothing.  Returns (offset, base, lo,
    hi) per group, the slot mask and each listed pair's slot.
    """
    off = pairs[:, 1] - pairs[:, 0]
    key = off * 4 + shell
    keys, gidx = np.unique(key, return_inverse=True)
    g_off = (keys // 4).astype(np.int64)
    g_sh = keys % 4
    base = np.concatenate([[0], np.cumsum(n - g_off)]).astype(np.int64)
    slot = (base[gidx] + pairs[:, 0]).astype(np.int64)
    mask = np.zeros(base[-1])
    mask[slot] = 1.0
    lo = np.ascontiguousarray(basins[g_sh, 0])
    hi = np.ascontiguousarray(basins[g_sh, 1])
    return g_off, base, lo, hi, mask, slot


def lattice_arrays(x_rest: np.ndarray, mass: float, a: float, pairs: np.ndarray, r0: np.ndarray, shell: np.ndarray,
                   basins: np.ndarray) -> LatticeArrays:
    """The structure for a lattice with pairs (P, 2), rest distances, rest shells and the model's root
    intervals per shell (force.SevenRoot.basins)."""
    n = x_rest.shape[0]
    g_off, g_base, g_lo, g_hi, mask, slot = stencil(pairs, shell, n, basins)
    r0s = np.zeros(mask.shape[0])
    r0s[slot] = r0
    g_r0 = np.zeros(g_off.shape[0])
    g_r0[np.searchsorted(g_base, slot, side="right") - 1] = r0  # a group's pairs share their rest shell
    return LatticeArrays(
        x_rest=np.ascontiguousarray(x_rest, dtype=np.float64), mass=float(mass), a=float(a),
        pi=np.ascontiguousarray(pairs[:, 0], dtype=np.int64), pj=np.ascontiguousarray(pairs[:, 1], dtype=np.int64),
        r0=np.ascontiguousarray(r0, dtype=np.float64), lo=np.ascontiguousarray(basins[shell, 0]),
        hi=np.ascontiguousarray(basins[shell, 1]), g_off=g_off, g_base=g_base, g_lo=g_lo, g_hi=g_hi, g_r0=g_r0,
        mask=mask, r0s=r0s, slot=slot)
