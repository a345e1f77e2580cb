"""The fast FiPy set-up (solvers/continuum/fipy_fast.py) gives FiPy's own discretisation, bit for bit.

TensorGrid3D computes face areas and centres with the same floating-point operations as FiPy's generic
Mesh (area: the product of two vertex-coordinate differences; centre: the 4 vertex coordinates summed in
the builder's order, divided by 4), and everything else with FiPy's own methods; the DiffusionTerm skips
only a right-hand-side contribution that is exactly zero.  So the tests demand equality, not a tolerance
(measured: identical arrays); the solutions, which also go through AMG-CG, are compared to 1e-12 relative.
"""

from __future__ import annotations

import gc
import weakref

import numpy as np
import pytest

from pcverify.harness.study.catalogue import make_scene
from pcverify.scene import Resolution
from pcverify.solvers.continuum.fipy_fast import diffusion_term, tensor_grid3d
from pcverify.solvers.continuum.fipy_heat import FipyHeat, grid_axes
from pcverify.solvers.protocol import effective_params

fp = pytest.importorskip("fipy")
SOLVER = FipyHeat()
SPACINGS = {  # random non-uniform spacings, and the dual grid of the bar (half cells at both ends)
    "random": tuple(np.random.default_rng(7).uniform(0.2, 2.0, m) for m in (3, 4, 5)),
    "dual": tuple(np.diff(e) for e in grid_axes(make_scene("bar-heat-faces"), Resolution(3, 2))[0]),
}


def _arrays(mesh, names):
    return {n: np.ma.filled(np.ma.asarray(getattr(mesh, n)), -1) for n in names}


@pytest.mark.parametrize("spacing", sorted(SPACINGS))
def test_tensor_grid_geometry_is_fipys(spacing):
    dx, dy, dz = SPACINGS[spacing]
    stock, fast = fp.Grid3D(dx=dx, dy=dy, dz=dz), tensor_grid3d(dx, dy, dz)
    from fipy.meshes.nonUniformGrid3D import NonUniformGrid3D

    assert type(stock) is NonUniformGrid3D and isinstance(fast, NonUniformGrid3D)
    names = [n for n, v in vars(stock).items() if isinstance(v, np.ndarray) or n == "faceNormals"]
    deferred = sorted(set(names) - set(vars(fast)))
    # what the steady heat solve never reads is not computed at construction ...
    assert deferred == sorted(["_cellAreas", "_cellNormals", "_cellToCellDistances", "_faceAspectRatios",
                               "_faceCellToCellNormals", "_faceTangents1", "_faceTangents2",
                               "_scaledCellToCellDistances"])
    eager = _arrays(fast, [n for n in names if n not in deferred])
    # ... and every array, eager or computed on first access, equals the stock mesh's bit for bit
    for name, value in {**eager, **_arrays(fast, deferred)}.items():
        ref = np.ma.filled(np.ma.asarray(getattr(stock, name)), -1)
        assert value.shape == ref.shape and np.array_equal(value, ref), name
    assert np.array_equal(np.asarray(fast.cellCenters), np.asarray(stock.cellCenters))


@pytest.mark.parametrize("scene_name, resolution, params", [
    ("bar-heat-faces", Resolution(4, 2), {}),
    ("bar-heat-patch", Resolution(2, 12), {}),  # cut: FaceVariable coefficients k / theta on 27 faces
    ("bar-heat-patch", Resolution(3, 4), {"patch": "fraction"}),
    ("bar-heat-paper", Resolution(4, 3), {}),  # point constraints, penalty rows
])
def test_assembled_system_is_fipys(scene_name, resolution, params):
    scene = make_scene(scene_name)
    edges, hs = grid_axes(scene, resolution)
    p = effective_params(SOLVER, params)
    ref = SOLVER._assemble(scene, edges, hs, p, stock=True)
    new = SOLVER._assemble(scene, edges, hs, p)
    if scene_name == "bar-heat-patch" and not params:
        assert new["ncut"] == ref["ncut"] > 0
    for key in ("indptr", "indices", "data"):
        assert np.array_equal(getattr(new["K"], key), getattr(ref["K"], key)), key
    for key in ("f", "vol", "B", "fixed", "tfix"):
        assert np.array_equal(new[key], ref[key]), key


@pytest.mark.parametrize("scene_name, kw", [("bar-heat-patch", {}),
                                            ("bar-heat-faces", {"mode": "transient", "t_end": 0.5, "dt": 0.1})])
def test_solution_is_fipys(monkeypatch, scene_name, kw):
    # AMG-CG on the same matrix from the same seed: the same field (1e-12 relative asked; measured identical)
    scene, res = make_scene(scene_name, **kw), Resolution(4, 3)
    new = SOLVER.solve(scene, res, linear_solver="amg")
    plain = FipyHeat._assemble
    monkeypatch.setattr(FipyHeat, "_assemble", lambda self, *a: plain(self, *a, stock=True))
    ref = SOLVER.solve(scene, res, linear_solver="amg")
    for name in ref.samples:
        a, b = new.samples[name]["values"], ref.samples[name]["values"]
        assert np.max(np.abs(a - b)) <= 1e-12 * np.max(np.abs(b)), name
    assert new.summary == pytest.approx(ref.summary, rel=1e-12, abs=1e-14)


def test_gradient_constraint_still_reaches_the_equations():
    # the skip applies only when the face gradient is unconstrained; with a flux constraint (FiPy's
    # faceGrad.constrain) the term is FiPy's, including the face gradient on the deferred tangents
    dx, dy, dz = SPACINGS["random"]
    systems = []
    for mesh, term in ((fp.Grid3D(dx=dx, dy=dy, dz=dz), fp.DiffusionTerm), (tensor_grid3d(dx, dy, dz), diffusion_term)):
        T = fp.CellVariable(mesh=mesh, value=np.linspace(0.0, 1.0, mesh.numberOfCells))
        T.constrain(1.0, where=mesh.facesFront)
        T.faceGrad.constrain([[0.0], [0.0], [2.5]], where=mesh.facesBack)
        s = term(coeff=3.0)._prepareLinearSystem(T, None, (), None)
        systems.append((s.matrix.matrix.toarray(), np.asarray(s.RHSvector), np.asarray(T.faceGrad)))
    (k0, b0, g0), (k1, b1, g1) = systems
    assert np.any(b0 != 0) and np.array_equal(k0, k1) and np.array_equal(b0, b1) and np.array_equal(g0, g1)
    # and without the constraint FiPy's gradient contribution is the exact zero the fast term skips
    mesh = fp.Grid3D(dx=dx, dy=dy, dz=dz)
    T = fp.CellVariable(mesh=mesh, value=np.linspace(0.0, 1.0, mesh.numberOfCells))
    T.constrain(1.0, where=mesh.facesFront)
    assert fp.DiffusionTerm(coeff=3.0)._constrainGradient(T)[0] == 0
    assert not np.any(np.asarray(fp.DiffusionTerm(coeff=3.0)._constrainGradient(T)[1]))


def test_no_fipy_object_outlives_the_solve():
    # FiPy's mesh and variables form reference cycles: dropped, they wait for the cyclic collector (control below).
    # The solver frees them as its FiPy set-up returns, so a following solve does not pay for them (~GB at 673 501
    # cells).  With the collector off, nothing FiPy is left after a solve.
    from fipy.meshes.mesh import Mesh
    from fipy.variables.variable import Variable

    enabled = gc.isenabled()
    gc.collect()
    gc.disable()
    try:
        dx, dy, dz = SPACINGS["dual"]
        mesh = weakref.ref(fp.Grid3D(dx=dx, dy=dy, dz=dz))
        assert mesh() is not None  # control: unreferenced, yet alive (a cycle)
        gc.collect()
        assert mesh() is None
        for name in ("bar-heat-faces", "bar-heat-patch", "bar-heat-paper"):
            SOLVER.solve(make_scene(name), Resolution(4, 2))
            assert not [o for o in gc.get_objects() if isinstance(o, (Mesh, Variable))], name
    finally:
        if enabled:
            gc.enable()
