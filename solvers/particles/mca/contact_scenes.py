"""The MCA solver's contact scenes: two bodies pressed together, pressed and slid, or slid and heated by
friction (contact.py holds the segment method and the friction law; this module maps a scene's Contact part
onto the model and summarises the run: pressure, mu at the drive and the clamp, Newton's third law, angular
momentum, the drive's power, the heat split by conductivities) (docs/physics.md, "The MCA solver in detail",
"Contact scenes").
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np
from scipy.special import erfc

from pcverify.scene import Contact, FaceClamp, FaceSupport, Scene, SceneError, shown
from pcverify.solvers.energy import balance_error
from pcverify.solvers.protocol import heat_summary

from . import contact as ct
from . import heat as mca_heat
from . import kernel as mk
from . import roughness as rg
from .automata import Automata, body_automata
from .kernels import timed
from .model import Elastic, Model, rebuild_pairs, relax, relax_status

FACE_AXES = "xyz"


def law_of(aut: Automata, contact: Contact, p: dict[str, Any], shear: float) -> ct.ContactLaw:
    """The contact law of the solver parameters (h0 = the spacing across the interface; `contact_stiffness` by
    default 2 G / h0, `shear` = G).  A sliding scene needs the automata's rotations, for the contact's moments."""
    rough = rg.Roughness(on=bool(p["roughness_a1"] > 0 or p["roughness_a2"] > 0), a1=float(p["roughness_a1"]),
                         a2=float(p["roughness_a2"]), d1=float(p["roughness_d1"]), d2=float(p["roughness_d2"]),
                         spread=float(p["roughness_spread"]), seed=int(p["seed"]))
    h0 = float(aut.spacing[contact.axis_index])
    mu1 = float(p["mu1"])
    mu_s = mu1 if p["mu_s"] is None else float(p["mu_s"])
    if mu_s < mu1:
        raise SceneError(f"mu_s={shown(p['mu_s'])} is below the kinetic coefficient mu1={shown(mu1)}; allowed: "
                         "mu_s >= mu1 (none: mu_s = mu1)")
    if contact.sliding and not p["rotations"]:
        raise SceneError("rotations=false with a sliding contact: the contact's friction acts at the contact "
                         "point and its moments need the automata's rotations; allowed: rotations=true")
    kt = 2.0 * shear / h0 if p["contact_stiffness"] is None else float(p["contact_stiffness"])
    return ct.ContactLaw(h0=h0, mu0=float(p["mu0"]), mu1=mu1,
                         sigma0=math.inf if p["sigma0"] is None else float(p["sigma0"]), v_reg=float(p["v_reg"]),
                         rough=rough, axis=contact.axis_index, direction=contact.direction_index,
                         static=p["friction_law"] == "static", mu_s=mu_s, kt=kt)


def far_faces(contact: Contact) -> tuple[str, str]:
    """(body 1's far face, body 2's far face): the box faces at the two ends of the contact axis."""
    a = contact.axis
    return f"{a}0", f"{a}{'WHL'[contact.axis_index]}"


def _rigid_set(aut: Automata, face: str, extent: np.ndarray, fixm: np.ndarray) -> None:
    """Hold the rigid motions a face support leaves free: both tangential translations at the face's corner at
    the origin of the two other axes, the second one at the corner at the far end of the first (force-free in
    a homogeneous state)."""
    ax = FACE_AXES.index(face[0])
    e1, e2 = (ax + 1) % 3, (ax + 2) % 3
    idx = aut.on_face(face, extent)
    pos = aut.positions[idx]
    tol = 1e-9 * float(extent.max())
    a = idx[(np.abs(pos[:, e1]) <= tol) & (np.abs(pos[:, e2]) <= tol)]
    b = idx[(np.abs(pos[:, e1] - extent[e1]) <= tol) & (np.abs(pos[:, e2]) <= tol)]
    fixm[a, e1] = fixm[a, e2] = fixm[b, e2] = mk.PRESCRIBED


def _supports(scene: Scene, aut: Automata, rate_of: dict[str, float]) -> tuple[np.ndarray, np.ndarray]:
    """(fixm, fixv) of the scene's supports and clamps; rigid sets on supported (unclamped) far faces."""
    ext = scene.box.extent
    fixm = np.zeros((aut.size, 6), dtype=np.uint8)
    fixv = np.zeros((aut.size, 6))
    clamped = set()
    for c in scene.constraints:
        if not isinstance(c, (FaceSupport, FaceClamp)):
            raise SceneError(f"mca contact: constraint {type(c).__name__} is not supported")
        idx = aut.on_face(c.face, ext)
        if isinstance(c, FaceClamp):
            fixm[idx] = mk.PRESCRIBED
            clamped.add(c.face)
        else:
            ax = FACE_AXES.index(c.face[0])
            fixm[idx, ax] = mk.PRESCRIBED
            fixv[idx, ax] = rate_of.get(c.face, 0.0)
    for c in scene.constraints:
        if isinstance(c, FaceSupport) and c.face not in clamped:
            _rigid_set(aut, c.face, ext, fixm)
    return fixm, fixv


def contact_summary(st: mk.State) -> dict[str, Any]:
    """Contact pressure of the closed contacts: area-weighted mean, uniformity, count (static law: and how many
    slip)."""
    con = st.contact
    closed = con.facet >= 0
    out: dict[str, Any] = {"contacts": int(closed.sum()), "slaves": int(len(con.slave))}
    if con.law.static:  # the static law: how many closed contacts slip (the others stick on their springs)
        out["contacts_slipping"] = int((con.slipping[closed] == 1).sum())
    if closed.any():
        pres = -con.sigma[closed]
        area = con.area[closed]
        mean = float((pres * area).sum() / area.sum())
        out.update(contact_pressure_mean=mean,
                   contact_pressure_uniformity=float((pres.max() - pres.min()) / mean) if mean > 0 else math.nan,
                   contact_area=float(area.sum()))
    return out


def pressed(scene: Scene, aut: Automata, bonded: Automata, el: Elastic, law: ct.ContactLaw, p: dict[str, Any]
            ) -> dict[str, Any]:
    """Pressed: the supports compress the stack across the interface, relaxed dynamically (docs/physics.md)."""
    contact = scene.contact
    rate = Model(bonded, el).relaxation_rate()
    t_ramp = p["ramp_periods"] * 2 * math.pi / rate
    disp = {c.face: c.displacement for c in scene.constraints if isinstance(c, FaceSupport)}
    fixm, fixv = _supports(scene, aut, {f: d / t_ramp for f, d in disp.items()})
    gamma = rate if p["damping"] is None else p["damping"]
    length = float(scene.box.extent[contact.axis_index])
    strain = max((abs(d) for d in disp.values()), default=0.0) / length
    e_load = 0.5 * el.youngs * max(strain, 1e-6) ** 2 * scene.box.volume
    model = Model(aut, el, rotations=p["rotations"], krot=p["krot"], cfl=p["cfl"], gamma=gamma, fixm=fixm, fixv=fixv,
                  t_stop=t_ramp, ke_limit=p["blowup"] * e_load, contact=law, step_automata=bonded)
    st = model.new_state()
    scale = el.youngs * max(strain, 1e-12) * float(aut.spacing.min()) ** 2
    status, res, _ = relax(model, st, scale, tol=p["relax_tol"], max_steps=p["max_steps"])
    u = st.x - aut.positions
    steps = int(st.counters[mk.C_STEPS])
    low, high = far_faces(contact)
    ax = contact.axis_index
    react = float(-st.f[aut.on_face(high, scene.box.extent), ax].sum())
    summary: dict[str, Any] = {"residual": res, "steps": steps, "dt": model.dt, "damping": gamma, "ramp_s": t_ramp,
                               "reaction_force": react}
    summary.update(contact_summary(st))
    if low in disp and high in disp:
        axial = (disp[high] - disp[low]) / length
        area = float(np.prod(np.delete(scene.box.extent, ax)))
        expected = el.youngs * abs(axial)
        summary.update(axial_strain=axial, E_eff=react / area / axial, axial_stress_expected=expected)
        if "contact_pressure_mean" in summary:
            summary["contact_pressure_error"] = abs(summary["contact_pressure_mean"] / expected - 1)
        lateral = [aut.face_strain(u, k, scene.box.extent) for k in range(3) if k != ax]
        summary["nu_eff"] = -float(np.mean(lateral)) / axial
    kstat, reason = relax_status(status, res, p["relax_tol"], steps, p["max_steps"])
    return {"field": u, "quantity": "u (m)", "summary": summary, "status": kstat, "reason": reason,
            "model": model, "state": st}





def sliding(scene: Scene, aut: Automata, bonded: Automata, el: Elastic, law: ct.ContactLaw, p: dict[str, Any]
            ) -> dict[str, Any]:
    """Sliding: preloaded, then driven along the plane; mu_dr and the energy balance over the window (module
    docstring)."""
    contact = scene.contact
    ext = scene.box.extent
    ax, dr = contact.axis_index, contact.direction_index
    third = 3 - ax - dr
    fixm, fixv = _supports(scene, aut, {})
    _, high = far_faces(contact)
    top = aut.on_face(high, ext)
    if np.any(aut.body[top] != 1):
        raise SceneError(f"mca contact: face {high} is not body 2's far face")
    fixm[top, dr] = fixm[top, third] = mk.PRESCRIBED
    face_area = aut.extent[top][:, [k for k in range(3) if k != ax]].prod(axis=1)
    load = np.zeros((aut.size, 3))
    load[top, ax] = -contact.normal_stress * face_area
    f_normal = float(contact.normal_stress * face_area.sum())
    rate = Model(bonded, el).relaxation_rate()
    e_load = 0.5 * contact.normal_stress**2 / el.youngs * scene.box.volume + 0.5 * float(aut.mass.sum()) * \
        contact.speed**2
    model = Model(aut, el, rotations=p["rotations"], krot=p["krot"], cfl=p["cfl"], gamma=rate, fixm=fixm, fixv=fixv,
                  t_stop=0.0, ke_limit=p["blowup"] * e_load, load=load, contact=law, step_automata=bonded)
    st = model.new_state()
    t_ramp = p["slide_ramp"] if p["slide_ramp"] is not None else default_slide_ramp(rate)
    ramp_steps, window_steps = slide_steps(contact, t_ramp, model.dt)
    summary: dict[str, Any] = {"dt": model.dt, "normal_force_applied": f_normal, "slide_steps_needed":
                               ramp_steps + window_steps}
    if ramp_steps + window_steps > p["max_steps"]:  # the window would be cut: refused before any step is spent
        reason = (f"max_steps={p['max_steps']} would be reached before the averaging window ends: sliding needs "
                  f"{ramp_steps + window_steps} steps (ramp {ramp_steps} + duration {contact.duration:g} s = "
                  f"{window_steps} steps of dt {model.dt:.3g} s); allowed: max_steps >= {ramp_steps + window_steps} "
                  "or a shorter duration")
        return {"field": None, "quantity": "", "summary": summary, "status": "failed", "reason": reason,
                "model": model, "state": st}
    scale = contact.normal_stress * float(aut.spacing.min()) ** 2
    status, res, _ = relax(model, st, scale, tol=p["preload_tol"], max_steps=p["max_steps"])
    pre_steps = int(st.counters[mk.C_STEPS])
    summary.update(preload_steps=pre_steps, preload_residual=res)
    summary.update({f"preload_{k}": v for k, v in contact_summary(st).items() if k.startswith("contact_pressure")})
    if status != mk.OK or not res <= p["preload_tol"]:
        kstat, reason = relax_status(status, res, p["preload_tol"], pre_steps, p["max_steps"])
        return {"field": None, "quantity": "", "summary": summary, "status": kstat, "reason": f"preload: {reason}",
                "model": model, "state": st}
    t0 = float(st.clock[0])
    fixv[top, dr] = contact.speed
    if contact.platen:
        fixm[top, ax] = mk.PRESCRIBED  # held at the preloaded height (fixv 0 there): a rigid platen
    frame = np.zeros((aut.size, 3))
    frame[aut.body == 1, dr] = contact.speed
    st = st._replace(frame=mk.Frame(frame))
    held = np.where(fixm[:, :3] == mk.PRESCRIBED, 1 + aut.body[:, None], 0)
    st.contact.held[:] = held  # the clamp's (body 1) and the drive's (body 2) reactions are recorded
    st.contact.held_rot[:] = np.where(fixm[:, 3:] == mk.PRESCRIBED, 1 + aut.body[:, None], 0)
    gamma = rate if p["slide_damping"] is None else p["slide_damping"]
    model.params = model.params._replace(gamma=float(gamma), t_stop=math.inf, ramp_start=t0, ramp=t_ramp)
    total = ramp_steps + window_steps
    every = max(1, total // p["records"])
    st = st._replace(hist=np.zeros((total // every + 2, mk.N_H)))
    rows: list[np.ndarray] = []
    st, code, rebuilds = advance_listed(model, st, pre_steps + ramp_steps, every, rows)
    t1 = float(st.clock[0])
    heat0 = st.contact.heat.copy()
    dissipated0 = st.contact.dissipated.copy()
    marks = [_mark(st)]
    for until in (pre_steps + ramp_steps + window_steps // 2, pre_steps + total):  # the window's two halves
        if code == mk.OK:
            st, code, more = advance_listed(model, st, until, every, rows)
            rebuilds += more
            marks.append(_mark(st))
    done = int(st.counters[mk.C_STEPS]) - pre_steps
    h = np.concatenate(rows) if rows else np.zeros((0, mk.N_H))
    summary.update(steps=int(st.counters[mk.C_STEPS]), slide_steps=done, slide_ramp_s=t_ramp,
                   pair_list_rebuilds=rebuilds)
    summary.update(contact_summary(st))
    window = h[h[:, mk.H_T] >= t1]
    if code in (mk.NAN, mk.GROWTH):
        status, reason = "unstable", f"{mk.STATUS_TEXT[code]} at step {done} of sliding; history up to there kept"
    elif len(window) < 10:
        status, reason = "failed", f"only {len(window)} history rows in the sliding window"
    else:
        summary.update(_friction_summary(window, st, law, contact, f_normal))
        summary.update(start_balance(h, st, model.params))
        if len(marks) == 3:
            summary.update(_reaction_summary(marks, st, aut, law, contact, f_normal, float(gamma)))
            summary.update(_drive_power(window, marks[1].t))
            unc = summary.get("mu_dr_uncertainty", math.nan)
            for name in ("drive", "clamp") if unc > 0 else ():  # rough: in units of the run length's uncertainty
                summary[f"mu_{name}_zscore"] = (summary[f"mu_{name}"] - summary[f"mu_{name}_expected"]) / unc
            summary.update(_worse_of_reactions(summary))
        slid, room = slid_distance(aut, st, contact, ext), footprint_room(aut, contact)
        summary.update(slid_distance=slid, slide_room=room)
        reason = contact_lost(window, slid, room, contact)
        status = "failed" if reason else "ok"
    window_s = float(st.clock[0]) - t1
    heat = st.contact.heat - heat0
    summary["friction_heat_J"] = float(heat.sum())
    summary["friction_power_W"] = float(heat.sum() / window_s) if window_s > 0 else math.nan
    diag = {"history": {"columns": list(mk.HISTORY_COLUMNS), "rows": h}}
    return {"field": heat / aut.volume, "quantity": "friction heat received in the window (J/m^3)",
            "summary": summary, "status": status, "reason": reason, "diagnostics": diag, "model": model, "state": st,
            "power": (st.contact.dissipated - dissipated0) / window_s if window_s > 0 else None}


class Mark(NamedTuple):
    """The state at an instant of the sliding window (SI units; moments about the origin): the held degrees of
    freedom's impulses and angular impulses (2, 3), the momentum and angular momentum (3,), positions, angles."""

    t: float
    impulse: np.ndarray
    momentum: np.ndarray
    x: np.ndarray
    angular_impulse: np.ndarray
    angular: np.ndarray
    phi: np.ndarray


def _mark(st: mk.State) -> Mark:
    spin = st.rot.inertia[:, None] * st.rot.w if st.rot is not None else np.zeros_like(st.x)
    phi = st.rot.phi.copy() if st.rot is not None else np.zeros_like(st.x)
    return Mark(float(st.clock[0]), st.contact.impulse.copy(), (st.mass[:, None] * st.v).sum(axis=0), st.x.copy(),
                st.contact.angular_impulse.copy(), (np.cross(st.x, st.mass[:, None] * st.v) + spin).sum(axis=0), phi)


def angular_balance(a: Mark, b: Mark, st: mk.State, gamma: float) -> np.ndarray:
    """Mean external moments about the origin over [a.t, b.t] less the change of angular momentum (3,; N m): zero
    when the bodies' internal forces and moments exert no net couple.  External: the held degrees of freedom's
    reactions, the loads and the damping on the free ones (at their mean positions over the window)."""
    span = b.t - a.t
    mid = 0.5 * (a.x + b.x)
    free = st.fixm[:, :3] == mk.FREE
    load = st.load.force if st.load is not None else np.zeros_like(st.x)
    loads = np.cross(mid, np.where(free, load, 0.0)).sum(axis=0)
    ref = st.frame.vel if st.frame is not None else np.zeros_like(st.x)
    drift = st.mass[:, None] * np.where(free, b.x - a.x - ref * span, 0.0)
    damping = -gamma * np.cross(mid, drift).sum(axis=0) / span
    if st.rot is not None:
        turn = np.where(st.fixm[:, 3:] == mk.FREE, b.phi - a.phi, 0.0)
        damping -= gamma * (st.rot.inertia[:, None] * turn).sum(axis=0) / span
    held = (b.angular_impulse - a.angular_impulse).sum(axis=0) / span
    return held + loads + damping - (b.angular - a.angular) / span


def external_forces(a: Mark, b: Mark, st: mk.State, gamma: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean forces over [a.t, b.t] from outside the two bodies: the reactions (2, 3) of each body's held degrees of
    freedom, the damping's (3,) and the sum of every external force less the momentum change (3,), which
    Newton's third law makes zero."""
    span = b.t - a.t
    load = st.load.force if st.load is not None else np.zeros_like(st.x)
    held = st.contact.held
    react = (b.impulse - a.impulse) / span
    for g in range(2):
        react[g] -= np.where(held == g + 1, load, 0.0).sum(axis=0)
    free = st.fixm[:, :3] == mk.FREE
    ref = st.frame.vel if st.frame is not None else np.zeros_like(st.x)
    damping = -gamma * (st.mass[:, None] * np.where(free, b.x - a.x - ref * span, 0.0)).sum(axis=0) / span
    residual = react.sum(axis=0) + load.sum(axis=0) + damping - (b.momentum - a.momentum) / span
    return react, damping, residual


def _reaction_summary(marks: list[Mark], st: mk.State, aut: Automata, law: ct.ContactLaw, contact: Contact,
                      f_applied: float, gamma: float) -> dict[str, Any]:
    """mu measured at the drive and at the clamp (over the window and each half of it) against the law's mu_dr
    for the normal force each measures; Newton's third law relative to the applied normal force F_N, and the
    balance of angular momentum relative to F_N h0."""
    ax, dr = contact.axis_index, contact.direction_index
    load = st.load.force if st.load is not None else np.zeros_like(st.x)
    on_base, on_slider = (load[aut.body == g].sum(axis=0) for g in (0, 1))

    def measured(a: Mark, b: Mark) -> tuple[float, float, float, float, np.ndarray, np.ndarray]:
        react, damping, residual = external_forces(a, b, st, gamma)
        n_clamp = float(react[0, ax] + on_base[ax])
        n_drive = float(-(react[1, ax] + on_slider[ax]))
        mu_clamp = -float(react[0, dr]) / n_clamp if n_clamp > 0 else math.nan  # none: the bodies separated
        mu_drive = float(react[1, dr]) / n_drive if n_drive > 0 else math.nan
        return mu_clamp, mu_drive, n_clamp, n_drive, damping, residual

    mu_clamp, mu_drive, n_clamp, n_drive, damping, residual = measured(marks[0], marks[2])
    couple = angular_balance(marks[0], marks[2], st, gamma)
    halves = [measured(marks[0], marks[1]), measured(marks[1], marks[2])]
    out: dict[str, Any] = {"mu_drive": mu_drive, "mu_clamp": mu_clamp, "normal_drive_ratio": n_drive / f_applied,
                           "normal_clamp_ratio": n_clamp / f_applied,
                           "newton_error": float(np.linalg.norm(residual)) / f_applied,
                           "angular_momentum_error": float(np.linalg.norm(couple)) / (f_applied * law.h0),
                           "damping_force_ratio": float(np.linalg.norm(damping)) / f_applied}
    for name, mu, normal, k in (("drive", mu_drive, n_drive, 1), ("clamp", mu_clamp, n_clamp, 0)):
        expected = mu_dr_expected(law, contact.speed, contact.normal_stress * normal / f_applied)
        out[f"mu_{name}_expected"] = expected
        out[f"mu_{name}_error"] = abs(mu / expected - 1) if expected > 0 else math.nan
        out[f"mu_{name}_drift"] = abs(halves[0][k] - halves[1][k]) / expected if expected > 0 else math.nan
    return out


def _worse_of_reactions(summary: dict[str, Any]) -> dict[str, Any]:
    """The drive's and the clamp's measurements as one: the larger error, the larger drift, the z-score of larger
    magnitude (a claim on both reactions at once)."""
    out = {"mu_reactions_error": max(summary["mu_drive_error"], summary["mu_clamp_error"]),
           "mu_reactions_drift": max(summary["mu_drive_drift"], summary["mu_clamp_drift"])}
    if "mu_drive_zscore" in summary:
        out["mu_reactions_zscore"] = max(summary["mu_drive_zscore"], summary["mu_clamp_zscore"], key=abs)
    return out


def _drive_power(window: np.ndarray, t_mid: float) -> dict[str, Any]:
    """The power the drive and the load deliver to friction, measured at them: their work minus the change of the
    bodies' kinetic and elastic energy and the damping's dissipation, over the window's history rows (W), and
    the drift between its two halves relative to it (the window's stationarity)."""

    def power(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
        work = b[mk.H_WORK] + b[mk.H_LOAD] - a[mk.H_WORK] - a[mk.H_LOAD]
        kept = b[mk.H_KE] + b[mk.H_U] + b[mk.H_DISS] - a[mk.H_KE] - a[mk.H_U] - a[mk.H_DISS]
        span = float(b[mk.H_T] - a[mk.H_T])
        return float(work - kept) / span, float(work) / span

    mid = int(np.argmin(np.abs(window[:, mk.H_T] - t_mid)))
    whole, work = power(window[0], window[-1])
    first, second = power(window[0], window[mid])[0], power(window[mid], window[-1])[0]
    return {"drive_power_W": whole, "drive_work_power_W": work,
            "drive_power_drift": abs(first - second) / abs(whole) if whole else math.nan}


def advance_listed(model: Model, st: mk.State, until: int, every: int, rows: list[np.ndarray]
           ) -> tuple[mk.State, int, int]:
    """Advance to step `until` in chunks, keeping the history rows and rebuilding the lists whenever an
    automaton moved beyond the skin: (state, kernel status, rebuilds)."""
    code, rebuilds = mk.OK, 0
    while int(st.counters[mk.C_STEPS]) < until:
        code = model.advance(st, min(20 * every, until - int(st.counters[mk.C_STEPS])), every)
        rows.append(st.hist[: st.counters[mk.C_ROWS]].copy())
        if code == mk.MOVED:
            st, _ = rebuild_pairs(model, st)
            rebuilds += 1
            code = mk.OK
            continue
        if code != mk.OK:
            break
    return st, code, rebuilds


def default_slide_ramp(rate: float) -> float:
    """The drive's smooth start when `slide_ramp` is not given: two periods 2 pi / rate of the relaxation rate."""
    return 2 * 2 * math.pi / rate


def slide_steps(contact: Contact, t_ramp: float, dt: float) -> tuple[int, int]:
    """(ramp steps, window steps) of a sliding run: the smooth start, then `duration` at full speed (the
    averaging window); the solver refuses to cut either short, and `estimate` counts both."""
    return math.ceil(t_ramp / dt), math.ceil(contact.duration / dt)


def slid_distance(aut: Automata, st: mk.State, contact: Contact, extent: np.ndarray) -> float:
    """How far body 2 was driven along the sliding direction (m): the mean displacement of its far face."""
    _, high = far_faces(contact)
    top = aut.on_face(high, extent)
    return float(np.mean(st.x[top, contact.direction_index] - aut.positions[top, contact.direction_index]))


def footprint_room(aut: Automata, contact: Contact) -> float:
    """How far body 2 may slide along the direction before its leading automata leave body 1's surface: to body
    1's last automata, plus the EDGE a foot may lie outside a facet (half a spacing)."""
    d = contact.direction_index
    along = aut.positions[:, d]
    lead = float(along[aut.body == 1].max())
    end = float(along[aut.body == 0].max())
    return end - lead + ct.EDGE * float(aut.spacing[d])


def contact_lost(window: np.ndarray, slid: float, room: float, contact: Contact) -> str:
    """Why the bodies did not stay in contact over the whole averaging window ("" if they did): body 2 slid
    beyond body 1's surface, or a history row of the window has no closed contact; mu_dr and the energy balance
    then describe something other than two bodies sliding on each other."""
    if slid > room:
        return (f"the bodies did not stay in contact: body 2 slid {slid:.3g} m along {contact.direction} by the end "
                f"of the averaging window, beyond body 1's surface ({room:.3g} m of room for its footprint); "
                "allowed: speed x (ramp + duration) within the room")
    open_rows = window[:, mk.H_NC] < 1
    if open_rows.any():
        first = float(window[np.argmax(open_rows), mk.H_T])
        return (f"the bodies did not stay in contact: no closed contact in {int(open_rows.sum())} of "
                f"{len(window)} history rows of the averaging window (first at t = {first:.4g} s; window "
                f"{float(window[0, mk.H_T]):.4g} to {float(window[-1, mk.H_T]):.4g} s)")
    return ""


def heating(scene: Scene, aut: Automata, bonded: Automata, el: Elastic, law: ct.ContactLaw, p: dict[str, Any]
            ) -> dict[str, Any]:
    """Sliding, then MCA heat of the bonded automata from the initial temperature to t_end, fed by each contact's
    mean friction power over the window, split by `thermal_split` (body 1's share to the rest partners)."""
    out = sliding(scene, aut, bonded, el, law, p)
    slave_power = out.pop("power", None)
    summary = out["summary"]
    if out["status"] != "ok" or slave_power is None:
        return out | {"field": None}
    contact, heat = scene.contact, scene.conduction
    ax = contact.axis_index
    section = float(np.prod(np.delete(scene.box.extent, ax)))
    conductivity, rho_c = body_thermal(scene, aut)
    k_base, k_slider = float(conductivity[aut.body == 0][0]), float(conductivity[aut.body == 1][0])
    base_share = thermal_split(k_base, k_slider)
    rest = ct.rest_partners(out["state"].contact, aut)
    power = np.zeros(aut.size)
    paired = rest.facet >= 0
    np.add.at(power, rest.slave, (1.0 - base_share) * slave_power)
    for v in range(3):
        np.add.at(power, rest.facets[rest.facet[paired], v], base_share * slave_power[paired] * rest.w[paired, v])
    flux = float(slave_power.sum()) / section
    per_area = slave_power[paired] / rest.area[paired]
    held, values = mca_heat.held_temperatures(scene, bonded)
    i, j = bonded.pairs[:, 0], bonded.pairs[:, 1]
    pair_conductivity = 2.0 * conductivity[i] * conductivity[j] / (conductivity[i] + conductivity[j])  # in series
    hs, hp, steps = mca_heat.transient(bonded, pair_conductivity, rho_c, values, held, heat.t_end, p["heat_cfl"],
                                       power)
    heat_s = timed("heat", hs, hp, steps)
    rise = hs.temp - heat.initial_temperature
    near = np.abs(np.abs(aut.positions[:, ax] - contact.position) - 0.5 * law.h0) < 1e-6 * law.h0
    stored = rise * rho_c * bonded.volume
    summary.update(heat_dt=hp.dt, heat_steps=steps, heat_kernel_s=heat_s, flux_friction=flux,
                   flux_uniformity=float(np.ptp(per_area) / per_area.mean()),
                   flux_drive=summary["drive_power_W"] / section, interface_rise=float(rise[near].mean()),
                   interface_rise_base=float(rise[near & (aut.body == 0)].mean()),
                   interface_rise_slider=float(rise[near & (aut.body == 1)].mean()),
                   heat_split_base=base_share, heat_share_base=float(stored[aut.body == 0].sum() / stored.sum()))
    declared = heat.interface.flux if heat.interface is not None else math.nan
    if math.isfinite(declared) and declared > 0:
        diffusivity = conductivity / rho_c
        effusivity = np.sqrt(conductivity * rho_c)
        e_base, e_slider = float(effusivity[aut.body == 0][0]), float(effusivity[aut.body == 1][0])
        share = e_base / (e_base + e_slider)  # two semi-infinite solids in perfect contact
        summary.update(flux_declared=declared, flux_ratio=flux / declared,
                       flux_drive_ratio=summary["flux_drive"] / declared, heat_share_base_expected=share)
        for side, body, q in (("base", 0, share * declared), ("slider", 1, (1 - share) * declared)):
            k = float(conductivity[aut.body == body][0])
            expect = semi_infinite_rise(q, k, float(diffusivity[aut.body == body][0]), heat.t_end, 0.5 * law.h0)
            summary[f"interface_rise_{side}_expected"] = expect
            summary[f"interface_rise_{side}_ratio"] = summary[f"interface_rise_{side}"] / expect
        expect = 0.5 * (summary["interface_rise_base_expected"] + summary["interface_rise_slider_expected"])
        summary.update(interface_rise_expected=expect, interface_rise_error=summary["interface_rise"] / expect - 1,
                       interface_rise_sides_error=max(abs(summary[f"interface_rise_{side}_ratio"] - 1)
                                                      for side in ("base", "slider")))
    temp = hs.temp / heat.t_max
    summary.update(heat_summary(temp, float((temp * bonded.volume).sum() / bonded.volume.sum())))
    out["diagnostics"]["notes"] = ["frictional heating: the mean friction power of the sliding window feeds MCA "
                                   "heat on the rest geometry for t_end (quasi-steady one-way coupling)"]
    return out | {"field": temp, "quantity": "T/t_max"}


def body_thermal(scene: Scene, aut: Automata) -> tuple[np.ndarray, np.ndarray]:
    """Conductivity (W/(m K)) and rho c (J/(m^3 K)) of every automaton: the scene material's, body 1's own where
    the contact gives them (dissimilar blocks)."""
    mat, contact = scene.material, scene.contact
    base = aut.body == 0
    k_base = mat.conductivity if contact.base_conductivity is None else contact.base_conductivity
    c_base = mat.heat_capacity if contact.base_heat_capacity is None else contact.base_heat_capacity
    return (np.where(base, k_base, mat.conductivity).astype(float),
            mat.density * np.where(base, c_base, mat.heat_capacity).astype(float))


def thermal_split(k_base: float, k_slider: float) -> float:
    """Body 1's share of the friction heat generated between the automata next to the interface: k1 / (k1 + k2),
    the finite-volume split of a source on a cell face, second order in a (docs/physics.md)."""
    return k_base / (k_base + k_slider)


def semi_infinite_rise(flux: float, conductivity: float, diffusivity: float, t: float, depth: float) -> float:
    """Rise at `depth` below the surface of a semi-infinite solid taking `flux` from t = 0 (Carslaw & Jaeger
    §2.9): (2 q / k) sqrt(alpha t) ierfc(depth / (2 sqrt(alpha t))); the scene's reference at short times, with
    q the half of the interface flux each body takes."""
    root = math.sqrt(diffusivity * t)
    u = depth / (2.0 * root)
    return 2.0 * flux / conductivity * root * (math.exp(-u * u) / math.sqrt(math.pi) - u * float(erfc(u)))


def mu_dr_expected(law: ct.ContactLaw, speed: float, pressure: float) -> float:
    """mu_dr = F_dr / F_N that the friction law (contact.py, eq. 16) gives when every contact slides at the drive's
    speed V under the same normal stress sigma = F_N / A:
        mu_dr = mu0 V / sigma + mu1 (1 + K_av) min(1, sigma0 / sigma) min(1, V / v_reg),
    K_av the mean of the roughness process (the static law: no regularisation, the last factor 1).  Exact for a
    uniform pressure, or one wholly above sigma0; not in it: the explicit step's cap of the regularised slope
    (`friction_step_ratio` says how close a run comes to it)."""
    if not pressure > 0:
        return math.nan
    slope = 1.0 if law.static else min(1.0, speed / law.v_reg)  # a slipping static contact carries mu1 at any speed
    dry = law.mu1 * (1 + rg.mean(law.rough)) * min(1.0, law.sigma0 / pressure) * slope
    return dry + law.mu0 * speed / pressure


def _friction_summary(window: np.ndarray, st: mk.State, law: ct.ContactLaw, contact: Contact,
                      f_normal: float) -> dict[str, Any]:
    """mu_dr statistics over the sliding window, their expected value and uncertainty, the energy balance."""
    ratio = float(window[:, mk.H_FN].mean() / f_normal)
    f_applied = f_normal
    if contact.platen:  # the platen's reaction is the normal force: the contacts' normal force
        f_normal *= ratio
    mu = window[:, mk.H_FT] / f_normal
    out: dict[str, Any] = {"mu_dr_mean": float(mu.mean()), "mu_dr_std": float(mu.std()), "normal_force_ratio": ratio,
                           "window_s": float(window[-1, mk.H_T] - window[0, mk.H_T])}
    expected = mu_dr_expected(law, contact.speed, f_normal / f_applied * contact.normal_stress)
    out["mu_dr_expected"] = expected
    out["mu_dr_error"] = abs(out["mu_dr_mean"] / expected - 1) if expected > 0 else math.nan
    con = st.contact
    closed = con.facet >= 0
    if law.rough.on and closed.any():
        load = -con.sigma[closed] * con.area[closed]
        share = load / load.sum()
        distance = contact.speed * out["window_s"]
        unc = law.mu1 * math.sqrt(float((share**2).sum()) * rg.variance_of_mean(law.rough, distance))
        out["mu_dr_uncertainty"] = unc
        out["mu_dr_zscore"] = (out["mu_dr_mean"] - expected) / unc if unc > 0 else math.nan
    if closed.any():
        out["slip_speed_min"] = float(con.speed[closed].min())
    first, last = window[0], window[-1]

    def supplied(r: np.ndarray) -> float:
        return r[mk.H_WORK] + r[mk.H_LOAD]

    def held(r: np.ndarray) -> float:
        return r[mk.H_KE] + r[mk.H_U] + r[mk.H_FRIC] + r[mk.H_DISS]

    work = supplied(last) - supplied(first)
    stored = window[:, mk.H_KE] + window[:, mk.H_U] + window[:, mk.H_FRIC] + window[:, mk.H_DISS] - held(first)
    put_in = window[:, mk.H_WORK] + window[:, mk.H_LOAD] - supplied(first)
    out.update(drive_work_J=float(work), friction_dissipation_J=float(last[mk.H_FRIC] - first[mk.H_FRIC]),
               energy_balance_error=balance_error(stored, (put_in,), abs(work)))
    return out


def start_balance(rows: np.ndarray, st: mk.State, par: mk.Params) -> dict[str, Any]:
    """The energy balance from the drive's start to the run's end (every history row of the sliding, ramp
    included): there the translational and the rotational kinetic energy, the elastic energy, the friction's and
    the damping's dissipation all change, so a defect in any one of them does not cancel as it does over the
    stationary window; relative to the drive's and the load's work over the same rows.  The driven automata
    move as prescribed (fixv times the ramp), so the drive also supplies their own kinetic energy, which the
    reactions' work does not hold: it is added to the work, at the velocity each row's step set."""
    t = rows[:, mk.H_T] - 0.5 * par.dt  # the drive's factor of a row's step is taken at its middle
    s = np.clip((t - par.ramp_start) / par.ramp, 0.0, 1.0) if par.ramp > 0 else np.ones_like(t)
    driven = st.fixm == mk.PRESCRIBED
    mass = np.c_[np.repeat(st.mass[:, None], 3, axis=1),
                 np.zeros((st.mass.size, 3)) if st.rot is None else np.repeat(st.rot.inertia[:, None], 3, axis=1)]
    driven_ke = 0.5 * float((mass * st.fixv**2)[driven].sum()) * (s * s * (3.0 - 2.0 * s)) ** 2
    first, last = rows[0], rows[-1]
    supplied = rows[:, mk.H_WORK] + rows[:, mk.H_LOAD] - first[mk.H_WORK] - first[mk.H_LOAD] + driven_ke - driven_ke[0]
    held = rows[:, mk.H_KE] + rows[:, mk.H_U] + rows[:, mk.H_FRIC] + rows[:, mk.H_DISS]
    return {"energy_balance_start_error": balance_error(held - held[0], (supplied,), abs(float(supplied[-1]))),
            "start_work_J": float(supplied[-1]),
            "start_kinetic_change_J": float(last[mk.H_KE] - last[mk.H_KEROT] - first[mk.H_KE] + first[mk.H_KEROT]),
            "start_kinetic_rot_change_J": float(last[mk.H_KEROT] - first[mk.H_KEROT]),
            "start_elastic_change_J": float(last[mk.H_U] - first[mk.H_U]),
            "start_friction_J": float(last[mk.H_FRIC] - first[mk.H_FRIC])}


def on_bodies(run: Callable[..., dict[str, Any]]) -> Callable[[Scene, int, dict[str, Any]],
                                                              tuple[dict[str, Any], Automata]]:
    """`run` (pressed, sliding, heating) on the two bodies of a contact scene at resolution n, with the contact law
    of the parameters: the solver's out dict (field, summary, status, ...) and the automata the field lives on."""

    def on_two_bodies(scene: Scene, n: int, p: dict[str, Any]) -> tuple[dict[str, Any], Automata]:
        contact = scene.contact
        aut, bonded = body_automata(scene.box, n, scene.material.density, contact)
        el = Elastic.of(scene, p)
        law = law_of(aut, contact, p, el.shear)
        out = run(scene, aut, bonded, el, law, p)
        out.pop("power", None)
        model = with_work(out)
        out["summary"]["friction_step_ratio"] = friction_step_ratio(model, law, contact)
        return out, aut

    return on_two_bodies


def with_work(out: dict[str, Any]) -> Model:
    """Move a run's model and state out of `out`, putting the run's work and unknowns in their place; the model."""
    model, st = out.pop("model"), out.pop("state")
    out["work"] = model.work(st)
    out["unknowns"] = model.free_dofs
    return model


def friction_step_ratio(model: Model, law: ct.ContactLaw, contact: Contact) -> float:
    """dt c / m of the stiffest regularised friction damper at the nominal normal stress (c = S (mu0 + mu1 (1 +
    K_max) sigma_N / v_reg), m the smallest automaton's mass): explicit kicks of a damper between two masses are
    stable below 2 (reduced mass m/2 at worst: ratio 1)."""
    a = model.aut
    area = float(np.max(np.prod(np.delete(a.extent, contact.axis_index, axis=1), axis=1)))
    k_max = (1 + law.rough.spread) * (law.rough.a1 + law.rough.a2)
    coef = area * (law.mu0 + law.mu1 * (1 + k_max) * contact.normal_stress / law.v_reg)
    return float(model.dt * coef / a.mass.min())
