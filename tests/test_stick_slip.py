"""The stick-slip scene, its analytic reference, the MCA run's measurement and the scalar errors the compare step
stores.

The reference's closed form is checked against a direct integration of the rigid block (scipy, with the stick
and slip phases as events); the measurement of a run (solvers/particles/mca/stick_slip.measure) against the
rigid block's own history; the scene's bad values are one error line each (a tally per family at the end).
"""

from __future__ import annotations

import json
import math
import re

import numpy as np
import pandas as pd
import pytest
from red_team import check_tally, tally
from scipy.integrate import solve_ivp

from pcverify.harness.cli import main
from pcverify.harness.judge.compare import scalar_errors
from pcverify.harness.judge.verdict import judge
from pcverify.harness.study.catalogue import make_scene
from pcverify.harness.study.study import load_study
from pcverify.references import contact as ref
from pcverify.scene import Contact, SceneError
from pcverify.solvers.particles.mca import stick_slip as mss
from pcverify.solvers.particles.mca.solver import PARAMETERS

BLOCK = dict(mass=1.4e-3, normal_force=100.0, stiffness=5e4, speed=0.5, mu_static=0.4, mu_kinetic=0.3)


def rigid_block(mass, normal_force, stiffness, speed, mu_static, mu_kinetic, t_end, rows=40001):
    """The rigid block integrated directly: stick (x' = 0) until |F| reaches mu_s N, then slip under mu_k N until
    its velocity is 0 again; rows (t, F, x', x) on a uniform grid of `rows` times."""
    t_grid = np.linspace(0.0, t_end, rows)
    out = np.zeros((rows, 4))
    out[:, 0] = t_grid
    t, x = 0.0, 0.0
    k = 0
    while t < t_end:
        # stick: x constant until k (V t - x) = mu_s N
        t_break = (mu_static * normal_force / stiffness + x) / speed
        while k < rows and t_grid[k] <= min(t_break, t_end):
            out[k, 1:] = stiffness * (speed * t_grid[k] - x), 0.0, x
            k += 1
        t = t_break
        if t >= t_end:
            break

        def rhs(_, y):
            return [y[1], (stiffness * (speed * _ - y[0]) - mu_kinetic * normal_force) / mass]

        def stops(_, y):
            return y[1]

        stops.terminal, stops.direction = True, -1
        inside = t_grid[(t_grid > t) & (t_grid <= t_end)]
        sol = solve_ivp(rhs, (t, t_end), [x, 1e-12], t_eval=inside, events=stops, rtol=1e-11, atol=1e-14,
                        dense_output=True, max_step=1e-6)
        t_stop = sol.t_events[0][0] if len(sol.t_events[0]) else t_end
        while k < rows and t_grid[k] <= t_stop:
            y = sol.sol(t_grid[k])
            out[k, 1:] = stiffness * (speed * t_grid[k] - y[0]), y[1], y[0]
            k += 1
        t, x = t_stop, float(sol.sol(t_stop)[0])
    return out


def test_the_closed_form_cycle_is_the_rigid_blocks_integrated_directly() -> None:
    c = ref.cycle(**BLOCK)
    rows = rigid_block(**BLOCK, t_end=c.first_stick + 4 * c.period)
    m = mss.measure(rows, BLOCK["speed"])
    assert m["stick_slip_cycles"] == 3
    # the grid is 0.19 us; a slip's ends are the rows where the velocity is below REST_SPEED V, ~1.4 us inside the
    # slip at each end (REST_SPEED V m / Delta): slip time -0.4 %, stick +0.35 %, peak +0.09 %, trough -0.17 %,
    # drop +0.35 % (measured here); the period (start to start) and the largest force and velocity are unbiased
    for name, exact, tol in (("spring_peak_N", c.peak, 2e-3), ("spring_trough_N", c.trough, 3e-3),
                             ("force_drop_N", c.drop, 5e-3), ("spring_max_N", c.largest, 1e-4),
                             ("period_s", c.period, 1e-3), ("slip_s", c.slip, 6e-3), ("stick_s", c.stick, 6e-3),
                             ("slip_velocity_peak", c.slip_velocity, 1e-3)):
        assert m[name] == pytest.approx(exact, rel=tol), name
    # every slip of the block from mu_s N reaches the same largest force: the bound the study's claim judges with
    assert m["largest_spring_force_N"] == pytest.approx(c.largest, rel=1e-4)
    assert c.peak == 40.0 and c.drop == pytest.approx(20.0) and c.period == pytest.approx(1.4582854e-3, rel=1e-6)


def test_the_analytic_spring_force_follows_the_integrated_block() -> None:
    c = ref.cycle(**BLOCK)
    rows = rigid_block(**BLOCK, t_end=c.first_stick + 3 * c.period, rows=6001)
    force = ref.spring_force(rows[:, 0], **BLOCK)
    assert np.abs(force - rows[:, 1]).max() < 1e-3 * c.peak


def test_equal_coefficients_have_no_stick() -> None:
    c = ref.cycle(**(BLOCK | {"mu_static": 0.3}))
    assert c.stick == 0.0 and c.drop == 0.0 and c.peak == c.trough == pytest.approx(30.0)
    assert c.slip == pytest.approx(2 * math.pi / c.omega)


def test_the_scene_declares_the_rigid_block_the_reference_takes() -> None:
    s = ref.setting(make_scene("stick-slip"))
    assert s.mass == pytest.approx(2800 * 0.01 * 0.005 * 0.01) and s.normal_force == pytest.approx(100.0)
    assert (s.stiffness, s.speed, s.mu_static, s.mu_kinetic) == (5e4, 0.5, 0.4, 0.3)
    assert ref.setting(make_scene("block-sliding")) is None and ref.expected(make_scene("block-sliding")) == {}


def test_the_compare_step_stores_relative_errors_of_the_reported_scalars() -> None:
    scene = make_scene("stick-slip")
    got = scalar_errors(scene, {"spring_peak_N": 41.0, "period_s": math.nan, "slip_s": 6e-4, "other": 1.0})
    assert set(got) == set(ref.expected(scene)) | {f"{q}_given_peak" for q in (
        "spring_trough_N", "spring_max_N", "stick_s", "slip_s", "period_s", "slip_velocity_peak")}
    assert got["stick_s"]["value"] is None and got["stick_s"]["error"] is None
    assert got["spring_peak_N"]["error"] == pytest.approx(0.025) and got["spring_peak_N"]["expected"] == 40.0
    assert got["period_s"]["error"] is None and got["period_s"]["reference"] == "analytic"
    # the kinetic half from the measured breakaway (41 N): Delta' = 11 N
    given = ref.cycle(1.4e-3, 100.0, 5e4, 0.5, 0.41, 0.3)
    assert got["slip_s_given_peak"]["expected"] == pytest.approx(given.slip)
    assert got["slip_s_given_peak"]["error"] == pytest.approx(abs(6e-4 / given.slip - 1))
    below = scalar_errors(scene, {"spring_peak_N": 29.0, "slip_s": 6e-4})  # no slip from below mu_k N
    assert below["slip_s_given_peak"]["expected"] is None and below["slip_s_given_peak"]["error"] is None
    assert scalar_errors(make_scene("block-sliding"), {"spring_peak_N": 41.0}) == {}


def test_the_kinetic_half_from_the_static_limit_is_the_whole_cycle() -> None:
    c = ref.cycle(**BLOCK)
    given = ref.given_peak(ref.Setting(**BLOCK), c.peak)
    assert given == {"spring_trough_N_given_peak": c.trough, "spring_max_N_given_peak": c.largest,
                     "stick_s_given_peak": c.stick, "slip_s_given_peak": c.slip, "period_s_given_peak": c.period,
                     "slip_velocity_peak_given_peak": c.slip_velocity}
    assert ref.given_peak(ref.Setting(**BLOCK), 30.0) == {}


def test_an_incline_sticks_below_tan_theta_mu_s_and_slides_at_g_sin_minus_mu_k_cos_above() -> None:
    at = {a: ref.incline_acceleration(make_scene("incline", angle=a)) for a in (20.0, 21.8, 21.81, 30.0)}
    assert at[20.0] == at[21.8] == 0.0  # tan 21.8 deg = 0.39997 <= mu_s = 0.4
    assert at[21.81] == pytest.approx(1e5 * (math.sin(math.radians(21.81)) - 0.3 * math.cos(math.radians(21.81))))
    assert at[30.0] == pytest.approx(1e5 * (0.5 - 0.3 * math.sqrt(3) / 2))
    assert ref.incline_acceleration(make_scene("stick-slip")) is None
    got = scalar_errors(make_scene("incline"), {"slide_acceleration": 1.01 * at[30.0]})
    assert got["slide_acceleration"]["error"] == pytest.approx(0.01)
    stuck = scalar_errors(make_scene("incline", angle=20.0), {"slide_acceleration": 3.0})
    assert stuck["slide_acceleration"]["expected"] == 0.0 and stuck["slide_acceleration"]["error"] is None


def test_short_phases_merge_into_their_neighbours() -> None:
    moving = np.array([0, 0, 0, 1, 1, 1, 1, 0, 1, 1, 1, 1, 0, 0, 0, 0, 1, 0, 0, 0, 1, 1, 1], dtype=bool)
    assert mss.phases(moving) == [(3, 12), (20, 23)]


@pytest.mark.parametrize("setting, named", [
    ("mu_static=0.2", "mu_static=0.2 is out of range; allowed: number in [mu_kinetic=0.3, 5]"),
    ("mu_kinetic=-1", "mu_kinetic=-1.0 is out of range"),
    ("spring_stiffness=0", "spring_stiffness=0.0 is out of range"),
    ("speed=-0.5", "speed=-0.5 is out of range"),
    ("duration=2", "duration=2.0 is out of range"),
    ("mu_static=nan", "mu_static=nan is out of range"),
    ("angle=95", "angle=95.0 is out of range"),
    ("gravity=0", "gravity=0.0 is out of range"),
])
def test_a_bad_scene_value_is_one_error_line(setting, named, capsys) -> None:
    scene = "incline" if setting.startswith(("angle", "gravity")) else "stick-slip"
    code = main(["run", scene, "--solver", "mca", "--set", setting])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and err[0].startswith("pcverify: error: ") and named in err[0], err
    tally("stick-slip scene", "rejected")


@pytest.mark.parametrize("fields, named", [
    ({"mu_static": 0.4, "mu_kinetic": 0.3}, "not allowed without spring_stiffness"),
    ({"spring_stiffness": 5e4, "mu_static": 0.4, "mu_kinetic": 0.3, "speed": 0.0}, "not allowed without speed"),
    ({"spring_stiffness": 5e4, "speed": 1.0, "normal_stress": 1e6, "duration": 1e-3}, "mu_kinetic=None"),
    ({"incline_angle": 30.0, "mu_static": 0.4, "mu_kinetic": 0.3}, "both (an incline) or neither"),
    ({"incline_angle": 30.0, "gravity": 1e5, "mu_static": 0.4, "mu_kinetic": 0.3, "normal_stress": 1e6},
     "not allowed with a spring, a speed or a normal_stress"),
    ({"incline_angle": 90.0, "gravity": 1e5, "mu_static": 0.4, "mu_kinetic": 0.3},
     "incline_angle=90.0 is out of range"),
])
def test_a_contact_refuses_a_spring_or_friction_pair_out_of_place(fields, named) -> None:
    with pytest.raises(SceneError, match=re.escape(named)):
        Contact(axis="y", position=0.005, direction="z", **fields)
    tally("stick-slip contact", "rejected")


def test_the_regularised_law_does_not_stick(capsys) -> None:
    """Today's law (no static friction): the slider slides steadily behind the spring, so the run has no cycle to
    measure and fails saying so (the study's claims then fail on it)."""
    law = ["--set", "friction_law=regularised"] if "friction_law" in {p.name for p in PARAMETERS} else []
    code = main(["run", "stick-slip", "--solver", "mca", "--n", "4", *law, "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == 1 and out["status"] == "failed"
    assert out["reason"].startswith("no stick-slip cycle to measure: 0 slips after the first")
    assert out["summary"]["slipping_share"] > 0.5 and out["summary"]["first_peak_N"] < 40.0
    assert (out["scalar_errors"].get("spring_peak_N") or {}).get("error") is None


def test_zz_stick_slip_tally() -> None:
    check_tally({"stick-slip scene": 8, "stick-slip contact": 6})


def test_the_force_bound_is_judged_on_a_run_a_blow_up_stopped() -> None:
    """A slider that runs away (a spring pushing it, say) blows up before it makes a cycle: the cycle claims have
    nothing to read, the bound on every row of the run measures it on the rows kept up to the blow-up."""
    claim = next(c for c in load_study("stick-slip").claims if c.id == "stick-slip-force-bounded")
    rows = pd.DataFrame({"group": "cycle", "scene": "stick-slip", "solver": "mca", "n": [4, 6],
                         "status": ["ok", "unstable"], "reason": ["", "kinetic energy above the blow-up limit"],
                         "largest_spring_force_N": [38.0, 595.0], "ref.spring_max_N": [40.84, 40.84]})
    verdicts = {v["case"]: v for v in judge("stick-slip", claim, {"cycle-cells": rows})}
    assert verdicts["n=4"]["verdict"] == "pass"
    assert verdicts["n=6"]["verdict"] == "fail" and verdicts["n=6"]["value"] == 595.0
