"""Stability study: the measured time-step limit of each particle model against its theory, and a
stability map over (dt, damping, drive amplitude).

A solver refuses a time step above its theoretical limit (that is input validation), so measuring
where a model really becomes unstable needs a *probe*: a per-model adapter that builds the run the
solver would build and integrates it at dt = ratio * dt_theory, beyond the guard.  Each probe states
its theory.  Two kinds of study cell use a probe (a group with `analysis = "stability"`):

- `probe = "limit"`: bisection on ratio = dt / dt_theory between `ratio_lo` (must be stable) and
  `ratio_hi` (must be unstable) down to `ratio_tol`; the measured limit is reported as the safety
  factor dt * omega_max / 2 next to the theory, and optionally next to the linear-discrete limit
  (spectral radius of the scheme's amplification matrix of the linearised, held lattice).
- `probe = "map"`: one run at `dt_ratio`, classified ok (stable), unstable, defect or non-stationary;
  an independent check of the final state with the issue's three criteria (finite; no particle more
  than a outside the bar; kinetic energy at most blowup_factor times the energy supplied, i.e. the
  initial energy plus the drive and bath work plus the drives' own energy scale) flags any blow-up
  that the solver did not report (`undetected`).

Nothing here changes a solver; the report reads the cached cell results through `report_tables`.
"""

from __future__ import annotations

import math
import textwrap
import time
from pathlib import Path
from typing import Any

import numpy as np

from pcverify.harness.scene import Param, Scene, SceneError, resolve_params

PROBE_KINDS = ("limit", "map")

PROBE_PARAMS: tuple[Param, ...] = (
    Param("dt_ratio", 1.0, "", "map: dt / dt_theory of the run", low=0.0, high=10.0, low_open=True),
    Param("ratio_lo", 0.05, "", "limit: lower bracket of dt / dt_theory (must be stable)", low=0.0, high=10.0,
          low_open=True),
    Param("ratio_hi", 1.5, "", "limit: upper bracket of dt / dt_theory (must be unstable)", low=0.0, high=10.0,
          low_open=True),
    Param("ratio_tol", 1e-3, "", "limit: bisection stops when the bracket is narrower than this", low=1e-6,
          high=0.5),
    Param("linear", False, "", "limit: also compute the linear-discrete limit (dense eigenvalues; n <= 5)",
          kind=bool),
)
PROBE_NAMES = {p.name for p in PROBE_PARAMS}

THEORY = {
    "macromolecule": "velocity Verlet with radial pair damping lagged half a step: a mode of frequency omega and "
                     "damping ratio zeta is stable for omega dt / 2 < sqrt(1 + zeta^2) - zeta (Jury criterion of "
                     "x_{n+1} - 2x_n + x_{n-1} = -h^2 x_n - 2 zeta h (x_n - x_{n-1}), h = omega dt); the top mode "
                     "(omega_max, zeta from the damped modal problem) sets dt_theory",
}


HEAT_STEPS = 20_000  # a mode amplified by 1 + 1e-3 per step grows e^20 times: bisection to 1e-3 resolves it

THEORY["mca"] = ("velocity Verlet: undamped, stable for omega_max dt < 2; MCA sets dt = cfl * 2 / omega_G with "
                 "omega_G >= omega_max a Gershgorin bound, so every cfl <= 1 is stable (the guarantee) and the "
                 "undamped limit lies at cfl = omega_G / omega_max >= 1; viscous damping lowers it (single mode: "
                 "sqrt(1+zeta^2) - zeta).  Probed through the public `cfl` parameter; dt_theory = dt at cfl = 1.  "
                 "Heat (transient): forward Euler, stable iff dt <= 2 / lambda_max(C^-1 L); dt_theory = the "
                 "Gershgorin step min C_i / sum_j G_ij, which guarantees it (ratio 1); the exact limit is reported "
                 "as the linear-discrete limit")


class ProbeUnavailable(LookupError):
    """A model without a stability probe (the study skips its cells with this reason)."""


def split_params(params: dict[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """(solver params, probe params) of a cell; probe params validated against PROBE_PARAMS."""
    solver = {k: v for k, v in params.items() if k not in PROBE_NAMES}
    probe = resolve_params(PROBE_PARAMS, {k: v for k, v in params.items() if k in PROBE_NAMES}, "stability probe")
    for key in ("dt", "safety"):
        if key in solver:
            raise SceneError(f"{key}={solver[key]!r} is not allowed in a stability cell; allowed: set dt_ratio "
                             "(the probe sets dt = dt_ratio * dt_theory)")
    return solver, probe


# ----------------------------------------------------------------------------- per-model probes
class MacromoleculeProbe:
    """Stability probe of the macromolecule solver: its own setup and kernel, dt set by the probe."""

    name = "macromolecule"
    theory = THEORY["macromolecule"]

    def __init__(self) -> None:
        from pcverify.solvers.particles.macromolecule.solver import Macromolecule

        self.solver = Macromolecule()
        self.version = f"{self.solver.version}+probe2"  # bump when the probe's results change
        self.parameters = self.solver.parameters

    def supports(self, scene: Scene) -> tuple[bool, str]:
        return self.solver.supports(scene)

    def prepare(self, scene: Scene, n: int, params: dict[str, Any]) -> dict[str, Any]:
        """Everything before a run (lattice, fixes, A, delta, zeta, dt_theory); validates params."""
        from pcverify.solvers.protocol import effective_params

        p = effective_params(self.solver, params)
        s = self.solver.setup(scene, n, p)
        w = 2 * math.pi * s["f_top"]
        safety = math.sqrt(1 + s["zeta"] ** 2) - s["zeta"]  # the stated theory, whatever guard the solver uses
        return {"p": p, "s": s, "omega_max": w, "zeta": s["zeta"], "dt_theory": 2 * safety / w,
                "safety_theory": safety, "solver_dt_limit": s["dt_limit"], "scene_hash": scene.content_hash(),
                "n": n}

    def run(self, prep: dict[str, Any], ratio: float) -> dict[str, Any]:
        """One run at dt = ratio * dt_theory over the solver's window; status and an independent check."""
        from pcverify.solvers.particles.macromolecule import kernel_reference as ig
        from pcverify.solvers.particles.macromolecule.solver import simulate

        p, s = prep["p"], prep["s"]
        lat, fx = s["lat"], s["fx"]
        dt = ratio * prep["dt_theory"]
        run = simulate(lat, s["model"], fx, s["delta"], dt, p["t_end"], p["t_start"],
                       2 * math.pi * p["drive_frequency"], seed=p["seed"], blowup_factor=p["blowup_factor"],
                       contact_fraction=p["contact_fraction"], **({"kernel": p["kernel"]} if "kernel" in p else {}))
        H = run.hot[0]
        free = (fx.kind == ig.FREE) & (fx.gamma == 0.0)
        status, reason, flags = self.solver._status(run, H, free, p)
        e = run.energy
        finite = bool(np.isfinite(run.x).all() and np.isfinite(e).all())
        disp = float(np.max(np.linalg.norm(run.x - lat.positions, axis=1)) / lat.a) if finite else math.inf
        outside = float(np.max(np.maximum(lat.positions.min(axis=0) - run.x, run.x - lat.positions.max(axis=0)))
                        / lat.a) if finite else math.inf
        held = fx.kind != ig.FREE
        w = 2 * math.pi * p["drive_frequency"]
        e_scale = 1.5 * fx.kt.sum() + 0.5 * lat.mass * w**2 * float((fx.amp[held] ** 2).sum())
        supplied = max(e[ig.E_START] + e[ig.E_DRIVE] + e[ig.E_BATH], 0.0) + e_scale
        ke_ratio = float(e[ig.E_KIN_END] / supplied) if finite else math.inf
        # the three criteria, re-evaluated on the final state (the kernel checks every few steps)
        blown = (not finite) or outside > 1.0 or ke_ratio > p["blowup_factor"]
        return {"status": status, "reason": reason, "dt": dt, "dt_ratio": ratio,
                "safety": dt * prep["omega_max"] / 2, "steps": run.steps,
                "steps_planned": int(round(p["t_end"] / dt)), "stopped_at_step": flags["stopped_at_step"],
                "kernel_status": flags["kernel_status"], "hops": flags["hops"],
                "stationarity": flags["stationarity"], "max_displacement_over_a": disp, "outside_over_a": outside,
                "kinetic_end_over_supplied": ke_ratio, "blown": blown,
                "undetected": bool(blown and status != "unstable")}

    def linear_limit(self, prep: dict[str, Any], tol: float = 1e-5) -> float:
        """Safety factor at which the spectral radius of the linearised scheme (held lattice at rest,
        lagged pair damping; Langevin bath friction left out) crosses 1: the linear-discrete limit.
        It does not depend on the drive amplitude or the run length, so it is memoised per lattice."""
        import scipy.linalg as sla

        p = prep["p"]
        key = (prep["scene_hash"], prep["n"], prep["omega_max"], prep["s"]["delta"],
               tuple(p[k] for k in ("p", "s", "unstable_fraction", "pairs_at_2a")), tol)
        if key in _LINEAR_LIMITS:
            return _LINEAR_LIMITS[key]

        from pcverify.solvers.particles.macromolecule.modal import damping_matrix, free_dofs, hessian

        s = prep["s"]
        lat, fx = s["lat"], s["fx"]
        dofs = free_dofs(~fx.held)
        K = hessian(lat.positions, lat.pairs, s["model"], lat.a)[dofs][:, dofs].toarray() / lat.mass
        C = damping_matrix(lat.positions, lat.pairs, s["delta"])[dofs][:, dofs].toarray() / lat.mass
        eye = np.eye(len(dofs))
        w = prep["omega_max"]

        def rho(h: float) -> float:
            dt = 2 * h / w
            amp = np.block([[2 * eye - dt * C - dt * dt * K, -eye + dt * C], [eye, 0 * eye]])
            return float(np.abs(sla.eigvals(amp)).max())

        lo, hi = 0.05, 1.5
        while hi - lo > tol:
            mid = 0.5 * (lo + hi)
            lo, hi = (lo, mid) if rho(mid) > 1 + 1e-9 else (mid, hi)
        _LINEAR_LIMITS[key] = 0.5 * (lo + hi)
        return _LINEAR_LIMITS[key]


_LINEAR_LIMITS: dict[tuple, float] = {}


class McaProbe:
    """Stability probe of the MCA solver through its own `cfl` (dt / (2 / omega_G)); mechanics scenes only."""

    name = "mca"
    theory = THEORY["mca"]

    def __init__(self) -> None:
        from pcverify.solvers.registry import get_solver

        self.solver = get_solver("mca")
        self.version = f"{self.solver.version}+probe2"
        self.parameters = self.solver.parameters

    def supports(self, scene: Scene) -> tuple[bool, str]:
        ok, why = self.solver.supports(scene)
        if ok and "elasticity" not in scene.physics and scene.conduction.mode != "transient":
            return False, "steady mca heat is a direct solve: no time stepping, no stability probe needed"
        if ok and "modes" in scene.physics:
            return False, "bar-modes is an eigenproblem: no time stepping"
        return ok, why

    def prepare(self, scene: Scene, n: int, params: dict[str, Any]) -> dict[str, Any]:
        from pcverify.harness.scene import Resolution
        from pcverify.solvers.protocol import effective_params

        if "cfl" in params or "heat_cfl" in params:
            raise SceneError("cfl and heat_cfl are not allowed in a stability cell; allowed: set dt_ratio (the probe "
                             "sets the step)")
        effective_params(self.solver, params)
        if "elasticity" not in scene.physics:
            return self._prepare_heat(scene, n)
        return {"p": params, "scene": scene, "resolution": Resolution(n), "omega_max": math.nan,
                "zeta": math.nan, "dt_theory": math.nan, "safety_theory": 1.0,
                "solver_dt_limit": math.nan, "scene_hash": scene.content_hash(), "n": n}

    def _prepare_heat(self, scene: Scene, n: int) -> dict[str, Any]:
        """Explicit heat transfer (forward Euler on the automata): the solver's own arrays; dt_theory is its
        Gershgorin step, guaranteed stable; the exact limit comes from the generalised eigenproblem."""
        from pcverify.solvers.particles.mca import heat as mca_heat
        from pcverify.solvers.particles.mca.automata import bar_automata

        aut = bar_automata(scene.box, n, scene.material.density)
        held, values = self.solver._held(scene, aut)
        mat = scene.material
        cap, g, dt_g = mca_heat.explicit_system(aut, mat.conductivity, mat.density * mat.heat_capacity, held)
        return {"p": {}, "heat": (aut, held, values, cap, g), "omega_max": math.nan, "zeta": 0.0,
                "dt_theory": dt_g, "safety_theory": 1.0, "solver_dt_limit": dt_g,
                "scene_hash": scene.content_hash(), "n": n, "t_max": scene.conduction.t_max}

    def _run_heat(self, prep: dict[str, Any], ratio: float) -> dict[str, Any]:
        """HEAT_STEPS forward-Euler steps at dt = ratio * dt_G; unstable when the temperature leaves
        [-1, 2] t_max (the exact field stays in [0, 1] t_max) or is not finite."""
        from pcverify.solvers.particles.mca import heat as mca_heat

        aut, held, values, cap, g = prep["heat"]
        dt = ratio * prep["dt_theory"]
        # a seeded 1e-9 t_max perturbation of the free automata excites every mode: symmetric data alone
        # never reach the antisymmetric top mode, and the measured limit would be that of the symmetric modes
        noise = np.random.default_rng(0).standard_normal(aut.size) * 1e-9 * prep["t_max"] * (held == 0)
        temp = mca_heat.explicit_run(values.astype(float) + noise, cap, aut.pairs[:, 0].copy(),
                                     aut.pairs[:, 1].copy(), g, held.astype(np.int64), dt, HEAT_STEPS)
        rel = temp / prep["t_max"]
        finite = bool(np.all(np.isfinite(rel)))
        blown = not finite or float(np.max(np.abs(rel - 0.5))) > 1.5
        status, reason = ("unstable", "temperature left [-1, 2] t_max (or not finite)") if blown else ("ok", "")
        return {"status": status, "reason": reason, "dt": dt, "dt_ratio": ratio, "safety": ratio,
                "steps": HEAT_STEPS, "steps_planned": HEAT_STEPS, "stopped_at_step": HEAT_STEPS if blown else -1,
                "kernel_status": reason or "completed", "hops": 0, "stationarity": math.nan,
                "max_displacement_over_a": math.nan, "outside_over_a": math.nan,
                "kinetic_end_over_supplied": math.nan, "blown": blown, "undetected": False}

    def run(self, prep: dict[str, Any], ratio: float) -> dict[str, Any]:
        """One solve at cfl = ratio (the public parameter caps it at 10); heat: forward Euler at ratio * dt_G."""
        if "heat" in prep:
            return self._run_heat(prep, ratio)
        sol = self.solver.solve(prep["scene"], prep["resolution"], cfl=min(ratio, 10.0), **prep["p"])
        finite = all(np.all(np.isfinite(np.asarray(v["values"], dtype=float))) for v in sol.samples.values())
        steps = int(sol.summary.get("steps", sol.work.get("time_steps", 0)) or 0)
        dt = float(sol.summary.get("dt", math.nan))
        blown = not finite and sol.status != "unstable"
        return {"status": sol.status, "reason": sol.reason, "dt": dt, "dt_ratio": ratio, "safety": ratio,
                "steps": steps, "steps_planned": steps, "stopped_at_step": steps if sol.status == "unstable" else -1,
                "kernel_status": sol.reason or "completed", "hops": 0, "stationarity": math.nan,
                "max_displacement_over_a": math.nan, "outside_over_a": math.nan, "kinetic_end_over_supplied": math.nan,
                "blown": blown or sol.status == "unstable", "undetected": blown}

    def linear_limit(self, prep: dict[str, Any], tol: float = 1e-5) -> float:
        """Heat: the exact forward-Euler limit 2 / lambda_max(C^-1 L) over the free automata, in units of
        dt_G.  Mechanics: nan (the MCA's Hessian is not public)."""
        if "heat" not in prep:
            return math.nan
        import scipy.linalg as sla

        from pcverify.solvers.particles.mca import heat as mca_heat

        aut, held, _, cap, g = prep["heat"]
        free = np.flatnonzero(held == 0)
        lap = mca_heat.laplacian(aut, g)[free][:, free].toarray()
        lam = sla.eigh(lap, np.diag(cap[free]), eigvals_only=True)[-1]
        return float(2.0 / lam / prep["dt_theory"])


PROBES: dict[str, type] = {"macromolecule": MacromoleculeProbe, "mca": McaProbe}


def get_probe(name: str) -> Any:
    """The probe of model `name`; ProbeUnavailable (a skip reason) if unregistered or without a probe."""
    from pcverify.solvers.registry import REGISTRY, SolverUnavailable, get_solver

    if name not in REGISTRY:
        raise ProbeUnavailable(f"solver {name!r} is not registered (yet): no stability measurement")
    if name not in PROBES:
        try:
            get_solver(name)
        except SolverUnavailable as exc:
            raise ProbeUnavailable(str(exc)) from None
        raise ProbeUnavailable(f"solver {name!r} has no stability probe in harness/stability.py (a probe must run "
                               "its kernel at a dt above the solver's own limit)")
    return PROBES[name]()


# ----------------------------------------------------------------------------- measurements
def measure_limit(probe: Any, prep: dict[str, Any], lo: float, hi: float, tol: float) -> dict[str, Any]:
    """Bisection on ratio = dt / dt_theory for the onset of status 'unstable'.

    Assumes one crossing inside [lo, hi]; the bracket ends are checked first and the result says
    'bracket' when lo is already unstable or hi still stable.  Every run's verdict is kept."""
    runs = []

    def unstable(r: float) -> bool:
        out = probe.run(prep, r)
        runs.append(out)
        return out["status"] == "unstable"

    verdict = "bisected"
    if unstable(lo):  # blows up however small dt is: the drive, not the time step, is unstable
        verdict, hi = f"unstable at every dt tried, down to ratio_lo={lo:g}: not a time-step limit", lo
    elif not unstable(hi):
        verdict, lo = f"stable up to ratio_hi={hi:g}", hi
    else:
        while hi - lo > tol:
            mid = 0.5 * (lo + hi)
            lo, hi = (lo, mid) if unstable(mid) else (mid, hi)
    ratio = 0.5 * (lo + hi)
    return {"verdict": verdict, "ratio_stable": lo, "ratio_unstable": hi, "measured_ratio": ratio,
            "measured_safety": ratio * prep["safety_theory"], "runs": len(runs),
            "undetected": sum(r["undetected"] for r in runs),
            "unstable_runs": sum(r["status"] == "unstable" for r in runs)}


def run_probe_cell(kind: str, probe: Any, scene: Scene, n: int, params: dict[str, Any]) -> dict[str, Any]:
    """Result of one stability cell (JSON-ready): status, reason and a summary of scalars."""
    t0 = time.perf_counter()
    solver_params, pp = split_params(params)
    prep = probe.prepare(scene, n, solver_params)
    head = {"omega_max": prep["omega_max"], "zeta": prep["zeta"], "dt_theory": prep["dt_theory"],
            "safety_theory": prep["safety_theory"], "solver_dt_limit_ratio": prep["solver_dt_limit"] /
            prep["dt_theory"], "drive_amplitude": prep["p"].get("drive_amplitude", math.nan), "probe": kind}
    if kind == "map":
        out = probe.run(prep, pp["dt_ratio"])
        summary = head | {k: v for k, v in out.items() if k not in ("status", "reason")}
        status, reason = out["status"], out["reason"]
    else:
        lim = measure_limit(probe, prep, pp["ratio_lo"], pp["ratio_hi"], pp["ratio_tol"])
        summary = head | lim | {"ratio_tol": pp["ratio_tol"]}
        if pp["linear"]:
            summary["linear_safety"] = probe.linear_limit(prep)
        summary["relative_deviation"] = lim["measured_safety"] / prep["safety_theory"] - 1.0
        status, reason = "ok", "" if lim["verdict"] == "bisected" else lim["verdict"]
    return {"status": status, "reason": reason, "summary": summary, "theory": probe.theory,
            "wall_s": time.perf_counter() - t0, "resolution": {"n": n, "refine": 1}}


# ----------------------------------------------------------------------------- report
def _tables(results: list[dict[str, Any]]) -> tuple[Any, Any]:
    import pandas as pd

    rows = {"limit": [], "map": []}
    for r in results:
        s = r.get("summary") or {}
        if r.get("status") in ("skipped", "failed") or "probe" not in s:
            continue
        sp = r.get("solver_params") or {}
        row = {"solver": r["solver"], "scene": r["scene"], "n": r["n"],
               "damping_ratio": s["zeta"], "drive_amplitude": s.get("drive_amplitude", sp.get("drive_amplitude")),
               "damping": sp.get("damping"),
               "safety_theory": s["safety_theory"]}
        if s["probe"] == "limit":
            row |= {k: s.get(k) for k in ("measured_safety", "linear_safety", "relative_deviation", "ratio_tol",
                                          "verdict", "runs", "unstable_runs", "undetected")}
        else:
            row |= {"dt_ratio": s["dt_ratio"], "safety": s["safety"], "status": r["status"],
                    "kernel_status": s["kernel_status"], "stopped_at_step": s["stopped_at_step"],
                    "steps_planned": s["steps_planned"], "hops": s["hops"], "undetected": s["undetected"]}
        rows[s["probe"]].append(row)
    return pd.DataFrame(rows["limit"]), pd.DataFrame(rows["map"])


STATUS_STYLE = {"ok": ("o", "tab:green"), "unstable": ("x", "tab:red"), "defect": ("s", "tab:orange"),
                "non-stationary": ("^", "tab:blue")}


def report_tables(results: list[dict[str, Any]], folder: Path, gid: str, title: str
                  ) -> tuple[dict[str, Any], list[str]]:
    """Tables ({name: DataFrame}) and figure files of a stability group, figures written into `folder`."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    limits, smap = _tables(results)
    tables, figures = {}, []
    if not limits.empty:
        tables[f"{gid}-limits"] = limits
        fig, ax = plt.subplots(figsize=(6, 4))
        z = np.linspace(0.0, max(0.5, float(limits["damping_ratio"].max())), 200)
        ax.plot(z, np.sqrt(1 + z**2) - z, "k-", label="theory sqrt(1+zeta^2) - zeta")
        for (solver, n, D), seq in limits.groupby(["solver", "n", "drive_amplitude"]):
            seq = seq.sort_values("damping_ratio")
            ax.plot(seq["damping_ratio"], seq["measured_safety"], "o--", label=f"{solver} n={n} D={D:g}a")
        if "linear_safety" in limits:
            lin = limits.dropna(subset=["linear_safety", "damping_ratio"])
            lin = lin.drop_duplicates(["solver", "n", "damping_ratio"])
            for (solver, n), seq in lin.groupby(["solver", "n"]):
                seq = seq.sort_values("damping_ratio")
                ax.plot(seq["damping_ratio"], seq["linear_safety"], ":", color="grey",
                        label=f"{solver} n={n} linear-discrete limit")
        ax.set_xlabel("top-mode damping ratio zeta")
        ax.set_ylabel("limit of dt omega_max / 2")
        ax.set_title("\n".join(textwrap.wrap(title, 80)), fontsize=8)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=6)
        fig.tight_layout()
        for (solver, scene), seq in limits[limits["damping_ratio"].isna()].groupby(["solver", "scene"]):
            ax.plot(np.zeros(len(seq)), seq["measured_safety"], "s", label=f"{solver} {scene} (cfl limit, n="
                    f"{','.join(map(str, seq['n']))}; theory >= 1)")
        fig.savefig(folder / f"{gid}-limits.png", dpi=110)
        fig.savefig(folder / f"{gid}-limits.svg")
        plt.close(fig)
        figures.append(f"{gid}-limits.png")
    if not smap.empty:
        tables[f"{gid}-map"] = smap
        amps = sorted(smap["drive_amplitude"].unique())
        for (solver, n), part in smap.groupby(["solver", "n"]):
            fig, axes = plt.subplots(1, len(amps), figsize=(3.2 * len(amps), 3.4), sharey=True, squeeze=False)
            for ax, D in zip(axes[0], amps, strict=True):
                sub = part[part["drive_amplitude"] == D]
                for status, (marker, colour) in STATUS_STYLE.items():
                    pick = sub[sub["status"] == status]
                    ax.scatter(pick["dt_ratio"], pick["damping_ratio"].clip(lower=1e-5), marker=marker, c=colour,
                               label=status)
                ax.axvline(1.0, color="k", lw=0.8)
                ax.set_yscale("log")
                ax.set_xlabel("dt / dt_theory")
                ax.set_title(f"D = {D:g} a", fontsize=8)
            axes[0][0].set_ylabel("damping ratio (0 drawn at 1e-5)")
            axes[0][-1].legend(fontsize=6)
            fig.suptitle(f"{title}: {solver} n={n}", fontsize=9)
            fig.tight_layout()
            name = f"{gid}-map-{solver}-n{n}"
            fig.savefig(folder / f"{name}.png", dpi=110)
            fig.savefig(folder / f"{name}.svg")
            plt.close(fig)
            figures.append(f"{name}.png")
    return tables, figures
