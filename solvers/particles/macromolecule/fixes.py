"""Fixes of the macromolecule lattice (LAMMPS "fixes"): what each particle's motion is, from the scene.

FREE (Newton, optionally a Langevin bath), FROZEN, PRESCRIBED (kinematic drive), GROUP (a rigid side of the
red pair).  The red pair: m at the hot corner, q one spacing below, (r_m - r_q).e_y = a + D a sin(2 pi f t);
drive_sharing "free-centre": the pair's centre of mass moves freely under the forces on it, so m takes
m_q/(m_m + m_q) of the stroke and q the rest; "symmetric": the same split, centre at rest.  In bar-heat-patch
the m side is every particle in the hot patch (rigid), frozen every particle in a frozen one.  A hot face is
a Langevin bath (or driven), a cold face a 0 K viscous bath (or frozen).  The numba half, inlined into the
kernel's step: kicks, drive positions, start velocities, and a fix's force lambda_n = m (v_{n+1/2} -
v_{n-1/2}) / dt - F_n, whose work the ledger counts.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numba import njit

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

    @property
    def held(self) -> np.ndarray:
        """Particles held in the modal problem (frozen or driven)."""
        return self.kind != FREE

    def energy_scale(self, mass: float, omega: float) -> float:
        """The drives' and baths' energy scale (J): 3/2 sum kT plus 1/2 m omega^2 sum amp^2 of the held particles."""
        return 1.5 * self.kt.sum() + 0.5 * mass * omega**2 * float((self.amp[self.held] ** 2).sum())


def make_fixes(scene: Scene, lat: Lattice, p: dict[str, Any], omega_top: float | None = None) -> Fixes:
    """Map the scene's temperature constraints to fixes on the lattice."""
    N = lat.size
    kind, amp, phase, gamma, kt = np.zeros(N, dtype=np.int64), np.zeros((N, 3)), np.zeros(N), np.zeros(N), np.zeros(N)
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
                    ke = 0.25 * lat.mass * (2 * np.pi * p["drive_frequency"] * stroke) ** 2  # mean KE of the drive
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
        sign = 1.0 if lat.positions[m, 1] - lat.a >= -1e-9 * lat.a else -1.0  # q below m, or above on the bottom
        q = int(lat.node_at(lat.positions[m] - sign * np.array([0.0, lat.a, 0.0]))[0])
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


@njit(inline="always")
def group_force(kind, held, fx, fy, fz):
    """Sum of the forces on the group particles (in index order)."""
    s0 = s1 = s2 = 0.0
    for q in range(held.shape[0]):
        i = held[q]
        if kind[i] == GROUP:
            s0 += fx[i]
            s1 += fy[i]
            s2 += fz[i]
    return s0, s1, s2


@njit(inline="always")
def held_velocity(t_next, t_now, dt, kind, held, amp, phase, omega, vc, vx, vy, vz, start):
    """Velocity of the held particles over [t_now, t_next] into vx, vy, vz (0 for frozen ones).  `start` (a
    constant): v_{-1/2} divides the sine difference by dt, without the group's centre velocity (added after);
    a step multiplies by 1/dt and adds it."""
    inv_dt = 1.0 / dt
    for q in range(held.shape[0]):
        i = held[q]
        if kind[i] == FROZEN:
            vx[i] = vy[i] = vz[i] = 0.0
        else:
            if start:
                ds = (math.sin(omega * t_next + phase[i]) - math.sin(omega * t_now + phase[i])) / dt
            else:
                ds = (math.sin(omega * t_next + phase[i]) - math.sin(omega * t_now + phase[i])) * inv_dt
            vx[i], vy[i], vz[i] = amp[i, 0] * ds, amp[i, 1] * ds, amp[i, 2] * ds
            if not start and kind[i] == GROUP:
                vx[i], vy[i], vz[i] = vx[i] + vc[0], vy[i] + vc[1], vz[i] + vc[2]


@njit(inline="always")
def _lam(q, i, mass, inv_dt, f, vm, vp, lam):
    """lambda of particle i (row q): m (vp - vm) / dt - F."""
    lam[q, 0] = mass * (vp[0][i] - vm[0][i]) * inv_dt - f[0][i]
    lam[q, 1] = mass * (vp[1][i] - vm[1][i]) * inv_dt - f[1][i]
    lam[q, 2] = mass * (vp[2][i] - vm[2][i]) * inv_dt - f[2][i]


@njit(inline="always")
def held_kick(t_next, t_now, dt, kind, held, amp, phase, omega, mass, f, vm, vp, lam, vc, group_mass, free_centre):
    """v_{n+1/2} of the held particles (prescribed, group; the group's centre from the forces on it)."""
    if free_centre:
        s0, s1, s2 = group_force(kind, held, f[0], f[1], f[2])
        vc[0], vc[1], vc[2] = vc[0] + dt * s0 / group_mass, vc[1] + dt * s1 / group_mass, vc[2] + dt * s2 / group_mass
    held_velocity(t_next, t_now, dt, kind, held, amp, phase, omega, vc, vp[0], vp[1], vp[2], False)
    inv_dt = 1.0 / dt
    for q in range(held.shape[0]):
        _lam(q, held[q], mass, inv_dt, f, vm, vp, lam)


@njit(inline="always")
def bath_kick(dt, bath, gamma, kt, mass, f, vm, vp, lam):
    """Langevin particles: exact OU factor with seeded noise, then the kick (kT = 0: an absorbing face)."""
    fx, fy, fz = f
    vmx, vmy, vmz = vm
    vpx, vpy, vpz = vp
    inv_dt = 1.0 / dt
    for q in range(bath.shape[0]):
        i = bath[q]
        damp = math.exp(-gamma[i] * dt)
        sig = math.sqrt(kt[i] / mass * (1.0 - damp * damp))
        vpx[i] = vmx[i] * damp + sig * np.random.standard_normal() + dt * fx[i] / mass  # noqa: NPY002
        vpy[i] = vmy[i] * damp + sig * np.random.standard_normal() + dt * fy[i] / mass  # noqa: NPY002
        vpz[i] = vmz[i] * damp + sig * np.random.standard_normal() + dt * fz[i] / mass  # noqa: NPY002
        _lam(q, i, mass, inv_dt, f, vm, vp, lam)


@njit(cache=True)
def start_velocity(v0, f, vm, kind, held, free, amp, phase, omega, dt, dtm, vc, group_mass, free_centre):
    """v_{-1/2} from v0 and the forces at t = 0, so that v_{+1/2} = v0 + dt/2 a0 (held particles: their
    motion over [-dt, 0]; the group's centre velocity from the forces on the group)."""
    fx, fy, fz = f
    vmx, vmy, vmz = vm
    h = 0.5 * dtm
    for q in range(free.shape[0]):
        i = free[q]
        vmx[i], vmy[i], vmz[i] = v0[i, 0] - h * fx[i], v0[i, 1] - h * fy[i], v0[i, 2] - h * fz[i]
    held_velocity(0.0, -dt, dt, kind, held, amp, phase, omega, vc, vmx, vmy, vmz, True)
    if free_centre:
        s0, s1, s2 = group_force(kind, held, fx, fy, fz)
        vc[0], vc[1], vc[2] = -0.5 * dt * s0 / group_mass, -0.5 * dt * s1 / group_mass, -0.5 * dt * s2 / group_mass
        for q in range(held.shape[0]):
            i = held[q]
            if kind[i] == GROUP:
                vmx[i], vmy[i], vmz[i] = vmx[i] + vc[0], vmy[i] + vc[1], vmz[i] + vc[2]


@njit(inline="always")
def drive_positions(t1, dt, moving, kind, x_rest, amp, phase, omega, vc, cpos, free_centre, pos):
    """Positions of the driven particles at t1 (after the drift of all particles): x_rest + amp sin(omega t1 +
    phase), plus the group's centre displacement, advanced here by dt times its velocity."""
    px, py, pz = pos
    if free_centre:
        for d in range(3):
            cpos[d] += dt * vc[d]
    for q in range(moving.shape[0]):
        i = moving[q]
        w = math.sin(omega * t1 + phase[i])
        px[i], py[i], pz[i] = x_rest[i, 0] + amp[i, 0] * w, x_rest[i, 1] + amp[i, 1] * w, x_rest[i, 2] + amp[i, 2] * w
        if kind[i] == GROUP:
            px[i], py[i], pz[i] = px[i] + cpos[0], py[i] + cpos[1], pz[i] + cpos[2]


@njit(inline="always")
def fix_work(idx, v, lam0, lam1):
    """sum over idx of v . (lambda_prev + lambda_now) (times dt/2: the work of a fix over one interval)."""
    vx, vy, vz = v
    w = 0.0
    for q in range(idx.shape[0]):
        i = idx[q]
        w += vx[i] * (lam0[q, 0] + lam1[q, 0]) + vy[i] * (lam0[q, 1] + lam1[q, 1]) + vz[i] * (lam0[q, 2] + lam1[q, 2])
    return w
