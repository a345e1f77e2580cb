"""Everything before a macromolecule run: lattice, fixes, force scale A from f_top, pair damping from a
damping ratio (damped modal problem) and the time step under its stability limit."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from pcverify.scene import Scene, SceneError

from . import modal
from .fixes import Fixes, make_fixes
from .force import SevenRoot
from .lattice import Lattice, build_lattice
from .parameters import DEFAULT_DAMPING_RATIO

MIN_WINDOW_STEPS = 100  # hotness is a time average: fewer steps cannot make one


@dataclass(frozen=True, eq=False)
class Setup:
    """A prepared run: lattice and fixes, force model (A), damping (delta and the top mode's ratio, with how
    it was found), the time step and its limits (linearised scheme; single-mode estimate)."""

    lattice: Lattice
    fixes: Fixes
    model: SevenRoot
    stiffness_A: float
    f_top: float
    delta: float
    damping_ratio: float
    damping_ratio_method: str
    damping_in_force: str
    damping_ratio_rough: float
    dt: float
    dt_limit: float
    dt_limit_single_mode: float


def prepare(scene: Scene, n: int, p: dict[str, Any]) -> Setup:
    """Lattice, fixes, A, delta and zeta, dt for effective solver parameters `p` (no integration)."""
    lat = build_lattice(scene.box, n, scene.material.density, p["pairs_at_2a"])
    fx = make_fixes(scene, lat, p, omega_top=1.0)
    dofs = modal.free_dofs(~fx.held)
    K0 = modal.hessian(lat.positions, lat.pairs, SevenRoot(1.0, p["p"], p["s"], p["unstable_fraction"]), lat.a)
    omega0, phi, method = modal.modal_basis(K0, lat.mass, dofs)  # at A = 1; K = A K0 has the same shapes
    w0 = float(omega0[-1])
    A = p["stiffness"] if p["stiffness"] is not None else (2 * np.pi * p["f_top"] / w0) ** 2
    w_top = w0 * math.sqrt(A)
    if not (0.0 < w_top < math.inf and A > 0.0):
        raise SceneError(f"the force scale A = {A:.3g} N (from f_top={p['f_top']:g} Hz or stiffness) leaves the "
                         "lattice without stiffness in floating point; allowed: f_top in [1e-3, 1e5] Hz")
    model = SevenRoot(A, p["p"], p["s"], p["unstable_fraction"])
    fx = make_fixes(scene, lat, p, omega_top=w_top)
    basis = (omega0 * math.sqrt(A), phi, method)
    C1 = modal.damping_matrix(lat.positions, lat.pairs, 1.0)
    if p["delta"] is not None and p["damping_ratio"] is not None:
        raise SceneError("delta and damping_ratio are exclusive; give one (damping_ratio defaults to "
                         f"{DEFAULT_DAMPING_RATIO})")
    if p["delta"] is not None:
        in_force, delta = "delta", p["delta"]
        zeta, _, method = modal.damped_top_mode(basis, C1 * delta, dofs)
    else:
        in_force = "damping_ratio"
        zeta = DEFAULT_DAMPING_RATIO if p["damping_ratio"] is None else p["damping_ratio"]
        delta = modal.delta_for_damping_ratio(basis, C1, dofs, zeta)
        method = basis[2]
    single = 2.0 * (math.sqrt(1 + zeta**2) - zeta) / w_top
    limit = 2.0 * modal.discrete_stability_limit(basis, C1 * delta, dofs) / w_top if delta > 0 else 2.0 / w_top
    dt = p["dt"] if p["dt"] is not None else p["safety"] * 2.0 / w_top
    if p["dt"] is None and dt > limit:  # heavy damping: the damped limit is below safety * 2 / omega_max
        dt = p["safety"] * limit
    if dt > limit and p["dt_guard"]:
        raise SceneError(f"dt={dt:.6g} s is above the stability limit {limit:.6g} s of the linearised scheme "
                         f"(spectral radius 1; single-mode estimate 2 (sqrt(1+zeta^2) - zeta) / omega_max = "
                         f"{single:.6g} s, omega_max = {w_top:.6g} rad/s, zeta = {zeta:.3g}); allowed: dt <= limit")
    steps = p["t_end"] / dt
    window = (p["t_end"] - p["t_start"]) / dt
    if window < MIN_WINDOW_STEPS and p["dt_guard"]:
        raise SceneError(f"(t_end - t_start) / dt = {window:.3g} steps is out of range; allowed: at least "
                         f"{MIN_WINDOW_STEPS} steps in the averaging window (dt = {dt:.3g} s from omega_max = "
                         f"{w_top:.3g} rad/s); raise t_end or f_top")
    if steps > p["max_steps"]:
        raise SceneError(f"t_end / dt = {p['t_end']:g} s / {dt:.3g} s = {steps:.3g} steps is out of range; "
                         f"allowed: at most max_steps={p['max_steps']}; lower t_end or f_top, or raise max_steps")
    if p["t_start"] >= p["t_end"]:
        raise SceneError(f"t_start={p['t_start']!r} is out of range; allowed: number in [0, "
                         f"t_end={p['t_end']:g}) s")
    return Setup(lattice=lat, fixes=fx, model=model, stiffness_A=A, f_top=w_top / (2 * np.pi), delta=delta,
                 damping_ratio=zeta, damping_ratio_method=method, damping_in_force=in_force, dt=dt, dt_limit=limit,
                 dt_limit_single_mode=single, damping_ratio_rough=delta / (2 * lat.mass * w_top))
