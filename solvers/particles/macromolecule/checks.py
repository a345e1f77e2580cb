"""Independent measurements of a macromolecule run against closed forms: what a verification study's claims read.

Each number compares what the kernel measured (hotness sums, the energy ledger) with a value computed here from
the scene and the parameters alone, never from the fixes or the kernel's own bookkeeping: the top mode's
kinetic energy and damping against the closed-form recurrence of the kernel's scheme on one mode
(`top_mode_kinetic_ratio`, `top_mode_damping_ratio`), the driven red pair's kinetic energy against its
prescribed stroke (`red_pair_kinetic_ratio`), the kinetic energy at the 0 K points (`cold_kinetic_max`),
omega_max recomputed from the Hessian of the force model as built (`setup_check`) and the stationarity stop's
effect on the hotness (`stop_check`).  `force_law_summary` reports the force law and lattice as built (roots found
from the force itself, stiffness, force at fixed separations, particle count, mass and positions) for the
lattice family's independent specification (references/lattice.py) to judge.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.optimize import brentq

from pcverify.scene import PatchTemperature, PointTemperature, Scene

from . import codes, modal
from .force import force_array, force_slope_x
from .setup import Setup
from .simulate import RunResult


def top_mode(s: Setup) -> tuple[float, np.ndarray]:
    """(omega_max, shape): the top angular frequency of the held lattice from the Hessian of the force model as
    built (A included) and its shape as (N, 3) displacements, largest particle displacement 1, held particles 0."""
    lat = s.lattice
    dofs = modal.free_dofs(~s.fixes.held)
    omega, phi = modal.top_modes(modal.hessian(lat.positions, lat.pairs, s.model, lat.a), lat.mass, dofs, k=1)
    shape = np.zeros(3 * lat.size)
    shape[dofs] = phi[:, -1]
    shape = shape.reshape(-1, 3)
    return float(omega[-1]), shape / np.linalg.norm(shape, axis=1).max()


def top_mode_start(s: Setup, amplitude: float) -> np.ndarray:
    """Start positions: the lattice displaced along its top mode, largest displacement `amplitude` a."""
    return s.lattice.positions + amplitude * s.lattice.a * top_mode(s)[1]


def mode_sequence(omega: float, zeta: float, dt: float, steps: int) -> np.ndarray:
    """x_0 .. x_steps of one mode started at rest at x_0 = 1 under the kernel's scheme, in closed form (its two
    roots): x_1 = 1 - h^2 / 2 (h = omega dt; the damping lags from v_0 = 0), then the recurrence
    x_{n+1} = (2 - 2 zeta h - h^2) x_n - (1 - 2 zeta h) x_{n-1}."""
    h = omega * dt
    b, c = 2.0 - 2.0 * zeta * h - h * h, 1.0 - 2.0 * zeta * h
    z1, z2 = np.roots([1.0, -b, c]).astype(complex)
    x1 = 1.0 - 0.5 * h * h
    coef1 = (x1 - z2) / (z1 - z2)
    n = np.arange(steps + 1)
    return np.real(coef1 * z1**n + (1.0 - coef1) * z2**n)


def mode_kinetic_mean(omega: float, zeta: float, dt: float, n0: int, count: int) -> float:
    """Mean of v_n^2 (v_n = (x_{n+1} - x_{n-1}) / 2 dt, v_0 = 0) over the steps n0 .. n0 + count - 1 of
    `mode_sequence`: twice the mean kinetic energy per unit mass of the mode."""
    x = mode_sequence(omega, zeta, dt, n0 + count + 1)
    v = np.zeros(n0 + count)
    v[1:] = (x[2:n0 + count + 1] - x[:n0 + count - 1]) / (2.0 * dt)
    return float(np.mean(v[n0:] ** 2))


def mode_energy_ratio(omega: float, zeta: float, dt: float, steps: int) -> float:
    """E_steps / E_0 of `mode_sequence` with the kernel's ledger energy E_n = 1/2 v_{n-1/2} v_{n+1/2} + 1/2
    omega^2 x_n^2 (v_{-1/2} = omega^2 dt / 2: the start from rest)."""
    x = mode_sequence(omega, zeta, dt, steps + 1)
    e0 = 0.5 * omega**2 * (1.0 - 0.25 * (omega * dt) ** 2)
    vm, vp = (x[steps] - x[steps - 1]) / dt, (x[steps + 1] - x[steps]) / dt
    return float((0.5 * vm * vp + 0.5 * omega**2 * x[steps] ** 2) / e0)


def measured_damping_ratio(omega: float, dt: float, steps: int, ratio: float) -> float:
    """The zeta whose `mode_energy_ratio` over `steps` is `ratio` (NaN when none in [-0.1, 0.5] is)."""
    def miss(zeta: float) -> float:
        return mode_energy_ratio(omega, zeta, dt, steps) - ratio

    lo, hi = -0.1, 0.5
    if not (math.isfinite(ratio) and ratio > 0 and miss(lo) > 0 > miss(hi)):
        return math.nan
    return float(brentq(miss, lo, hi, xtol=1e-14, rtol=1e-12))


def top_mode_summary(s: Setup, p: dict[str, Any], run: RunResult, x0: np.ndarray) -> dict[str, float]:
    """The top-mode run's kinetic energy and damping against the closed forms, at the f_top asked for."""
    lat = s.lattice
    omega = 2.0 * math.pi * p["f_top"]
    n0 = int(round(p["t_start"] / s.dt))
    count = int(run.counters[codes.K_HOT_STEPS])
    amplitude2 = float(((x0 - lat.positions) ** 2)[~s.fixes.held].sum())  # sum of |u_i|^2 over the free particles
    expected = 0.5 * lat.mass * amplitude2 * mode_kinetic_mean(omega, s.damping_ratio, s.dt, n0, count)
    ratio = run.energy[codes.E_END] / run.energy[codes.E_START]
    return {"top_mode_kinetic_ratio": float(run.hot[0].sum() / expected),
            "top_mode_damping_ratio": measured_damping_ratio(omega, s.dt, run.steps, ratio)}


def red_pair_summary(scene: Scene, s: Setup, p: dict[str, Any], run: RunResult) -> dict[str, float]:
    """The driven pairs' mean kinetic energy against their strokes' (points held hot, symmetric drive only)."""
    lat, t_max = s.lattice, scene.conduction.t_max
    hot = [c for c in scene.constraints if c.value >= t_max * (1 - 1e-12)]
    if p["drive_sharing"] != "symmetric" or not hot or not all(isinstance(c, PointTemperature) for c in hot):
        return {}
    nodes = []
    for c in hot:
        point = np.array(c.point, dtype=float)
        below = point[1] - lat.a >= -1e-9 * lat.a  # the pair's second particle: one spacing below, or above
        nodes += [point, point - (1.0 if below else -1.0) * np.array([0.0, lat.a, 0.0])]
    measured = float(run.hot[0][lat.node_at(np.array(nodes))].sum())
    omega, stroke = 2.0 * math.pi * p["drive_frequency"], p["drive_amplitude"] * lat.a
    n0 = int(round(p["t_start"] / s.dt))
    t = (n0 + np.arange(int(run.counters[codes.K_HOT_STEPS]))) * s.dt
    w = (np.sin(omega * (t + s.dt)) - np.sin(omega * (t - s.dt))) / (2.0 * s.dt)  # the stroke's v_n per unit
    expected = len(hot) * 0.5 * (0.5 * lat.mass) * stroke**2 * float(np.mean(w**2))
    return {"red_pair_kinetic_ratio": measured / expected}


def cold_kinetic_max(scene: Scene, s: Setup, H: np.ndarray, free: np.ndarray) -> dict[str, float]:
    """The largest mean kinetic energy at the scene's 0 K points and patches over the hottest free particle's."""
    lat = s.lattice
    nodes: list[np.ndarray] = []
    for c in scene.constraints:
        if c.value != 0.0 or not isinstance(c, (PointTemperature, PatchTemperature)):
            continue
        if isinstance(c, PointTemperature):
            nodes.append(lat.node_at(np.array(c.point)))
        else:
            nodes.append(np.union1d(lat.within(np.array(c.centre), c.radius), lat.node_at(np.array(c.centre))))
    hottest = H[free].max() if free.any() else 0.0
    if not nodes or not hottest > 0:
        return {}
    return {"cold_kinetic_max": float(H[np.concatenate(nodes)].max() / hottest)}


def setup_summary(s: Setup) -> dict[str, float]:
    """f_top and the time step's safety dt omega_max / 2 with omega_max recomputed from the force model as built."""
    omega = top_mode(s)[0]
    return {"f_top_check_hz": omega / (2.0 * math.pi), "dt_safety_check": s.dt * omega / 2.0}


FORCE_PROBES = (0.95, 1.1, 1.3, 1.5, 1.65, 1.8, 1.9)  # r / a where the force is reported (force_0p95a, ...)
# where sign changes of F are looked for: a step of 1/997 from an irrational offset never lands on a root
# (a product exactly 0 changes no sign); the seventh root, 2, is excluded: F is 0 beyond it
ROOT_SCAN = 0.9 + 1e-3 * math.pi + np.arange(1087) / 997.0


def force_law_summary(scene: Scene, s: Setup, n: int) -> dict[str, float]:
    """The force law and the lattice as built: the roots of the kernel's pair force (sign changes on ROOT_SCAN,
    refined by brentq), dF/dr at the first three (stable) ones, F at FORCE_PROBES, the particle count, mass,
    spacing, the rest positions' rms distance from the box's centre, the pairs and the held particles."""
    lat, c = s.lattice, s.model.coeffs()
    f = force_array(ROOT_SCAN, c)
    change = np.flatnonzero(np.sign(f[:-1]) * np.sign(f[1:]) < 0)
    found = [brentq(lambda x: float(force_array(np.array([x]), c)[0]), ROOT_SCAN[k], ROOT_SCAN[k + 1],
                    xtol=1e-14, rtol=1e-14) for k in change]
    out: dict[str, float] = {"force_root_count": float(len(found))}
    out |= {f"force_root_{k + 1}": float(x) for k, x in enumerate(found[:6])}
    out |= {f"root_stiffness_{k // 2 + 1}": force_slope_x(found[k], c)[1] / lat.a for k in (0, 2, 4) if k < len(found)}
    probe = force_array(np.array(FORCE_PROBES), c)
    out |= {"force_" + f"{x:.2f}".replace(".", "p") + "a": float(v) for x, v in zip(FORCE_PROBES, probe, strict=True)}
    centre = 0.5 * np.asarray(scene.box.extent, dtype=float)
    return out | {"lattice_n": float(n), "lattice_spacing": lat.a, "particle_mass": lat.mass,
                  "lattice_rms_radius": float(np.sqrt(np.mean(np.sum((lat.positions - centre) ** 2, axis=1)))),
                  "held_particles": float(np.count_nonzero(s.fixes.held))}
