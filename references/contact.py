"""The contact family: two duralumin blocks pressed, slid, pulled by a spring, tilted and heated by friction, their
references (the contact pressure, the rigid block's stick-slip cycle, also from a measured breakaway, and incline,
the heat share e1 / (e1 + e2), the heat family's slab) and the summary scalars a contact solver reports (`SCALARS`:
names, units, signs).  The closed forms: (docs/physics.md, "Analytic references", "The contact family").
"""

from __future__ import annotations

import functools
import math
from typing import Any, NamedTuple

import numpy as np

from pcverify.references.heat import analytic, effusivity, effusivity_shares
from pcverify.references.shared import DIMENSIONS, DURALUMIN_THERMAL, box_of, number
from pcverify.scene import (
    DURALUMIN,
    Conduction,
    Contact,
    Elasticity,
    FaceClamp,
    FaceSupport,
    InterfaceFlux,
    Param,
    Reference,
    Scalar,
    Scene,
    SceneError,
    SceneSpec,
)


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
    """The rigid block's closed-form cycle (docs/physics.md, "Analytic references"; SI units;
    mu_static >= mu_kinetic >= 0, the rest > 0)."""
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
    steady cycle (stick ramps at k V, slips as F of the closed form in docs/physics.md)."""
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


class Contacts(NamedTuple):
    """A rigid slider's discrete contacts, collapsed into rows across the sliding direction: each row's position
    along it from the footprint's centre (m) and its contact area (m^2); the height (m) above the interface of the
    slider's centre of mass, where the scene's spring pulls."""

    z: np.ndarray
    area: np.ndarray
    height: float


def slider_contacts(scene: Scene, spacing: float) -> Contacts:
    """The contacts of a stick-slip scene's slider on the cubic lattice of the given spacing: one per node of its
    bottom node plane (the first above the interface), each its node's cell clipped by the slider, so end rows
    carry half a cell; the height is the mass-weighted mean of the slider's node planes above the interface
    (their cells clipped by the slider likewise)."""
    contact = scene.contact
    ext = np.asarray(scene.box.extent, dtype=float)
    ax, dr = contact.axis_index, contact.direction_index
    across = 3 - ax - dr
    lo, hi = contact.span if contact.span is not None else (0.0, float(ext[dr]))

    def cells(first: float, last: float) -> tuple[np.ndarray, np.ndarray]:
        nodes = np.arange(math.ceil(first / spacing - 1e-6), math.floor(last / spacing + 1e-6) + 1) * spacing
        return nodes, np.minimum(nodes + spacing / 2, last) - np.maximum(nodes - spacing / 2, first)

    z, width = cells(lo, hi)
    y, thick = cells(contact.position, float(ext[ax]))
    return Contacts(z=z - 0.5 * (lo + hi), area=width * float(ext[across]),
                    height=float((thick * (y - contact.position)).sum() / thick.sum()))


class Rows(NamedTuple):
    """A rigid block's run: per step the time (s), the spring force (N) and the block's velocity (m/s)."""

    t: np.ndarray
    force: np.ndarray
    velocity: np.ndarray


def contact_block(s: Setting, contacts: Contacts, kt: float, duration: float, pull_height: float | None = None,
                  damping: float = 0.0, steps_per_period: int = 60) -> Rows:
    """A rigid block on discrete Cundall-Strack contacts, pulled from rest by the spring (its far end from the
    spring's unstretched length at t = 0): per contact a tangential spring kt (Pa/m) times its area, limited by
    mu_s sigma while it sticks and by mu_k sigma once it slips, stuck again when the block's velocity turns
    against its stress.  The block slides but does not turn: the contacts' normal stresses are its quasi-static
    equilibrium on equal normal springs (the pitching vibration, ~1e5 Hz, far above the cycle), linear along the
    sliding direction, their resultant N and their moment about the footprint's centre the friction's R h plus
    the spring's F (pull_height - h) (h = contacts.height; pull_height None: at h).  Leapfrog at 1 /
    steps_per_period of the block's period on its stuck contacts.  Undamped (damping 0) as the scene's slider
    moving as a whole (its damping acts relative to its mean velocity); damping > 0 adds a viscous stress on each
    stuck contact, that fraction of critical for the block on all of them (1: the ringing a re-stick starts dies
    within a period; without it a later breakaway comes early by up to the drop, as the ringing's crest
    reaches mu_s sigma first)."""
    h = contacts.height
    hs = h if pull_height is None else pull_height
    z, area = contacts.z, contacts.area
    total, second = area.sum(), (area * z * z).sum()
    omega_c = math.sqrt(kt * total / s.mass)
    dt = 2.0 * math.pi / omega_c / steps_per_period
    viscous = 2.0 * damping * s.mass * omega_c / total  # Pa s/m on a stuck contact
    n = math.ceil(duration / dt)
    tau = np.zeros_like(z)  # the contacts' tangential stress (Pa), on the block against +z
    slipping = np.zeros(z.shape, dtype=bool)
    t = np.arange(n + 1) * dt
    force, vel = np.zeros(n + 1), np.zeros(n + 1)
    x, v, resist = 0.0, 0.0, 0.0
    for i in range(n):
        f = s.stiffness * (s.speed * t[i] - x)
        force[i] = f
        v += dt * (f - resist) / s.mass
        x += dt * v
        vel[i + 1] = v
        sigma = s.normal_force / total + (z * (h * resist + (hs - h) * f) / second if second > 0 else 0.0)
        slipping &= tau * v > 0.0
        trial = tau + kt * v * dt
        limit = np.where(slipping, s.mu_kinetic, s.mu_static) * sigma
        over = np.abs(trial) > limit
        slipping |= over
        tau = np.where(over, np.sign(trial) * s.mu_kinetic * sigma, trial)
        resist = float((area * tau).sum()) + viscous * float(area[~slipping].sum()) * v
    force[n] = s.stiffness * (s.speed * t[n] - x)
    return Rows(t=t, force=force, velocity=vel)


CONTACT_DAMPING = 0.0  # undamped, as the scene's slider moving as a whole (1: critically damped, the bracket)
CYCLE_NAMES = ("spring_peak_N", "spring_trough_N", "force_drop_N", "spring_max_N", "slip_s", "slip_velocity_peak",
               "stick_s", "period_s")


def cycle_of(rows: Rows, speed: float, slip_speed: float = 0.1, rest_speed: float = 0.02) -> dict[str, float]:
    """The cycle of a block's rows as the scene's measurement defines it: slips where the velocity exceeds
    slip_speed x speed, from and to the nearest rows below rest_speed x speed; first_peak_N the first slip's
    starting force; the rest means over the typical cycles: peak, trough, drop, largest force, slip time and
    largest velocity of every slip after the first, the stick before each slip after the second (the stick
    after the first slip follows an untypical slip), the period from each slip after the first to the next."""
    t, force, vel = rows
    fast = np.flatnonzero(np.diff(np.r_[False, vel > slip_speed * speed, False]))
    still = vel <= rest_speed * speed
    bounds = []
    for a, b in zip(fast[::2], fast[1::2], strict=True):
        before, after = np.flatnonzero(still[:a]), np.flatnonzero(still[b:])
        if len(before) and len(after):
            bounds.append((int(before[-1]), int(b + after[0])))
    out: dict[str, Any] = {"first_peak_N": float(force[bounds[0][0]]) if bounds else math.nan}
    values: dict[str, list[float]] = {k: [] for k in CYCLE_NAMES}
    for k in range(1, len(bounds)):
        a, b = bounds[k]
        values["spring_peak_N"].append(force[a])
        values["spring_trough_N"].append(force[b])
        values["force_drop_N"].append(force[a] - force[b])
        values["spring_max_N"].append(force[a:b + 1].max())
        values["slip_s"].append(t[b] - t[a])
        values["slip_velocity_peak"].append(vel[a:b + 1].max())
        if k >= 2:
            values["stick_s"].append(t[a] - t[bounds[k - 1][1]])
        if k + 1 < len(bounds):
            values["period_s"].append(t[bounds[k + 1][0]] - t[a])
    return out | {k: float(np.mean(v)) if v else math.nan for k, v in values.items()}


@functools.lru_cache(maxsize=64)
def _contact_rows(scene: Scene, spacing: float, kt: float, damping: float) -> Rows:
    contacts = slider_contacts(scene, spacing)
    return contact_block(setting(scene), contacts, kt, scene.contact.duration, damping=damping)


def _shear_stiffness(scene: Scene, spacing: float, kt: float | None) -> float:
    """kt (Pa/m) as given, or the bonded pair's shear stiffness 2 G / spacing, G = E / (2 (1 + nu))."""
    if kt is not None:
        return float(kt)
    mat = scene.material
    return 2.0 * mat.youngs_modulus / (2.0 * (1.0 + mat.poisson_ratio)) / spacing


def contact_cycle(scene: Scene, spacing: float, kt: float | None = None, damping: float = CONTACT_DAMPING
                  ) -> dict[str, float]:
    """The cycle (`cycle_of`) of the rigid block on the contacts of the scene's slider at the lattice spacing
    (m), pulled at its centre of mass for the scene's duration; kt (Pa/m) by default the bonded pair's shear
    stiffness 2 G / spacing, G = E / (2 (1 + nu))."""
    rows = _contact_rows(scene, float(spacing), _shear_stiffness(scene, spacing, kt), float(damping))
    return cycle_of(rows, scene.contact.speed)


def _history(scene: Scene, t: np.ndarray, summary: dict[str, Any] | None = None) -> tuple[np.ndarray, str]:
    """The spring force the history figure draws under a run: the rigid block on the slider's contacts at the
    run's lattice spacing and contact stiffness when its summary reports them (what the contact-block claims
    judge), else the rigid block's closed form."""
    spacing = number((summary or {}).get("lattice_spacing"))
    if spacing is None or spacing <= 0:
        return spring_force(t, *setting(scene)), "rigid block (analytic)"
    kt = number((summary or {}).get("contact_stiffness_Pa_per_m"))
    rt, force, _ = _contact_rows(scene, spacing, _shear_stiffness(scene, spacing, kt), CONTACT_DAMPING)
    return np.interp(t, rt, force), f"rigid block on the slider's contacts (spacing {spacing * 1e3:.3g} mm)"


SCALARS = (
    Scalar("contact_pressure_mean", "Pa", "area-weighted mean pressure of the closed contacts (positive pressing)"),
    Scalar("contact_pressure_uniformity", "", "(max - min) / mean of the closed contacts' pressure"),
    Scalar("mu_dr_mean", "", "friction coefficient F_dr / F_N over the sliding window (eq. 17; also mu_dr_error)"),
    Scalar("energy_balance_error", "", "largest energy imbalance over the sliding window per the drive's work"),
    Scalar("energy_balance_start_error", "", "largest energy imbalance from the drive's start (ramp included: "
           "every energy term changes) per the drive's and the load's work there"),
    Scalar("spring_peak_N", "N", "spring force at breakaway, mean over the cycles after the first (also "
           "spring_trough_N, force_drop_N, spring_max_N; stick_s, slip_s, period_s in s; slip_velocity_peak in m/s)"),
    Scalar("largest_spring_force_N", "N", "the largest spring force over the whole run, every row (up to a blow-up, "
           "if one stops the run): defined with or without a cycle"),
    Scalar("slide_acceleration", "m/s^2", "the slider's acceleration down an incline (0 while it sticks)"),
    Scalar("heat_share_base", "", "share of the friction heat the lower block holds at t_end"),
    Scalar("interface_rise_base_ratio", "", "rise next to the plane in the base against two semi-infinite solids "
           "(also _slider_ratio; flux_ratio: the law's mean flux against the declared one)"),
)
GIVEN_PEAK = ("spring_trough_N", "spring_max_N", "stick_s", "slip_s", "period_s", "slip_velocity_peak")


def _cycle(scene: Scene, summary: dict[str, Any]) -> dict[str, float]:
    """The rigid block's cycle, its kinetic half from the measured breakaway (NAME_given_peak: NaN unless the
    summary's spring_peak_N is above mu_k N), and the cycle of the rigid block on the slider's contacts at the
    run's lattice spacing and contact stiffness (NAME_given_contacts: only when the summary reports them)."""
    peak = number(summary.get("spring_peak_N"))
    given = given_peak(setting(scene), peak if peak is not None else math.nan)
    out = expected(scene) | {f"{name}_given_peak": given.get(f"{name}_given_peak", math.nan) for name in GIVEN_PEAK}
    spacing = number(summary.get("lattice_spacing"))
    if spacing is not None and spacing > 0:
        out |= {f"{name}_given_contacts": value for name, value in
                contact_cycle(scene, spacing, number(summary.get("contact_stiffness_Pa_per_m"))).items()}
    return out


def _pressure(scene: Scene, summary: dict[str, Any]) -> dict[str, float]:
    """The uniaxial stress E |strain| of the bonded stack crosses the interface uniformly."""
    return {"contact_pressure_mean": scene.material.youngs_modulus * abs(dict(scene.params)["strain"]),
            "contact_pressure_uniformity": 0.0}


def _heat_share(scene: Scene, summary: dict[str, Any]) -> dict[str, float]:
    """Two semi-infinite solids in contact share a flux made between them as their effusivities (source=friction)."""
    contact, mat = scene.contact, scene.material
    if contact is None:
        return {}
    k = mat.conductivity if contact.base_conductivity is None else contact.base_conductivity
    c = mat.heat_capacity if contact.base_heat_capacity is None else contact.base_heat_capacity
    return {"heat_share_base": effusivity_shares(effusivity(k, mat.density, c), effusivity(
        mat.conductivity, mat.density, mat.heat_capacity))[0]}


def _pressed(p: dict[str, Any]) -> Scene:
    box = box_of(p)
    cons = (FaceSupport("z0"), FaceSupport("zL", p["strain"] * box.length))
    return Scene("block-contact-compression", COMPRESSION.description, box, DURALUMIN,
                 frozenset({"elasticity", "contact"}), cons, elasticity=Elasticity(),
                 contact=Contact(axis="z", position=box.length / 2), params=tuple(sorted(p.items())))


def _slider(name: str, p: dict[str, Any], physics: set[str], **contact: Any) -> Scene:
    """A slider (the middle third of the upper half) on its base clamped at y=0."""
    box = box_of(p)
    part = Contact(axis="y", position=box.height / 2, direction="z", duration=p["duration"],
                   span=(box.length / 3, 2 * box.length / 3), **contact)
    return Scene(name, SPECS[name].description, box, DURALUMIN, frozenset({"elasticity", "contact", *physics}),
                 (FaceClamp("y0"),), elasticity=Elasticity(), contact=part, params=tuple(sorted(p.items())))


def _heating(p: dict[str, Any]) -> Scene:
    if p["dt"] > p["t_end"]:
        raise SceneError(f"dt={p['dt']!r} is out of range; allowed: number in (0, t_end={p['t_end']:g}] s")
    box = box_of(p)
    flux = p["friction"] * p["normal_stress"] * p["speed"]
    heat = Conduction(t_max=p["t_max"], mode="transient", t_end=p["t_end"], dt=p["dt"],
                      interface=InterfaceFlux(flux, box.length / 2, "z"))
    physics = {"conduction", "interface-flux"}
    base = {k: p[k] for k in ("base_conductivity", "base_heat_capacity") if p[k] is not None}
    if p["source"] == "flux" and base:
        name = next(iter(base))
        raise SceneError(f"{name}={base[name]!r} is not allowed with source='flux'; allowed: source='friction' (the "
                         "flux scene is one material, as the continuum solvers take it)")
    if p["source"] == "flux":
        return Scene("frictional-heating", HEATING.description, box, DURALUMIN_THERMAL, frozenset(physics), (),
                     conduction=heat, params=tuple(sorted(p.items())))
    contact = Contact(axis="z", position=box.length / 2, normal_stress=p["normal_stress"], speed=p["speed"],
                      direction="x", duration=p["duration"], heating=True, platen=True, **base)
    return Scene("frictional-heating", HEATING.description, box, DURALUMIN_THERMAL,
                 frozenset(physics | {"elasticity", "contact", "frictional-heating"}), (FaceClamp("z0"),),
                 conduction=heat, elasticity=Elasticity(), contact=contact, params=tuple(sorted(p.items())))


MU_STATIC = Param("mu_static", 0.4, "", "static friction coefficient of the two surfaces (>= mu_kinetic)", low=0.0,
                  high=5.0)
MU_KINETIC = Param("mu_kinetic", 0.3, "", "kinetic friction coefficient of the two surfaces", low=0.0, high=5.0)
HEAT_SOURCES = ("friction", "flux")
COMPRESSION = SceneSpec(
    "block-contact-compression",
    "Two duralumin blocks stacked along z, unlinked at the interface z = L/2 (contact by the segment method), "
    "compressed between frictionless supports on z=0 and z=L by strain * L (analytic: the uniaxial stress "
    "E |strain| of the bonded bar crosses the interface uniformly); n even",
    (*DIMENSIONS, Param("strain", -1e-3, "", "nominal axial strain (negative = compression)", low=-0.01,
                        high=0.0, high_open=True)),
    _pressed, Reference(scalars=_pressure), SCALARS)
SLIDING = SceneSpec(
    "block-sliding",
    "A duralumin slider (the middle third of the upper half, y > H/2) pressed by normal_stress on a base "
    "(y < H/2, clamped at y=0) and driven along z at speed for duration after a smooth start: the macroscopic "
    "friction coefficient mu_dr = F_dr / F_N (eq. 17) and the energy balance; n even",
    (
        *DIMENSIONS,
        Param("normal_stress", 1e6, "Pa", "pressure on the slider's top face", low=0.0, high=1e9, low_open=True),
        Param("speed", 1.0, "m/s", "sliding speed of the slider's top face", low=0.0, high=100.0, low_open=True),
        Param("duration", 1e-3, "s", "sliding time at full speed (the averaging window)", low=0.0, high=1.0,
              low_open=True),
    ),
    lambda p: _slider("block-sliding", p, set(), normal_stress=p["normal_stress"], speed=p["speed"]), None, SCALARS)
STICK_SLIP = SceneSpec(
    "stick-slip",
    "The block-sliding slider pressed by normal_stress on its clamped base and pulled along z by a spring of "
    "stiffness spring_stiffness whose far end moves at speed (pulling at the slider's centre of mass), with "
    "static and kinetic friction mu_static >= mu_kinetic: against a rigid block on the slider's discrete "
    "Cundall-Strack contacts pulled at the same height (the friction's moment; at the run's lattice spacing), and "
    "the analytic cycle of a rigid block (peak mu_static N, force drop 2 (mu_static - mu_kinetic) N, period, "
    "largest slip velocity; its kinetic half from the measured breakaway); defaults: the spring's 0.95 kHz far "
    "below the slider's lowest elastic frequency (~150 kHz), 3 cycles after the first in duration; n even",
    (
        *DIMENSIONS,
        Param("normal_stress", 1e6, "Pa", "pressure on the slider's top face", low=0.0, high=1e9, low_open=True),
        Param("speed", 0.5, "m/s", "speed of the spring's far end", low=0.0, high=100.0, low_open=True),
        Param("spring_stiffness", 5e4, "N/m", "stiffness of the drive spring", low=0.0, high=1e12, low_open=True),
        MU_STATIC,
        MU_KINETIC,
        Param("duration", 7e-3, "s", "time the spring's far end moves (the whole run after the preload)",
              low=0.0, high=1.0, low_open=True),
    ),
    lambda p: _slider("stick-slip", p, {"stick-slip"}, normal_stress=p["normal_stress"], speed=p["speed"],
                      spring_stiffness=p["spring_stiffness"], mu_static=p["mu_static"], mu_kinetic=p["mu_kinetic"]),
    Reference(scalars=_cycle, history=_history),
    SCALARS)
INCLINE = SceneSpec(
    "incline",
    "The block-sliding slider on its clamped base under its own weight only, the body force gravity tilted by "
    "angle from the contact's normal towards +z, friction pair mu_static >= mu_kinetic: a rigid block sticks "
    "while tan(angle) <= mu_static, else slides with the acceleration gravity (sin(angle) - mu_kinetic "
    "cos(angle)) (references/contact.py); gravity is large by default (1e5 m/s^2: the slider's weight "
    "137 N) so that the contact is pressed as in stick-slip; n even",
    (
        *DIMENSIONS,
        Param("angle", 30.0, "degrees", "tilt of the body force from the contact's normal", low=0.0, high=89.0),
        Param("gravity", 1e5, "m/s^2", "magnitude of the body force per mass", low=0.0, high=1e9, low_open=True),
        MU_STATIC,
        MU_KINETIC,
        Param("duration", 5e-4, "s", "time the tilted weight acts (after the normal preload)", low=0.0,
              high=1.0, low_open=True),
    ),
    lambda p: _slider("incline", p, {"incline"}, mu_static=p["mu_static"], mu_kinetic=p["mu_kinetic"],
                      incline_angle=p["angle"], gravity=p["gravity"]),
    Reference(scalars=lambda scene, summary: {"slide_acceleration": incline_acceleration(scene)}), SCALARS)
HEATING = SceneSpec(
    "frictional-heating",
    "Two duralumin blocks stacked along z (interface z = L/2, base clamped at z=0), the upper one pressed by "
    "normal_stress and slid along x at speed under a platen: the friction power heats both (MCA mechanics "
    "-> MCA heat, source=friction); the reference is the same bar with the interface flux q = friction * "
    "normal_stress * speed (source=flux: continuum solvers; analytic slab and, at short times, the "
    "semi-infinite rise); insulated faces, from 0 K to t_end; n even",
    (
        *DIMENSIONS,
        Param("source", "friction", "", "friction: MCA's sliding contact makes the heat; flux: the interface "
              "flux is given (any heat solver)", choices=HEAT_SOURCES, kind=str),
        Param("normal_stress", 1e6, "Pa", "pressure on the upper block's top face", low=0.0, high=1e9,
              low_open=True),
        Param("speed", 1.0, "m/s", "sliding speed", low=0.0, high=100.0, low_open=True),
        Param("friction", 0.3, "", "friction coefficient of the declared flux q = friction normal_stress "
              "speed (MCA's own law must dissipate it: its mu1 defaults to the same 0.3)", low=0.0, high=5.0),
        Param("duration", 3e-4, "s", "sliding time at full speed over which the friction power is averaged",
              low=0.0, high=1.0, low_open=True),
        Param("t_end", 0.5, "s", "heating time", low=0.0, high=1e4, low_open=True),
        Param("dt", 0.005, "s", "continuum time step", low=0.0, high=1e4, low_open=True),
        Param("t_max", 10.0, "K", "temperature scale (relative results are T/t_max)", low=1e-3, high=1e5),
        Param("base_conductivity", None, "W/(m K)", "the lower block's own conductivity (dissimilar blocks, "
              "source=friction; none = duralumin's 121)", low=0.0, high=1e4, low_open=True, optional=True),
        Param("base_heat_capacity", None, "J/(kg K)", "the lower block's own heat capacity (dissimilar "
              "blocks, source=friction; none = duralumin's 875)", low=0.0, high=1e5, low_open=True,
              optional=True),
    ),
    _heating, Reference(field=analytic, scalars=_heat_share), SCALARS)
SCENES = (COMPRESSION, SLIDING, STICK_SLIP, INCLINE, HEATING)
SPECS = {spec.name: spec for spec in SCENES}
