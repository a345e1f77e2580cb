"""Scenes on a non-default box: every solver reports the same h and node count for the same resolution, and
the heat solvers agree with the analytic references on it.

The lattice of resolution n has one spacing a = width / (n - 1) on every axis (`Box.lattice_shape`).  On a
1 : 1 : 6 bar (0.01 x 0.01 x 0.06 m) that is 2 x 2 x 7 = 28 nodes at n = 2 and 3 x 3 x 13 = 117 at n = 3;
at refine = 1 the continuum grids are those nodes (FiPy: one cell per node) and the particles are them.
"""

from __future__ import annotations

import numpy as np
import pytest

from pcverify.harness.study.catalogue import make_scene
from pcverify.references.heat import analytic
from pcverify.scene import ALUMINIUM, Box, Conduction, FaceTemperature, Resolution, Scene
from pcverify.solvers.registry import SHIPPED, get_solver

BAR_1_1_6 = {"width": 0.01, "height": 0.01, "length": 0.06}
SCENES = (("bar-heat-faces", {}), ("bar-heat-paper", {}), ("bar-compression", {}), ("bar-modes", {"modes": 4}))
# the hotness is not compared here, only what the run reports about its lattice: a short run
SOLVER_PARAMS = {"macromolecule": {"t_end": 0.2}}
HEAT = ("skfem", "fipy", "mca")


@pytest.mark.parametrize("n, nodes", [(2, 28), (3, 117)])
def test_every_solver_reports_the_lattice_h_and_node_count(n, nodes):
    box = Box(**BAR_1_1_6)
    assert np.prod(box.lattice_shape(n)) == nodes
    ran: dict[str, list[str]] = {}
    for scene_name, params in SCENES:
        scene = make_scene(scene_name, **BAR_1_1_6, **params)
        for name in SHIPPED:
            solver = get_solver(name)
            if not solver.supports(scene)[0]:
                continue
            sol = solver.solve(scene, Resolution(n), **SOLVER_PARAMS.get(name, {}))
            assert sol.resolution["h"] == pytest.approx(box.lattice_spacing(n), rel=1e-12), (name, scene_name)
            assert sol.resolution["nodes"] == nodes, (name, scene_name)
            ran.setdefault(name, []).append(scene_name)
    # every shipped solver ran on this bar: the heat ones on heat scenes, the elastic ones on compression/modes
    assert set(ran) == set(SHIPPED)
    assert {"bar-compression", "bar-modes"} <= set(ran["skfem-elastic"]) and "bar-compression" in ran["mca"]
    assert "bar-modes" in ran["macromolecule"] and "bar-heat-paper" in ran["macromolecule"]


def _error(sol, scene) -> float:
    return max(float(np.abs(v["values"] - analytic(scene, v["points"])).max()) for v in sol.samples.values())


def test_continuum_and_mca_heat_agree_on_the_1_1_6_bar():
    """Steady faces: the linear profile is in every heat solver's space (Q1, FV, the automata's FV): round-off.
    Transient to 1 s: each converges to the Fourier series; measured errors n = 2 -> 3: skfem 0.0359 -> 0.0101,
    fipy 0.0326 -> 0.0086, mca 0.0164 -> 0.0045 (factors 3.56, 3.81, 3.65; 4 would be order 2 exactly)."""
    steady = make_scene("bar-heat-faces", **BAR_1_1_6)
    transient = make_scene("bar-heat-faces", mode="transient", t_end=1.0, dt=0.01, **BAR_1_1_6)
    for name in HEAT:
        solver = get_solver(name)
        assert _error(solver.solve(steady, Resolution(3)), steady) < 1e-12
        e2, e3 = (_error(solver.solve(transient, Resolution(n)), transient) for n in (2, 3))
        assert e3 < 0.011 and e2 / e3 > 3.0, name


@pytest.mark.parametrize("axis", ["x", "y", "z"])
def test_held_faces_on_a_box_with_three_different_sides(axis):
    """Height != width != length: faces held on one axis give a linear profile along it in every heat solver
    (exact in each space), so each solver maps the faces and the axes of a general box correctly."""
    box = Box(0.01, 0.02, 0.04)
    lo, hi = {"x": ("x0", "xW"), "y": ("y0", "yH"), "z": ("z0", "zL")}[axis]
    scene = Scene("box", "box", box, ALUMINIUM, frozenset({"conduction"}),
                  (FaceTemperature(lo, 500.0), FaceTemperature(hi, 100.0)), conduction=Conduction(t_max=500.0))
    for name in HEAT:
        sol = get_solver(name).solve(scene, Resolution(3))
        assert sol.resolution["nodes"] == 3 * 5 * 9
        assert _error(sol, scene) < 1e-12, name
