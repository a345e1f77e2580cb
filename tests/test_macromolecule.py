"""Verification of the macromolecule solver: force model, modal analysis, integrator, solver contract.

Sizes are kept small (n = 2, 3) so the file runs in well under a minute after numba compilation.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from pcverify.harness.study.catalogue import make_scene
from pcverify.scene import Resolution, SceneError
from pcverify.solvers.particles.macromolecule import codes
from pcverify.solvers.particles.macromolecule.computes import unlisted_contact
from pcverify.solvers.particles.macromolecule.fixes import make_fixes
from pcverify.solvers.particles.macromolecule.force import STABLE, SevenRoot, force_array, force_slope_array
from pcverify.solvers.particles.macromolecule.kernel import stencil
from pcverify.solvers.particles.macromolecule.lattice import build_lattice
from pcverify.solvers.particles.macromolecule.modal import (
    damped_top_mode,
    damping_matrix,
    free_dofs,
    hessian,
    linear_step_limit,
    modal_basis,
    top_modes,
)
from pcverify.solvers.particles.macromolecule.setup import prepare
from pcverify.solvers.particles.macromolecule.simulate import energy_balance_error, simulate
from pcverify.solvers.particles.macromolecule.solver import Macromolecule
from pcverify.solvers.protocol import effective_params

SOLVER = Macromolecule()
PAPER = make_scene("bar-heat-paper")


def _setup(n: int, **given):
    p = effective_params(SOLVER, given)
    s = prepare(PAPER, n, p)
    return p, s


def _undriven(n: int, **given):
    """Lattice of bar-heat-paper with the red pair held still (no drive), and its setup."""
    p, s = _setup(n, **given)
    fx = make_fixes(PAPER, s.lattice, p, 2 * np.pi * s.f_top)
    fx.amp[:] = 0.0
    return p, s, fx


# ---------------------------------------------------------------- force model
@pytest.mark.parametrize("p", [0.0, 1.0, 2.0, 4.0, 8.0])
@pytest.mark.parametrize("s", [0.6, 0.8, 0.9, 0.95])
@pytest.mark.parametrize("frac", [0.2, 0.5, 0.8])
def test_root_slopes(p: float, s: float, frac: float) -> None:
    """dF/dr > 0 at the stable roots a, sqrt2 a, sqrt3 a; < 0 at every unstable root.

    At 2a the STEP ends with zero value and slope, so F ~ c (r - 2a)^3: F' = 0 there, F < 0
    (repulsion) just inside and F = 0 beyond: stable only to third order (documented).
    """
    m = SevenRoot(A=1.0, p=p, s=s, unstable_fraction=frac)
    c = m.coeffs()
    f_s, df_s = force_slope_array(STABLE.copy(), c)
    f_u, df_u = force_slope_array(m.roots[1::2].copy(), c)
    assert np.all(np.abs(f_s) < 1e-14) and np.all(np.abs(f_u) < 1e-14)
    assert np.all(df_s[:3] > 0)
    assert np.all(df_u < 0)
    assert df_s[3] == 0.0
    eps = np.array([1e-5, 1e-4])
    inside = force_array(2.0 - eps, c)
    assert np.all(inside < 0) and np.all(force_array(2.0 + eps, c) == 0)
    assert inside[1] / inside[0] == pytest.approx(1e3, rel=0.05)  # cubic: ratio of eps^3


def test_slope_matches_finite_difference() -> None:
    """force_slope_x's analytic derivative equals a central difference of force_array (inside the STEP too)."""
    c = SevenRoot(A=3.0, p=2.5, s=0.8).coeffs()
    x = np.linspace(0.8, 1.99, 301)
    h = 1e-6
    fd = (force_array(x + h, c) - force_array(x - h, c)) / (2 * h)
    _, df = force_slope_array(x, c)
    assert np.max(np.abs(fd - df)) <= 1e-7 * np.max(np.abs(df))


# ---------------------------------------------------------------- modal analysis
def test_hessian_equals_finite_difference() -> None:
    """Analytic Hessian (with the geometric term) equals a central-difference Hessian to 1e-6 relative,
    at a perturbed configuration where pair forces are non-zero."""
    lat = build_lattice(PAPER.box, 2, 2700.0)
    m = SevenRoot(A=1.0)
    rng = np.random.default_rng(3)
    x = lat.positions + rng.normal(scale=0.03 * lat.a, size=lat.positions.shape)
    K = hessian(x, lat.pairs, m, lat.a).toarray()
    c = m.coeffs()
    pi, pj = lat.pairs.T

    def force(xx: np.ndarray) -> np.ndarray:
        d = xx[pj] - xx[pi]
        r = np.linalg.norm(d, axis=1)
        fr = force_array(r / lat.a, c)[:, None] * d / r[:, None]
        f = np.zeros_like(xx)
        np.add.at(f, pi, fr)
        np.add.at(f, pj, -fr)
        return f.ravel()

    h = 1e-6 * lat.a
    fdK = np.empty_like(K)
    for k in range(K.shape[0]):
        e = np.zeros(K.shape[0])
        e[k] = h
        fdK[:, k] = -(force(x + e.reshape(x.shape)) - force(x - e.reshape(x.shape))) / (2 * h)
    assert np.max(np.abs(fdK - K)) <= 1e-6 * np.max(np.abs(K))
    assert np.max(np.abs(K - K.T)) <= 1e-12 * np.max(np.abs(K))


@pytest.mark.parametrize("n", [2, 3, 4])
def test_f_top_sets_highest_frequency(n: int) -> None:
    """A from f_top: the highest eigenfrequency of the held lattice equals f_top to 1e-9."""
    p, s = _setup(n, f_top=37.0)
    lat, fx = s.lattice, s.fixes
    w = top_modes(hessian(lat.positions, lat.pairs, s.model, lat.a), lat.mass, free_dofs(~fx.held), k=1)[0][-1]
    assert w / (2 * np.pi) == pytest.approx(37.0, rel=1e-9)


def test_damping_ratio_subspace_and_rough_estimate() -> None:
    """The top-mode damping ratio from the modal subspace equals the full damped eigenproblem's, and
    the rough delta/(2 m omega) underestimates it several-fold (docs/physics.md, "The macromolecule
    model")."""
    p, s = _setup(3, damping_ratio=0.05)
    lat, fx = s.lattice, s.fixes
    dofs = free_dofs(~fx.held)
    K = hessian(lat.positions, lat.pairs, s.model, lat.a)
    C = damping_matrix(lat.positions, lat.pairs, s.delta)
    zeta_sub = damped_top_mode(modal_basis(K, lat.mass, dofs), C, dofs)[0]
    zeta_all = damped_top_mode(modal_basis(K, lat.mass, dofs, subspace=10**6), C, dofs)[0]
    assert zeta_sub == pytest.approx(0.05, rel=1e-9)
    assert zeta_all == pytest.approx(0.05, rel=1e-3)
    assert s.damping_ratio_rough < 0.05 / 3


# ---------------------------------------------------------------- integrator
def test_energy_conserved_undamped() -> None:
    """delta = 0, no drive, small random velocities, 1e5 steps at safety 0.1: the leapfrog energy
    error stays <= 1e-6; the on-step energy of velocity Verlet oscillates by ~(omega dt)^2/16 but
    does not drift."""
    p, s, fx = _undriven(3, delta=0.0, safety=0.1)
    lat = s.lattice
    w = 2 * np.pi * s.f_top
    assert s.dt * w / 2 == pytest.approx(0.1, rel=1e-12)
    v0 = np.random.default_rng(1).normal(size=(lat.size, 3)) * 1e-6 * lat.a * w
    r = simulate(lat, s.model, fx, 0.0, s.dt, 1e5 * s.dt, v0=v0)
    assert r.steps == 100_000 and r.status_code == codes.DONE
    assert energy_balance_error(r) <= 1e-6
    e_on = r.history[:, codes.H_KIN] + r.history[:, codes.H_POT]
    wdt = w * s.dt
    assert np.ptp(e_on) / e_on[0] < wdt**2 / 4
    half = len(e_on) // 2
    assert abs(e_on[half:].mean() - e_on[:half].mean()) / e_on[0] < 1e-4  # no drift


def _measured_limit(n: int, zeta: float) -> tuple[float, float, float]:
    """(bisected dt*omega_max/2, linear-discrete limit from the amplification matrix, top-mode zeta)."""
    p, s, fx = _undriven(n, damping_ratio=zeta)
    lat = s.lattice
    w = 2 * np.pi * s.f_top
    v0 = np.random.default_rng(1).normal(size=(lat.size, 3)) * 1e-6 * lat.a * w

    def unstable(h: float) -> bool:
        dt = 2 * h / w
        r = simulate(lat, s.model, fx, s.delta, dt, 3000 * dt, v0=v0, blowup_factor=100.0, check_every=20)
        return r.status_code != codes.DONE

    lo, hi = 0.6, 1.1
    for _ in range(11):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if unstable(mid) else (mid, hi)
    dofs = free_dofs(~fx.held)
    K = hessian(lat.positions, lat.pairs, s.model, lat.a)[dofs][:, dofs].toarray() / lat.mass
    C = damping_matrix(lat.positions, lat.pairs, s.delta)[dofs][:, dofs].toarray() / lat.mass
    return 0.5 * (lo + hi), linear_step_limit(K, C, w, 0.6, 1.1, 0.5 / 2**20), s.damping_ratio


def test_stability_limit_undamped() -> None:
    """Measured limit dt*omega_max/2 within 2 % of 1 at small amplitude (n = 3)."""
    measured, linear, _ = _measured_limit(3, 0.0)
    assert measured == pytest.approx(1.0, rel=0.02)
    assert linear == pytest.approx(1.0, rel=1e-6)


@pytest.mark.parametrize("n,zeta", [(2, 0.05), (2, 0.2), (3, 0.05), (3, 0.2)])
def test_stability_limit_damped(n: int, zeta: float) -> None:
    """Lagged (half-step) damping.  The measured limit (bisection on blow-up of the nonlinear run) is
    within 1 % of the exact linear-discrete limit (spectral radius 1 of the one-step amplification
    matrix), and the solver's modal-basis limit equals that one (n = 2: all modes, exact; n = 3:
    top-48-mode subspace, within 1 %).  The single-mode formula sqrt(1+zeta^2) - zeta for the top
    mode's zeta holds within 3 % at n = 3 but NOT at n = 2, zeta = 0.2: the damping is
    non-proportional and a lower, more damped mode (|lambda| = 0.96 omega_max, zeta = 0.29) goes
    unstable first (measured 0.752, exact linear 0.758, single-mode 0.820)."""
    measured, linear, z = _measured_limit(n, zeta)
    _, s, _ = _undriven(n, damping_ratio=zeta)
    solver_limit = s.dt_limit * 2 * np.pi * s.f_top / 2
    single = math.sqrt(1 + zeta**2) - zeta
    assert z == pytest.approx(zeta, rel=1e-9)
    assert measured == pytest.approx(linear, rel=0.01)
    assert solver_limit == pytest.approx(linear, rel=1e-6 if n == 2 else 0.01)
    assert s.dt_limit_single_mode * 2 * np.pi * s.f_top / 2 == pytest.approx(single, rel=1e-12)
    if n == 2 and zeta == 0.2:
        assert single / measured - 1 > 0.05
    else:
        assert measured == pytest.approx(single, rel=0.03)


@pytest.mark.parametrize("n,zeta,D", [(2, 0.01, 0.05), (3, 0.01, 0.05), (4, 0.01, 0.05), (3, 0.05, 0.02),
                                     (4, 0.01, 0.02), (5, 0.01, 0.02)])
def test_energy_balance_driven_damped(n: int, zeta: float, D: float) -> None:
    """Driven and damped at the default dt: E_end - E_start + dissipated - drive work closes to 1e-3
    of the drive work (15 s, f = 50 Hz): the paper's three runs (D = 0.05 a; n = 3, 4 hop, measured
    6.2e-5 and 6.8e-4) and runs without hops, n = 5 included (5.0e-4; 2.0e-3 at safety 0.1).  The
    accounting is the exact discrete identity of kernel.py, so the residual is the quadrature
    error of the anharmonic conservative forces (see the next test)."""
    sol = SOLVER.solve(PAPER, Resolution(n), damping_ratio=zeta, drive_amplitude=D)
    e = sol.diagnostics["energy"]
    assert e["drive_work"] > 0 and e["dissipated"] > 0
    assert sol.summary["energy_balance_error"] <= 1e-3
    if D < 0.05:
        assert sol.summary["hops"] == 0


def test_energy_balance_residual_is_anharmonic_integration_error() -> None:
    """n = 5, zeta = 0.01, D = 0.02: at safety 0.1 the residual is 2e-3 of the drive work (above the
    1e-3 target; why the default safety is 0.05).  It is an integration error, not bookkeeping: it
    falls as dt^2 (ratio 4 +- 10 % from safety 0.1 to 0.05; an accounting inconsistency would not
    scale with dt), and it comes from the nonlinear resonance of the chain below the red pair (pair
    amplitude +-4 % of a): with the pair forces replaced by their linearisation the same run closes
    to 2e-7 (measured with an instrumented kernel, see kernel.py).  At safety 0.05 it meets 1e-3."""
    errs = []
    for safety in (0.1, 0.05):
        sol = SOLVER.solve(PAPER, Resolution(5), damping_ratio=0.01, drive_amplitude=0.02, t_end=5.0, safety=safety)
        assert sol.summary["hops"] == 0
        errs.append(sol.summary["energy_balance_error"])
    assert errs[0] > 1e-3
    assert errs[0] / errs[1] == pytest.approx(4.0, rel=0.1)
    assert errs[1] <= 1e-3


def test_bit_identical_rerun() -> None:
    """Same seed: bit-identical hotness (Langevin faces use the seeded in-kernel RNG)."""
    faces = make_scene("bar-heat-faces")
    a = SOLVER.solve(faces, Resolution(2), t_end=1.0, seed=7)
    b = SOLVER.solve(faces, Resolution(2), t_end=1.0, seed=7)
    c = SOLVER.solve(faces, Resolution(2), t_end=1.0, seed=8)
    assert np.array_equal(a.samples["nodes"]["values"], b.samples["nodes"]["values"])
    assert not np.array_equal(a.samples["nodes"]["values"], c.samples["nodes"]["values"])


# ---------------------------------------------------------------- solver contract
def test_solution_contract() -> None:
    """Samples at the scene's sets, summary keys, work counters, normalisations."""
    sol = SOLVER.solve(PAPER, Resolution(2), t_end=2.0)
    sets = PAPER.sample_sets(2)
    assert set(sol.samples) == set(sets)
    for k, pts in sets.items():
        assert np.allclose(sol.samples[k]["points"], pts)
    v = sol.samples["nodes"]["values"]
    lat = build_lattice(PAPER.box, 2, 2700.0)
    hot = lat.node_at(np.array([0.0, 0.01, 0.0]))[0]
    assert v[hot] == 1.0  # constrained particles report their constraint value
    assert sol.samples["front_top_edge"]["values"][0] == 1.0
    assert sol.samples["bottom_back_edge"]["values"][0] == 0.0
    free = v[(v != 0.0) & (v != 1.0)]
    assert free.max() <= 1.0 and free.min() >= 0.0
    for key in ("f_top_hz", "dt", "steps", "pairs", "pair_steps", "hops", "stationarity", "energy_balance_error",
                "bulk_median", "volume_mean", "bulk_median_by_driven", "damping_in_force", "delta", "damping_ratio",
                "kernel_s", "kernel_cpu_s", "dt_limit", "dt_limit_single_mode"):
        assert key in sol.summary
    assert 0 < sol.summary["kernel_s"] < sol.wall_s
    assert sol.summary["damping_in_force"] == "damping_ratio"
    assert sol.work["pair_steps"] == sol.summary["pairs"] * sol.work["time_steps"]
    assert sol.work["unknowns"] == sol.unknowns == 3 * 12  # 16 particles: the red pair driven, two frozen
    assert sol.status in ("ok", "non-stationary", "defect", "unstable")


def test_parameter_errors() -> None:
    with pytest.raises(SceneError, match="refine"):
        SOLVER.solve(PAPER, Resolution(2, refine=2))
    with pytest.raises(SceneError, match="drive_amplitude"):
        SOLVER.solve(PAPER, Resolution(2), drive_amplitude=0.2)
    with pytest.raises(SceneError, match=r"dt=.*stability limit"):
        SOLVER.solve(PAPER, Resolution(2), dt=0.01)
    with pytest.raises(SceneError, match="exclusive"):
        SOLVER.solve(PAPER, Resolution(2), delta=1e-4, damping_ratio=0.01)
    ok, why = SOLVER.supports(make_scene("bar-heat-faces", mode="transient"))
    assert not ok and "hotness" in why
    assert SOLVER.supports(make_scene("bar-heat-patch"))[0]


def test_delta_in_force_reports_its_damping_ratio() -> None:
    """Given delta, the solver reports the damping ratio it implies (and vice versa, round trip)."""
    a = SOLVER.solve(PAPER, Resolution(2), t_end=0.5, damping_ratio=0.03)
    b = SOLVER.solve(PAPER, Resolution(2), t_end=0.5, delta=a.summary["delta"])
    assert b.summary["damping_in_force"] == "delta"
    assert b.summary["damping_ratio"] == pytest.approx(0.03, rel=1e-8)


@pytest.mark.parametrize("direction", ["x", "y", "z"])
def test_face_drive_direction(direction: str) -> None:
    """bar-heat-faces with hot_face=driven: every z=0 particle is driven along the requested axis only,
    with the stroke D a, and the seeded phases are distinct."""
    scene = make_scene("bar-heat-faces")
    p = effective_params(SOLVER, {"hot_face": "driven", "face_drive_direction": direction})
    lat = build_lattice(scene.box, 3, 2700.0)
    fx = make_fixes(scene, lat, p, 1.0)
    face = np.flatnonzero(lat.positions[:, 2] == 0.0)
    assert np.all(fx.kind[face] == codes.PRESCRIBED) and np.sum(fx.kind == codes.PRESCRIBED) == len(face)
    axis = "xyz".index(direction)
    assert np.allclose(fx.amp[face, axis], 0.05 * lat.a)
    assert np.all(np.delete(fx.amp[face], axis, axis=1) == 0.0)
    assert len(np.unique(fx.phase[face])) == len(face)


def test_patch_scene_holds_patch_particles() -> None:
    """bar-heat-patch: particles inside the frozen spheres are frozen, the hot patch moves with the drive."""
    scene = make_scene("bar-heat-patch", rho=3e-3)
    p = effective_params(SOLVER, {})
    lat = build_lattice(scene.box, 5, 2700.0)  # a = 2.5 mm: the spheres hold the corner and its 3 neighbours
    fx = make_fixes(scene, lat, p, 1.0)
    assert np.sum(fx.kind == codes.FROZEN) == 8
    assert np.sum(fx.kind == codes.GROUP) == 4  # corner + 2 patch mates on the m side, q below
    m_side = (fx.kind == codes.GROUP) & (fx.amp[:, 1] > 0)
    q = (fx.kind == codes.GROUP) & (fx.amp[:, 1] < 0)
    # relative stroke D a, momentum-neutral split
    assert fx.amp[m_side, 1][0] - fx.amp[q, 1][0] == pytest.approx(0.05 * lat.a)
    assert fx.amp[m_side, 1].sum() + fx.amp[q, 1].sum() == pytest.approx(0.0, abs=1e-18)


@pytest.mark.parametrize("n,drop", [(2, False), (3, False), (4, True)])
def test_stencil_holds_each_pair_once(n: int, drop: bool) -> None:
    """The kernel's stencil layout: every listed pair (i, j) sits in exactly one slot, of a
    group with offset j - i and the pair's shell basin, at slot base + i with mask 1; all other
    slots have mask 0 (so they contribute nothing); n = 2 has offsets shared by two shells."""
    lat = build_lattice(PAPER.box, n, 2700.0, "drop" if drop else "keep")
    basins = SevenRoot().basins()
    g_off, base, lo, hi, mask, slot = stencil(lat.pairs, lat.shell, lat.size, basins)
    assert len(np.unique(slot)) == len(lat.pairs) and mask.sum() == len(lat.pairs)
    assert np.all(mask[slot] == 1.0)
    group = np.searchsorted(base, slot, side="right") - 1
    assert np.array_equal(g_off[group], lat.pairs[:, 1] - lat.pairs[:, 0])
    assert np.array_equal(slot - base[group], lat.pairs[:, 0])
    assert np.array_equal(lo[group], basins[lat.shell, 0]) and np.array_equal(hi[group], basins[lat.shell, 1])
    assert base[-1] == mask.size == np.sum(lat.size - g_off)


def test_runs_beyond_max_steps_are_refused_before_they_start() -> None:
    """f_top = 1e5 Hz would need ~4.7e7 steps over 15 s: refused at once, naming max_steps."""
    with pytest.raises(SceneError, match=r"steps is out of range; allowed: at most max_steps=20000000"):
        Macromolecule().solve(make_scene("bar-heat-paper"), Resolution(2), f_top=1e5)
    sol = Macromolecule().solve(make_scene("bar-heat-paper"), Resolution(2), t_end=0.2, max_steps=1000)
    assert sol.summary["steps"] <= 1000


# ---------------------------------------------------------------- compilation, timing
_FRESH_PROCESS_RUN = textwrap.dedent("""
    import json, math
    from pcverify.harness.study.catalogue import make_scene
    from pcverify.solvers.particles.macromolecule import computes, kernel
    from pcverify.solvers.particles.macromolecule.setup import prepare
    from pcverify.solvers.particles.macromolecule.simulate import simulate
    from pcverify.solvers.particles.macromolecule.solver import Macromolecule
    from pcverify.solvers.protocol import effective_params
    s = prepare(make_scene("bar-heat-paper"), 3, effective_params(Macromolecule(), {"drive_amplitude": 0.02}))
    runs = [simulate(s.lattice, s.model, s.fixes, s.delta, s.dt, 0.3, omega=100 * math.pi)
            for _ in range(2)]
    fns = {f.__name__: f for f in (kernel.run_p2, kernel.run_any, computes.potential_any)}
    print(json.dumps({"compiled": {k: len(f.signatures) for k, f in fns.items()},
                      "cache_hits": sum(kernel.run_p2.stats.cache_hits.values()),
                      "cpu_s": [r.cpu_s for r in runs], "steps": runs[0].steps}))
""")


def _fresh_process() -> dict:
    out = subprocess.run([sys.executable, "-c", _FRESH_PROCESS_RUN], capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_a_run_compiles_only_its_kernel_loads_it_from_the_cache_and_times_the_integration_alone() -> None:
    """In a fresh process a run at p = 2 compiles (or loads) run_p2 only, not the other envelope's kernel or
    potential.  The structures the kernel takes (named tuples) cache: a second fresh process loads run_p2
    from numba's cache.  The kernel's clock starts after the load: the first run (loading) and the second
    (warm) of the same 0.3 s take CPU times within 3x + 20 ms of each other (the load alone: 0.1-0.4 s)."""
    _fresh_process()  # the cache holds run_p2 from here on
    got = _fresh_process()
    assert got["compiled"] == {"run_p2": 1, "run_any": 0, "potential_any": 0}
    assert got["cache_hits"] == 1
    first, second = got["cpu_s"]
    assert got["steps"] > 500 and first <= 3 * second + 0.02, got


# ---------------------------------------------------------------- one integrator, the probe through solve
def test_removed_kernel_parameter_is_one_error_line() -> None:
    """The one integrator has no `kernel` parameter: kernel="reference" (or "ensemble") is refused before
    anything runs, with one message naming the parameter."""
    for name in ("reference", "fastmath", "ensemble"):
        with pytest.raises(SceneError, match=r"kernel") as err:
            SOLVER.solve(PAPER, Resolution(2), kernel=name)
        assert "\n" not in str(err.value)
    assert not hasattr(SOLVER, "solve_batch")


def test_dt_guard_refuses_above_the_limit_and_false_runs_it() -> None:
    """dt 10 % above the solver's stability limit: refused by default (naming the limit), run with
    dt_guard=false, where the run's own checks stop it as unstable."""
    _, s = _setup(2)
    dt = 1.1 * s.dt_limit
    with pytest.raises(SceneError, match=r"^dt=.* is above the stability limit"):
        SOLVER.solve(PAPER, Resolution(2), dt=dt, t_end=1.0)
    sol = SOLVER.solve(PAPER, Resolution(2), dt=dt, t_end=1.0, dt_guard=False)
    assert sol.status == "unstable" and sol.summary["stopped_at_step"] < round(1.0 / dt)


def test_probe_runs_are_the_solvers_solves() -> None:
    """The stability probe integrates through `solve` (dt = ratio * dt_theory, dt_guard false): its run's
    status, steps and hop count are the solve's, and its independent re-check reads the solve's final
    state (a stable run: finite, inside the bar; a blown one: blown and detected)."""
    probe = SOLVER.stability_probe()
    params = {"t_end": 1.0, "damping_ratio": 0.0, "drive_amplitude": 0.01}
    setup = probe.prepare(PAPER, Resolution(2), params)
    for ratio, blown in ((0.9, False), (1.2, True)):
        run = probe.run(setup, ratio)
        sol = SOLVER.solve(PAPER, Resolution(2), dt=ratio * setup.dt_theory, dt_guard=False, **params)
        assert (run.status, run.steps, run.details["hops"]) == (sol.status, sol.summary["steps"], sol.summary["hops"])
        assert run.blown is blown and not run.undetected
        assert (run.status == "unstable") is blown


# ---------------------------------------------------------------- stationarity stop
FACES = make_scene("bar-heat-faces")
DRIVEN = {"hot_face": "driven", "face_drive_direction": "z", "drive_amplitude": 0.02}


def _faces(n: int, **given):
    return SOLVER.solve(FACES, Resolution(n), **(DRIVEN | given))


def test_a_stationary_run_stops_at_the_first_window_whose_halves_agree() -> None:
    """The driven-face bar at n = 3 over 15 s with stop_tol 0.03: the run stops at a mark of the doubling window
    (measured: 7.5 s, halves 2.0 % apart), and the run of that length without a stop gives the same hotness (the
    same window; only the summation order of the halves differs); the window before it was not yet stationary
    (measured 4.2 %)."""
    stopped = _faces(3, t_end=15.0, stop_tol=0.03)
    s = stopped.summary
    assert s["stationary_at_step"] == s["steps"] > 0 and s["status"] == "ok"
    full = round(15.0 / s["dt"])
    assert s["steps"] in {full >> k for k in range(1, 4)}  # a mark: L/2, L/4 or L/8 (the first test is at L/8)
    assert s["stationarity"] <= 0.03
    window = s["steps"] * s["dt"]
    plain = _faces(3, t_end=window, stop_tol=0.0)
    assert plain.summary["stationary_at_step"] == -1 and plain.summary["steps"] == s["steps"]
    for key in stopped.samples:
        np.testing.assert_allclose(stopped.samples[key]["values"], plain.samples[key]["values"], rtol=1e-12)
    before = _faces(3, t_end=window / 2, stop_tol=0.0)  # an independent run of the previous window
    assert before.summary["stationarity"] > 0.03


def test_a_run_that_is_not_stationary_runs_to_t_end_and_stop_tol_0_never_stops() -> None:
    """bar-heat-paper at n = 2: its halves differ by 5.6 % of the hottest over 15 s (measured), so the stop at 2 %
    never fires and the run is the paper's 15 s; stop_tol = 0 gives the same steps on a stationary scene."""
    r = SOLVER.solve(PAPER, Resolution(2), stop_tol=0.02)
    assert r.summary["stationary_at_step"] == -1 and r.summary["steps"] == round(15.0 / r.summary["dt"])
    assert r.summary["stationarity"] > 0.02
    whole = _faces(3, t_end=15.0, stop_tol=0.0)
    assert whole.summary["steps"] == round(15.0 / whole.summary["dt"]) and whole.summary["stationary_at_step"] == -1


def test_stop_tol_outside_its_range_is_one_error() -> None:
    with pytest.raises(SceneError, match=r"stop_tol.*allowed"):
        SOLVER.solve(PAPER, Resolution(2), stop_tol=1.5)


def _contact_brute_force(x: np.ndarray, x_rest: np.ndarray, lim: float, cut2: float) -> bool:
    d2 = ((x[:, None, :] - x[None, :, :]) ** 2).sum(-1)
    r2 = ((x_rest[:, None, :] - x_rest[None, :, :]) ** 2).sum(-1)
    upper = np.triu(np.ones_like(d2, dtype=bool), 1)
    return bool(np.any(upper & (r2 > cut2) & (d2 < lim**2)))


@pytest.mark.parametrize("seed", range(40))
def test_the_cell_list_finds_an_unlisted_contact_exactly_when_the_all_pairs_search_does(seed: int) -> None:
    """Lattices of bar-heat-paper shaken by up to 0.6 a (6 of the 40 with a contact closer than 0.5 a): the O(N)
    cell list of the neighbourhood check answers as the all-pairs search does, also at a contact distance far below
    a (the cell side doubles) and with every particle in one cell."""
    rng = np.random.default_rng(seed)
    lat = build_lattice(PAPER.box, int(rng.integers(2, 5)), PAPER.material.density)
    a = lat.a
    x = lat.positions + rng.uniform(0.0, 0.6) * a * rng.standard_normal(lat.positions.shape)
    cut2 = (2.0 * a * (1 + 1e-9)) ** 2
    for lim in (0.5 * a, 1e-4 * a, 50.0 * a):
        want = _contact_brute_force(x, lat.positions, lim, cut2)
        got = unlisted_contact(*(np.ascontiguousarray(x[:, d]) for d in range(3)), lat.positions, lim, cut2)
        assert got == want


def test_the_cell_list_finds_a_single_unlisted_contact_in_any_direction() -> None:
    """One particle moved to within 0.4 a of an unlisted one (rest distance beyond 2 a), in 300 random directions
    and pairs: the only contact closer than 0.5 a, found whichever neighbouring cell it falls in."""
    rng = np.random.default_rng(7)
    lat = build_lattice(PAPER.box, 3, PAPER.material.density)
    a, rest = lat.a, lat.positions
    cut2 = (2.0 * a * (1 + 1e-9)) ** 2
    far = np.argwhere(((rest[:, None, :] - rest[None, :, :]) ** 2).sum(-1) > cut2)
    for i, j in far[rng.choice(len(far), 300, replace=False)]:
        x = rest.copy()
        e = rng.standard_normal(3)
        x[i] = rest[j] + 0.4 * a * e / np.linalg.norm(e)
        assert _contact_brute_force(x, rest, 0.5 * a, cut2)
        assert unlisted_contact(*(np.ascontiguousarray(x[:, d]) for d in range(3)), rest, 0.5 * a, cut2)
