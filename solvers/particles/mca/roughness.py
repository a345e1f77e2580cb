"""Micro-roughness K_mu of an MCA contact (eq. 18 of the MCA paper), and its analytic mean.

Two piecewise sinusoids of positive half-waves advanced by the sliding distance, each fragment's half-period and
amplitude drawn from a counter-based generator (the same K on any number of threads), started stationary; the
mean K_av = (2 / pi)(a_1 + a_2) and its variance (docs/physics.md, "The MCA solver in detail", "Micro-roughness").
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

GOLDEN = np.uint64(0x9E3779B97F4A7C15)
MIX1 = np.uint64(0xBF58476D1CE4E5B9)
MIX2 = np.uint64(0x94D049BB133111EB)


class Roughness(NamedTuple):
    """The process's constants: mean amplitudes a1, a2 (dimensionless), mean half-periods d1, d2 (m), spread
    s in [0, 1), seed; on = whether any amplitude is non-zero."""

    on: bool
    a1: float
    a2: float
    d1: float
    d2: float
    spread: float
    seed: int


class RoughState(NamedTuple):
    """Per contact and sinusoid: coordinate x in [l, 2l), half-period l, amplitude A, fragment number."""

    x: np.ndarray  # (ns, 2)
    ell: np.ndarray  # (ns, 2)
    amp: np.ndarray  # (ns, 2)
    frag: np.ndarray  # (ns, 2) int64


@njit(cache=True)
def _mix(z):
    z = z + GOLDEN
    z = (z ^ (z >> np.uint64(30))) * MIX1
    z = (z ^ (z >> np.uint64(27))) * MIX2
    return z ^ (z >> np.uint64(31))


@njit(cache=True)
def uniform(seed, contact, sinusoid, fragment, which):
    """A uniform number in [0, 1) for (seed, contact, sinusoid, fragment, which) (splitmix64 of the counter)."""
    z = _mix(np.uint64(seed))
    z = _mix(z ^ np.uint64(contact))
    z = _mix(z ^ np.uint64(8 * fragment + 4 * sinusoid + which))
    return float(z >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@njit(cache=True)
def _draw(law, k, m, j):
    """(half-period, amplitude) of fragment j of sinusoid m of contact k."""
    mean_l = law.d1 if m == 0 else law.d2
    mean_a = law.a1 if m == 0 else law.a2
    s = law.spread
    ell = mean_l * (1.0 + s * (2.0 * uniform(law.seed, k, m, j, 0) - 1.0))
    amp = mean_a * (1.0 + s * (2.0 * uniform(law.seed, k, m, j, 1) - 1.0))
    return ell, amp


@njit(cache=True)
def start(rs, law):
    """Every contact in the stationary state of its process: the first fragment's half-period drawn with the
    length bias of a fragment that covers a given point (density proportional to l on [(1 - s) d, (1 + s) d]),
    entered at a uniform phase.  Then E[K] = K_av at every sliding distance, from the first step on."""
    for k in range(rs.x.shape[0]):
        for m in range(2):
            mean_l = law.d1 if m == 0 else law.d2
            lo = mean_l * (1.0 - law.spread)
            hi = mean_l * (1.0 + law.spread)
            ell = math.sqrt(lo * lo + uniform(law.seed, k, m, 0, 0) * (hi * hi - lo * lo))
            _, amp = _draw(law, k, m, 0)
            rs.ell[k, m] = ell
            rs.amp[k, m] = amp
            rs.x[k, m] = ell * (1.0 + uniform(law.seed, k, m, 0, 2))
            rs.frag[k, m] = 0


@njit(cache=True)
def value(rs, k):
    """K_mu of contact k."""
    out = 0.0
    for m in range(2):
        ell = rs.ell[k, m]
        out += rs.amp[k, m] * math.sin(math.pi * (rs.x[k, m] - ell) / ell)
    return out


@njit(cache=True)
def advance(rs, law, k, distance):
    """Slide contact k by `distance` (m): both sinusoids advance, starting new fragments as they end."""
    for m in range(2):
        x = rs.x[k, m] + distance
        while x >= 2.0 * rs.ell[k, m]:
            over = x - 2.0 * rs.ell[k, m]
            rs.frag[k, m] += 1
            ell, amp = _draw(law, k, m, rs.frag[k, m])
            rs.ell[k, m] = ell
            rs.amp[k, m] = amp
            x = ell + over
        rs.x[k, m] = x


def new_state(contacts: int) -> RoughState:
    """Zeroed process state of `contacts` contacts (`start` draws the first fragments)."""
    return RoughState(x=np.zeros((contacts, 2)), ell=np.ones((contacts, 2)), amp=np.zeros((contacts, 2)),
                      frag=np.zeros((contacts, 2), dtype=np.int64))


def mean(law: Roughness) -> float:
    """K_av = (2 / pi) (a1 + a2): the long-run average of K over the sliding distance."""
    return 2.0 / math.pi * (law.a1 + law.a2)


def variance_of_mean(law: Roughness, distance: float) -> float:
    """Variance of one contact's average of K over a sliding `distance` (m), both sinusoids."""
    s = law.spread
    return sum(4.0 / (3.0 * math.pi**2) * s**2 * a**2 * d * (1.0 + s**2 / 3.0) / distance
               for a, d in ((law.a1, law.d1), (law.a2, law.d2)))
