"""The lammps-bpm solver: LAMMPS's bonded particle model (bond_style bpm/spring) on the bar lattice, driven
in-process, for static compression, eigenfrequencies and tensile fracture.

The lattice and its stiffness: lattice.py.  work.kernel_s is the wall time of LAMMPS's own commands (minimize,
dynamical_matrix and the eigensolve, run), which the harness turns into the CPU share of the solve;
work.lammps_cpu_s is LAMMPS's CPU time itself.  Summary keys are the MCA's (E_eff, nu_eff, reaction_force,
f_<kind>_hz, failure_stress, ...), so the harness compares the two particle models alike.  A LAMMPS error is a
failed solve whose reason is LAMMPS's own error line.
"""

from __future__ import annotations

import math
import os
import time
from pathlib import Path
from typing import Any

import numpy as np
import scipy.linalg as sla

from pcverify.scene import FaceClamp, FaceSupport, Resolution, Scene, SceneError
from pcverify.solvers.modes import classify, cut_is_complete, kind_summary, symmetric_lateral
from pcverify.solvers.protocol import Solution, WorkEstimate, effective_params, read_notes

from .driver import Bpm, LammpsError
from .lattice import Lattice, bar_lattice, gershgorin_omega
from .loader import load_lammps
from .parameters import PARAMETERS

NOTES_FILE = Path(__file__).with_name("model_notes.txt")
LATTICE_NU = 0.25  # Poisson's ratio of any isotropic central-spring cubic lattice (the Cauchy relation)
DENSE_LIMIT = 3000  # free dofs up to which the eigenproblem is solved densely
HISTORY_ROWS = 2000  # fracture: history rows kept in the diagnostics
QUANTITY = {"static": "u (m)", "modes": "frequencies (Hz)", "fracture": "u (m)"}

_cls, WHY_UNAVAILABLE = load_lammps()
if _cls is None:  # the registry reports this as SolverUnavailable, with the reason
    raise ImportError(f"lammps-bpm needs LAMMPS: {WHY_UNAVAILABLE}")


def analysis_of(scene: Scene) -> tuple[str | None, str]:
    """("static" | "modes" | "fracture", "") or (None, why this solver declines the scene)."""
    phys = set(scene.physics)
    if "elasticity" not in phys or phys - {"elasticity", "modes", "fracture"}:
        return None, f"lammps-bpm does elasticity of the bar only; scene needs {sorted(phys)}"
    if not any(isinstance(c, (FaceSupport, FaceClamp)) for c in scene.constraints):
        return None, "an unsupported elastic bar is singular: no FaceSupport or FaceClamp"
    if "fracture" in phys:
        resp = scene.elasticity.response
        if resp is None or resp.kind != "elastic":
            return None, ("lammps-bpm breaks elastic springs only; response="
                          f"{getattr(resp, 'kind', None)} needs a plastic or degrading bond law")
        return "fracture", ""
    return ("modes", "") if "modes" in phys else ("static", "")


class LammpsBpm:
    """LAMMPS bpm/spring lattice (axis and face-diagonal central springs, k = 2 E a / 5): nu = 1/4 by the
    Cauchy relation."""

    name = "lammps-bpm"
    kind = "particle"
    parameters = PARAMETERS

    @property
    def notes(self) -> tuple[str, ...]:
        """The model notes (model_notes.txt beside this module)."""
        return read_notes(NOTES_FILE)

    def supports(self, scene: Scene) -> tuple[bool, str]:
        what, why = analysis_of(scene)
        return what is not None, why

    def estimate(self, scene: Scene, resolution: Resolution, **params: Any) -> WorkEstimate:
        p = effective_params(self, params)
        what, why = analysis_of(scene)
        if what is None:
            raise SceneError(why)
        a = float(scene.box.extent[0]) / (resolution.n - 1)
        nodes = int(np.prod([round(float(e) / a) + 1 for e in scene.box.extent]))
        steps = 1
        if what == "fracture":
            wave = math.sqrt(scene.material.youngs_modulus / scene.material.density)
            dt = p["cfl"] * 0.25 * a / wave  # below the Gershgorin step of the network (about 0.3 a / c)
            steps = math.ceil(1.5 * _strength(scene) / scene.material.youngs_modulus
                              / scene.elasticity.strain_rate / dt)
        dense = (3 * nodes) ** 2 * 8 * 3 if what == "modes" else 0
        return WorkEstimate(unknowns=3 * nodes, steps=steps, bytes=dense + 2000 * nodes)

    def solve(self, scene: Scene, resolution: Resolution, samples: dict[str, np.ndarray] | None = None,
              **params: Any) -> Solution:
        p = effective_params(self, params)
        what, why = analysis_of(scene)
        if what is None:
            raise SceneError(why)
        if resolution.n < 2:
            raise SceneError(f"n={resolution.n} is out of range; allowed: integer >= 2")
        t_wall = time.perf_counter()
        mat = scene.material
        lat = bar_lattice(scene.box.extent, resolution.n, mat.youngs_modulus, mat.density)
        res = {"n": resolution.n, "refine": 1, "h": lat.spacing, "nodes": lat.size}
        run = {"static": _static, "modes": _modes, "fracture": _fracture}[what]
        try:
            out = run(scene, lat, p)
        except LammpsError as err:
            return Solution(scene=scene.name, solver=self.name, params=p, resolution=res, samples={},
                            unknowns=3 * lat.size, wall_s=time.perf_counter() - t_wall, status="failed",
                            reason=str(err), quantity=QUANTITY[what])
        field = out.pop("field")
        pts = scene.sample_sets(resolution.n) if samples is None else samples
        values = {} if field is None else {k: {"points": np.asarray(v, float), "values": field[_node_at(lat, v)]}
                                           for k, v in pts.items()}
        out["summary"]["kernel_s"] = out["work"]["kernel_s"]
        return Solution(scene=scene.name, solver=self.name, params=p, resolution=res, samples=values,
                        unknowns=out["work"]["unknowns"], wall_s=time.perf_counter() - t_wall,
                        status=out.get("status", "ok"), reason=out.get("reason", ""), quantity=QUANTITY[what],
                        work=out["work"], summary=out["summary"], diagnostics=out.get("diagnostics", {}))


def _node_at(lat: Lattice, points: np.ndarray) -> np.ndarray:
    """The node nearest each sample point (the samples sit on lattice nodes)."""
    idx = np.rint(np.asarray(points, float) / lat.spacing).astype(int)
    idx = np.clip(idx, 0, np.array(lat.shape) - 1)
    return (idx[:, 0] * lat.shape[1] + idx[:, 1]) * lat.shape[2] + idx[:, 2]


def _strength(scene: Scene) -> float:
    """Uniaxial tensile strength sigma_c / k of the scene's response."""
    resp = scene.elasticity.response
    return resp.sigma_c / resp.k


def _rigid_set(scene: Scene, lat: Lattice) -> list[tuple[np.ndarray, str]]:
    """(nodes, "x y z" setforce arguments) of each constraint, and the rigid-body set of a bar held on its z
    faces only (u_x = u_y = 0 at (0, 0, 0), u_y = 0 at (W, 0, 0)), as the MCA's nodes packing."""
    ext = scene.box.extent
    out: list[tuple[np.ndarray, str]] = []
    clamped = False
    supported = set()
    for c in scene.constraints:
        if isinstance(c, FaceClamp):
            out.append((lat.on_face(c.face, ext), "0.0 0.0 0.0"))
            clamped = True
        elif isinstance(c, FaceSupport):
            ax = "xyz".index(c.face[0])
            out.append((lat.on_face(c.face, ext), " ".join("0.0" if d == ax else "NULL" for d in range(3))))
            supported.add(ax)
        else:
            raise SceneError(f"lammps-bpm: constraint {type(c).__name__} is not supported")
    if not clamped and supported == {2}:
        z0 = lat.on_face("z0", ext)
        p = lat.positions[z0]
        tol = 1e-9 * float(ext[0])
        origin = z0[np.all(np.abs(p[:, :2]) <= tol, axis=1)]
        far = z0[(np.abs(p[:, 0] - ext[0]) <= tol) & (np.abs(p[:, 1]) <= tol)]
        out += [(origin, "0.0 0.0 NULL"), (far, "NULL 0.0 NULL")]
    elif not clamped and supported != {0, 1, 2}:
        raise SceneError("lammps-bpm: supports that leave rigid motion free are implemented for z faces only")
    return out


def _hold(bpm: Bpm, scene: Scene, lat: Lattice) -> list[str]:
    """Groups (zL, z0, held<k>) and the setforce fixes of the constraints, to be defined after the fix
    "hold_zL" that reads the reaction on face zL (setforce sums the force before it zeroes it)."""
    lines = []
    for k, (nodes, args) in enumerate(_rigid_set(scene, lat)):
        bpm.group(f"held{k}", nodes)
        lines.append(f"fix held{k} held{k} setforce {args}")
    bpm.group("zL", lat.on_face("zL", scene.box.extent))
    bpm.group("z0", lat.on_face("z0", scene.box.extent))
    return lines


def _face_strain(lat: Lattice, u: np.ndarray, ax: int, ext: np.ndarray) -> float:
    lo = lat.on_face("xyz"[ax] + "0", ext)
    hi = lat.on_face("xyz"[ax] + "L", ext)
    return float((u[hi, ax].mean() - u[lo, ax].mean()) / ext[ax])


def _static(scene: Scene, lat: Lattice, p: dict[str, Any]) -> dict[str, Any]:
    """The faces displaced at once, then LAMMPS's minimize (FIRE: CG's energy line search stalls on round-off at
    small strains) to the equilibrium."""
    ext = scene.box.extent
    disp = {c.face: c.displacement for c in scene.constraints if isinstance(c, FaceSupport)}
    strain = max((abs(d) for d in disp.values()), default=1e-3) / scene.box.length
    ftol = p["ftol"] * scene.material.youngs_modulus * max(strain, 1e-12) * lat.spacing**2
    with Bpm(lat) as bpm:
        holds = _hold(bpm, scene, lat)
        bpm.commands(["run 0 post no"])  # the bonds store their rest lengths at the first setup
        for face, d in disp.items():
            ax = "xyz".index(face[0])
            bpm.group(f"moved_{face}", lat.on_face(face, ext))
            bpm.commands([f"displace_atoms moved_{face} move " + " ".join(f"{d if k == ax else 0.0:.17g}"
                                                                         for k in range(3))])
        bpm.commands(["fix hold_zL zL setforce NULL NULL 0.0", *holds, "min_style fire",
                      f"min_modify integrator verlet dmax {0.01 * lat.spacing:.17g}"])
        its = p["max_iterations"]
        bpm.timed([f"minimize 0.0 {ftol:.17g} {its} {10 * its}"])
        u = bpm.positions() - lat.positions
        react = -bpm.fix_vector("hold_zL", 2)
        iterations = int(bpm.lmp.extract_global("ntimestep"))
        held = np.zeros((lat.size, 3), bool)
        for nodes, args in _rigid_set(scene, lat):
            held[nodes] |= np.array([a != "NULL" for a in args.split()])
        f = bpm.forces()
        residual = float(np.abs(f[~held]).max(initial=0.0))
        version = bpm.version
        cpu, wall = bpm.cpu_s, bpm.wall_s
    summary: dict[str, Any] = {"reaction_force": react, "residual": residual, "iterations": iterations,
                               "lammps_version": version}
    if "zL" in disp and "z0" in disp:
        axial = _face_strain(lat, u, 2, ext)
        lateral = 0.5 * (_face_strain(lat, u, 0, ext) + _face_strain(lat, u, 1, ext))
        area = scene.box.width * scene.box.height
        summary.update(axial_strain=axial, lateral_strain=lateral, E_eff=react / area / axial,
                       nu_eff=-lateral / axial)
    status, reason = "ok", ""
    if residual > ftol:
        status, reason = "non-stationary", (f"minimize stopped at a residual force {residual:.3g} N above ftol "
                                            f"{ftol:.3g} N after {iterations} iterations; raise max_iterations")
    work = {"unknowns": int(np.count_nonzero(~held)), "iterations": iterations, "kernel_s": wall,
            "lammps_cpu_s": cpu, "lammps_wall_s": wall}
    return {"field": u, "summary": summary, "work": work, "status": status, "reason": reason}


def _modes(scene: Scene, lat: Lattice, p: dict[str, Any]) -> dict[str, Any]:
    """LAMMPS's dynamical_matrix (finite differences of its bond forces, mass-weighted) on the free nodes, then
    a dense symmetric eigensolve; modes classified by the shared classifier (solvers/modes.py)."""
    held = np.zeros((lat.size, 3), bool)
    for nodes, args in _rigid_set(scene, lat):
        held[nodes] |= np.array([a != "NULL" for a in args.split()])
    if held.any(axis=1).sum() != held.all(axis=1).sum():
        raise SceneError("lammps-bpm modes: partly held nodes are not supported; allowed: FaceClamp")
    free_nodes = np.flatnonzero(~held.any(axis=1))
    nf = 3 * free_nodes.size
    if nf > DENSE_LIMIT:
        raise SceneError(f"lammps-bpm modes: {nf} free dofs exceed the dense limit {DENSE_LIMIT}; allowed: a "
                         "smaller n")
    count = int(scene.elasticity.modes)
    with Bpm(lat) as bpm:
        bpm.group("free", free_nodes)
        path = os.path.join(bpm._tmp.name, "dynmat.dat")
        bpm.commands(["run 0 post no"])
        bpm.timed([f"dynamical_matrix free regular {p['fd_delta'] * lat.spacing:.17g} file {path}"])
        dyn = np.loadtxt(path).reshape(nf, nf)
        cpu, wall, version = bpm.cpu_s, bpm.wall_s, bpm.version
    t0 = time.perf_counter()
    dyn = 0.5 * (dyn + dyn.T)
    if count >= nf - 1:
        raise SceneError(f"modes={count} is out of range; allowed: integer in [1, {nf - 2}] at this resolution")
    want = count + 2
    while True:  # the lowest modes, widened until the degenerate cluster at the cut is complete
        vals, vecs = sla.eigh(dyn, subset_by_index=[0, min(nf, want) - 1])
        if want >= nf or cut_is_complete(vals, count):
            break
        want *= 2
    keep = vals.size
    m_free = np.repeat(lat.mass[free_nodes], 3)
    full = np.zeros((3 * lat.size, keep))
    dofs = (3 * free_nodes[:, None] + np.arange(3)).ravel()
    full[dofs] = vecs / np.sqrt(m_free)[:, None]  # mass-weighted eigenvectors back to displacements
    mass = np.repeat(lat.mass, 3)
    cls = classify(full, vals, mass, lat.positions, scene.box.extent, lat.spacing,
                   order=(1.0, 0.0), energy=(symmetric_lateral,)).first(count)
    freqs = np.sqrt(np.clip(vals[:count], 0.0, None)) / (2 * np.pi)
    summary: dict[str, Any] = {"frequencies_hz": freqs, "mode_kinds": cls.kinds, "lammps_version": version}
    summary.update(kind_summary(cls.kinds, freqs))
    eig_s = time.perf_counter() - t0
    work = {"unknowns": nf, "kernel_s": wall + eig_s, "lammps_cpu_s": cpu, "lammps_wall_s": wall,
            "eigensolve_s": eig_s}
    return {"field": None, "summary": summary, "work": work}


def breaking_strains(lat: Lattice, scene: Scene, scale: str) -> np.ndarray:
    """Breaking strain of each spring: sigma_t / E for the axis springs, that times the diagonals' share of the
    axial strain in uniaxial tension along an axis for the face diagonals spanning that axis ((1 - nu)/2 with
    nu = 1/4 of this lattice, "lattice"; with the scene's nu, "material"; 1, "equal").  Calibrated on one load
    path: uniaxial tension along a lattice axis."""
    eps = _strength(scene) / scene.material.youngs_modulus
    nu = {"lattice": LATTICE_NU, "material": scene.material.poisson_ratio, "equal": -1.0}[scale]
    return np.where(lat.family == 0, eps, eps * (1.0 - nu) / 2.0)


def _fracture(scene: Scene, lat: Lattice, p: dict[str, Any]) -> dict[str, Any]:
    """Face z0 on supports, face zL pulled at the strain rate (velocity held, force zeroed), fix nve, no
    damping; the reaction on zL recorded every step by LAMMPS (fix ave/time to a file)."""
    length = scene.box.length
    area = scene.box.width * scene.box.height
    speed = scene.elasticity.strain_rate * length
    strength = _strength(scene)
    eps_fail = strength / scene.material.youngs_modulus
    dt = p["cfl"] * 2.0 / gershgorin_omega(lat)
    steps = math.ceil(1.5 * eps_fail / scene.elasticity.strain_rate / dt)
    eps_c = breaking_strains(lat, scene, p["diagonal_break"])
    with Bpm(lat, eps_c) as bpm:
        holds = _hold(bpm, scene, lat)
        hist = os.path.join(bpm._tmp.name, "reaction.txt")
        bpm.commands(["fix hold_zL zL setforce NULL NULL 0.0", *holds, f"velocity zL set NULL NULL {speed:.17g}",
                      "fix move all nve", f"timestep {dt:.17g}",
                      "variable react equal -f_hold_zL[3]", "variable uz equal step*dt*" + f"{speed:.17g}",
                      f"fix rec all ave/time 1 1 1 v_uz v_react file {hist} format \" %.17g\"", "thermo 0"])
        bpm.timed([f"run {steps}"])
        bpm.commands(["unfix rec"])
        left = bpm.bonds_left()
        cpu, wall, version = bpm.cpu_s, bpm.wall_s, bpm.version
        h = np.loadtxt(hist, ndmin=2)
        u = bpm.positions() - lat.positions
    uz, react = h[:, 1], h[:, 2]
    top = int(np.argmax(react))
    summary: dict[str, Any] = {"dt": dt, "steps": steps, "failure_stress": float(react[top] / area),
                               "failure_strain": float(uz[top] / length), "reaction_force": float(react[top]),
                               "peak_step": top, "strength_expected": strength,
                               "linked_fraction": left / lat.i.size, "unlink_events": int(lat.i.size - left),
                               "lammps_version": version}
    stress = react / area
    rise = (stress > 0.1 * stress[top]) & (stress < 0.6 * stress[top]) & (np.arange(stress.size) < top)
    if np.count_nonzero(rise) >= 4:
        summary["E_eff"] = float(np.polyfit(uz[rise] / length, stress[rise], 1)[0])
    status, reason = "ok", ""
    if left == lat.i.size:
        status, reason = "failed", f"no bond broke up to strain {1.5 * eps_fail:.3g}"
    elif top < 50:
        status, reason = "failed", f"the peak stress came after {top} steps (fewer than 50): lower strain_rate"
    work = {"unknowns": 3 * lat.size, "time_steps": steps, "pair_steps": steps * int(lat.i.size),
            "kernel_s": wall, "lammps_cpu_s": cpu, "lammps_wall_s": wall}
    thin = max(1, h.shape[0] // HISTORY_ROWS)  # the peak above is read from every step
    diag = {"history": {"columns": ["u_z (m)", "reaction (N)"], "rows": h[::thin, 1:]}}
    return {"field": u, "summary": summary, "work": work, "status": status, "reason": reason,
            "diagnostics": diag}
