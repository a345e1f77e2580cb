"""The MCA solver's incline run: the slider on its clamped base under its own weight, the body force `gravity`
tilted by `incline_angle` from the contact's normal towards the sliding direction (docs/physics.md, the MCA
model's incline).

The weight's normal part presses the slider first (relaxed as the stick-slip preload), then its tangential part
rises smoothly over `slide_ramp` in RAMP_PIECES pieces (applied at once it overshoots the contacts' static
stress, and the slider slid at 18 degrees) and the run lasts the scene's duration, damped as the stick-slip run
is.  A kernel.Spring of zero stiffness records the slider's mean velocity and displacement; the acceleration is
the least-squares fit u(t) = u0 + v0 t + a t^2 / 2 over the rows after the ramp (`slide_acceleration`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from pcverify.scene import FaceClamp, Scene, SceneError

from . import contact_scenes as cs
from . import kernel as mk
from .automata import Automata, body_automata
from .model import Elastic, Model
from .stick_slip import HISTORY_COLUMNS, drive, law_params, preload

RAMP_PIECES = 20  # the tangential part of the weight rises in this many steps of a smooth ramp


def run(scene: Scene, n: int, p: dict[str, Any]) -> tuple[dict[str, Any], Automata]:
    """The incline run on the two bodies at resolution n (module docstring): the solver's out dict and the automata
    its field lives on."""
    out, aut = _run(scene, n, p)
    cs.with_work(out)
    return out, aut


def _run(scene: Scene, n: int, p: dict[str, Any]) -> tuple[dict[str, Any], Automata]:
    contact = scene.contact
    aut, bonded = body_automata(scene.box, n, scene.material.density, contact)
    el = Elastic.of(scene, p)
    law = cs.law_of(aut, contact, law_params(scene, p), el.shear)
    fixm = np.zeros((aut.size, 6), dtype=np.uint8)
    for c in scene.constraints:
        if not isinstance(c, FaceClamp):
            raise SceneError(f"mca incline: constraint {type(c).__name__} is not supported; allowed: FaceClamp")
        fixm[aut.on_face(c.face, scene.box.extent)] = mk.PRESCRIBED
    ax, dr = contact.axis_index, contact.direction_index
    slider = aut.body == 1
    theta = math.radians(contact.incline_angle)
    weight = np.where(slider, aut.mass, 0.0) * contact.gravity
    load = np.zeros((aut.size, 3))
    load[:, ax] = -weight * math.cos(theta)
    mass = float(aut.mass[slider].sum())
    rate = Model(bonded, el).relaxation_rate()
    e_scale = 0.5 * mass * (contact.gravity * contact.duration) ** 2 + 0.5 * (weight.sum() * math.cos(theta)) ** 2 \
        / (el.youngs * float(aut.spacing.min()))
    model = Model(aut, el, rotations=p["rotations"], krot=p["krot"], cfl=p["cfl"], gamma=rate, fixm=fixm,
                  t_stop=0.0, ke_limit=p["blowup"] * e_scale, load=load, contact=law, step_automata=bonded)
    st = model.new_state()
    steps = math.ceil(contact.duration / model.dt)
    summary: dict[str, Any] = {"dt": model.dt, "slider_mass": mass, "weight_N": float(weight.sum()),
                               "law_mu_kinetic": contact.mu_kinetic, "law_mu_static": contact.mu_static,
                               "tan_angle": math.tan(theta), "run_steps_needed": steps}
    out: dict[str, Any] = {"field": None, "quantity": "", "summary": summary, "model": model, "state": st}
    failed = preload(model, st, float(weight.max()) * math.cos(theta), steps, p, summary)
    if failed:
        return out | failed, aut
    pre_steps = summary["preload_steps"]
    t_ramp = p["slide_ramp"] if p["slide_ramp"] is not None else cs.default_slide_ramp(rate)
    ramp_steps = min(steps, math.ceil(t_ramp / model.dt))
    every = max(1, steps // p["records"])
    share = np.where(slider, aut.mass, 0.0) / mass
    u0 = float((share * (st.x[:, dr] - aut.positions[:, dr])).sum())
    recorder = mk.Spring(weight=share, axis=dr, stiffness=0.0, speed=0.0, start=float(st.clock[0]), offset=u0,
                         every=every, out=np.zeros(3), hist=np.zeros((steps // every + 2, len(HISTORY_COLUMNS))),
                         rows=np.zeros(1, dtype=np.int64))
    gamma = rate if p["slide_damping"] is None else float(p["slide_damping"])
    st = st._replace(spring=recorder, frame=mk.Frame(np.zeros((aut.size, 3))) if gamma > 0 else None,
                     hist=np.zeros((22, mk.N_H)))
    model.params = model.params._replace(gamma=gamma, t_stop=math.inf)
    code, rebuilds, parts = mk.OK, 0, []
    for k in range(1, RAMP_PIECES + 1):  # the tangential part rises smoothly (in pieces) over the ramp
        tangential = weight * math.sin(theta) * k * k * (3.0 - 2.0 * k / RAMP_PIECES) / RAMP_PIECES**2
        st.f[:, dr] += tangential - st.load.force[:, dr]  # the forces of the current state with the new load
        st.load.force[:, dr] = tangential
        st, code, more, part = drive(model, st, pre_steps + ramp_steps * k // RAMP_PIECES, every)
        rebuilds += more
        parts.append(part)
        if code != mk.OK:
            break
    if code == mk.OK:
        st, code, more, part = drive(model, st, pre_steps + steps, every)
        rebuilds += more
        parts.append(part)
    contact_rows = np.concatenate(parts)
    rows = st.spring.hist[: int(st.spring.rows[0])].copy()
    rows[:, 0] -= recorder.start
    rows = rows[rows[:, 0] >= ramp_steps * model.dt]  # after the ramp: the whole tilted weight acts
    summary["ramp_s"] = ramp_steps * model.dt
    if len(rows) >= 3:
        fit = np.polyfit(rows[:, 0], rows[:, 3] - u0, 2)
        summary.update(slide_acceleration=float(2.0 * fit[0]), slid_distance=float(rows[-1, 3] - u0),
                       slide_velocity_end=float(rows[-1, 2]))
    if len(contact_rows):
        summary.update(contact_normal_force_min=float(contact_rows[:, mk.H_FN].min()),
                       contacts_closed_min=int(contact_rows[:, mk.H_NC].min()))
    summary.update(steps=int(st.counters[mk.C_STEPS]), pair_list_rebuilds=rebuilds,
                   slide_room=cs.footprint_room(aut, contact))
    out |= {"field": st.contact.heat / aut.volume, "quantity": "friction heat received (J/m^3)", "state": st,
            "diagnostics": {"history": {"columns": list(HISTORY_COLUMNS), "rows": rows}}}
    if code in (mk.NAN, mk.GROWTH):
        return out | {"status": "unstable", "reason": f"{mk.STATUS_TEXT[code]} at step {int(st.counters[mk.C_STEPS])}"
                      }, aut
    if len(rows) < 3:
        return out | {"status": "failed", "reason": f"only {len(rows)} rows of the slider's motion"}, aut
    if summary["slid_distance"] > summary["slide_room"]:
        return out | {"status": "failed", "reason": f"the slider slid {summary['slid_distance']:.3g} m, beyond its "
                      f"base's surface ({summary['slide_room']:.3g} m of room); allowed: a shorter duration"}, aut
    return out | {"status": "ok", "reason": ""}, aut
