"""The MCA solver's stick-slip run: a slider pressed on its clamped base and pulled by a spring (Contact's
spring_stiffness) whose far end moves at the contact's speed (docs/physics.md, the MCA model's stick-slip).

The cycle is measured from the spring's rows alone, not from the friction law's bookkeeping: slips between
SLIP_SPEED and REST_SPEED of the drive speed, each slip after the first giving peak, trough, drop, largest force,
slip time, largest velocity and the period to the next slip; each slip after the second the stick before it (the
first slip starts from the first, untypical breakaway, and the stick after it is untypical too); the thresholds'
bias and the damping relative to the slider's mean velocity: (docs/physics.md, "Contact scenes").
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from pcverify.scene import FaceClamp, Scene, SceneError

from . import contact_scenes as cs
from . import kernel as mk
from .automata import Automata, body_automata
from .model import Elastic, Model, relax, relax_status

SLIP_SPEED = 0.1  # a row slips when the slider's mean velocity exceeds this fraction of the drive's speed
REST_SPEED = 0.02  # a slip starts and ends at the nearest rows whose mean velocity is below this fraction of it
MIN_PHASE_ROWS = 3  # stick or slip phases shorter than this many rows are merged into their neighbours
MIN_CYCLES = 2  # slips after the first that a cycle's measurement needs
HISTORY_COLUMNS = ("t", "spring_force", "velocity", "displacement")


def law_params(scene: Scene, p: dict[str, Any]) -> dict[str, Any]:
    """The solver parameters with the contact law's friction pair taken from the scene (mu1 = mu_kinetic, mu_s =
    mu_static)."""
    return p | {"mu1": scene.contact.mu_kinetic, "mu_s": scene.contact.mu_static}


def run(scene: Scene, n: int, p: dict[str, Any]) -> tuple[dict[str, Any], Automata]:
    """The stick-slip run on the two bodies at resolution n (module docstring): the solver's out dict (field,
    summary, status, work, ...) and the automata its field lives on."""
    out, aut = _run(scene, n, p)
    cs.with_work(out)
    return out, aut


def steps(scene: Scene, h: float, p: dict[str, Any], relax_steps: int, dt: float) -> int:
    """Time steps of a run: the preload's relaxation (`relax_steps`, the caller's estimate) and the duration at
    the step dt."""
    return relax_steps + math.ceil(scene.contact.duration / dt)


def _run(scene: Scene, n: int, p: dict[str, Any]) -> tuple[dict[str, Any], Automata]:
    contact = scene.contact
    aut, bonded = body_automata(scene.box, n, scene.material.density, contact)
    el = Elastic.of(scene, p)
    law = cs.law_of(aut, contact, law_params(scene, p), el.shear)
    ext = scene.box.extent
    fixm = np.zeros((aut.size, 6), dtype=np.uint8)
    for c in scene.constraints:
        if not isinstance(c, FaceClamp):
            raise SceneError(f"mca stick-slip: constraint {type(c).__name__} is not supported; allowed: FaceClamp")
        fixm[aut.on_face(c.face, ext)] = mk.PRESCRIBED
    _, high = cs.far_faces(contact)
    top = aut.on_face(high, ext)
    ax, dr = contact.axis_index, contact.direction_index
    face_area = aut.extent[top][:, [k for k in range(3) if k != ax]].prod(axis=1)
    load = np.zeros((aut.size, 3))
    load[top, ax] = -contact.normal_stress * face_area
    slider = aut.body == 1
    mass = float(aut.mass[slider].sum())
    normal_force = float(contact.normal_stress * face_area.sum())
    rate = Model(bonded, el).relaxation_rate()
    peak_force = contact.mu_static * normal_force
    e_scale = 0.5 * contact.normal_stress**2 / el.youngs * scene.box.volume + peak_force**2 / contact.spring_stiffness
    model = Model(aut, el, rotations=p["rotations"], krot=p["krot"], cfl=p["cfl"], gamma=rate, fixm=fixm,
                  t_stop=0.0, ke_limit=p["blowup"] * e_scale, load=load, contact=law, step_automata=bonded)
    st = model.new_state()
    steps = math.ceil(contact.duration / model.dt)
    summary: dict[str, Any] = {"dt": model.dt, "slider_mass": mass, "normal_force_applied": normal_force,
                               "law_mu_kinetic": contact.mu_kinetic, "law_mu_static": contact.mu_static,
                               "run_steps_needed": steps, "lattice_spacing": float(aut.spacing[contact.axis_index]),
                               "contact_stiffness_Pa_per_m": law.kt}
    out: dict[str, Any] = {"field": None, "quantity": "", "summary": summary, "model": model, "state": st}
    failed = preload(model, st, contact.normal_stress * float(aut.spacing.min()) ** 2, steps, p, summary)
    if failed:
        return out | failed, aut
    pre_steps = summary["preload_steps"]
    every = max(1, steps // p["records"])
    weight = np.where(slider, aut.mass, 0.0) / mass
    u0 = float((weight * (st.x[:, dr] - aut.positions[:, dr])).sum())
    spring = mk.Spring(weight=weight, axis=dr, stiffness=float(contact.spring_stiffness), speed=float(contact.speed),
                       start=float(st.clock[0]), offset=u0, every=every, out=np.zeros(3),
                       hist=np.zeros((steps // every + 2, len(HISTORY_COLUMNS))), rows=np.zeros(1, dtype=np.int64))
    gamma = rate if p["slide_damping"] is None else float(p["slide_damping"])
    st = st._replace(spring=spring, frame=mk.Frame(np.zeros((aut.size, 3))) if gamma > 0 else None)
    model.params = model.params._replace(gamma=gamma, t_stop=math.inf)
    heat0 = st.contact.heat.copy()
    st = st._replace(hist=np.zeros((20 + 2, mk.N_H)))
    st, code, rebuilds, contact_rows = drive(model, st, pre_steps + steps, every)
    rows = st.spring.hist[: int(st.spring.rows[0])].copy()
    rows[:, 0] -= spring.start
    if len(contact_rows):  # the contacts' own resultants (the law's bookkeeping): diagnostics, not measurements
        summary.update(contact_normal_force_min=float(contact_rows[:, mk.H_FN].min()),
                       contact_normal_force_max=float(contact_rows[:, mk.H_FN].max()),
                       contacts_closed_min=int(contact_rows[:, mk.H_NC].min()))
    summary.update(steps=int(st.counters[mk.C_STEPS]), pair_list_rebuilds=rebuilds,
                   spring_work_J=float(st.spring.out[2]),
                   slid_distance=float(rows[-1, 3] - u0) if len(rows) else math.nan,
                   slide_room=cs.footprint_room(aut, contact))
    summary.update(measure(rows, contact.speed))
    out |= {"field": (st.contact.heat - heat0) / aut.volume, "quantity": "friction heat received in the run (J/m^3)",
            "state": st, "diagnostics": {"history": {"columns": list(HISTORY_COLUMNS), "rows": rows},
                                         "contact_history": {"columns": list(mk.HISTORY_COLUMNS),
                                                             "rows": contact_rows}}}
    if code in (mk.NAN, mk.GROWTH):
        return out | {"status": "unstable", "reason": f"{mk.STATUS_TEXT[code]} at step {int(st.counters[mk.C_STEPS])}"
                      "; rows up to there kept"}, aut
    if summary["slid_distance"] > summary["slide_room"]:
        return out | {"status": "failed", "reason": f"the slider slid {summary['slid_distance']:.3g} m, beyond its "
                      f"base's surface ({summary['slide_room']:.3g} m of room); allowed: speed x duration within the "
                      "room"}, aut
    if summary["stick_slip_cycles"] < MIN_CYCLES:
        return out | {"status": "failed", "reason": f"no stick-slip cycle to measure: {summary['stick_slip_cycles']} "
                      f"slips after the first in {contact.duration:g} s ({summary['slip_phases']} slip phases, the "
                      f"slider's mean velocity above {SLIP_SPEED:g} x speed in {summary['slipping_share']:.0%} of the "
                      f"rows); allowed: at least {MIN_CYCLES}"}, aut
    return out | {"status": "ok", "reason": ""}, aut


def drive(model: Model, st: mk.State, until: int, every: int) -> tuple[mk.State, int, int, np.ndarray]:
    """Advance to step `until` as the sliding scenes do (`contact_scenes.advance_listed`: chunks of 20 rows, the
    lists rebuilt whenever an automaton moved beyond the skin): (state, kernel status, rebuilds, the kernel's
    history rows every `every` steps)."""
    rows: list[np.ndarray] = []
    st, code, rebuilds = cs.advance_listed(model, st, until, every, rows)
    return st, code, rebuilds, np.concatenate(rows) if rows else np.zeros((0, mk.N_H))


def preload(model: Model, st: mk.State, scale: float, steps: int, p: dict[str, Any], summary: dict[str, Any]
            ) -> dict[str, str]:
    """Relax the pressed bodies (residual force in units of `scale`) and check that `steps` more fit in
    max_steps; the preload's steps and residual go into `summary`.  {} when the run may go on, else its status
    and reason."""
    status, res, _ = relax(model, st, scale, tol=p["preload_tol"], max_steps=p["max_steps"])
    pre_steps = int(st.counters[mk.C_STEPS])
    summary.update(preload_steps=pre_steps, preload_residual=res)
    if status != mk.OK or not res <= p["preload_tol"]:
        kstat, reason = relax_status(status, res, p["preload_tol"], pre_steps, p["max_steps"])
        return {"status": kstat, "reason": f"preload: {reason}"}
    if pre_steps + steps > p["max_steps"]:
        return {"status": "failed", "reason": f"max_steps={p['max_steps']} would be reached before the run ends: it "
                f"needs {steps} steps of dt {model.dt:.3g} s after {pre_steps} of preload; allowed: max_steps >= "
                f"{pre_steps + steps} or a shorter duration"}
    return {}


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(first row, row after the last) of each run of True in a boolean row mask."""
    edges = np.flatnonzero(np.diff(np.r_[False, mask, False]))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist(), strict=True))


def phases(moving: np.ndarray) -> list[tuple[int, int]]:
    """The slip phases (first row, row after the last) of a boolean row mask: slips shorter than MIN_PHASE_ROWS
    dropped, then sticks between two slips shorter than that filled."""
    moving = moving.copy()
    for a, b in _runs(moving):
        if b - a < MIN_PHASE_ROWS:
            moving[a:b] = False
    for a, b in _runs(~moving):
        if 0 < a and b < len(moving) and b - a < MIN_PHASE_ROWS:
            moving[a:b] = True
    return _runs(moving)


def _edge(vel: np.ndarray, start: int, step: int, limit: int, still: float) -> int:
    """From row `start` walk by `step` (-1 back, +1 on) while the velocity exceeds `still`, at most to `limit`:
    the row where the slider is (nearly) at rest next to a slip phase."""
    k = start
    while k != limit and vel[k] > still:
        k += step
    return k


def measure(rows: np.ndarray, speed: float) -> dict[str, Any]:
    """The cycle measured from the spring's rows (t, force, velocity, u): the module docstring's quantities, and
    the largest spring force over every row (defined with or without a cycle)."""
    largest = float(rows[:, 1].max()) if len(rows) else math.nan
    if len(rows) < 2 * MIN_PHASE_ROWS:
        return {"stick_slip_cycles": 0, "slip_phases": 0, "slipping_share": math.nan, "largest_spring_force_N": largest}
    t, force, vel = rows[:, 0], rows[:, 1], rows[:, 2]
    slips = phases(vel > SLIP_SPEED * speed)
    still = REST_SPEED * speed
    bounds, previous = [], 0
    for a, b in slips:  # the rows at rest just before and just after each slip phase
        if b >= len(rows):
            break
        start, end = _edge(vel, a - 1, -1, previous, still), _edge(vel, b, 1, len(rows) - 1, still)
        bounds.append((start, end))
        previous = end
    out: dict[str, Any] = {"slip_phases": len(slips), "slipping_share": float(np.mean(vel > SLIP_SPEED * speed)),
                           "largest_spring_force_N": largest,
                           "first_peak_N": float(force[bounds[0][0]]) if bounds else largest}
    cycles: dict[str, list[float]] = {k: [] for k in ("spring_peak_N", "spring_trough_N", "force_drop_N",
                                                      "spring_max_N", "slip_s", "slip_velocity_peak", "stick_s",
                                                      "period_s")}
    for k in range(1, len(bounds)):
        a, b = bounds[k]
        cycles["spring_peak_N"].append(float(force[a]))
        cycles["spring_trough_N"].append(float(force[b]))
        cycles["force_drop_N"].append(float(force[a] - force[b]))
        cycles["spring_max_N"].append(float(force[a:b + 1].max()))
        cycles["slip_s"].append(float(t[b] - t[a]))
        cycles["slip_velocity_peak"].append(float(vel[a:b + 1].max()))
        if k >= 2:  # the stick after the first slip follows an untypical slip (from the first breakaway)
            cycles["stick_s"].append(float(t[a] - t[bounds[k - 1][1]]))
        if k + 1 < len(bounds):
            cycles["period_s"].append(float(t[bounds[k + 1][0]] - t[a]))
    out["stick_slip_cycles"] = max(len(bounds) - 1, 0)
    for name, values in cycles.items():
        enough = len(values) >= MIN_CYCLES
        out[name] = float(np.mean(values)) if enough else math.nan
        out[f"{name}_spread"] = float(np.std(values, ddof=1)) if enough else math.nan
    return out
