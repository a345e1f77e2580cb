"""The stick-slip cycle of a rigid block pulled by a spring across a plane with static and kinetic friction.

A block of mass m, pressed by the normal force N, is pulled along the plane by a spring of stiffness k whose far
end moves at the constant speed V; friction holds it while the spring force F stays within mu_s N (stick) and
resists at mu_k N while it slides (mu_k <= mu_s).  Starting at rest with the spring unstretched, it sticks for
t_0 = mu_s N / (k V); then every slip is the same.  With omega = sqrt(k / m), Delta = (mu_s - mu_k) N and tau
the time since the slip began, F'' = -omega^2 (F - mu_k N) during the slip, from F = mu_s N and F' = k V:
    F - mu_k N = Delta cos(omega tau) + (k V / omega) sin(omega tau),
    x' = V (1 - cos(omega tau)) + (omega Delta / k) sin(omega tau)   (the block's velocity),
and the slip ends when x' is 0 again: tan(omega tau / 2) = -omega Delta / (k V), i.e. after
    t_slip = (pi + 2 atan(k V / (omega Delta))) / omega,
where F - mu_k N = -Delta: the trough is (2 mu_k - mu_s) N, the force drop 2 Delta. While the block slips the force
first still rises (F' = k (V - x')), to its largest value mu_k N + sqrt(Delta^2 + (k V / omega)^2). The block then
sticks (|F| <= mu_s N) until F is back at mu_s N:
    t_stick = 2 Delta / (k V),   period = t_stick + t_slip,
and the largest slip velocity is V + sqrt(V^2 + (omega Delta / k)^2).  With mu_s = mu_k there is no stick:
t_stick = 0 and the block slides on (its velocity touches 0 once a period 2 pi / omega).
A scene's cycle: m = density x the slider's volume (body 2), N = normal_stress x its far face's area.

An elastic slider need not break away at mu_s N (its contacts do not reach the static limit together: a slip
front runs across them); whatever force F_p it breaks away at, the rigid block's slip from F_p follows from the
same equations with Delta' = F_p - mu_k N in place of Delta (`given_peak`): trough mu_k N - Delta', slip time
(pi + 2 atan(k V / (omega Delta'))) / omega, stick 2 Delta' / (k V), largest velocity V + sqrt(V^2 + (omega
Delta' / k)^2), largest force mu_k N + sqrt(Delta'^2 + (k V / omega)^2): the kinetic half of the cycle, checked
apart from the static limit.

An incline (a block under its own weight m g tilted by theta from the plane's normal): it sticks while tan theta
<= mu_s, else it slides with the acceleration g (sin theta - mu_k cos theta) (`incline_acceleration`).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from pcverify.scene import Scene


class Cycle(NamedTuple):
    """The steady cycle: spring force at slip onset (peak) and at slip end (trough) and their difference (N),
    stick and slip times and their sum (s), the largest slip velocity (m/s), the first stick (s), omega (1/s), the
    largest spring force (N, reached while slipping)."""

    peak: float
    trough: float
    drop: float
    stick: float
    slip: float
    period: float
    slip_velocity: float
    first_stick: float
    omega: float
    largest: float


def cycle(mass: float, normal_force: float, stiffness: float, speed: float, mu_static: float,
          mu_kinetic: float) -> Cycle:
    """The closed-form cycle of the module docstring (SI units; mu_static >= mu_kinetic >= 0, the rest > 0)."""
    omega = math.sqrt(stiffness / mass)
    delta = (mu_static - mu_kinetic) * normal_force
    slip = (math.pi + 2.0 * math.atan2(stiffness * speed, omega * delta)) / omega
    stick = 2.0 * delta / (stiffness * speed)
    return Cycle(peak=mu_static * normal_force, trough=(2.0 * mu_kinetic - mu_static) * normal_force,
                 drop=2.0 * delta, stick=stick, slip=slip, period=stick + slip,
                 slip_velocity=speed + math.hypot(speed, omega * delta / stiffness),
                 first_stick=mu_static * normal_force / (stiffness * speed), omega=omega,
                 largest=mu_kinetic * normal_force + math.hypot(delta, stiffness * speed / omega))


def given_peak(setting: Setting, peak: float) -> dict[str, float]:
    """The rigid block's cycle from a breakaway at the spring force `peak` (N) instead of mu_s N (module
    docstring), by the summary names a solver reports with the suffix `_given_peak`; empty unless peak lies in
    (mu_k N, inf)."""
    kinetic = setting.mu_kinetic * setting.normal_force
    if not (math.isfinite(peak) and peak > kinetic):
        return {}
    c = cycle(setting.mass, setting.normal_force, setting.stiffness, setting.speed, peak / setting.normal_force,
              setting.mu_kinetic)
    return {"spring_trough_N_given_peak": c.trough, "spring_max_N_given_peak": c.largest,
            "stick_s_given_peak": c.stick, "slip_s_given_peak": c.slip, "period_s_given_peak": c.period,
            "slip_velocity_peak_given_peak": c.slip_velocity}


def spring_force(t: np.ndarray, mass: float, normal_force: float, stiffness: float, speed: float, mu_static: float,
                 mu_kinetic: float) -> np.ndarray:
    """The spring force F(t) (N) from the start (spring unstretched, block at rest): the first stick, then the
    steady cycle (stick ramps at k V, slips as the module docstring's F)."""
    c = cycle(mass, normal_force, stiffness, speed, mu_static, mu_kinetic)
    t = np.asarray(t, dtype=float)
    delta = (mu_static - mu_kinetic) * normal_force
    out = stiffness * speed * np.maximum(t, 0.0)
    late = t > c.first_stick
    phase = np.mod(t[late] - c.first_stick, c.period)
    slipping = phase < c.slip
    wt = c.omega * phase
    slip = mu_kinetic * normal_force + delta * np.cos(wt) + stiffness * speed / c.omega * np.sin(wt)
    stick = c.trough + stiffness * speed * (phase - c.slip)
    out[late] = np.where(slipping, slip, stick)
    return out


class Setting(NamedTuple):
    """What the cycle of a scene takes: the slider's mass (kg), the normal force (N), the spring's stiffness
    (N/m), its far end's speed (m/s) and the friction pair."""

    mass: float
    normal_force: float
    stiffness: float
    speed: float
    mu_static: float
    mu_kinetic: float


def setting(scene: Scene) -> Setting | None:
    """The rigid block a stick-slip scene declares (None for any other scene): body 2 (above the contact plane,
    within its span along the sliding direction) as the block, pressed by normal_stress on its far face."""
    contact = scene.contact
    if contact is None or contact.spring_stiffness is None:
        return None
    extent = np.asarray(scene.box.extent, dtype=float).copy()
    extent[contact.axis_index] -= contact.position
    if contact.span is not None:
        extent[contact.direction_index] = contact.span[1] - contact.span[0]
    face = float(np.prod(np.delete(extent, contact.axis_index)))
    return Setting(mass=scene.material.density * float(np.prod(extent)), normal_force=contact.normal_stress * face,
                   stiffness=contact.spring_stiffness, speed=contact.speed, mu_static=contact.mu_static,
                   mu_kinetic=contact.mu_kinetic)


def expected(scene: Scene) -> dict[str, float]:
    """The cycle of a stick-slip scene by the summary names a solver reports it under (empty for other scenes):
    spring_peak_N, spring_trough_N, force_drop_N, spring_max_N, stick_s, slip_s, period_s, slip_velocity_peak
    (m/s)."""
    s = setting(scene)
    if s is None:
        return {}
    c = cycle(*s)
    return {"spring_peak_N": c.peak, "spring_trough_N": c.trough, "force_drop_N": c.drop, "spring_max_N": c.largest,
            "stick_s": c.stick,
            "slip_s": c.slip, "period_s": c.period, "slip_velocity_peak": c.slip_velocity}


def incline_acceleration(scene: Scene) -> float | None:
    """The acceleration (m/s^2) of a rigid block on an incline scene (None for any other scene): 0 while tan(theta)
    <= mu_s (it sticks), else g (sin(theta) - mu_k cos(theta)), theta = incline_angle, g = gravity."""
    contact = scene.contact
    if contact is None or contact.incline_angle is None:
        return None
    theta = math.radians(contact.incline_angle)
    if math.tan(theta) <= contact.mu_static:
        return 0.0
    return contact.gravity * (math.sin(theta) - contact.mu_kinetic * math.cos(theta))
