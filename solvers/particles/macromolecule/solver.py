"""The macromolecule solver: parameters, what it supports, and a run's sums turned into a Solution.

Conventions: hotness H_j = (1/(t_end - t_start)) int KE_j dt; samples are H_j / max over FREE
particles; the second normalisation (by the driven particle) is in the summary as *_by_driven.
Held particles report their constraint value (frozen 0, driven 1), as constrained nodes do.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from pcverify.scene import FaceTemperature, Resolution, Scene, SceneError, point_patch_note
from pcverify.solvers.protocol import Solution, WorkEstimate, effective_params, heat_summary

from . import checks, codes
from .elastic_modes import macromolecule_modes
from .fixes import Fixes
from .force import SevenRoot
from .lattice import Lattice
from .parameters import PARAMETERS
from .probe import MacromoleculeProbe
from .setup import Setup, prepare
from .simulate import RunResult, energy_balance_error, run_setup, run_status

BYTES_PER_PARTICLE = 3_000

class Macromolecule:
    """Solver "macromolecule": relative hotness of the seven-root particle lattice."""

    name = "macromolecule"
    kind = "particle"
    parameters = PARAMETERS

    def stability_probe(self) -> MacromoleculeProbe:
        """The probe that runs this solver's set-up and kernel at steps beyond its own guard."""
        return MacromoleculeProbe(self)

    def estimate(self, scene: Scene, resolution: Resolution, **params: Any) -> WorkEstimate:
        """Unknowns (3 per particle), time steps (t_end / dt; dt = safety * 2 / (2 pi f_top) when no dt is given)
        and memory (about 3 kB per particle: state, pair list, the set-up's sparse Hessian), before any build."""
        p = effective_params(self, params)
        particles = math.prod(scene.box.lattice_shape(resolution.n))
        if "modes" in scene.physics:
            return WorkEstimate(unknowns=3 * particles, steps=1, bytes=BYTES_PER_PARTICLE * particles
                                + 8 * (3 * particles) ** 2)  # a dense eigenproblem
        dt = p["dt"] if p["dt"] is not None else p["safety"] / (math.pi * p["f_top"])
        return WorkEstimate(unknowns=3 * particles, steps=max(1, round(p["t_end"] / dt)),
                            bytes=BYTES_PER_PARTICLE * particles)

    def supports(self, scene: Scene) -> tuple[bool, str]:
        if scene.physics == frozenset({"elasticity", "modes"}):
            return True, ""  # the lattice's eigenfrequencies, scaled to the material (elastic_modes)
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
        s = prepare(scene, n, p)
        x0 = checks.top_mode_start(s, p["start_amplitude"]) if p["start"] == "top-mode" else None
        return self._heat(scene, n, p, s, run_setup(s, p, x0=x0), t_wall, samples, x0)

    def _heat(self, scene: Scene, n: int, p: dict[str, Any], s: Setup, run: RunResult, t_wall: float,
              samples: dict[str, np.ndarray] | None, x0: np.ndarray | None) -> Solution:
        """The Solution of a heat run: relative hotness at the samples, status, summary (with the independent
        measurements of `checks`) and diagnostics."""
        lat, fx = s.lattice, s.fixes
        H = run.hot[0]
        free = (fx.kind == codes.FREE) & (fx.gamma == 0.0)  # bath particles are held, not free
        rel = H / H[free].max() if H[free].max() > 0 else np.full_like(H, np.nan)
        h_drv = H[fx.hot].mean() if len(fx.hot) else np.nan
        rel_drv = H / h_drv if h_drv > 0 else np.full_like(H, np.nan)
        status, reason, flags = run_status(run, H, free, p)
        reason = "; ".join(r for r in (reason, point_patch_note(scene.constraints, lat.a)) if r)
        rel_raw = rel
        rel = self._constrained_values(rel, fx)
        summary: dict[str, Any] = heat_summary(rel, float(rel.mean()))
        summary.update(
            bulk_median_by_driven=float(np.median(rel_drv)), volume_mean_by_driven=float(rel_drv.mean()),
            driven_over_hottest_free=float(h_drv / H[free].max()) if H[free].max() > 0 else math.nan,
            hottest_free_index=int(np.flatnonzero(free)[np.argmax(H[free])]),
            f_top_hz=s.f_top, stiffness_A=s.stiffness_A, dt=s.dt, dt_limit=s.dt_limit,
            dt_limit_single_mode=s.dt_limit_single_mode, steps=run.steps, kernel_s=run.wall_s,
            kernel_cpu_s=run.cpu_s,
            pairs=len(lat.pairs), pair_steps=len(lat.pairs) * run.steps, particles=lat.size,
            damping_in_force=s.damping_in_force, delta=s.delta, damping_ratio=s.damping_ratio,
            damping_ratio_method=s.damping_ratio_method, damping_ratio_rough=s.damping_ratio_rough,
            energy_balance_error=energy_balance_error(run), mean_kinetic_energy=float(H.sum()),
            status=status, **flags,
        )
        diagnostics: dict[str, Any] = {
            "energy": {k: float(run.energy[i]) for k, i in (("start", codes.E_START), ("end", codes.E_END),
                       ("dissipated", codes.E_DISS), ("drive_work", codes.E_DRIVE), ("bath_work", codes.E_BATH),
                       ("kinetic_end", codes.E_KIN_END))},
            "positions_end": run.x,
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
        work = {"pair_steps": len(lat.pairs) * run.steps, "time_steps": run.steps,
                "unknowns": 3 * int(np.count_nonzero(fx.kind == codes.FREE)), "kernel_s": run.wall_s}
        summary.update(checks.cold_kinetic_max(scene, s, H, free))
        summary.update(checks.red_pair_summary(scene, s, p, run))
        summary.update(checks.force_law_summary(scene, s, n))
        if x0 is not None:
            summary.update(checks.top_mode_summary(s, p, run, x0))
        if p["setup_check"]:
            summary.update(checks.setup_summary(s))
        if p["dt_check"]:
            Hf = run_setup(s, p, s.dt / 2, x0=x0).hot[0]
            relf = Hf / Hf[free].max()
            summary["dt_sensitivity"] = float(np.max(np.abs(relf - rel)[free]))
            summary["dt_sensitivity_bulk_median"] = float(np.median(relf) - np.median(rel))
            work["pair_steps"] += len(lat.pairs) * 2 * run.steps
            work["time_steps"] += 2 * run.steps
        if p["stop_check"]:
            whole = run_setup(s, p | {"stop_tol": 0.0}, x0=x0)
            Hw = whole.hot[0]
            summary["stop_deviation"] = float(np.max(np.abs(Hw / Hw[free].max() - rel_raw)[free]))
            work["pair_steps"] += len(lat.pairs) * whole.steps
            work["time_steps"] += whole.steps
        nodes = scene.sample_sets(n) if samples is None else samples
        out = {k: {"points": np.asarray(v, float), "values": rel[lat.node_at(v)]} for k, v in nodes.items()}
        return Solution(scene=scene.name, solver=self.name, params=p, samples=out,
                        resolution={"n": n, "refine": 1, "h": lat.a, "nodes": lat.size},
                        unknowns=work["unknowns"], wall_s=time.perf_counter() - t_wall, status=status, reason=reason,
                        quantity="relative hotness H/H_max (hottest free particle)", work=work, summary=summary,
                        diagnostics=diagnostics)

    def _modes(self, scene: Scene, n: int, p: dict[str, Any], t_wall: float) -> Solution:
        """Eigenfrequencies of the seven-root lattice (shape p, s, unstable_fraction as given) clamped at z = 0,
        its stiffness scaled so that its uniaxial Young's modulus is the material's (elastic_modes)."""
        t0, mat = time.perf_counter(), scene.material
        m = macromolecule_modes(scene.box, n, mat.youngs_modulus, mat.density, scene.elasticity.modes,
                                model=SevenRoot(1.0, p["p"], p["s"], p["unstable_fraction"]))
        kernel, unknowns = time.perf_counter() - t0, 3 * int(m["particles"])
        return Solution(scene=scene.name, solver=self.name, params=p, samples={}, unknowns=unknowns,
                        resolution={"n": n, "refine": 1, "h": scene.box.lattice_spacing(n), "nodes": unknowns // 3},
                        wall_s=time.perf_counter() - t_wall, quantity="frequency (Hz)",
                        summary={"frequencies_hz": m["frequencies_hz"], "nu_eff": m["nu_eff"], "stiffness_A": m["A"],
                                 "kernel_s": kernel}, work={"unknowns": unknowns, "kernel_s": kernel})

    @staticmethod
    def _constrained_values(rel: np.ndarray, fx: Fixes) -> np.ndarray:
        """Held particles report their constraint value, like constrained nodes of a continuum solve:
        frozen and 0 K baths 0, driven and hot baths 1 (their own hotness stays in the diagnostics)."""
        out = rel.copy()
        out[fx.kind == codes.FROZEN] = 0.0
        out[(fx.kind == codes.PRESCRIBED) | (fx.kind == codes.GROUP)] = 1.0
        out[(fx.gamma > 0) & (fx.kt > 0)] = 1.0
        out[(fx.gamma > 0) & (fx.kt == 0)] = 0.0
        return out

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
        return {"interior_slope": float(slope), "interior_intercept": float(icpt),
                "fourier_rms_deviation": float(np.sqrt(np.mean((prof[interior] - (1 - z[interior])) ** 2))),
                "interior_flatness": float(np.ptp(prof[interior]))}


