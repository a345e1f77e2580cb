"""MCA pair states at the kernel level: unlinked pairs carry compression and Coulomb friction only,
re-linking (micro-welding) on compression, and the pair-list rebuild after large motion.

A 2 x 2 x 2 block of automata (h = 5 mm); one step of the force routine is applied to a prescribed
displacement increment, and the pair forces are compared with the contact law written out by hand.
"""

from __future__ import annotations

import numpy as np
import pytest

from pcverify.solvers.particles.mca import kernel as mk
from pcverify.solvers.particles.mca.automata import build_automata
from pcverify.solvers.particles.mca.model import Elastic, Model, rebuild_pairs

H = 0.005
EL = Elastic(70e9, 0.33)


def _model(**kw) -> tuple[Model, object]:
    aut = build_automata(np.full(3, H), (2, 2, 2), 2800.0)
    model = Model(aut, EL, fracture=False, **kw)
    return model, model.new_state()


def _forces(model: Model, st, dx: np.ndarray) -> None:
    """Move by dx (N, 3) and evaluate the pair forces once (as one kernel step would)."""
    st.x[:] += dx
    st.dx[:] = dx
    st.rot.dphi[:] = 0.0
    mk.forces(st, model.params)


def _z_pair(model: Model) -> int:
    return int(np.flatnonzero(model.aut.axis == 2)[0])


@pytest.mark.parametrize("sign", [-1.0, 1.0])
def test_unlinked_pair_carries_compression_only(sign):
    model, st = _model()
    st.linked[:] = 0
    p = _z_pair(model)
    i, j = model.aut.pairs[p]
    dx = np.zeros((model.aut.size, 3))
    delta = 1e-3 * H
    dx[j, 2] = sign * delta
    _forces(model, st, dx)
    expected = EL.contact * min(0.0, sign * delta / H)  # total form: kc min(0, (r - r0) / r0)
    assert st.sig[p] == pytest.approx(expected, rel=1e-9, abs=1e-6)
    assert st.f[j, 2] == pytest.approx(-expected * model.aut.area[p], rel=1e-9, abs=1e-9)
    others = np.setdiff1d(np.arange(len(st.sig)), [p])
    assert np.all(st.sig[others] == 0.0)


def test_unlinked_pair_friction_is_capped_by_coulomb():
    model, st = _model(friction=0.3)
    st.linked[:] = 0
    p = _z_pair(model)
    _, j = model.aut.pairs[p]
    dx = np.zeros((model.aut.size, 3))
    dx[j, 2] = -1e-3 * H  # compression
    dx[j, 0] = 1e-2 * H  # sliding: the elastic trial tangential stress far exceeds mu |sig|
    _forces(model, st, dx)
    assert st.sig[p] < 0
    assert np.linalg.norm(st.tau[p]) == pytest.approx(0.3 * abs(st.sig[p]), rel=1e-9)
    # a linked pair under the same increment keeps its elastic tangential stress 2G delta_t / r0
    model2, st2 = _model()
    _forces(model2, st2, dx)
    assert np.linalg.norm(st2.tau[p]) > 10 * np.linalg.norm(st.tau[p])


def test_relinking_on_compression():
    model, st = _model(relink_stress=50e6)
    st.linked[:] = 0
    p = _z_pair(model)
    _, j = model.aut.pairs[p]
    dx = np.zeros((model.aut.size, 3))
    dx[j, 2] = -1e-4 * H  # kc * 1e-4 = 10 MPa: below the welding stress
    _forces(model, st, dx)
    assert st.linked[p] == 0
    dx[j, 2] = -1e-3 * H  # now 0.0011 total: about 114 MPa of compression
    _forces(model, st, dx)
    assert st.linked[p] == 1 and st.counters[mk.C_RELINK] == 1


def test_pair_list_rebuild_adds_the_new_neighbours_unlinked():
    model, st = _model()
    a = model.aut
    # bring the two automata of a face diagonal (not listed) to contact distance
    far = np.flatnonzero(np.all(np.isclose(a.positions, [H, H, 0.0]), axis=1))[0]
    st.x[far] = a.positions[0] + [0.9 * H, 0.0, 0.0]
    before = len(a.pairs)
    st, added = rebuild_pairs(model, st)
    assert added >= 1 and len(model.aut.pairs) == before + added
    new = model.aut.pairs[before:]
    assert any(set(pr) == {0, far} for pr in new.tolist())
    assert np.all(st.linked[before:] == 0) and np.all(st.sig[before:] == 0.0)
    assert np.array_equal(st.xref, st.x)
