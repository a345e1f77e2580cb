"""The macromolecule's independent measurements (solvers/particles/macromolecule/checks.py), each against a number
computed another way: the closed forms against the recurrence stepped by hand and against trigonometry, the
solver's summary against a lattice whose stiffness or drive is known to differ from what the closed form assumes;
and the mutant catalogues of the macromolecule and stability studies (they load, every edit applies).

n = 2 and short runs: the file runs in seconds after numba compilation.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from pcverify.harness.cli import main
from pcverify.harness.study.catalogue import make_scene
from pcverify.harness.study.mutants import read_mutants_file
from pcverify.harness.study.shipped import study_files
from pcverify.harness.study.study import load_study
from pcverify.references import lattice  # the specification, written apart from the solver
from pcverify.scene import Resolution
from pcverify.solvers.particles.macromolecule import checks, codes
from pcverify.solvers.particles.macromolecule.setup import prepare
from pcverify.solvers.particles.macromolecule.solver import Macromolecule
from pcverify.solvers.protocol import effective_params

SOLVER = Macromolecule()
PAPER = make_scene("bar-heat-paper")
TOP_MODE = {"start": "top-mode", "drive_amplitude": 1e-9, "drive_frequency": 1e-3, "drive_sharing": "symmetric",
            "t_end": 0.2, "stop_tol": 0.0}


def _solve(n: int = 2, scene=PAPER, **params):
    return SOLVER.solve(scene, Resolution(n), **params)


def _stepped(omega: float, zeta: float, dt: float, steps: int) -> np.ndarray:
    """The kernel's scheme on one mode, stepped as the kernel steps it: kick with the force and the damping of the
    last half-step velocity (none at the start: v0 = 0), then drift."""
    x, v_half = 1.0, 0.5 * dt * omega**2  # v_{-1/2} = v0 - dt/2 a0
    out = [x]
    for k in range(steps):
        damping = 0.0 if k == 0 else -2.0 * zeta * omega * v_half
        v_half = v_half + dt * (-(omega**2) * x + damping)
        x = x + dt * v_half
        out.append(x)
    return np.array(out)


# ---------------------------------------------------------------- closed forms
@pytest.mark.parametrize("zeta", [0.0, 0.01, 0.2])
def test_mode_sequence_is_the_scheme_stepped_by_hand(zeta: float) -> None:
    omega, dt = 2 * math.pi * 50.0, 0.05 * 2 / (2 * math.pi * 50.0)
    x = checks.mode_sequence(omega, zeta, dt, 700)
    assert np.max(np.abs(x - _stepped(omega, zeta, dt, 700))) <= 1e-11


def test_undamped_mode_sequence_is_a_cosine_at_the_discrete_frequency() -> None:
    """Undamped, Verlet's sequence from rest is exactly cos(n theta) with sin(theta / 2) = omega dt / 2."""
    omega, dt = 314.0, 4e-4
    theta = 2 * math.asin(omega * dt / 2)
    n = np.arange(5001)
    assert np.max(np.abs(checks.mode_sequence(omega, 0.0, dt, 5000) - np.cos(n * theta))) <= 1e-9


def test_undamped_mode_kinetic_mean_is_half_the_discrete_amplitude() -> None:
    """v_n = -sin(n theta) sin(theta) / dt: over whole periods the mean of v_n^2 is sin(theta)^2 / (2 dt^2),
    omega^2 (1 - (omega dt / 2)^2) / 2."""
    omega, dt = 314.0, 1e-4
    theta = 2 * math.asin(omega * dt / 2)
    count = int(round(40 * math.pi / theta))  # 20 periods
    expected = 0.5 * omega**2 * (1 - (omega * dt / 2) ** 2)
    assert checks.mode_kinetic_mean(omega, 0.0, dt, 0, count) == pytest.approx(expected, rel=1e-4)


def test_measured_damping_ratio_recovers_the_ratio_and_the_continuous_decay() -> None:
    omega, dt, steps = 314.0, 3e-4, 700
    for zeta in (0.0, 0.004, 0.03):
        ratio = checks.mode_energy_ratio(omega, zeta, dt, steps)
        assert checks.measured_damping_ratio(omega, dt, steps, ratio) == pytest.approx(zeta, abs=1e-12)
    # against the continuous oscillator: E(T) / E(0) = exp(-2 zeta omega T) up to a wiggle of relative size zeta
    ratio = checks.mode_energy_ratio(omega, 0.01, dt, steps)
    assert ratio == pytest.approx(math.exp(-2 * 0.01 * omega * steps * dt), rel=0.02)
    assert math.isnan(checks.measured_damping_ratio(omega, dt, steps, -1.0))


# ---------------------------------------------------------------- the solver's summary
def test_top_mode_run_measures_the_stiffness_it_runs_with() -> None:
    """At the A that f_top sets, the kinetic energy is the closed form's (ratio 1); a lattice given twice that A
    (the stiffness parameter) oscillates at sqrt(2) f_top, so against the closed form at the f_top asked for its
    kinetic energy is twice as large, and the recomputed omega_max says sqrt(2) * 50 Hz."""
    base = _solve(**TOP_MODE, damping_ratio=0.0, setup_check=True)
    m = base.summary
    assert base.status == "ok"
    assert m["top_mode_kinetic_ratio"] == pytest.approx(1.0, abs=1e-4)
    assert m["f_top_check_hz"] == pytest.approx(50.0, rel=1e-12) and m["dt_safety_check"] == pytest.approx(0.05)
    assert abs(m["top_mode_damping_ratio"]) <= 1e-9  # undamped: no energy lost
    stiff = _solve(**TOP_MODE, damping_ratio=0.0, setup_check=True, stiffness=2 * m["stiffness_A"]).summary
    assert stiff["f_top_check_hz"] == pytest.approx(50.0 * math.sqrt(2), rel=1e-9)
    # 1.987: the closed form's window holds whole periods at 50 Hz, not at 70.7 Hz (a part period: |sin| / 4 omega T)
    assert stiff["top_mode_kinetic_ratio"] == pytest.approx(2.0, rel=1e-2)


def test_top_mode_start_is_the_top_mode_and_its_energy_is_its_frequency() -> None:
    """The start shape is held where the lattice is held, has largest displacement start_amplitude a, and its
    potential energy (the kernel's ledger at rest: E_start) is 1/2 m omega_max^2 |u|^2."""
    p = effective_params(SOLVER, TOP_MODE | {"damping_ratio": 0.0})
    s = prepare(PAPER, 2, p)
    x0 = checks.top_mode_start(s, 1e-5)
    u = x0 - s.lattice.positions
    assert np.all(u[s.fixes.held] == 0.0)
    assert np.linalg.norm(u, axis=1).max() == pytest.approx(1e-5 * s.lattice.a, rel=1e-12)
    sol = _solve(**TOP_MODE, damping_ratio=0.0)
    omega = 2 * math.pi * 50.0
    e0 = sol.diagnostics["energy"]["start"]  # v_{-1/2} v_{1/2} < 0 at rest: the (1 - (omega dt / 2)^2) factor
    assert e0 == pytest.approx(0.5 * s.lattice.mass * omega**2 * (u**2).sum() * (1 - 0.05**2), rel=1e-4)


def test_damped_top_mode_measures_the_damping_it_runs_with() -> None:
    """zeta = 0.01 as asked: measured 0.0099 (the radial damping mixes the top mode with others at O(zeta)); the
    same lattice given twice the pair damping (delta) decays at about twice the rate."""
    sol = _solve(**TOP_MODE, damping_ratio=0.01)
    m = sol.summary
    assert m["top_mode_damping_ratio"] == pytest.approx(0.01, rel=0.05)
    assert m["top_mode_kinetic_ratio"] == pytest.approx(1.0, abs=0.02)
    double = _solve(**TOP_MODE, delta=2 * m["delta"]).summary
    assert double["damping_ratio"] == pytest.approx(0.02, rel=0.05)  # the damped modal problem says so too
    assert double["top_mode_damping_ratio"] == pytest.approx(0.02, rel=0.05)


def test_red_pair_kinetic_energy_is_its_stroke_on_the_reduced_mass() -> None:
    """Symmetric drive: the red pair's summed hotness against 1/4 (m/2) (D a omega)^2 sinc(omega dt)^2 (whole
    periods of cos^2 average 1/2: checked to 1e-3, the window's part period) and the ratio the solver reports
    against the discrete closed form to rounding; the free-centre drive (the pair's centre moves) has none."""
    D, f = 0.02, 50.0
    sol = _solve(drive_amplitude=D, drive_frequency=f, drive_sharing="symmetric", t_end=1.0)
    lat_a, dt = sol.resolution["h"], sol.summary["dt"]
    mass = PAPER.material.density * PAPER.box.volume / sol.resolution["nodes"]
    omega = 2 * math.pi * f
    H = sol.diagnostics["hotness"]
    corner, below = (0.0, 0.01, 0.0), (0.0, 0.01 - lat_a, 0.0)
    pts = sol.samples["nodes"]["points"]
    idx = [int(np.argmin(np.linalg.norm(pts - np.array(q), axis=1))) for q in (corner, below)]
    expected = 0.25 * (0.5 * mass) * (D * lat_a * omega) ** 2 * (math.sin(omega * dt) / (omega * dt)) ** 2
    assert H[idx].sum() == pytest.approx(expected, rel=1e-3)
    assert sol.summary["red_pair_kinetic_ratio"] == pytest.approx(1.0, abs=1e-12)
    assert "red_pair_kinetic_ratio" not in _solve(drive_amplitude=D, t_end=1.0).summary


def test_cold_kinetic_max_reads_the_scene_points_not_the_fixes() -> None:
    """0 at the paper's frozen corners (held at rest); a hotness planted at one corner's node shows as its ratio
    to the hottest free particle."""
    p = effective_params(SOLVER, {})
    s = prepare(PAPER, 2, p)
    free = (s.fixes.kind == codes.FREE) & (s.fixes.gamma == 0.0)
    H = np.where(free, 1.0, 0.0)
    H[int(np.flatnonzero(free)[0])] = 4.0
    assert checks.cold_kinetic_max(PAPER, s, H, free) == {"cold_kinetic_max": 0.0}
    cold = [c for c in PAPER.constraints if c.value == 0.0][1]
    H[s.lattice.node_at(np.array(cold.point))] = 1.0
    assert checks.cold_kinetic_max(PAPER, s, H, free) == {"cold_kinetic_max": 0.25}
    assert _solve(t_end=1.0).summary["cold_kinetic_max"] == 0.0


def test_setup_check_reads_the_time_step_the_run_really_takes() -> None:
    """A dt given outright: dt_safety_check is dt omega_max / 2 with omega_max = 2 pi 50 Hz."""
    sol = _solve(dt=1e-4, t_end=0.1, setup_check=True)
    assert sol.summary["dt_safety_check"] == pytest.approx(1e-4 * math.pi * 50.0, rel=1e-12)
    assert "dt_safety_check" not in _solve(t_end=0.1).summary


def test_stop_deviation_is_the_change_between_the_stopped_and_the_whole_run() -> None:
    """stop_deviation against the relative hotness of the same cell solved twice, with the stop and without; a run
    that does not stop deviates by exactly 0."""
    given = {"damping_ratio": 0.1, "drive_amplitude": 0.02}  # stops at a quarter of its 15 s
    stopped = _solve(**given, stop_check=True)
    whole = _solve(**given, stop_tol=0.0)
    assert stopped.summary["stationary_at_step"] > 0 and stopped.summary["stationarity"] <= 0.02
    p = effective_params(SOLVER, given)
    s = prepare(PAPER, 2, p)
    free = (s.fixes.kind == codes.FREE) & (s.fixes.gamma == 0.0)
    dev = np.max(np.abs(stopped.diagnostics["relative_hotness_raw"] - whole.diagnostics["relative_hotness_raw"])[free])
    assert stopped.summary["stop_deviation"] == pytest.approx(float(dev), rel=1e-12) and 0 < dev <= 0.01
    assert _solve(**given | {"stop_tol": 0.0}, stop_check=True).summary["stop_deviation"] == 0.0


def test_the_specification_sees_what_the_self_checks_cannot() -> None:
    """The force law and lattice as built equal the lattice family's specification to round-off at the defaults;
    an unstable root off the midpoint (unstable_fraction 0.45: force and Hessian change together) still gives the
    50 Hz asked for by the model's own Hessian, but its roots, A and forces leave the specification."""
    scene = make_scene("bar-heat-lattice")
    for given, apart in (({}, False), ({"unstable_fraction": 0.45}, True)):
        s = prepare(scene, 2, effective_params(SOLVER, given))
        built = checks.force_law_summary(scene, s, 2) | {"stiffness_A": s.stiffness_A, "pairs": len(s.lattice.pairs)}
        spec = lattice.spec_scalars(scene, {"lattice_n": 2})
        assert checks.setup_summary(s)["f_top_check_hz"] == pytest.approx(50.0, rel=1e-12)
        off = {k for k in spec if k in built and abs(built[k] / spec[k] - 1.0) > 1e-12}
        if apart:
            assert {"force_root_2", "force_root_4", "force_root_6", "stiffness_A", "force_1p10a"} <= off
            assert not off & {"particles", "pairs", "particle_mass", "lattice_rms_radius", "force_root_1"}
        else:
            assert not off and set(spec) - set(built) == {"particles", "f_top_hz"}  # the run's own summary has them


# ---------------------------------------------------------------- the study's verification claims
VERIFICATION_GROUPS = ("top-mode", "top-mode-ends", "energy-balance", "red-pair", "energy-check", "stop-paper",
                       "stop-faces", "lattice-spec")


def test_every_verification_claim_of_the_macromolecule_study_passes_on_the_original(tmp_path, capsys) -> None:
    """The study's verification groups (25 cells, seconds) judged as `pcverify study --group` judges them: every
    claim on them passes, case by case (the values are those the claims' comments state)."""
    groups = [a for g in VERIFICATION_GROUPS for a in ("--group", g)]
    code = main(["study", "macromolecule", *groups, "--jobs", "1", "--out", str(tmp_path), "--json"])
    out = capsys.readouterr().out
    assert code == 0
    (doc,) = json.loads(out)
    verdicts = {(v["claim"], v["case"]): v["verdict"] for v in doc["verdicts"]}
    # 25 verdicts of the kernel against itself, 12 claims against the specification at n = 2, 3, 4
    assert len(verdicts) == 25 + 12 * 3 and set(verdicts.values()) == {"pass"}, verdicts
    assert {c for c, _ in verdicts} == {c.id for c in load_study("macromolecule").claims}


# ---------------------------------------------------------------- the mutant catalogues
@pytest.mark.parametrize("study", ["macromolecule", "stability"])
def test_the_catalogue_loads_and_every_mutant_applies_and_names_claims_of_its_study(study: str) -> None:
    path = study_files()[study]
    mutants = read_mutants_file(path.with_name(f"{study}.mutants.toml"))
    claims = {c.id for c in load_study(study).claims}
    assert len(mutants) >= {"macromolecule": 8, "stability": 2}[study]
    assert len({m.name for m in mutants}) == len(mutants)
    for m in mutants:
        source, edited = m.edited()
        assert m.changes_code(source, edited) and m.breaks, m.name
        assert m.expect and set(m.expect) <= claims, (m.name, m.expect)
    if study == "stability":
        assert sum(m.file == "harness/study/stability.py" for m in mutants) >= 2
