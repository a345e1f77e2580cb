"""The macromolecule solver (Arinchev): heat conduction as forced vibration of a particle lattice.

Pieces (LAMMPS split): `lattice` (nodes, masses, fixed pair list), `seven_root` (pair style),
`integrate` (fixes: frozen, kinematic drive, Langevin/absorbing faces; velocity-Verlet kernel;
computes: hotness, energy balance, hops, neighbourhood), `modal` (Hessian, frequencies, damping
ratio).  This module is the glue: it maps a scene's constraints to fixes, sets A from f_top and
delta from a damping ratio, picks dt, runs, and turns sums into a Solution.

Conventions:
- hotness H_j = (1/(t_end - t_start)) int KE_j dt; samples are H_j / max over FREE particles;
  the second normalisation (by the driven particle) is in the summary as *_by_driven.
- the red pair: m at the hot corner, q one spacing below; (r_m - r_q).e_y = a + D a sin(2 pi f t)
  with D = drive_amplitude in units of a.  drive_sharing "free-centre" (default): the relative
  motion is prescribed, the pair's centre of mass moves freely under the forces on the pair, so
  m takes m_q/(m_m + m_q) of the stroke and q the rest (1/2 each for single particles);
  "symmetric": the same split, centre held at rest (both fully prescribed).
  In bar-heat-patch the m side is every particle inside the hot patch sphere (moving rigidly),
  the q side the particle below the corner; frozen = every particle inside a frozen sphere.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pcverify.harness.scene import FaceTemperature, Param, PointTemperature, Resolution, Scene, SceneError
from pcverify.solvers.protocol import Solution, effective_params, heat_summary

from . import kernel_fast as fk
from . import kernel_reference as ig
from .force import SevenRoot
from .lattice import Lattice, build_lattice
from .modal import (
    damped_top_mode,
    damping_matrix,
    delta_for_damping_ratio,
    discrete_stability_limit,
    free_dofs,
    hessian,
    modal_basis,
)

DEFAULT_DAMPING_RATIO = 0.01
N_HISTORY = 400

PARAMETERS: tuple[Param, ...] = (
    Param("f_top", 50.0, "Hz", "target highest natural frequency of the held lattice; sets A", low=0.0, high=1e5,
          low_open=True),
    Param("stiffness", None, "N", "force scale A (overrides f_top)", low=0.0, high=1e12, low_open=True, optional=True),
    Param("p", 2.0, "", "envelope exponent of (a/r)^p", low=0.0, high=12.0),
    Param("s", 0.9, "", "STEP start 2 s a (STEP ends at 2a)", low=0.5, high=0.99),
    Param("unstable_fraction", 0.5, "", "position of each unstable root inside its gap (0.5: midpoint)",
          low=0.05, high=0.95),
    Param("delta", None, "N s/m", "radial pair damping (the paper's parameter); excludes damping_ratio", low=0.0,
          high=1e6, optional=True),
    Param("damping_ratio", None, "", f"damping ratio of the top mode (damped modal problem); default "
          f"{DEFAULT_DAMPING_RATIO} when delta is not given", low=0.0, high=0.5, optional=True),
    Param("drive_amplitude", 0.05, "a", "D: stroke of the red pair (or face drive amplitude)", low=0.0, high=0.1,
          low_open=True),
    Param("drive_frequency", 50.0, "Hz", "f of the drive", low=0.0, high=1e5, low_open=True),
    Param("drive_sharing", "free-centre", "", "how the red pair's stroke is shared", choices=("free-centre",
          "symmetric"), kind=str),
    Param("t_end", 15.0, "s", "end of the run and of the averaging window", low=0.0, high=1e5, low_open=True),
    Param("t_start", 0.0, "s", "start of the averaging window", low=0.0, high=1e5),
    Param("safety", 0.05, "", "dt = safety * 2 / omega_max; default 0.05, not 0.1: at 0.1 the driven lattice's "
          "energy balance misses 1e-3 from n = 4 on (2.0-3.1e-3, velocity Verlet's dt^2 error on the anharmonic "
          "force; integrate.py), at 0.05 it closes to <= 8e-4 for n = 2..11", low=0.0, high=1.0, low_open=True),
    Param("dt", None, "s", "time step (overrides safety; must be below the stability limit)", low=0.0, high=1.0,
          low_open=True, optional=True),
    Param("pairs_at_2a", "keep", "", "keep or drop the pairs resting at exactly 2a", choices=("keep", "drop"),
          kind=str),
    Param("face_drive_direction", "y", "", "bar-heat-faces, hot_face=driven: direction of the face drive (z: "
          "normal to the face, longitudinal)", choices=("x", "y", "z"), kind=str),
    Param("kernel", "fast", "", "time-stepping kernel: fast (kernel.py), fastmath (its pair loop with FMA and "
          "approximate reciprocals) or the plain reference (integrate.py); the same scheme, equal to rounding",
          choices=("fast", "fastmath", "reference"), kind=str),
    Param("hot_face", "langevin", "", "bar-heat-faces: z=0 face thermostatted or kinematically driven",
          choices=("langevin", "driven"), kind=str),
    Param("far_face", "absorbing", "", "bar-heat-faces: z=L face viscous (0 K bath) or frozen",
          choices=("absorbing", "frozen"), kind=str),
    Param("face_gamma", None, "1/s", "bath friction rate of the faces (default omega_max / 2)", low=0.0, high=1e9,
          low_open=True, optional=True),
    Param("seed", 0, "", "seed of face phases and Langevin noise", low=0, high=2**31 - 1, kind=int),
    Param("stationarity_tol", 0.1, "", "non-stationary if the hotness of a free particle changes by more than this "
          "(relative to the hottest free one) between the halves of the window", low=0.0, high=10.0, low_open=True),
    Param("blowup_factor", 10.0, "", "unstable if the kinetic energy exceeds this times the energy supplied",
          low=1.0, high=1e12),
    Param("contact_fraction", 0.5, "a", "unlisted particles closer than this break the pair list", low=0.0, high=1.0,
          low_open=True),
    Param("max_steps", 20_000_000, "", "largest number of time steps a run may take (t_end / dt)", low=1, high=1e10,
          kind=int),
    Param("dt_check", False, "", "rerun at dt/2 and report the change in relative hotness", kind=bool),
)


@dataclass
class Fixes:
    """Per-particle fixes (integrate.FREE/FROZEN/PRESCRIBED/GROUP) and the bath arrays."""

    kind: np.ndarray
    amp: np.ndarray
    phase: np.ndarray
    gamma: np.ndarray
    kt: np.ndarray
    free_centre: bool = False
    hot: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))  # hot reference particles
    notes: str = ""

    @property
    def held(self) -> np.ndarray:
        """Particles held in the modal problem (frozen or driven)."""
        return self.kind != ig.FREE


def make_fixes(scene: Scene, lat: Lattice, p: dict[str, Any], omega_top: float | None = None) -> Fixes:
    """Map the scene's temperature constraints to fixes on the lattice."""
    N = lat.size
    kind = np.zeros(N, dtype=np.int64)
    amp = np.zeros((N, 3))
    phase = np.zeros(N)
    gamma = np.zeros(N)
    kt = np.zeros(N)
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
                    kind[idx] = ig.PRESCRIBED
                    amp[idx, "xyz".index(p["face_drive_direction"])] = stroke
                    phase[idx] = np.random.default_rng(p["seed"]).uniform(0, 2 * np.pi, len(idx))
                else:
                    w = 2 * np.pi * p["drive_frequency"]
                    ke = 0.25 * lat.mass * (w * stroke) ** 2  # time-mean KE of the same drive
                    gamma[idx] = p["face_gamma"] or 0.5 * omega_top
                    kt[idx] = 2.0 / 3.0 * ke
            elif p["far_face"] == "frozen":
                kind[idx] = ig.FROZEN
            else:
                gamma[idx] = p["face_gamma"] or 0.5 * omega_top
            continue
        if isinstance(con, PointTemperature):
            centre, members = np.array(con.point), lat.node_at(np.array(con.point))
        else:
            centre = np.array(con.centre)
            members = np.union1d(lat.within(centre, con.radius), lat.node_at(centre))
        if not hot:
            kind[members] = ig.FROZEN
            continue
        m = int(lat.node_at(centre)[0])
        below = lat.positions[m] - np.array([0.0, lat.a, 0.0])
        sign = 1.0
        if below[1] < -1e-9 * lat.a:
            below, sign = lat.positions[m] + np.array([0.0, lat.a, 0.0]), -1.0
        q = int(lat.node_at(below)[0])
        side_m = np.setdiff1d(members, [q])
        mm, mq = lat.mass * len(side_m), lat.mass
        kind[side_m] = ig.GROUP if p["drive_sharing"] == "free-centre" else ig.PRESCRIBED
        kind[q] = kind[m]
        amp[side_m, 1] = sign * stroke * mq / (mm + mq)
        amp[q, 1] = -sign * stroke * mm / (mm + mq)
        fx.free_centre = p["drive_sharing"] == "free-centre"
        hot_sets.append(np.array([m]))
    fx.hot = np.concatenate(hot_sets) if hot_sets else np.zeros(0, dtype=np.int64)
    return fx


@dataclass
class RunResult:
    """Raw kernel output plus the derived per-particle hotness."""

    hot: np.ndarray  # (3, N) mean KE over window, first half, second half (J)
    energy: np.ndarray
    counters: np.ndarray
    history: np.ndarray
    ever: np.ndarray
    x: np.ndarray
    wall_s: float
    steps: int
    cpu_s: float = math.nan  # CPU seconds of this process inside the kernel (robust on a shared machine)

    @property
    def status_code(self) -> int:
        return int(self.counters[ig.K_STATUS])


def simulate(lat: Lattice, model: SevenRoot, fx: Fixes, delta: float, dt: float, t_end: float, t_start: float = 0.0,
             omega: float = 0.0, v0: np.ndarray | None = None, seed: int = 0, blowup_factor: float = 10.0,
             contact_fraction: float = 0.5, check_every: int | None = None, kernel: str = "fast") -> RunResult:
    """Run the kernel from rest (or from velocities v0) and return averaged hotness and diagnostics.

    kernel "fast" (`kernel.run`, the default), "fastmath" (the same with its pair loop compiled with
    `kernel.FASTMATH`) or "reference" (`integrate.run`, the plain one): the same scheme, equal to
    rounding."""
    N = lat.size
    n_steps = int(round(t_end / dt))
    n_start = min(int(round(t_start / dt)), n_steps)
    basins = model.basins()
    lo = np.ascontiguousarray(basins[lat.shell, 0])
    hi = np.ascontiguousarray(basins[lat.shell, 1])
    x = lat.positions + fx.amp * np.sin(fx.phase)[:, None]
    v = np.zeros((N, 3)) if v0 is None else np.array(v0, dtype=float)
    v[fx.kind != ig.FREE] = 0.0
    hot = np.zeros((3, N))
    energy = np.zeros(8)
    counters = np.zeros(9, dtype=np.int64)
    history = np.full((N_HISTORY + 2, 6), np.nan)
    ever = np.zeros(len(lat.pairs), dtype=np.int8)
    check = check_every or max(1, n_steps // N_HISTORY)
    ext = lat.positions.max(axis=0)
    cutoff = lat.r0.max() * (1 + 1e-9)
    unlisted = 2.0 * lat.a * (1 + 1e-6) if cutoff < 1.999 * lat.a else math.sqrt(5.0) * lat.a
    skin = unlisted - contact_fraction * lat.a
    held = fx.kind != ig.FREE
    e_scale = 1.5 * fx.kt.sum() + 0.5 * lat.mass * omega**2 * float((fx.amp[held] ** 2).sum())
    pi, pj = lat.pairs[:, 0].copy(), lat.pairs[:, 1].copy()
    box_lo, box_hi = -lat.a * np.ones(3), ext + lat.a
    if kernel == "reference":
        t0, c0 = time.perf_counter(), time.process_time()
        rows = ig.run(x, v, lat.positions, fx.kind, fx.amp, fx.phase, omega, fx.free_centre, lat.mass, fx.gamma,
                      fx.kt, seed, pi, pj, lat.r0, lo, hi, model.coeffs(), lat.a, delta, dt, n_steps, n_start,
                      n_steps, check, blowup_factor, e_scale, box_lo, box_hi, contact_fraction, cutoff, skin, hot,
                      energy, counters, history, ever)
    elif kernel in ("fast", "fastmath"):
        pint = int(model.p) if float(model.p).is_integer() and 0 <= model.p <= 64 else -1
        g_off, g_base, g_lo, g_hi, mask, slot = fk.stencil(lat.pairs, lat.shell, N, basins)
        t0, c0 = time.perf_counter(), time.process_time()
        rows = fk.run(x, v, lat.positions, fx.kind, fx.amp, fx.phase, omega, fx.free_centre, lat.mass, fx.gamma,
                      fx.kt, seed, pi, pj, g_off, g_base, g_lo, g_hi, mask, slot, pint, lat.a, delta, dt, n_steps,
                      n_start, n_steps, check, blowup_factor, e_scale, box_lo, box_hi, contact_fraction, cutoff, skin,
                      model.coeffs(), lat.r0, hot, energy, counters, history, ever, kernel == "fastmath")
    else:
        raise SceneError(f"kernel={kernel!r} is not allowed; allowed: fast, fastmath, reference")
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    steps = np.maximum(counters[[ig.K_HOT_STEPS, ig.K_HALF1, ig.K_HALF2]], 1) * dt
    return RunResult(hot / steps[:, None], energy, counters, history[:rows], ever, x, wall, int(counters[ig.K_STEPS]),
                     cpu)


def energy_balance_error(r: RunResult) -> float:
    """|E_end - E_start + dissipated - work in| relative to the largest energy flow."""
    e = r.energy
    resid = e[ig.E_END] - e[ig.E_START] + e[ig.E_DISS] - e[ig.E_DRIVE] - e[ig.E_BATH]
    scale = max(abs(e[ig.E_START]), abs(e[ig.E_END]), abs(e[ig.E_DRIVE]), abs(e[ig.E_BATH]), e[ig.E_DISS], 1e-300)
    return float(abs(resid) / scale)


class Macromolecule:
    """Solver "macromolecule": relative hotness of the seven-root particle lattice."""

    name = "macromolecule"
    kind = "particle"
    version = "4"
    parameters = PARAMETERS

    def supports(self, scene: Scene) -> tuple[bool, str]:
        if scene.physics == frozenset({"elasticity", "modes"}):
            return True, ""  # the lattice's eigenfrequencies, scaled to the material (mca_compare)
        if scene.physics != frozenset({"conduction"}):
            return False, (f"macromolecule does conduction (and the modes of its lattice); scene needs "
                           f"{sorted(scene.physics)}")
        if scene.conduction.mode != "steady":
            return False, ("hotness is a time average over a stationary state; the transient of bar-heat-faces "
                           "has no hotness counterpart")
        for c in scene.constraints:
            if 0.0 < c.value < scene.conduction.t_max * (1 - 1e-12):
                return False, f"constraint value {c.value:g} K is neither 0 nor t_max: only hot (driven) and frozen"
        if not any(c.value > 0 for c in scene.constraints):
            return False, "no hot constraint to drive"
        return True, ""

    def setup(self, scene: Scene, n: int, p: dict[str, Any]) -> dict[str, Any]:
        """Lattice, fixes, A, delta and zeta, dt: everything before the run (no integration)."""
        lat = build_lattice(scene.box, n, scene.material.density, p["pairs_at_2a"])
        fx = make_fixes(scene, lat, p, omega_top=1.0)
        dofs = free_dofs(~fx.held)
        K0 = hessian(lat.positions, lat.pairs, SevenRoot(1.0, p["p"], p["s"], p["unstable_fraction"]), lat.a)
        omega0, phi, method = modal_basis(K0, lat.mass, dofs)  # at A = 1; K = A K0 has the same shapes
        w0 = float(omega0[-1])
        A = p["stiffness"] if p["stiffness"] is not None else (2 * np.pi * p["f_top"] / w0) ** 2
        model = SevenRoot(A, p["p"], p["s"], p["unstable_fraction"])
        w_top = w0 * math.sqrt(A)
        fx = make_fixes(scene, lat, p, omega_top=w_top)
        basis = (omega0 * math.sqrt(A), phi, method)
        C1 = damping_matrix(lat.positions, lat.pairs, 1.0)
        if p["delta"] is not None and p["damping_ratio"] is not None:
            raise SceneError("delta and damping_ratio are exclusive; give one (damping_ratio defaults to "
                             f"{DEFAULT_DAMPING_RATIO})")
        if p["delta"] is not None:
            in_force, delta = "delta", p["delta"]
            zeta, _, method = damped_top_mode(basis, C1 * delta, dofs)
        else:
            in_force = "damping_ratio"
            zeta = DEFAULT_DAMPING_RATIO if p["damping_ratio"] is None else p["damping_ratio"]
            delta = delta_for_damping_ratio(basis, C1, dofs, zeta)
            method = basis[2]
        single = 2.0 * (math.sqrt(1 + zeta**2) - zeta) / w_top
        limit = 2.0 * discrete_stability_limit(basis, C1 * delta, dofs) / w_top if delta > 0 else 2.0 / w_top
        dt = p["dt"] if p["dt"] is not None else p["safety"] * 2.0 / w_top
        if dt > limit:
            raise SceneError(f"dt={dt:.6g} s is above the stability limit {limit:.6g} s of the linearised scheme "
                             f"(spectral radius 1; single-mode estimate 2 (sqrt(1+zeta^2) - zeta) / omega_max = "
                             f"{single:.6g} s, omega_max = {w_top:.6g} rad/s, zeta = {zeta:.3g}); allowed: dt <= limit")
        steps = p["t_end"] / dt
        if steps > p["max_steps"]:
            raise SceneError(f"t_end / dt = {p['t_end']:g} s / {dt:.3g} s = {steps:.3g} steps is out of range; "
                             f"allowed: at most max_steps={p['max_steps']}; lower t_end or f_top, or raise max_steps")
        if p["t_start"] >= p["t_end"]:
            raise SceneError(f"t_start={p['t_start']!r} is out of range; allowed: number in [0, "
                             f"t_end={p['t_end']:g}) s")
        return dict(lat=lat, fx=fx, model=model, A=A, f_top=w_top / (2 * np.pi), delta=delta, zeta=zeta,
                    zeta_method=method, in_force=in_force, dt=dt, dt_limit=limit, dt_limit_single_mode=single,
                    zeta_rough=delta / (2 * lat.mass * w_top))

    def solve(self, scene: Scene, resolution: Resolution, samples: dict[str, np.ndarray] | None = None,
              **params: Any) -> Solution:
        t_wall = time.perf_counter()
        p = effective_params(self, params)
        if resolution.refine != 1:
            raise SceneError(f"refine={resolution.refine!r} is out of range; allowed: 1 (the particles are the nodes)")
        ok, why = self.supports(scene)
        if not ok:
            raise SceneError(f"macromolecule cannot solve {scene.name}: {why}")
        n = resolution.n
        if "modes" in scene.physics:
            return self._modes(scene, n, p, t_wall)
        s = self.setup(scene, n, p)
        lat, fx = s["lat"], s["fx"]
        w_drive = 2 * np.pi * p["drive_frequency"]
        run = simulate(lat, s["model"], fx, s["delta"], s["dt"], p["t_end"], p["t_start"], w_drive, seed=p["seed"],
                       blowup_factor=p["blowup_factor"], contact_fraction=p["contact_fraction"], kernel=p["kernel"])
        H = run.hot[0]
        free = (fx.kind == ig.FREE) & (fx.gamma == 0.0)  # bath particles are held, not free
        rel = H / H[free].max() if H[free].max() > 0 else np.full_like(H, np.nan)
        h_drv = H[fx.hot].mean() if len(fx.hot) else np.nan
        rel_drv = H / h_drv if h_drv > 0 else np.full_like(H, np.nan)
        status, reason, flags = self._status(run, H, free, p)
        rel_raw = rel
        rel = self._constrained_values(rel, fx)
        summary: dict[str, Any] = heat_summary(rel, float(rel.mean()))
        summary.update(
            bulk_median_by_driven=float(np.median(rel_drv)), volume_mean_by_driven=float(rel_drv.mean()),
            driven_over_hottest_free=float(h_drv / H[free].max()) if H[free].max() > 0 else math.nan,
            hottest_free_index=int(np.flatnonzero(free)[np.argmax(H[free])]),
            f_top_hz=s["f_top"], stiffness_A=s["A"], dt=s["dt"], dt_limit=s["dt_limit"],
            dt_limit_single_mode=s["dt_limit_single_mode"], steps=run.steps, kernel_s=run.wall_s,
            kernel_cpu_s=run.cpu_s,
            pairs=len(lat.pairs), pair_steps=len(lat.pairs) * run.steps, particles=lat.size,
            damping_in_force=s["in_force"], delta=s["delta"], damping_ratio=s["zeta"],
            damping_ratio_method=s["zeta_method"], damping_ratio_rough=s["zeta_rough"],
            energy_balance_error=energy_balance_error(run), mean_kinetic_energy=float(H.sum()),
            status=status, **flags,
        )
        diagnostics: dict[str, Any] = {
            "energy": {k: float(run.energy[i]) for k, i in (("start", ig.E_START), ("end", ig.E_END),
                       ("dissipated", ig.E_DISS), ("drive_work", ig.E_DRIVE), ("bath_work", ig.E_BATH))},
            "history": {"columns": ["t", "kinetic", "potential", "dissipated", "drive_work", "bath_work"],
                        "rows": run.history},
            "hopped_pairs_by_shell": np.bincount(lat.shell[run.ever == 1], minlength=4),
            "hotness_first_half": run.hot[1], "hotness_second_half": run.hot[2],
            "kernel_wall_s": run.wall_s,
            "hotness": H, "relative_hotness_raw": rel_raw,
        }
        if {c.face for c in scene.constraints if isinstance(c, FaceTemperature)} == {"z0", "zL"}:
            # held faces at both ends: the layer profile along z against Fourier's linear law
            summary.update(self._faces(lat, H, fx, diagnostics))
        if p["dt_check"]:
            fine = simulate(lat, s["model"], fx, s["delta"], s["dt"] / 2, p["t_end"], p["t_start"], w_drive,
                            seed=p["seed"], blowup_factor=p["blowup_factor"], contact_fraction=p["contact_fraction"],
                            kernel=p["kernel"])
            Hf = fine.hot[0]
            relf = Hf / Hf[free].max()
            summary["dt_sensitivity"] = float(np.max(np.abs(relf - rel)[free]))
            summary["dt_sensitivity_bulk_median"] = float(np.median(relf) - np.median(rel))
        nodes = scene.sample_sets(n) if samples is None else samples
        out = {k: {"points": np.asarray(v, float), "values": rel[lat.node_at(v)]} for k, v in nodes.items()}
        work = {"pair_steps": len(lat.pairs) * run.steps, "time_steps": run.steps, "unknowns": 3 * lat.size}
        if p["dt_check"]:
            work["pair_steps"] += len(lat.pairs) * 2 * run.steps
            work["time_steps"] += 2 * run.steps
        return Solution(scene=scene.name, solver=self.name, params=p, resolution={"n": n, "refine": 1}, samples=out,
                        unknowns=3 * lat.size, wall_s=time.perf_counter() - t_wall, status=status, reason=reason,
                        quantity="relative hotness H/H_max (hottest free particle)", work=work, summary=summary,
                        diagnostics=diagnostics)

    def _modes(self, scene: Scene, n: int, p: dict[str, Any], t_wall: float) -> Solution:
        """Eigenfrequencies of the seven-root lattice (shape p, s, unstable_fraction as given) clamped at z = 0,
        its stiffness scaled so that its uniaxial Young's modulus is the material's (mca_compare)."""
        from .elastic_modes import macromolecule_modes

        t0 = time.perf_counter()
        mat = scene.material
        m = macromolecule_modes(scene.box, n, mat.youngs_modulus, mat.density, scene.elasticity.modes,
                                model=SevenRoot(1.0, p["p"], p["s"], p["unstable_fraction"]))
        kernel = time.perf_counter() - t0
        return Solution(scene=scene.name, solver=self.name, params=p, resolution={"n": n, "refine": 1},
                        samples={}, unknowns=3 * int(m["particles"]), wall_s=time.perf_counter() - t_wall,
                        quantity="frequency (Hz)",
                        summary={"frequencies_hz": m["frequencies_hz"], "nu_eff": m["nu_eff"],
                                 "stiffness_A": m["A"], "kernel_s": kernel},
                        work={"unknowns": 3 * int(m["particles"]), "kernel_s": kernel})

    @staticmethod
    def _constrained_values(rel: np.ndarray, fx: Fixes) -> np.ndarray:
        """Held particles report their constraint value, like constrained nodes of a continuum solve:
        frozen and 0 K baths 0, driven and hot baths 1 (their own hotness stays in the diagnostics)."""
        out = rel.copy()
        out[fx.kind == ig.FROZEN] = 0.0
        out[(fx.kind == ig.PRESCRIBED) | (fx.kind == ig.GROUP)] = 1.0
        out[(fx.gamma > 0) & (fx.kt > 0)] = 1.0
        out[(fx.gamma > 0) & (fx.kt == 0)] = 0.0
        return out

    @staticmethod
    def _status(run: RunResult, H: np.ndarray, free: np.ndarray, p: dict[str, Any]) -> tuple[str, str, dict]:
        """Status ok / non-stationary / defect / unstable, its reason, and the diagnostic numbers."""
        code = run.status_code
        hmax = H[free].max() if free.any() else 0.0
        h1, h2 = run.hot[1], run.hot[2]
        stat = float(np.max(np.abs(h1 - h2)[free]) / hmax) if hmax > 0 else math.nan
        hops = int(run.counters[ig.K_HOP_EVENTS])
        flags = {
            "stationarity": stat,
            "hops": hops, "hopped_pairs": int(run.counters[ig.K_HOP_PAIRS]),
            "first_hop_step": int(run.counters[ig.K_FIRST_HOP]),
            "stopped_at_step": int(run.counters[ig.K_STOP_STEP]) if code != ig.DONE else -1,
            "kernel_status": ig.STATUS_TEXT[code],
            "running_integral_linearity": _linearity(run.history),
        }
        if code in (ig.NAN, ig.GROWTH, ig.LEFT_BAR):
            return "unstable", f"{ig.STATUS_TEXT[code]}; stopped at step {run.steps}, sums kept", flags
        if code in (ig.ISOLATED, ig.CONTACT):
            return "defect", (f"{ig.STATUS_TEXT[code]}: the fixed pair list is wrong; run stopped at step "
                              f"{run.steps} (not rebuilt), sums kept"), flags
        if hops:
            return "defect", (f"{flags['hopped_pairs']} pairs left their root interval ({hops} hop events, first at "
                              f"step {flags['first_hop_step']}): lattice defects, chaotic regime"), flags
        if not stat <= p["stationarity_tol"]:
            return "non-stationary", (f"hotness changed by {stat:.3g} (of the hottest free) between the halves of the "
                                      f"window; tolerance {p['stationarity_tol']:g}"), flags
        return "ok", "", flags

    @staticmethod
    def _faces(lat: Lattice, H: np.ndarray, fx: Fixes, diagnostics: dict) -> dict[str, Any]:
        """Layer profile along z normalised by the hot face, and its deviation from Fourier's linear law."""
        nz = lat.shape[2]
        layer = H.reshape(-1, nz).mean(axis=0)
        prof = layer / layer[0] if layer[0] > 0 else layer * np.nan
        z = np.linspace(0.0, 1.0, nz)
        interior = slice(1, nz - 1)
        slope, icpt = np.polyfit(z[interior], prof[interior], 1) if nz > 3 else (math.nan, math.nan)
        diagnostics["layer_profile"] = prof
        return {
            "interior_slope": float(slope),
            "interior_intercept": float(icpt),
            "fourier_rms_deviation": float(np.sqrt(np.mean((prof[interior] - (1 - z[interior])) ** 2))),
            "interior_flatness": float(np.ptp(prof[interior])),
        }


def _linearity(history: np.ndarray) -> float:
    """Paper's Fig. 8 check: max deviation of the running integral of total KE from its chord, relative."""
    if history.shape[0] < 3:
        return math.nan
    t, e = history[:, ig.H_T], history[:, ig.H_KIN]
    integ = np.concatenate([[0.0], np.cumsum(0.5 * (e[1:] + e[:-1]) * np.diff(t))])
    chord = integ[0] + (integ[-1] - integ[0]) * (t - t[0]) / (t[-1] - t[0])
    return float(np.max(np.abs(integ - chord)) / abs(integ[-1])) if integ[-1] != 0 else math.nan
