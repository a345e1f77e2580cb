"""MCA contact forces at the contact point, the slip velocity of the contact points and static friction.

- A closed contact exerts no net force and no net couple: its forces act at the contact point with their
  moments (measured independently: sum f and sum x x f + M over every automaton of a pressed, sliding pair
  whose bodies are otherwise unstrained, so that everything left is the contact's).
- Two pressed bodies spinning rigidly together do not slip: no friction force, no friction power.
- A sliding run balances angular momentum (the held automata's reaction moments, the load's and the damping's
  against the change of sum m x x v + J w), with the regularised and with the static law.
- Static friction (Cundall-Strack): a slave pressed on a held facet and pulled below mu_s N stays at its
  elastic spring deflection; above mu_s N it slides; a stored spring stress is carried with a rigid rotation.
- Bad input: mu_s below mu1, and a sliding contact without rotations, are one error line each.
Cases are counted per family (tests/red_team.py's tally) and the last test asserts how many were tried.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from red_team import TALLY, check_tally, tally
from scipy.spatial.transform import Rotation

from pcverify.harness.cli import main
from pcverify.harness.study.catalogue import make_scene
from pcverify.scene import Resolution
from pcverify.solvers.particles.mca import contact as ct
from pcverify.solvers.particles.mca import kernel as mk
from pcverify.solvers.particles.mca import roughness as rg
from pcverify.solvers.particles.mca.automata import body_automata
from pcverify.solvers.particles.mca.model import Elastic, Model
from pcverify.solvers.registry import get_solver

E, NU = 70e9, 0.33
G = E / (2 * (1 + NU))
NO_ROUGHNESS = rg.Roughness(on=False, a1=0.0, a2=0.0, d1=1.0, d2=1.0, spread=0.0, seed=0)


def _law(h0: float, **kw) -> ct.ContactLaw:
    """Dry friction mu1 = 0.3 regularised below v_reg = 0.05 m/s (the solver's defaults); kw: more fields."""
    given = dict(mu0=0.0, mu1=0.3, sigma0=math.inf, v_reg=0.05, rough=NO_ROUGHNESS, axis=2, direction=0) | kw
    return ct.ContactLaw(h0=h0, **given)


def _pressed_pair(press: float, shift: tuple[float, float]):
    """The block-contact-compression stack at n = 4 with rotations: body 2 moved rigidly into body 1 by `press`
    spacings along z and by `shift` spacings in x, y (oblique facet weights); every body unstrained, so the
    pairs carry nothing but the many-body share of the contact's volume strain (equal and opposite, central)."""
    scene = make_scene("block-contact-compression")
    aut, bonded = body_automata(scene.box, 4, scene.material.density, scene.contact)
    a = float(aut.spacing[2])
    model = Model(aut, Elastic(E, NU), rotations=True, krot=0.01, contact=_law(a), step_automata=bonded)
    st = model.new_state()
    top = aut.body == 1
    st.x[top] += np.array([shift[0] * a, shift[1] * a, -press * a])
    return model, st, a


def _net(st, centre: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Net force and net couple about `centre` of every automaton's force and moment."""
    return st.f.sum(axis=0), (np.cross(st.x - centre, st.f) + st.rot.mom).sum(axis=0)


def test_a_closed_contact_exerts_no_net_force_and_no_net_couple():
    """Body 2 slides at (1, 0.5) m/s over body 1 with its automata spinning (1e3 rad/s about random axes): the
    friction is dry (above v_reg) and large; summed over all automata, force and couple vanish to round-off
    (before: the forces at the centres left the couple h0 F_R, 0.3 h0 F_N)."""
    model, st, a = _pressed_pair(1e-3, (0.3, 0.2))
    top = model.aut.body == 1
    st.v[top] = [1.0, 0.5, 0.0]
    st.rot.w[:] = np.random.default_rng(1).normal(0.0, 1e3, st.rot.w.shape)
    mk.forces(st, model.params)
    fn = float(-(st.contact.sigma * st.contact.area).sum())
    friction = float(np.linalg.norm(st.contact.fric, axis=1).sum())
    assert fn > 0 and friction > 0.25 * fn  # a closed, sliding contact: the check is not vacuous
    force, couple = _net(st, st.x.mean(axis=0))
    assert np.linalg.norm(force) < 1e-12 * fn
    assert np.linalg.norm(couple) < 1e-12 * fn * a  # measured 2e-16 (before: 0.29 fn a)
    tally("contact-moments", "accepted")


@pytest.mark.parametrize("spin", [10.0, 100.0])
def test_a_rigidly_spinning_pressed_pair_does_not_slip(spin):
    """The pressed pair turned by 0.4 rad about x and spinning rigidly about x at `spin` rad/s (the contact
    points' velocities differ by spin h0 between the centres): no friction force, no friction power (before:
    friction / normal 0.15 and 0.3, and the power spin h0 mu F_N)."""
    model, st, a = _pressed_pair(1e-3, (0.0, 0.0))
    centre = np.array([0.0, 0.0075, 0.015])
    turn = Rotation.from_rotvec([0.4, 0.0, 0.0])
    st.x[:] = turn.apply(st.x - centre) + centre
    omega = np.array([spin, 0.0, 0.0])
    st.v[:] = np.cross(omega, st.x - centre)
    st.rot.w[:] = omega
    mk.forces(st, model.params)
    con = st.contact
    fn = float(-(con.sigma * con.area).sum())
    assert fn > 0 and (con.facet >= 0).sum() == 16
    assert float(np.abs(con.fric).max()) < 1e-12 * fn  # measured ~1e-15
    assert float(con.power.sum()) < 1e-12 * fn * spin * a
    tally("objective-slip", "accepted")


def _one_facet(law: ct.ContactLaw):
    """A slave (index 3) over one held triangle (0, 1, 2) = ((0,0,0), (r,0,0), (0,r,0)), r = 1 mm, pressed to
    h = 0.999 h0 (normal force E S 1e-3 = 70 N, lam = 0): positions, velocities, masses and the contact state."""
    r = 1e-3
    x = np.array([[0.0, 0.0, 0.0], [r, 0.0, 0.0], [0.0, r, 0.0], [0.3e-3, 0.3e-3, 0.999e-3]])
    con = ct.ContactState(
        slave=np.array([3]), faces=np.array([[False] * 4 + [True, False]]), facets=np.array([[0, 1, 2]]),
        side=np.array([5]), cand_ptr=np.array([0, 1]), cand=np.array([0]), extent=np.full((4, 3), r),
        facet=np.full(1, -1), w=np.zeros((1, 3)), nrm=np.zeros((1, 3)), gap=np.zeros(1), area=np.zeros(1),
        sigma=np.zeros(1), fric=np.zeros((1, 3)), speed=np.zeros(1), power=np.zeros(1), dissipated=np.zeros(1),
        heat=np.zeros(4), held=np.zeros((4, 3), dtype=np.int64), reaction=np.zeros((2, 3)), impulse=np.zeros((2, 3)),
        held_rot=np.zeros((4, 3), dtype=np.int64), moment=np.zeros((2, 3)), angular_impulse=np.zeros((2, 3)),
        tang=np.zeros((1, 3)), tnrm=np.zeros((1, 3)), slipping=np.zeros(1, dtype=np.int64), rough=rg.new_state(1),
        law=law)
    return x, np.zeros((4, 3)), con


def _pull(law: ct.ContactLaw, load: float, steps: int = 3000, dt: float = 1e-8, mass: float = 1e-4):
    """The slave pulled along x by `load` (N) from rest, its height held (constant normal force 70 N), the facet
    held: semi-implicit Euler over `steps` steps; returns its displacement along x per step and the state."""
    x, v, con = _one_facet(law)
    masses = np.array([1e30, 1e30, 1e30, mass])
    x0 = float(x[3, 0])
    path = np.empty(steps)
    f = np.zeros((4, 3))
    for i in range(steps):
        f[:] = 0.0
        ct.geometry(x, np.full(4, 1e-9), con, np.zeros(4))
        ct.forces(x, v, f, np.zeros(4), masses, E, 0.0, dt, con, None)
        v[3, 0] += dt * (f[3, 0] + load) / mass
        x[3, 0] += dt * v[3, 0]
        path[i] = x[3, 0] - x0
    return path, con


STATIC = dict(static=True, mu_s=0.5, kt=2 * G / 1e-3)
NORMAL = E * 1e-6 * 1e-3  # 70 N
SPRING = STATIC["kt"] * 1e-6  # N/m: kt S


@pytest.mark.parametrize("ratio", [0.0, 0.31, 0.45, 0.49])
def test_static_friction_holds_below_mu_s_at_its_elastic_deflection(ratio):
    """Pulled by ratio N (below mu_s N = 0.5 N; 0.31 and 0.45 above the kinetic mu1 N = 0.3 N): the slave never
    moves beyond the spring's deflection at the static limit, mu_s N / (kt S), and comes to rest at load / (kt
    S) (viscous mu0 damps the spring critically: no overshoot beyond the load's deflection)."""
    law = _law(1e-3, mu0=1.5e8, **STATIC)
    path, con = _pull(law, ratio * NORMAL)
    assert float(np.abs(path).max()) <= 0.5 * NORMAL / SPRING
    assert path[-1] == pytest.approx(ratio * NORMAL / SPRING, rel=1e-3, abs=1e-15)
    assert con.slipping[0] == 0 and np.linalg.norm(con.tang[0]) == pytest.approx(ratio * NORMAL / 1e-6, rel=1e-3,
                                                                                    abs=1e-6)
    tally("static-friction", "accepted")


@pytest.mark.parametrize("ratio", [0.51, 0.8])
def test_static_friction_slides_above_mu_s_against_the_kinetic_limit(ratio):
    """Pulled by ratio N above mu_s N: the slave slips, and while it slips the friction is the kinetic mu1 N (its
    acceleration (load - mu1 N) / m: the displacement at the end is 100 times the static deflection)."""
    law = _law(1e-3, mu0=0.0, **STATIC)
    path, con = _pull(law, ratio * NORMAL)
    assert path[-1] > 100 * 0.5 * NORMAL / SPRING
    assert con.slipping[0] == 1
    assert -con.fric[0, 0] == pytest.approx(0.3 * NORMAL, rel=1e-9)
    tally("static-friction", "accepted")


def test_the_regularised_law_has_no_stick():
    """The default law under the same load as the stuck static case (0.45 N): it creeps (viscous below v_reg),
    far beyond the static law's deflection -- the reason for the static option."""
    path, _ = _pull(_law(1e-3, mu0=1.5e8), 0.45 * NORMAL, steps=20000)
    assert path[-1] > 10 * 0.45 * NORMAL / SPRING
    tally("static-friction", "accepted")


def test_the_stored_spring_stress_turns_with_a_rigid_rotation():
    """A stuck contact carrying 10 MPa along x, turned rigidly by 90 degrees about (0.3, 0.5, 0.8) in 900 steps
    (positions rotated, velocities and spins of the rigid rotation): the stored stress keeps its magnitude to
    round-off and turns with the bodies (the minimal rotation of the normal plus the exact twist of the step's
    rotation about it: exact, measured about 2e-13 of its magnitude; the first-order twist left 1.1e-7 here and
    1.1e-5 at 1-degree steps), never just projected on the new plane.  Bound: 10 eps per step and per 90 degrees
    the round-off of the rigid velocities through the tangential spring (as tests/test_mca_contact_facet.py
    derives it), 1e-10."""
    law = _law(1e-3, mu1=0.3, **{**STATIC, "mu_s": 5.0})
    x, v, con = _one_facet(law)
    ct.geometry(x, np.full(4, 1e-9), con, np.zeros(4))
    con.tang[0] = [1e7, 0.0, 0.0]
    con.tnrm[0] = con.nrm[0]
    axis = np.array([0.3, 0.5, 0.8]) / np.linalg.norm([0.3, 0.5, 0.8])
    steps, total = 900, 0.5 * math.pi
    dt = 1e-6
    omega = axis * total / (steps * dt)
    step = Rotation.from_rotvec(axis * total / steps)
    centre = x.mean(axis=0)
    rot = mk.Rotation(phi=np.zeros((4, 3)), w=np.tile(omega, (4, 1)), mom=np.zeros((4, 3)), dphi=np.zeros((4, 3)),
                      inertia=np.full(4, 1e-12))
    for _ in range(steps):
        x[:] = step.apply(x - centre) + centre
        v[:] = np.cross(omega, x - centre)  # the rigid velocity field at the positions the contact sees
        ct.geometry(x, np.full(4, 1e-9), con, np.zeros(4))
        ct.forces(x, v, np.zeros((4, 3)), np.zeros(4), np.ones(4), E, 0.0, dt, con, rot)
    expected = Rotation.from_rotvec(axis * total).apply([1e7, 0.0, 0.0])
    assert np.linalg.norm(con.tang[0]) == pytest.approx(1e7, rel=1e-9)
    assert np.linalg.norm(con.tang[0] - expected) < 1e-10 * 1e7
    assert con.slipping[0] == 0
    tally("objective-slip", "accepted")


@pytest.mark.parametrize("law, params", [("regularised", {}), ("static", {"friction_law": "static", "mu_s": 0.5})])
def test_sliding_balances_angular_momentum_and_energy(law, params):
    """block-sliding at n = 4 (1 MPa, 1 m/s, every contact slipping): the held automata's reaction moments, the
    load's and the damping's, less the change of sum m x x v + J w, vanish over the window (measured 2.2e-5 and
    1.8e-5 of F_N h0; before, with the forces at the centres: 0.29997, the couple h0 mu1 F_N); mu_dr is the
    kinetic mu1 and the energy balance closes with the static law's spring energy stored and only its slip
    dissipated (measured 2.2e-7)."""
    sol = get_solver("mca").solve(make_scene("block-sliding"), Resolution(4), max_steps=200000, **params)
    s = sol.summary
    assert sol.status == "ok", sol.reason
    assert s["angular_momentum_error"] < 1e-3
    assert s["mu_dr_mean"] == pytest.approx(0.3, rel=1e-4)
    assert s["energy_balance_error"] < 1e-5 and s["newton_error"] < 1e-6
    tally("contact-moments", "accepted")


@pytest.mark.parametrize("args, names", [
    (["--set", "mu_s=0.2"], ("mu_s=0.2", "mu1=0.3", "mu_s >= mu1")),
    (["--set", "friction_law=static", "--set", "mu_s=0.1", "--set", "mu1=0.2"], ("mu_s=0.1", "mu_s >= mu1")),
    (["--set", "rotations=false"], ("rotations=false", "rotations=true")),
])
def test_bad_friction_input_is_one_error_line(args, names, capsys, tmp_path, monkeypatch):
    """mu_s below mu1, and a sliding contact without rotations (its moments would have nowhere to go), are refused
    before any step: one line naming the parameter and the allowed range, exit 2, nothing written."""
    monkeypatch.chdir(tmp_path)
    code = main(["run", "block-sliding", "--solver", "mca", "--n", "4", *args])
    out, err = capsys.readouterr()
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert code == 2 and len(lines) == 1 and lines[0].startswith("pcverify: error: ")
    assert all(n in lines[0] for n in names) and "Traceback" not in err
    assert not list(tmp_path.iterdir())
    tally("contact-input", "rejected")


def test_zz_contact_objectivity_tally():
    expected = {"contact-moments": 3, "objective-slip": 3, "static-friction": 7, "contact-input": 3}
    check_tally(expected)
    assert all(TALLY[f"{f} tried"] == n for f, n in expected.items())
