"""The movable cellular automaton (MCA) solver: elasticity, fracture, eigenfrequencies, heat and contact.

This module holds the table of analyses (`ANALYSES`): each kind of MCA run is one entry, chosen by what the scene
declares (never its name), with its refusal check, its work estimate and its run; `Mca` looks the scene's analysis
up and turns the run's results into a Solution.  The pieces are the sibling modules (automata, kernel, kernels,
model, stiffness, heat, response, contact_scenes, stick_slip, incline); the analyses: (docs/physics.md, "The MCA
solver in detail").
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.sparse.linalg import LinearOperator, eigsh, splu

from pcverify.scene import (
    FaceClamp,
    FaceSupport,
    Resolution,
    Scene,
    SceneError,
    point_patch_note,
)
from pcverify.solvers.energy import balance_error
from pcverify.solvers.modes import (
    ModeKinds,
    classify,
    cut_is_complete,
    kind_summary,
    rotational,
    symmetric_lateral,
)
from pcverify.solvers.protocol import Solution, WorkEstimate, effective_params, heat_summary, read_notes, skipped

from . import contact_scenes as cs
from . import heat as mca_heat
from . import incline as inc
from . import kernel as mk
from . import response as rf
from . import stick_slip as ss
from .automata import Automata, bar_automata, cell_automata
from .kernels import timed
from .model import Elastic, Model, rebuild_pairs, relax, relax_status
from .parameters import PACKINGS, PARAMETERS
from .probe import McaProbe
from .stiffness import mass_diagonal, stiffness

NOTES_FILE = Path(__file__).with_name("model_notes.txt")
BYTES_PER_AUTOMATON = 4096  # state, rotations, inelastic state and about 13 pairs of 10 arrays each
RELAX_STEPS_PER_CELL = 1000  # relaxation steps per spacing of the longest extent (measured 390-630, bar-compression)
ENERGY_ALARM = 1e-2  # relative energy-balance error of an undamped elastic phase that flags a run as unstable
MIN_PEAK_STEPS = 50  # time steps up to the peak stress below which fracture is not resolved in time
MIN_CHECK_ROWS = 10  # history rows of the elastic phase the energy check needs
MIN_RISE_ROWS = 4  # history rows on the rise (10-60 % of the peak) the E_eff fit needs

class Mca:
    """Movable cellular automata on the bar lattice (elasticity, fracture, modes, heat, contact)."""

    name = "mca"
    kind = "particle"
    parameters = PARAMETERS

    @property
    def notes(self) -> tuple[str, ...]:
        """The model notes (model_notes.txt beside this module): where this solver departs from the MCA paper."""
        return read_notes(NOTES_FILE)

    def stability_probe(self) -> McaProbe:
        """The probe of this solver's explicit heat and mechanics steps."""
        return McaProbe(self)

    def analysis(self, scene: Scene) -> Analysis:
        """The entry of ANALYSES that runs `scene`; SceneError with the reason when none does."""
        analysis, why = analysis_of(scene)
        if analysis is None:
            raise SceneError(why)
        return analysis

    def estimate(self, scene: Scene, resolution: Resolution, **params: Any) -> WorkEstimate:
        """Unknowns, time steps and memory of the solve, from the scene and the parameters alone (the scene's
        analysis's estimate)."""
        p = effective_params(self, params)
        return self.analysis(scene).estimate(scene, resolution, p)

    def supports(self, scene: Scene) -> tuple[bool, str]:
        analysis, why = analysis_of(scene)
        return analysis is not None, why

    def solve(self, scene: Scene, resolution: Resolution, samples: dict[str, np.ndarray] | None = None,
              **params: Any) -> Solution:
        p = effective_params(self, params)
        analysis = self.analysis(scene)
        t_wall = time.perf_counter()
        n = resolution.n
        pts = scene.sample_sets(n) if samples is None else samples
        if p["packing"] not in analysis.packings:
            return skipped(scene, self, resolution, f"mca's {analysis.name} runs packing "
                           f"{' or '.join(analysis.packings)} only; packing={p['packing']} is not implemented for it")
        out, aut = analysis.run(scene, n, p)
        if analysis.bodies > 1:  # a slider shorter than its base: the samples at its automata only
            pts = {k: v[aut.holds(v)] for k, v in pts.items()}
        field = out.pop("field")
        if "kernel_s" in out["work"]:  # seconds inside the time-stepping / solve kernel (ns per pair-step)
            out["summary"]["kernel_s"] = out["work"]["kernel_s"]
        values = {} if field is None else {k: {"points": np.asarray(v, float), "values": _at(aut, field, v)}
                                           for k, v in pts.items()}
        return Solution(scene=scene.name, solver=self.name, params=p,
                        resolution={"n": n, "refine": 1, "h": float(aut.spacing.min()), "nodes": aut.size},
                        samples=values, unknowns=out.pop("unknowns"),
                        wall_s=time.perf_counter() - t_wall, status=out.pop("status", "ok"),
                        reason=out.pop("reason", ""), quantity=out.pop("quantity"), work=out.pop("work"),
                        summary=out.pop("summary"), diagnostics=out.pop("diagnostics", {}))


def _at(aut: Automata, field: np.ndarray, points: np.ndarray) -> np.ndarray:
    """The field at the sample `points`: at the automata centred there ("nodes"), interpolated between the
    centres and extrapolated linearly to the faces ("cells", second order; `Automata.sampler`)."""
    if aut.packing == "nodes":
        return field[aut.node_at(points)]
    return np.asarray(aut.sampler(points) @ field)


# -- heat ----------------------------------------------------------------------------------------

def _steady_heat(scene: Scene, aut: Automata, p: dict[str, Any]) -> dict[str, Any]:
    """Steady: a direct solve of the automata's heat balance."""
    held, values = mca_heat.held_temperatures(scene, aut)
    power = mca_heat.sources(scene, aut)
    t0 = time.perf_counter()
    temp = mca_heat.steady(aut, scene.material.conductivity, values, held, power)
    return _heat_result(scene, aut, temp, {}, {"unknowns": int(np.count_nonzero(held == 0)), "time_steps": 0,
                                                "kernel_s": time.perf_counter() - t0})


def _transient_heat(scene: Scene, aut: Automata, p: dict[str, Any]) -> dict[str, Any]:
    """Transient: explicit steps at the stable step (times heat_cfl) to t_end."""
    mat = scene.material
    held, values = mca_heat.held_temperatures(scene, aut)
    st, par, steps = mca_heat.transient(aut, mat.conductivity, mat.density * mat.heat_capacity, values, held,
                                        scene.conduction.t_end, p["heat_cfl"], mca_heat.sources(scene, aut))
    work = {"unknowns": int(np.count_nonzero(held == 0)), "kernel_s": timed("heat", st, par, steps),
            "time_steps": steps, "pair_steps": steps * len(aut.pairs)}
    return _heat_result(scene, aut, st.temp, {"dt": par.dt, "steps": steps}, work)


def _heat_result(scene: Scene, aut: Automata, temp: np.ndarray, summary: dict[str, Any], work: dict[str, Any]
                 ) -> dict[str, Any]:
    """T / t_max at the automata, its summary, and a status that flags non-finite temperatures."""
    rel = temp / scene.conduction.t_max
    status, reason = ("ok", "") if np.all(np.isfinite(rel)) else ("unstable", "non-finite temperature")
    reason = "; ".join(r for r in (reason, point_patch_note(scene.constraints, float(aut.spacing.min()))) if r)
    summary.update(heat_summary(rel, float((rel * aut.volume).sum() / aut.volume.sum())))
    return {"field": rel, "unknowns": work["unknowns"], "quantity": "T/t_max", "work": work, "summary": summary,
            "status": status, "reason": reason}


# -- elasticity ----------------------------------------------------------------------------------

def _fixes(scene: Scene, aut: Automata, rate_of: dict[str, float]
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[str]]:
    """(fixm, fixv, group, notes): constrained dofs, their velocities, face groups (1 = zL, 2 = z0).  "cells"
    packing: the faces' constraints act through wall bonds (`face_walls`), so no face automaton is held."""
    n = aut.size
    ext = scene.box.extent
    fixm = np.zeros((n, 6), dtype=np.uint8)
    fixv = np.zeros((n, 6))
    group = np.zeros(n, dtype=np.int64)
    notes: list[str] = []
    clamped = False
    for c in scene.constraints:
        if not isinstance(c, (FaceSupport, FaceClamp)):
            raise SceneError(f"mca elasticity: constraint {type(c).__name__} is not supported")
        idx = aut.on_face(c.face, ext)
        if aut.packing == "cells":
            clamped = clamped or isinstance(c, FaceClamp)
        elif isinstance(c, FaceClamp):
            fixm[idx] = 1
            fixv[idx] = 0.0
            clamped = True
        else:
            ax = "xyz".index(c.face[0])
            fixm[idx, ax] = 1
            fixv[idx, ax] = rate_of.get(c.face, 0.0)
    group[aut.on_face("zL", ext)] = 1
    group[aut.on_face("z0", ext)] = 2
    supported = {"xyz".index(c.face[0]) for c in scene.constraints if isinstance(c, FaceSupport)}
    if not clamped and supported == {2}:
        z0 = aut.on_face("z0", ext)
        xy = aut.positions[z0, :2]
        lo, hi = _inset(aut), ext[0] - _inset(aut)  # the face layer's corner centres
        a = z0[np.flatnonzero(np.all(np.abs(xy - lo) <= 1e-9 * ext[0], axis=1))]
        b = z0[np.flatnonzero((np.abs(xy[:, 0] - hi) <= 1e-9 * ext[0]) & (np.abs(xy[:, 1] - lo) <= 1e-9 * ext[1]))]
        fixm[a, 0] = fixm[a, 1] = fixm[b, 1] = 1
        notes.append("rigid-body set: u_x = u_y = 0 at (0, 0, 0), u_y = 0 at (W, 0, 0)" if aut.packing == "nodes"
                     else "rigid-body set: u_x = u_y = 0 at (a/2, a/2, a/2), u_y = 0 at (W - a/2, a/2, a/2)")
    elif not clamped and supported != {0, 1, 2}:
        raise SceneError("mca elasticity: supports that leave rigid motion free are implemented for z faces "
                         "only; allowed: FaceSupport on z0/zL, or a FaceClamp")
    return fixm, fixv, group, notes


def _inset(aut: Automata) -> float:
    """Distance from a face to the centres of its layer: 0 ("nodes"), a/2 ("cells")."""
    return 0.0 if aut.packing == "nodes" else 0.5 * float(aut.spacing[0])


def face_walls(scene: Scene, aut: Automata) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
    """Wall bonds of the constrained faces ("cells": the face layer bonded to a wall point on the face by
    half-length pairs, a support's normal only), in the order of the scene's constraints; None ("nodes": the
    face automata themselves are held)."""
    if aut.packing == "nodes":
        return None
    held = [c for c in scene.constraints if isinstance(c, (FaceSupport, FaceClamp))]
    return aut.walls([c.face for c in held], [isinstance(c, FaceSupport) for c in held], scene.box.extent)


def _strains(scene: Scene, aut: Automata, u: np.ndarray) -> tuple[float, float]:
    """Axial strain between the z faces, lateral strain the mean of those between the x and the y faces."""
    ext = scene.box.extent
    return aut.face_strain(u, 2, ext), 0.5 * (aut.face_strain(u, 0, ext) + aut.face_strain(u, 1, ext))


def _static(scene: Scene, aut: Automata, p: dict[str, Any]) -> dict[str, Any]:
    if aut.packing == "cells":
        return _static_linear(scene, aut, p)
    el = Elastic.of(scene, p)
    probe = Model(aut, el)
    rate = probe.relaxation_rate()
    t_ramp = p["ramp_periods"] * 2 * math.pi / rate
    disp = {c.face: c.displacement for c in scene.constraints if isinstance(c, FaceSupport)}
    fixm, fixv, group, notes = _fixes(scene, aut, {f: d / t_ramp for f, d in disp.items()})
    gamma = rate if p["damping"] is None else p["damping"]
    strain = max(abs(d) for d in disp.values()) / scene.box.length if disp else 1e-3
    e_load = 0.5 * el.youngs * strain**2 * scene.box.volume
    model = Model(aut, el, rotations=p["rotations"], krot=p["krot"], cfl=p["cfl"], gamma=gamma, fixm=fixm,
                  fixv=fixv, group=group, t_stop=t_ramp, ke_limit=p["blowup"] * e_load)
    st = model.new_state()
    scale = el.youngs * max(strain, 1e-12) * float(aut.spacing.min()) ** 2
    status, res, _ = relax(model, st, scale, tol=p["relax_tol"], max_steps=p["max_steps"])
    u = st.x - aut.positions
    steps = int(st.counters[mk.C_STEPS])
    summary: dict[str, Any] = {"residual": res, "steps": steps, "dt": model.dt, "damping": gamma,
                               "ramp_s": t_ramp}
    react = float(-st.f[group == 1, 2].sum())
    summary["reaction_force"] = react
    if "zL" in disp and "z0" in disp:
        axial, lateral = _strains(scene, aut, u)
        area = scene.box.width * scene.box.height
        summary.update(axial_strain=axial, lateral_strain=lateral, E_eff=react / area / axial,
                       nu_eff=-lateral / axial)
    kstat, reason = relax_status(status, res, p["relax_tol"], steps, p["max_steps"])
    return {"field": u, "unknowns": model.free_dofs, "quantity": "u (m)", "summary": summary, "status": kstat,
            "reason": reason, "work": model.work(st), "diagnostics": {"notes": notes}}


def _static_linear(scene: Scene, aut: Automata, p: dict[str, Any]) -> dict[str, Any]:
    """Static elasticity of the "cells" packing: the linearised automata (stiffness.py, the kernel's potential
    to first order) with the faces' wall bonds, solved directly.  The wall points move with their support's
    displacement (a clamp's stay); the rigid-body set of `_fixes` holds the rest."""
    el = Elastic.of(scene, p)
    rot = p["rotations"]
    nd = 6 if rot else 3
    walls = face_walls(scene, aut)
    t0 = time.perf_counter()
    k = stiffness(aut, el.shear, el.lam, el.kn, p["krot"], rotations=rot, walls=walls).tocsr()
    fixm, _, _, notes = _fixes(scene, aut, {})
    held = np.r_[fixm[:, :nd].ravel() == 1, np.ones(nd * walls[0].size, dtype=bool)]
    u = np.zeros(k.shape[0])
    react = 0.0
    rows_of = {c.face: nd * (aut.size + first + np.arange(count)) + "xyz".index(c.face[0])
               for (first, count), c in _wall_starts(scene, aut)}  # each wall's normal displacements
    for c in scene.constraints:
        if isinstance(c, FaceSupport):
            u[rows_of[c.face]] = c.displacement
    free = np.flatnonzero(~held)
    u[free] = spla.spsolve(k[free][:, free].tocsc(), -(k[free][:, held] @ u[held]))
    force = k @ u  # the external force on every degree of freedom (zero on the free ones)
    field = u[: nd * aut.size].reshape(aut.size, nd)[:, :3]
    if "zL" in rows_of:
        react = float(force[rows_of["zL"]].sum())
    summary: dict[str, Any] = {"residual": float(np.abs(force[free]).max(initial=0.0)), "steps": 0,
                               "reaction_force": react}
    disp = {c.face for c in scene.constraints if isinstance(c, FaceSupport)}
    if "zL" in disp and "z0" in disp:
        axial, lateral = _strains(scene, aut, field)
        area = scene.box.width * scene.box.height
        summary.update(axial_strain=axial, lateral_strain=lateral, E_eff=react / area / axial,
                       nu_eff=-lateral / axial)
    notes.append("packing=cells: the linearised automata solved directly, the faces' constraints as wall bonds")
    return {"field": field, "unknowns": int(free.size), "quantity": "u (m)", "summary": summary, "status": "ok",
            "reason": "", "work": {"unknowns": int(free.size), "kernel_s": time.perf_counter() - t0},
            "diagnostics": {"notes": notes}}


def _wall_starts(scene: Scene, aut: Automata) -> list[tuple[tuple[int, int], FaceSupport | FaceClamp]]:
    """((first wall bond, count), constraint) of each constrained face, in the order of `face_walls`."""
    out, start = [], 0
    for c in scene.constraints:
        if isinstance(c, (FaceSupport, FaceClamp)):
            count = aut.on_face(c.face, scene.box.extent).size
            out.append(((start, count), c))
            start += count
    return out


# -- fracture ------------------------------------------------------------------------------------

def _fracture(scene: Scene, aut: Automata, p: dict[str, Any]) -> dict[str, Any]:
    el = Elastic.of(scene, p)
    resp = scene.elasticity.response
    length = scene.box.length
    speed = scene.elasticity.strain_rate * length
    fixm, fixv, group, notes = _fixes(scene, aut, {"zL": speed})
    gamma = 0.0 if p["damping"] is None else p["damping"]
    e_load = 0.5 * rf.tensile_strength(resp) ** 2 / el.youngs * scene.box.volume
    model = Model(aut, el, response=resp, fracture=True, rotations=p["rotations"], friction=p["friction"],
                  krot=p["krot"], relink_stress=p["relink_stress"], cfl=p["cfl"], gamma=gamma, fixm=fixm,
                  fixv=fixv, group=group, ke_limit=p["blowup"] * e_load)
    eps_fail = failure_strain(resp, el.youngs)
    t_end = 1.5 * eps_fail / scene.elasticity.strain_rate
    steps_total = min(p["max_steps"], math.ceil(t_end / model.dt))
    every = max(1, steps_total // p["records"])
    st = model.new_state(hist_rows=steps_total // every + 2, peak=True)
    area = scene.box.width * scene.box.height
    ke0 = 0.5 * float((aut.mass[:, None] * st.v**2).sum())
    rows = []
    done = 0
    code = mk.OK
    chunk = max(every, 2000 // every * every)
    rebuilds = added = 0
    first: dict[str, Any] = {}
    while done < steps_total:
        before = copied(st) if st.counters[mk.C_UNLINK] == 0 else None
        code = model.advance(st, min(chunk, steps_total - done), every)
        rows.append(st.hist[: st.counters[mk.C_ROWS], :mk.H_LOAD].copy())
        done = int(st.counters[mk.C_STEPS])
        if before is not None and st.counters[mk.C_UNLINK] > 0:
            first = first_unlink(model, before, length, int(st.counters[mk.C_STEPS]))
        if code == mk.MOVED:
            st, more = rebuild_pairs(model, st)
            added += more
            rebuilds += 1
            code = mk.OK
            continue
        if code != mk.OK:
            break
        h = np.concatenate(rows)
        peak = h[:, mk.H_R1].max()
        if st.counters[mk.C_UNLINK] > 0 and h[-1, mk.H_R1] < 0.05 * peak:
            break
    h = np.concatenate(rows) if rows else np.zeros((0, mk.H_LOAD))
    n_pairs = len(aut.pairs)
    summary: dict[str, Any] = {"dt": model.dt, "steps": done, "damping": gamma}
    peak_r, peak_u, peak_step = (float(v) for v in st.peak)
    if math.isfinite(peak_r):  # tracked every step: the history's thinning (records) does not move it
        summary.update(failure_stress=peak_r / area, failure_strain=peak_u / length, reaction_force=peak_r,
                       peak_step=int(peak_step), strength_expected=rf.tensile_strength(resp) if resp else math.inf)
    elastic = h[h[:, mk.H_LINKED] == n_pairs]
    elastic_law = resp is not None and resp.kind == "elastic"
    energy_check = elastic_law and gamma == 0.0  # undamped: the balance must close (damping's loss is not booked)
    if len(h):
        summary["linked_fraction"] = float(h[-1, mk.H_LINKED] / n_pairs)
        if elastic_law and len(elastic):  # damped too: there it measures what the damping took out
            summary["energy_error"] = balance_error(elastic[:, mk.H_KE] + elastic[:, mk.H_U] - ke0,
                                                    (elastic[:, mk.H_WORK],), max(np.max(elastic[:, mk.H_U]), 1e-300))
        if math.isfinite(peak_r):
            stress = h[:, mk.H_R1] / area
            before = h[:, mk.H_T] < (peak_step + 0.5) * model.dt
            rise = h[(stress > 0.1 * peak_r / area) & (stress < 0.6 * peak_r / area) & before]
            if len(rise) >= MIN_RISE_ROWS:
                summary["E_eff"] = float(np.polyfit(rise[:, mk.H_U1] / length, rise[:, mk.H_R1] / area, 1)[0])
            if resp is not None and resp.kind != "elastic":  # an elastic bar's ringing would read as a knee
                summary.update(bilinear_fit(h[before, mk.H_U1] / length, stress[before], peak_r / area))
            if gamma > 0.0:
                summary.update(drag_stress(h, peak_step * model.dt, area))
    summary.update(first)
    summary["unlink_events"] = int(st.counters[mk.C_UNLINK])
    summary["relink_events"] = int(st.counters[mk.C_RELINK])
    summary["pair_list_rebuilds"] = rebuilds
    summary["pairs_added"] = added
    status, reason = "ok", ""
    if code in (mk.NAN, mk.GROWTH):
        status, reason = "unstable", f"{mk.STATUS_TEXT[code]} at step {done}; history up to there kept"
    elif done >= p["max_steps"] and p["max_steps"] < math.ceil(t_end / model.dt):
        strain = done * model.dt * scene.elasticity.strain_rate
        status, reason = "failed", (f"max_steps={p['max_steps']} reached at strain {strain:.3g}, before the "
                                    f"planned end {1.5 * eps_fail:.3g} (1.5 times the failure strain); raise "
                                    "max_steps")
    elif energy_check and summary.get("energy_error", 0.0) > ENERGY_ALARM:
        status, reason = "unstable", (f"energy balance of the elastic phase off by {summary['energy_error']:.3g} "
                                      f"(> {ENERGY_ALARM:g}): the time step is too large; results kept")
    elif st.counters[mk.C_UNLINK] == 0:
        strain = done * model.dt * scene.elasticity.strain_rate
        status, reason = "failed", f"no pair unlinked up to strain {strain:.3g}"
    elif summary.get("peak_step", 0) < MIN_PEAK_STEPS:
        status, reason = "failed", (f"the peak stress came after {summary.get('peak_step', 0)} steps (fewer than "
                                    f"{MIN_PEAK_STEPS}): the loading is not resolved in time; lower strain_rate "
                                    "or cfl")
    elif energy_check and len(elastic) < MIN_CHECK_ROWS:
        status, reason = "failed", (f"the energy check of the elastic phase cannot run: {len(elastic)} history "
                                    f"rows before the first unlink (it needs {MIN_CHECK_ROWS}); raise records or "
                                    "lower strain_rate")
    elif "E_eff" not in summary:
        status, reason = "failed", (f"E_eff cannot be fitted: fewer than {MIN_RISE_ROWS} history rows between 10 % "
                                    "and 60 % of the peak stress; raise records or lower strain_rate")
    aut = model.aut
    diag = {"notes": notes, "history": {"columns": list(mk.HISTORY_COLUMNS[:mk.H_LOAD]), "rows": h}}
    return {"field": st.x - aut.positions, "unknowns": model.free_dofs, "quantity": "u (m)", "summary": summary,
            "status": status, "reason": reason, "work": model.work(st), "diagnostics": diag}


# -- modes ---------------------------------------------------------------------------------------

def _modes(scene: Scene, aut: Automata, p: dict[str, Any]) -> dict[str, Any]:
    el = Elastic.of(scene, p)
    rot = p["rotations"]
    t0 = time.perf_counter()
    nd = 6 if rot else 3
    k = stiffness(aut, el.shear, el.lam, el.kn, p["krot"], rotations=rot, walls=face_walls(scene, aut))
    k = k[: nd * aut.size, : nd * aut.size]  # the wall points, if any, are held
    m = mass_diagonal(aut, rotations=rot)
    fixm, _, _, _ = _fixes(scene, aut, {})
    held = fixm[:, :nd].ravel() == 1
    free = np.flatnonzero(~held)
    kff = k[free][:, free].tocsc()
    count = int(scene.elasticity.modes)
    if count >= free.size - 1:
        raise SceneError(f"modes={count} is out of range; allowed: integer in [1, {free.size - 2}] at this "
                         "resolution")
    dense = free.size <= 1500
    if dense:
        all_vals, all_vecs = sla.eigh(kff.toarray(), np.diag(m[free]))
    else:  # shift-invert about 0: one factorisation of K for every widening of the search
        inverse = LinearOperator(kff.shape, matvec=splu(kff).solve, dtype=float)
    v0 = np.random.default_rng(4).standard_normal(free.size)
    kmax = free.size - 2 if not dense else free.size

    def lowest(want: int) -> tuple[np.ndarray, np.ndarray]:
        """The lowest `want` modes and more, up to one beyond the degenerate cluster at the cut (all there are
        when fewer)."""
        extra = 2
        while True:
            size = min(want + extra, kmax)
            if dense:
                vals, vecs = all_vals[:size], all_vecs[:, :size]
            else:
                vals, vecs = eigsh(kff, k=size, M=sp.diags(m[free]).tocsc(), sigma=0.0, which="LM", v0=v0,
                                   OPinv=inverse)
                order = np.argsort(vals)
                vals, vecs = vals[order], vecs[:, order]
            if size == kmax or cut_is_complete(vals, want):
                return vals, vecs
            extra *= 2

    def kinds_of(vals: np.ndarray, vecs: np.ndarray) -> ModeKinds:
        full = np.zeros((k.shape[0], vals.size))
        full[free] = vecs
        # bending-x before bending-y in a degenerate cluster (x mirror only)
        unit = aut.spacing / 2  # mirror keys on half spacings: "cells" centres sit at half-integers of a
        return classify(full, vals, m, aut.positions, scene.box.extent, unit, rotations=rot,
                        order=(1.0, 0.0), energy=(rotational, symmetric_lateral))

    # widen the search until `count` modes of a continuum kind are found (the rotational ones do not count) and
    # the degenerate cluster at the cut is complete
    want = count
    while True:
        vals, vecs = lowest(want)
        cls = kinds_of(vals, vecs)
        others = np.flatnonzero(np.array(cls.kinds) != "rotational")
        keep = int(others[count - 1]) + 1 if others.size >= count else vals.size
        if vals.size >= kmax or (others.size >= count and cut_is_complete(vals, keep)):
            break
        want = keep if others.size >= count else min(kmax, 2 * want + count)  # few solves: each Lanczos restarts
    cls = cls.first(keep)
    freqs = np.sqrt(np.clip(vals[:keep], 0.0, None)) / (2 * np.pi)
    summary: dict[str, Any] = {"frequencies_hz": freqs, "mode_kinds": cls.kinds,
                               "rotational_mass_fraction": cls.shares.get("rotational", np.zeros(keep))}
    summary.update(kind_summary(cls.kinds, freqs))
    work = {"unknowns": int(free.size), "kernel_s": time.perf_counter() - t0}
    return {"field": None, "unknowns": int(free.size), "quantity": "frequencies (Hz)", "summary": summary,
            "work": work}


def copied(value: Any) -> Any:
    """A deep copy of a kernel state (NamedTuples of arrays, nested; scalars and None as they are)."""
    if isinstance(value, np.ndarray):
        return value.copy()
    if isinstance(value, tuple) and hasattr(value, "_fields"):
        return type(value)(*(copied(v) for v in value))
    return value


def drag_stress(h: np.ndarray, t_peak: float, area: float) -> dict[str, float]:
    """The net force of the two held faces per area, averaged over the rows between 30 % and 90 % of the time to
    the peak: in a damped pull, once the start-up has decayed, what the viscous damping of the moving automata
    takes out ({} when no row lies there)."""
    window = (h[:, mk.H_T] > 0.3 * t_peak) & (h[:, mk.H_T] < 0.9 * t_peak)
    if not window.any():
        return {}
    return {"drag_stress": float(np.mean(h[window, mk.H_R1] + h[window, mk.H_R2])) / area}


def first_unlink(model: Model, st: mk.State, length: float, until: int) -> dict[str, Any]:
    """Where the first pairs unlinked: the run replayed from the state `st` (a copy taken before the chunk in
    which the first unlink came, which ended at step `until`) one step at a time up to that unlink, which is the
    same run (the steps do not depend on the chunking).  first_unlink_z: the mean rest z of the unlinked pairs'
    midpoints over the bar's length; first_unlink_pairs: how many unlinked in that step.  {} if the replay stops
    on another status or reaches `until` without an unlink."""
    linked = st.linked.copy()
    kernel_s = model.kernel_s
    code = mk.OK
    while st.counters[mk.C_UNLINK] == 0 and st.counters[mk.C_STEPS] < until and code == mk.OK:
        code = model.advance(st, 1)
    model.kernel_s = kernel_s  # the replay is not the run's work
    if st.counters[mk.C_UNLINK] == 0:
        return {}
    broken = np.flatnonzero((linked == 1) & (st.linked == 0))
    z = 0.5 * (st.x0[st.pi[broken], 2] + st.x0[st.pj[broken], 2]) / length
    return {"first_unlink_z": float(z.mean()), "first_unlink_pairs": int(broken.size), "first_unlink_step":
            int(st.counters[mk.C_STEPS])}


def bilinear_fit(strain: np.ndarray, stress: np.ndarray, peak: float) -> dict[str, float]:
    """The yield stress and the post-linear modulus of a measured rise to the peak stress `peak`, read off the
    curve alone (not the response's parameters): the elastic line fitted on 10-60 % of the peak, the post-linear
    line on the rows past the departure from it (1 % of the peak below it) between 30 and 90 % of the rest of the
    rise, the yield stress where the two lines meet.  {} when the curve keeps to its elastic line (an elastic
    response) or either part has fewer than MIN_RISE_ROWS rows."""
    linear = (stress > 0.1 * peak) & (stress < 0.6 * peak)
    if np.count_nonzero(linear) < MIN_RISE_ROWS:
        return {}
    e, b = np.polyfit(strain[linear], stress[linear], 1)
    below = (e * strain + b - stress > 0.01 * peak) & (stress > 0.6 * peak)
    if not below.any():
        return {}
    first = int(np.argmax(below))
    s_dep = float(stress[first])
    upper = (np.arange(stress.size) >= first) & (stress >= s_dep + 0.3 * (peak - s_dep)) & \
        (stress <= s_dep + 0.9 * (peak - s_dep))
    if np.count_nonzero(upper) < MIN_RISE_ROWS:
        return {}
    hard, c = np.polyfit(strain[upper], stress[upper], 1)
    eps_y = (c - b) / (e - hard)
    return {"yield_stress": float(e * eps_y + b), "post_linear_modulus": float(hard)}


def failure_strain(resp, youngs: float) -> float:
    """Strain at which the exact uniaxial curve of `resp` fractures (0.2 if not before)."""
    if resp is None:
        return 0.2
    eps = np.linspace(0.0, 0.2, 20001)
    sig = rf.uniaxial_curve(resp, youngs, eps)
    broken = np.flatnonzero(np.isnan(sig))
    return float(eps[broken[0]]) if broken.size else 0.2


# -- the table of analyses -------------------------------------------------------------------------

@dataclass(frozen=True)
class SceneKind:
    """What chooses a scene's analysis: its physics words, its conduction mode and whether its contact slides
    (None where the scene has no such part)."""

    physics: frozenset[str]
    conduction: str | None = None
    sliding: bool | None = None

    @classmethod
    def of(cls, scene: Scene) -> SceneKind:
        return cls(frozenset(scene.physics), None if scene.conduction is None else scene.conduction.mode,
                   None if scene.contact is None else scene.contact.sliding)


Run = Callable[[Scene, int, dict[str, Any]], tuple[dict[str, Any], Automata]]
Steps = Callable[[Scene, float, dict[str, Any]], int]  # (scene, smallest spacing h, parameters) -> time steps


@dataclass(frozen=True)
class Analysis:
    """One kind of MCA run.  It runs a scene whose physics has every word of `needs` and none beyond `allows`,
    whose conduction mode is `conduction` and whose contact slides as `sliding` (None: either); `check` gives
    the reason it still refuses the scene ("" when it runs it).  Its work: `unknowns` per automaton of `bodies`
    copies of the bar lattice, `steps` time steps, a dense matrix up to `dense` unknowns.  `stepping`: the
    explicit scheme its stability probe runs ("heat", "mechanics"), or "" and `no_stepping` saying why none."""

    name: str
    needs: frozenset[str]
    run: Run
    steps: Steps | None  # None: a direct or eigen solve, one step
    allows: frozenset[str] = frozenset()
    conduction: str | None = None
    sliding: bool | None = None
    check: Callable[[Scene], str] = lambda scene: ""
    unknowns: int = 6
    bodies: int = 1
    dense: int = 0
    stepping: str = "mechanics"
    no_stepping: str = ""
    packings: tuple[str, ...] = ("nodes",)

    def matches(self, kind: SceneKind) -> bool:
        return (self.needs <= kind.physics <= self.needs | self.allows and self.conduction in (None, kind.conduction)
                and self.sliding in (None, kind.sliding))

    def mismatch(self, kind: SceneKind) -> str:
        """Why a scene of `kind` whose physics has every word this analysis needs is not one it runs."""
        extra = kind.physics - self.needs - self.allows
        if extra:
            return f"mca's {self.name} does not model {sorted(extra)}"
        parts = [f"{self.conduction} conduction"] if self.conduction not in (None, kind.conduction) else []
        if self.sliding not in (None, kind.sliding):
            parts.append("a sliding contact" if self.sliding else "a contact that does not slide")
        return f"mca's {self.name} needs {' and '.join(parts)}"

    def estimate(self, scene: Scene, resolution: Resolution, p: dict[str, Any]) -> WorkEstimate:
        """Unknowns, time steps and memory of the run, from the scene and the parameters alone."""
        shape = packed_shape(scene, resolution.n, p["packing"])
        count = math.prod(shape) * self.bodies
        gaps = 1 if p["packing"] == "nodes" else 0  # spacings across an axis: nodes - 1, or cells
        h = min(e / max(k - gaps, 1) for e, k in zip(scene.box.extent, shape, strict=True))
        unknowns = self.unknowns * count
        dense = 16 * unknowns**2 if unknowns <= self.dense else 0
        linear = self.steps is None or p["packing"] == "cells"  # cells: the linearised model, solved directly
        steps = 1 if linear else max(1, self.steps(scene, h, p))
        return WorkEstimate(unknowns=unknowns, steps=steps, bytes=BYTES_PER_AUTOMATON * count + dense)


def _on_bar(run: Callable[[Scene, Automata, dict[str, Any]], dict[str, Any]]) -> Run:
    """A run on the automata of the bar at resolution n, packed as the `packing` parameter says."""

    def on_bar(scene: Scene, n: int, p: dict[str, Any]) -> tuple[dict[str, Any], Automata]:
        build = cell_automata if p["packing"] == "cells" else bar_automata
        aut = build(scene.box, n, scene.material.density)
        held = [c.face for c in scene.constraints if isinstance(c, (FaceClamp, FaceSupport))]
        aut = aut.with_free_faces(held, scene.box.extent)
        return run(scene, aut, p), aut

    return on_bar


def packed_shape(scene: Scene, n: int, packing: str) -> tuple[int, int, int]:
    """Automata per axis of the bar at resolution n: the lattice's nodes, or n cells across the width."""
    if packing == "nodes":
        return scene.box.lattice_shape(n)
    ext = scene.box.extent
    return (int(n), max(1, round(n * ext[1] / ext[0])), max(1, round(n * ext[2] / ext[0])))


def _heat_steps(scene: Scene, h: float, p: dict[str, Any]) -> int:
    """Explicit heat steps to t_end: t_end / (heat_cfl h^2 / (6 alpha))."""
    mat = scene.material
    alpha = mat.conductivity / (mat.density * mat.heat_capacity)
    return math.ceil(scene.conduction.t_end / (p["heat_cfl"] * h * h / (6.0 * alpha)))


def _wave(scene: Scene, h: float, p: dict[str, Any]) -> tuple[float, float]:
    """(wave speed c, time step): about cfl h / (4 c), below the Gershgorin step (measured 0.32 cfl h / c), so
    more steps than the run takes, not fewer."""
    mat = scene.material
    wave = math.sqrt(mat.youngs_modulus / mat.density) if math.isfinite(mat.youngs_modulus) else 5000.0
    return wave, 0.25 * p["cfl"] * h / wave


def _relax_steps(scene: Scene, h: float, p: dict[str, Any]) -> int:
    """A relaxation: RELAX_STEPS_PER_CELL steps per spacing of the longest extent, capped by max_steps."""
    return min(p["max_steps"], math.ceil(RELAX_STEPS_PER_CELL * max(scene.box.extent) / h))


def _fracture_steps(scene: Scene, h: float, p: dict[str, Any]) -> int:
    """The loading time to 1.5 times the failure strain, capped by max_steps."""
    eps = 1.5 * failure_strain(scene.elasticity.response, scene.material.youngs_modulus)
    return min(p["max_steps"], math.ceil(eps / scene.elasticity.strain_rate / _wave(scene, h, p)[1]))


def _slide_steps(scene: Scene, h: float, p: dict[str, Any]) -> int:
    """A sliding contact: the preload's relaxation, then the drive's ramp and its whole duration, which nothing
    cuts (a run that would need more than max_steps for them fails before it starts)."""
    wave, dt = _wave(scene, h, p)
    rate = math.pi * wave / (4.0 * float(max(scene.box.extent)))  # Model.relaxation_rate
    t_ramp = p["slide_ramp"] if p["slide_ramp"] is not None else cs.default_slide_ramp(rate)
    return _relax_steps(scene, h, p) + sum(cs.slide_steps(scene.contact, t_ramp, dt))


def _stick_slip_steps(scene: Scene, h: float, p: dict[str, Any]) -> int:
    """Stick-slip: the preload's relaxation, then the spring's whole duration."""
    return ss.steps(scene, h, p, _relax_steps(scene, h, p), _wave(scene, h, p)[1])


def _heating_steps(scene: Scene, h: float, p: dict[str, Any]) -> int:
    """Frictional heating: the sliding run, then the heat's explicit steps to t_end."""
    return _slide_steps(scene, h, p) + _heat_steps(scene, h, p)


def _held_temperature(scene: Scene) -> str:
    return "" if scene.constraints else "steady conduction without any prescribed temperature is singular"


def _held_bar(scene: Scene) -> str:
    if any(isinstance(c, (FaceSupport, FaceClamp)) for c in scene.constraints):
        return ""
    return "an unsupported elastic bar is singular: no FaceSupport or FaceClamp"


HEAT = frozenset({"conduction"})
HEAT_LOADS = frozenset({"heat-source", "heat-source-field", "interface-flux"})
ELASTIC = frozenset({"elasticity"})
CONTACT = frozenset({"elasticity", "contact"})

ANALYSES: tuple[Analysis, ...] = (
    Analysis("steady heat", HEAT, _on_bar(_steady_heat), None, allows=HEAT_LOADS, conduction="steady",
             check=_held_temperature, unknowns=1, stepping="",
             no_stepping="steady mca heat is a direct solve: no time stepping, no stability probe needed"),
    Analysis("transient heat", HEAT, _on_bar(_transient_heat), _heat_steps, allows=HEAT_LOADS, conduction="transient",
             unknowns=1, stepping="heat"),
    Analysis("static elasticity", ELASTIC, _on_bar(_static), _relax_steps, check=_held_bar,
             packings=PACKINGS),
    Analysis("modes", ELASTIC | {"modes"}, _on_bar(_modes), None, check=_held_bar, dense=1500, stepping="",
             no_stepping="bar-modes is an eigenproblem: no time stepping", packings=PACKINGS),
    Analysis("fracture", ELASTIC | {"fracture"}, _on_bar(_fracture), _fracture_steps, check=_held_bar),
    Analysis("contact compression", CONTACT, cs.on_bodies(cs.pressed), _relax_steps, sliding=False, bodies=2),
    Analysis("sliding contact", CONTACT, cs.on_bodies(cs.sliding), _slide_steps, sliding=True, bodies=2),
    Analysis("frictional heating", CONTACT | {"conduction", "frictional-heating"}, cs.on_bodies(cs.heating),
             _heating_steps, allows=frozenset({"interface-flux"}), conduction="transient", sliding=True, bodies=2),
    Analysis("stick-slip", CONTACT | {"stick-slip"}, ss.run, _stick_slip_steps, sliding=True, bodies=2),
    Analysis("incline", CONTACT | {"incline"}, inc.run, _stick_slip_steps, sliding=False, bodies=2),
)


def analysis_of(scene: Scene) -> tuple[Analysis | None, str]:
    """The entry of ANALYSES that runs `scene` and "", or None and why none does: the entry's check, or the
    mismatch of the entries closest to the scene (those needing most of its physics, the ones that agree on its
    parts first)."""
    kind = SceneKind.of(scene)
    hits = [a for a in ANALYSES if a.matches(kind)]
    if len(hits) == 1:
        why = hits[0].check(scene)
        return (None, why) if why else (hits[0], "")
    if hits:
        raise RuntimeError(f"mca: the analyses {[a.name for a in hits]} all match physics {sorted(kind.physics)}")
    near = [a for a in ANALYSES if a.needs <= kind.physics]
    if not near:
        return None, f"mca does conduction and elasticity; scene needs {sorted(kind.physics)}"
    most = max(len(a.needs) for a in near)
    near = [a for a in near if len(a.needs) == most]
    parts = [a for a in near if a.matches(SceneKind(a.needs, kind.conduction, kind.sliding))]
    return None, "; ".join(dict.fromkeys(a.mismatch(kind) for a in parts or near))
