"""The lattice family's specification of the macromolecule model (references/lattice.py) states physical facts of
its own definition: the force vanishes at its seven roots and changes sign there, the shells a, sqrt2 a, sqrt3 a
are stable (dF/dr > 0) and the gaps' roots unstable, F and dF/dr vanish at 2a, the lattice has the paper's 16, 63
and 160 particles, and A makes the held lattice's top frequency 50 Hz (an independent assembly: scipy's sparse
eigensolver on a Hessian built pair by pair)."""

import math

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from pcverify.harness.study.catalogue import make_scene
from pcverify.references import lattice


def test_the_force_vanishes_and_changes_sign_at_its_roots() -> None:
    roots = lattice.roots()
    assert np.allclose(roots[0::2], [1.0, math.sqrt(2.0), math.sqrt(3.0), 2.0], rtol=0, atol=1e-15)
    assert np.all(np.abs(lattice.force(roots, 1.0)) < 1e-15)
    eps = 1e-6  # F ~ F'(x_k) (x - x_k): the signs alternate across the six roots below 2
    left, right = lattice.force(roots[:6] - eps, 1.0), lattice.force(roots[:6] + eps, 1.0)
    assert np.all(left * right < 0)
    slopes = np.array([lattice.root_slope(k) for k in range(6)])
    assert np.all(slopes[0::2] > 0) and np.all(slopes[1::2] < 0)  # stable shells, unstable gaps
    # the STEP's zero value and slope at 2: F ~ (x - 2)^3 there, nothing beyond
    assert lattice.root_slope(6) == 0.0 and np.all(lattice.force(np.array([2.0, 2.1, 3.0]), 1.0) == 0.0)


def test_the_slope_at_a_root_is_the_force_s_derivative() -> None:
    h = 1e-6  # central difference: error ~ F''' h^2 / 6 ~ 1e-12 for F''' of order 1e2
    for k in range(6):
        x = lattice.roots()[k]
        fd = (lattice.force(np.array(x + h), 1.0) - lattice.force(np.array(x - h), 1.0)) / (2 * h)
        assert abs(fd - lattice.root_slope(k)) < 1e-8 * max(1.0, abs(lattice.root_slope(k)))


def test_the_paper_s_particle_counts_and_a_top_frequency_of_50_hz() -> None:
    scene = make_scene("bar-heat-lattice")
    for n, count in ((2, 16), (3, 63), (4, 160)):
        pos, a = lattice.lattice(scene, n)
        assert pos.shape[0] == count and a == 0.01 / (n - 1)
        assert len(lattice.held(scene, pos, a)) == 4  # two frozen corners and the red pair
        spec = lattice.spec_scalars(scene, {"lattice_n": n})
        # the same lattice assembled as a sparse Hessian from the pair list, top eigenvalue by ARPACK
        i, j, k = lattice.spring_constants(pos, a)
        e = (pos[j] - pos[i]) / np.linalg.norm(pos[j] - pos[i], axis=1)[:, None]
        blocks = spec["stiffness_A"] * k[:, None, None] * e[:, :, None] * e[:, None, :]
        rows, cols, vals = [], [], []
        for r, c, sign in ((i, i, 1.0), (j, j, 1.0), (i, j, -1.0), (j, i, -1.0)):  # the four blocks of each pair
            rows.append(np.repeat(3 * r[:, None] + np.arange(3), 3, axis=1).ravel())
            cols.append(np.tile(3 * c[:, None] + np.arange(3), 3).ravel())
            vals.append(sign * blocks.ravel())
        K = sp.coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                          shape=(3 * count, 3 * count))
        free = np.setdiff1d(np.arange(count), lattice.held(scene, pos, a))
        dofs = (3 * free[:, None] + np.arange(3)).ravel()
        lam = spla.eigsh(K.tocsr()[dofs][:, dofs], k=1, which="LA", return_eigenvectors=False)[0]
        f_top = math.sqrt(lam / spec["particle_mass"]) / (2 * math.pi)
        assert abs(f_top - 50.0) < 1e-9  # ARPACK's tolerance is machine precision on the top eigenvalue
