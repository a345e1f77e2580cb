"""Kinds of the bar's vibration modes by their parities under the two mirror planes x = W/2 and y = H/2.

One classifier for every solver that computes modes (skfem-elastic, the MCA): each hands over its nodes'
positions, its mode vectors (node-interleaved dofs, rotations after the translations where a node rotates) and
its mass, and gets the kind of each mode: (-, +) bending-x, (+, -) bending-y, (-, -) torsion, (+, +) axial,
"mixed" when a parity is unclear.  Degenerate clusters are rotated to definite parities by a fixed rule, and a
solver classifies its modes only with the cluster at its cut complete (`cut_is_complete`), so the kinds are the
same on every CPU and BLAS.  Then the rules a solver asks for rename kinds by energy (`rotational`,
`symmetric_lateral`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.linalg import eigh

KIND_BY_PARITY = {(-1, 1): "bending-x", (1, -1): "bending-y", (-1, -1): "torsion", (1, 1): "axial"}
# the kinds whose lowest frequency a summary reports
KINDS = ("bending-x", "bending-y", "torsion", "axial", "rotational")
CLUSTER_RTOL = 1e-5  # eigenvalues closer than this (relative) are one degenerate cluster
AXIAL_SHARE = 0.5  # a (+, +) mode with less of its mass norm in u_z is symmetric-lateral
# a mode with more of its mass norm (its kinetic energy) in the rotations than in the translations is rotational:
# the translations carry what a continuum has, so past one half the mode is mostly what the continuum lacks.  On
# the MCA bar at n = 4 and 6 (the 40 lowest modes, krot 1e-4 to 1e-2) no mode lies between 0.13 and 0.92, so the
# line's place does not matter there; at n = 3 (two automata across) modes hybridise (shares 0.41 and 0.55).
ROTATIONAL_SHARE = 0.5

EnergyRule = Callable[[str, dict[str, float]], str]  # (parity kind, the mode's shares) -> its kind


@dataclass(frozen=True)
class Mirror:
    """A mirror plane as a signed permutation of the mode vectors' dofs: (R u)[j] = sign[j] * u[perm[j]]."""

    perm: np.ndarray
    sign: np.ndarray

    def __call__(self, phi: np.ndarray) -> np.ndarray:
        return phi[self.perm] * self.sign[:, None]


def mirror(positions: np.ndarray, extent: np.ndarray, axis: int, unit: float | np.ndarray,
           rotations: bool = False) -> Mirror:
    """The mirror x_axis -> extent - x_axis of node-interleaved dofs at `positions` (N, 3).

    Node i takes the values of its image; the normal translation u_axis changes sign, and with `rotations` (three
    more dofs per node, a pseudo-vector) the two rotations about the in-plane axes change sign, the one about
    the normal does not.  `unit`: the node spacing (a number, or one per axis), which makes the nodes' keys
    exact integers.  ValueError if a node has no image."""
    unit = np.broadcast_to(np.asarray(unit, dtype=float), (3,))
    keys = np.rint(positions / unit).astype(np.int64)
    image = keys.copy()
    image[:, axis] = int(np.rint(extent[axis] / unit[axis])) - keys[:, axis]
    span = keys.max(axis=0) + 1

    def code(k: np.ndarray) -> np.ndarray:
        return (k[:, 0] * span[1] + k[:, 1]) * span[2] + k[:, 2]

    own = code(keys)
    order = np.argsort(own)
    pos = np.minimum(np.searchsorted(own, code(image), sorter=order), own.size - 1)
    node = order[pos]
    if np.any(keys[node] != image):
        raise ValueError("the nodes are not mirror symmetric")
    per = 6 if rotations else 3
    sign = np.ones(per)
    sign[axis] = -1.0
    if rotations:
        sign[3:] = -1.0
        sign[3 + axis] = 1.0
    return Mirror(perm=(per * node[:, None] + np.arange(per)[None, :]).ravel(), sign=np.tile(sign, node.size))


@dataclass(frozen=True)
class ModeKinds:
    """The classified modes: the shapes (degenerate clusters rotated), their parities (k, 2) under the x and y
    mirrors, their kinds, and the share of each mode's mass norm in a group of dofs ("axial": u_z;
    "rotational": the rotations, where the nodes rotate)."""

    phi: np.ndarray
    parities: np.ndarray
    kinds: list[str]
    shares: dict[str, np.ndarray]

    def first(self, count: int) -> ModeKinds:
        """The lowest `count` modes."""
        return ModeKinds(self.phi[:, :count], self.parities[:count], self.kinds[:count],
                         {k: v[:count] for k, v in self.shares.items()})


def classify(phi: np.ndarray, omega2: np.ndarray, mass: Any, positions: np.ndarray, extent: np.ndarray,
             unit: float | np.ndarray, rotations: bool = False, order: tuple[float, float] = (1.0, 2.0),
             energy: tuple[EnergyRule, ...] = ()) -> ModeKinds:
    """Kind of each mode of `phi` (ndof, k), eigenvalues `omega2` ascending, `mass` the diagonal of M per dof
    (ndof,) or M itself (anything with `@`), nodes at `positions` (N, 3) with spacing `unit`, `rotations` when
    each node has three rotation dofs after its translations; `energy`: the rules that rename a parity kind by
    the mode's shares, applied in turn.

    A cluster of eigenvalues equal to CLUSTER_RTOL is rotated to the eigenvectors of w_x R_x + w_y R_y in the
    mass inner product, (w_x, w_y) = `order`: ascending, so the weights also fix the order of a cluster's modes
    ((1, 2): bending-y before bending-x; (1, 0): bending-x first, a cluster whose modes share their x parity
    left as it is)."""
    mirrors = [mirror(positions, extent, axis, unit, rotations) for axis in (0, 1)]
    phi = phi.copy()
    k = phi.shape[1]
    for start, stop in clusters(omega2[:k]):
        if stop - start > 1:
            block = phi[:, start:stop]
            mb = _times(mass, block)
            comb = sum(w * refl(block).T @ mb for w, refl in zip(order, mirrors, strict=True))
            _, vecs = eigh(0.5 * (comb + comb.T), block.T @ mb)
            phi[:, start:stop] = block @ vecs
    mphi = _times(mass, phi)
    norms = np.einsum("ij,ij->j", phi, mphi)
    parities = np.stack([np.einsum("ij,ij->j", refl(phi), mphi) / norms for refl in mirrors], axis=1)
    per = 6 if rotations else 3
    groups = {"axial": (2,)} | ({"rotational": (3, 4, 5)} if rotations else {})
    shares = {name: _share(phi, mass, comps, per) / norms for name, comps in groups.items()}
    kinds = []
    for j in range(k):
        key = tuple(int(np.sign(p)) if abs(p) > 0.5 else 0 for p in parities[j])
        kind = KIND_BY_PARITY.get(key, "mixed")
        for rule in energy:
            kind = rule(kind, {name: float(v[j]) for name, v in shares.items()})
        kinds.append(kind)
    return ModeKinds(phi=phi, parities=parities, kinds=kinds, shares=shares)


def clusters(omega2: np.ndarray) -> list[tuple[int, int]]:
    """(start, stop) of each run of ascending eigenvalues that are one degenerate cluster: each within
    CLUSTER_RTOL of the run's first."""
    out, start, k = [], 0, len(omega2)
    while start < k:
        stop = start + 1
        while stop < k and omega2[stop] - omega2[start] <= CLUSTER_RTOL * abs(omega2[start]):
            stop += 1
        out.append((start, stop))
        start = stop
    return out


def cut_is_complete(omega2: np.ndarray, count: int) -> bool:
    """Whether the cluster holding mode `count` - 1 ends inside the ascending eigenvalues `omega2`, one value
    at least beyond it: then `classify` rotates that cluster whole, and the first `count` modes have the same
    kinds on every machine (an eigensolver returns any basis of a degenerate cluster, so a cluster cut at its
    top is half a pair whose parity is whatever the machine's round-off made it)."""
    return any(start < count <= stop < len(omega2) for start, stop in clusters(omega2))


# -- kinds named by energy (EnergyRule): a kind by where a mode's mass norm sits


def rotational(kind: str, shares: dict[str, float]) -> str:
    """A mode with more than ROTATIONAL_SHARE of its mass norm in the rotations is rotational, whatever its
    parity: the alternating rotations of neighbours cost no shear energy in the MCA, and their (+, +) or (-, -)
    parity would otherwise name them axial or torsion."""
    return "rotational" if shares.get("rotational", 0.0) > ROTATIONAL_SHARE else kind


def symmetric_lateral(kind: str, shares: dict[str, float]) -> str:
    """A (+, +) mode whose mass is mostly lateral (u_z share below AXIAL_SHARE) is symmetric-lateral, not axial."""
    return "symmetric-lateral" if kind == "axial" and shares["axial"] < AXIAL_SHARE else kind


def lowest_of_each_kind(kinds: list[str], freqs: np.ndarray) -> dict[str, float]:
    """f_<kind>_hz: the lowest frequency of each kind of KINDS that occurs."""
    out = {}
    for kind in KINDS:
        hits = [j for j, kd in enumerate(kinds) if kd == kind]
        if hits:
            out[f"f_{kind.replace('-', '_')}_hz"] = float(freqs[hits[0]])
    return out


def kind_summary(kinds: list[str], freqs: np.ndarray) -> dict[str, Any]:
    """What a solver's summary reports of its classified modes: f_<kind>_hz (`lowest_of_each_kind`) and
    continuum_frequencies_hz, the frequencies of the modes a continuum has (the rotational ones left out), in
    order: a spectrum to compare across models whatever kinds the classifier gives the rest."""
    continuum = np.asarray(freqs, dtype=float)[np.array([kind != "rotational" for kind in kinds], dtype=bool)]
    return {"continuum_frequencies_hz": continuum} | lowest_of_each_kind(kinds, freqs)


def _times(mass: Any, phi: np.ndarray) -> np.ndarray:
    """M phi for M given as its diagonal (ndof,) or as a matrix."""
    return mass[:, None] * phi if isinstance(mass, np.ndarray) and mass.ndim == 1 else mass @ phi


def _share(phi: np.ndarray, mass: Any, comps: tuple[int, ...], per: int) -> np.ndarray:
    """(P phi)^T M (P phi) of each mode, P keeping the dofs `comps` of every node (`per` dofs a node)."""
    only = np.zeros_like(phi)
    for c in comps:
        only[c::per] = phi[c::per]
    weighted = _times(mass, only)
    return sum(np.einsum("ij,ij->j", phi[c::per], weighted[c::per]) for c in comps)
