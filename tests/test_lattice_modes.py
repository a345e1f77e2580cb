"""bar-modes on the particle lattices: MCA and the macromolecule lattice against scikit-fem Q2.

The reference is scikit-fem Q2 on the n = 2 grid refined 3 times (h = 3.3 mm), within ~0.3 % of the
Richardson-extrapolated frequencies (references.elastic: bending 8412.7 Hz):
small against the lattice errors asserted here (MCA 5-13 %, the macromolecule lattice ~40 %).
"""

from __future__ import annotations

import numpy as np
import pytest

from pcverify.harness.study.catalogue import make_scene
from pcverify.scene import Resolution
from pcverify.solvers.continuum.skfem_elastic import SkfemElastic
from pcverify.solvers.particles.macromolecule.elastic_modes import uniaxial_constants
from pcverify.solvers.particles.macromolecule.force import SevenRoot
from pcverify.solvers.particles.macromolecule.lattice import build_lattice
from pcverify.solvers.particles.macromolecule.modal import hessian
from pcverify.solvers.particles.macromolecule.solver import Macromolecule
from pcverify.solvers.particles.mca.solver import Mca

SCENE = make_scene("bar-modes", modes=4)


@pytest.fixture(scope="module")
def reference() -> float:
    sol = SkfemElastic().solve(SCENE, Resolution(2, 3), element="q2")
    return float(sol.summary["frequencies_hz"][0])


def test_reference_is_close_to_the_extrapolated_bending_frequency(reference: float) -> None:
    assert reference == pytest.approx(8412.7, rel=5e-3)


def test_macromolecule_lattice_is_scaled_to_the_material_and_square() -> None:
    sol = Macromolecule().solve(SCENE, Resolution(3))
    f = np.asarray(sol.summary["frequencies_hz"])
    assert sol.status == "ok" and len(f) == 4 and np.all(np.diff(f) >= 0)
    # square section: the two bending modes are a degenerate pair among the lowest three (at n = 3 a softer
    # torsion-like mode of the central-force lattice comes first: 4821.7 Hz, then the pair at 4833.6 Hz)
    assert np.min(np.abs(np.diff(f[:3])) / f[1:3]) < 1e-9
    lat = build_lattice(SCENE.box, 3, SCENE.material.density)
    k = hessian(lat.positions, lat.pairs, SevenRoot(1.0), lat.a).tocsr() * sol.summary["stiffness_A"]
    e_eff, nu_eff = uniaxial_constants(k, lat.positions, SCENE.box)
    assert e_eff == pytest.approx(70e9, rel=1e-9)
    assert nu_eff == pytest.approx(sol.summary["nu_eff"], rel=1e-12) and 0.0 < nu_eff < 0.1  # central forces


def test_mca_bending_converges_and_macromolecule_lattice_does_not(reference: float) -> None:
    mca = [Mca().solve(SCENE, Resolution(n)).summary["frequencies_hz"][0] for n in (4, 6)]
    err = [abs(f / reference - 1) for f in mca]
    assert err[1] < err[0] < 0.16 and err[1] < 0.08  # measured 13.3 %, 5.7 % (stiff: above the continuum)
    order = np.log(err[0] / err[1]) / np.log((1 / 3) / (1 / 5))  # a = W / (n - 1)
    assert 1.2 < order < 2.2  # measured 1.66 (the study's five-level fit: 1.66); clamp edges keep it below 2
    mm = [Macromolecule().solve(SCENE, Resolution(n)).summary["frequencies_hz"][0] for n in (4, 6)]
    # the seven-root lattice scaled to E is ~40 % soft in bending at every n: a model error, not discretisation
    assert all(f < 0.7 * reference for f in mm) and abs(mm[1] / mm[0] - 1) < 0.1
