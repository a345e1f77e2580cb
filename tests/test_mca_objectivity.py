"""MCA pair law under rigid motion: the incremental shear update is objective, the pair forces' net couple is zero.

A 3 x 3 x 3 block of automata (h = 5 mm, rotations on, krot 0.01 as the solver's default), unstressed or
pre-strained by a uniform strain (every component non-zero, |eps| ~ 1e-3: sig and tau non-zero), is turned
rigidly by 90° in equal increments: each increment moves the positions by the exact rotation about the
block's centre and sets every automaton's spin increment dphi to the same rotation vector, then evaluates the
pair-force function once (`mk.forces`, as one kernel step would).  A rigid motion must leave the stresses as
they were, turned with the body: sig unchanged, tau and the forces turned by the total rotation.

Bound: each evaluation adds round-off of a few ulp of the stress scale 2G to sig (the increment of r) and tau
(the difference d_new - R d_old), so after N increments the error is at most of order N eps_mach 2G (1.05 Pa at
N = 90 000); asserted: 2 N eps_mach 2G. Measured after the update: 0.34 Pa on tau and 0.83 Pa on sig at N = 90
000 (sig's is the incremental normal law, unchanged by this update; it is mostly the block's own round-off
stretch, the rotation matrix applied 90 000 times: kn dr / r0 up to 0.38 Pa). Measured before (the projection
update): 3.16e8 / 3.16e7 / 3.16e6 / 3.16e5 Pa at 1° / 0.1° / 0.01° / 0.001° steps about (0.3, 0.5, 0.8) (first
order in the step), 4.2e6 / 4.2e4 / 420 / 4.24 Pa about z and x (third order: only the 0.001° steps come near
the bound, at twice it), 5.4e7-8.3e7 Pa in the pre-strained block at every step size, and 2.6e7 Pa in the
unlinked (sliding) block. The 1° steps take the exact (trigonometric) branch of the rotation, the others its
series.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from pcverify.solvers.particles.mca import kernel as mk
from pcverify.solvers.particles.mca.automata import build_automata
from pcverify.solvers.particles.mca.model import Elastic, Model

H = 0.005
EL = Elastic(70e9, 0.33)
STRAIN = np.array([[1.0, 0.3, -0.2], [0.3, -0.5, 0.4], [-0.2, 0.4, 0.7]]) * 1e-3
AXES = {"oblique": (0.3, 0.5, 0.8), "z": (0.0, 0.0, 1.0), "x": (1.0, 0.0, 0.0)}


def _rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return np.eye(3) + math.sin(angle) * k + (1.0 - math.cos(angle)) * k @ k


def _block(rotations: bool = True, prestrain: bool = False) -> tuple[Model, mk.State, np.ndarray]:
    """The block at rest or after one evaluation of a uniform strain increment; its centre."""
    aut = build_automata(np.full(3, 2 * H), (3, 3, 3), 2800.0)
    model = Model(aut, EL, rotations=rotations, krot=0.01)
    st = model.new_state()
    centre = aut.positions.mean(axis=0)
    if prestrain:
        _move(model, st, st.x + (aut.positions - centre) @ STRAIN.T, np.zeros(3))
    return model, st, centre


def _move(model: Model, st: mk.State, x_new: np.ndarray, dphi: np.ndarray) -> None:
    st.dx[:] = x_new - st.x
    st.x[:] = x_new
    if st.rot is not None:
        st.rot.dphi[:] = dphi
        st.rot.phi[:] += dphi
    mk.forces(st, model.params)


def _turn(model: Model, st: mk.State, centre: np.ndarray, axis: tuple[float, ...], step_deg: float,
          total_deg: float = 90.0) -> tuple[np.ndarray, int]:
    """Turn the block rigidly by total_deg about `axis` in steps of step_deg; returns (total rotation, steps)."""
    a = np.asarray(axis) / np.linalg.norm(axis)
    steps = int(round(total_deg / step_deg))
    rot = _rotation(a, math.radians(step_deg))
    for _ in range(steps):
        _move(model, st, (st.x - centre) @ rot.T + centre, math.radians(step_deg) * a)
    return _rotation(a, math.radians(step_deg) * steps), steps


@pytest.mark.parametrize("prestrain", [False, True], ids=["unstressed", "prestrained"])
@pytest.mark.parametrize("axis", list(AXES), ids=list(AXES))
@pytest.mark.parametrize("step_deg", [1.0, 0.1, 0.01, 0.001])
def test_a_rigid_turn_leaves_the_stresses_turned_with_the_body(axis, step_deg, prestrain):
    model, st, centre = _block(prestrain=prestrain)
    sig0, tau0, f0, mom0 = st.sig.copy(), st.tau.copy(), st.f.copy(), st.rot.mom.copy()
    if prestrain:  # the pre-strain really loads both stresses (MPa), so "turned with the body" is tested
        assert np.abs(sig0).max() > 1e7 and np.abs(tau0).max() > 1e7
    total, steps = _turn(model, st, centre, AXES[axis], step_deg)
    bound = 2.0 * steps * np.finfo(float).eps * 2.0 * EL.shear  # Pa: see the module docstring
    assert np.abs(st.sig - sig0).max() <= bound
    assert np.abs(st.tau - tau0 @ total.T).max() <= bound
    face = 6.0 * model.aut.area.max()  # the most a bound per pair adds up to on one automaton
    arm = 0.5 * H * (1.0 + 1e-2)
    assert np.abs(st.f - f0 @ total.T).max() <= bound * face
    assert np.abs(st.rot.mom - mom0 @ total.T).max() <= bound * face * arm


def test_unlinked_pairs_turn_their_friction_with_the_body():
    """Every pair unlinked (contact only: compression, and the tangential stress capped at mu |sig|): a block
    compressed (-1e-3) and sheared (3e-3, the elastic trial far beyond the cap, so every pair slides at
    |tau| = 0.3 |sig|) keeps its stresses, turned, through a rigid turn about the oblique axis."""
    model, st, centre = _block()
    st.linked[:] = 0
    strain = np.array([[-1.0, 0.0, 3.0], [0.0, -1.0, 3.0], [3.0, 3.0, -1.0]]) * 1e-3
    _move(model, st, st.x + (st.x - centre) @ strain.T, np.zeros(3))
    sig0, tau0 = st.sig.copy(), st.tau.copy()
    sliding = np.linalg.norm(tau0, axis=1) >= 0.3 * np.abs(sig0) * (1 - 1e-12)
    assert np.all(sig0 < -1e7) and sliding.sum() >= len(sig0) // 2
    total, steps = _turn(model, st, centre, AXES["oblique"], 0.01)
    bound = 2.0 * steps * np.finfo(float).eps * EL.contact
    assert np.abs(st.sig - sig0).max() <= bound
    assert np.abs(st.tau - tau0 @ total.T).max() <= bound


def test_the_pair_forces_of_a_strained_spinning_block_have_no_net_couple():
    """Pairs are internal: their forces and moments sum to zero force and zero couple (angular momentum).
    Measured: net couple / sum of |x x f| = 6e-17 after, 4.5e-4 before (moment arms r0/2 with r != r0)."""
    model, st, centre = _block()
    rng = np.random.default_rng(1)
    x_new = st.x + (st.x - centre) @ STRAIN.T + 1e-6 * H * rng.standard_normal(st.x.shape)
    _move(model, st, x_new, 1e-4 * rng.standard_normal(st.x.shape))
    moment_arms = np.cross(st.x - centre, st.f)
    scale = np.abs(moment_arms).sum()
    couple = moment_arms.sum(axis=0) + st.rot.mom.sum(axis=0)
    assert np.abs(st.f.sum(axis=0)).max() <= 1e-13 * np.abs(st.f).sum()
    assert np.abs(couple).max() <= 1e-13 * scale


def test_a_free_spinning_strained_block_keeps_its_angular_momentum():
    """Undamped velocity Verlet of the free block: pre-strained, spinning rigidly at (300, 500, 800) rad/s,
    run until an automaton leaves the skin.  Measured: angular momentum kept to 5e-14 (relative) after,
    drifting by 3.1 % before."""
    model, st, centre = _block(prestrain=True)
    omega = np.array([300.0, 500.0, 800.0])
    st.v[:] = np.cross(omega, st.x - centre)
    st.rot.w[:] = omega
    st.dx[:] = 0.0
    mass, inertia = model.aut.mass[:, None], model.aut.inertia[:, None]

    def momentum() -> np.ndarray:
        cm = (mass * st.x).sum(axis=0) / mass.sum()
        return (mass * np.cross(st.x - cm, st.v)).sum(axis=0) + (inertia * st.rot.w).sum(axis=0)

    l0 = momentum()
    status = model.advance(st, 2000)
    assert status in (mk.OK, mk.MOVED) and int(st.counters[mk.C_STEPS]) > 500
    assert np.abs(momentum() - l0).max() <= 1e-11 * np.abs(l0).max()


def test_without_rotations_a_rigid_turn_is_read_as_shear_as_documented():
    """rotations = false holds the automata unturned: a rigid turn of the body is shear to the pair law, about
    2 G per radian (the limitation stated in kernel.py, solver.py and docs/physics.md; the same before
    and after the objective update, which cannot see a rotation the automata are not allowed).  Measured after
    a 1° turn in 0.1° steps about z: 0.92 GPa = 2 G theta to 0.1 %."""
    model, st, centre = _block(rotations=False)
    _turn(model, st, centre, AXES["z"], 0.1, total_deg=1.0)
    assert np.abs(st.tau).max() == pytest.approx(2.0 * EL.shear * math.radians(1.0), rel=2e-3)
