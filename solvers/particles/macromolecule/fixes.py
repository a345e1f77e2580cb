"""Fixes of the macromolecule lattice: what each particle's motion is, from the scene's constraints.

Kinds (LAMMPS "fixes"): FREE (Newton, optionally a Langevin bath), FROZEN (held at rest), PRESCRIBED
(kinematic drive) and GROUP (a rigid side of the red pair whose relative motion is prescribed).
The red pair: m at the hot corner, q one spacing below; (r_m - r_q).e_y = a + D a sin(2 pi f t) with
D = drive_amplitude.  drive_sharing "free-centre" (default): the relative motion is prescribed, the
pair's centre of mass moves freely under the forces on the pair, so m takes m_q/(m_m + m_q) of the
stroke and q the rest; "symmetric": the same split, centre held at rest.  In bar-heat-patch the m side
is every particle inside the hot patch sphere (moving rigidly); frozen = every particle inside a frozen
sphere.  A hot face is a Langevin bath (or driven, hot_face = "driven"), a cold face a 0 K viscous bath
(or frozen, far_face = "frozen").
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pcverify.scene import FaceTemperature, PointTemperature, Scene

from .codes import FREE, FROZEN, GROUP, PRESCRIBED
from .lattice import Lattice


@dataclass
class Fixes:
    """Per-particle fixes (FREE, FROZEN, PRESCRIBED, GROUP) and the bath arrays."""

    kind: np.ndarray
    amp: np.ndarray
    phase: np.ndarray
    gamma: np.ndarray
    kt: np.ndarray
    free_centre: bool = False
    hot: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))  # hot reference particles
    notes: str = ""

    @property
    def held(self) -> np.ndarray:
        """Particles held in the modal problem (frozen or driven)."""
        return self.kind != FREE


def make_fixes(scene: Scene, lat: Lattice, p: dict[str, Any], omega_top: float | None = None) -> Fixes:
    """Map the scene's temperature constraints to fixes on the lattice."""
    N = lat.size
    kind = np.zeros(N, dtype=np.int64)
    amp = np.zeros((N, 3))
    phase = np.zeros(N)
    gamma = np.zeros(N)
    kt = np.zeros(N)
    fx = Fixes(kind, amp, phase, gamma, kt)
    stroke = p["drive_amplitude"] * lat.a
    hot_sets: list[np.ndarray] = []
    for con in scene.constraints:
        hot = con.value >= scene.conduction.t_max * (1 - 1e-12)
        if isinstance(con, FaceTemperature):
            axis, side = {"x": 0, "y": 1, "z": 2}[con.face[0]], con.face[1:]
            coord = 0.0 if side == "0" else lat.positions[:, axis].max()
            idx = np.flatnonzero(np.abs(lat.positions[:, axis] - coord) < 1e-9 * lat.a)
            if hot:
                hot_sets.append(idx)
                if p["hot_face"] == "driven":
                    kind[idx] = PRESCRIBED
                    amp[idx, "xyz".index(p["face_drive_direction"])] = stroke
                    phase[idx] = np.random.default_rng(p["seed"]).uniform(0, 2 * np.pi, len(idx))
                else:
                    w = 2 * np.pi * p["drive_frequency"]
                    ke = 0.25 * lat.mass * (w * stroke) ** 2  # time-mean KE of the same drive
                    gamma[idx] = p["face_gamma"] or 0.5 * omega_top
                    kt[idx] = 2.0 / 3.0 * ke
            elif p["far_face"] == "frozen":
                kind[idx] = FROZEN
            else:
                gamma[idx] = p["face_gamma"] or 0.5 * omega_top
            continue
        if isinstance(con, PointTemperature):
            centre, members = np.array(con.point), lat.node_at(np.array(con.point))
        else:
            centre = np.array(con.centre)
            members = np.union1d(lat.within(centre, con.radius), lat.node_at(centre))
        if not hot:
            kind[members] = FROZEN
            continue
        m = int(lat.node_at(centre)[0])
        below = lat.positions[m] - np.array([0.0, lat.a, 0.0])
        sign = 1.0
        if below[1] < -1e-9 * lat.a:
            below, sign = lat.positions[m] + np.array([0.0, lat.a, 0.0]), -1.0
        q = int(lat.node_at(below)[0])
        side_m = np.setdiff1d(members, [q])
        mm, mq = lat.mass * len(side_m), lat.mass
        kind[side_m] = GROUP if p["drive_sharing"] == "free-centre" else PRESCRIBED
        kind[q] = kind[m]
        amp[side_m, 1] = sign * stroke * mq / (mm + mq)
        amp[q, 1] = -sign * stroke * mm / (mm + mq)
        fx.free_centre = p["drive_sharing"] == "free-centre"
        hot_sets.append(np.array([m]))
    fx.hot = np.concatenate(hot_sets) if hot_sets else np.zeros(0, dtype=np.int64)
    return fx


