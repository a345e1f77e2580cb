"""Fields of every kind: the elastic bar's displacement compared with its analytic field, point by point, and a
group whose error column would be empty refused at load."""

import numpy as np
import pytest

from pcverify.harness.judge.compare import errors
from pcverify.harness.judge.metrics import field_errors
from pcverify.harness.study.catalogue import make_scene
from pcverify.harness.study.study import load_study
from pcverify.scene import Resolution, SceneError
from pcverify.solvers.continuum.skfem_elastic import SkfemElastic
from pcverify.solvers.particles.mca.solver import Mca


def test_a_vector_field_error_is_the_length_of_the_difference():
    got = field_errors(np.array([[3.0, 4.0, 0.0], [0.0, 0.0, 1.0]]), np.zeros((2, 3)))
    assert got == {"l2": pytest.approx(np.sqrt((25 + 1) / 2)), "linf": 5.0}


@pytest.mark.parametrize("solver, bound", [(SkfemElastic(), 1e-12), (Mca(), 1e-5)])
def test_the_compressed_bars_displacement_matches_the_uniaxial_field(solver, bound):
    """u = (-nu eps x, -nu eps y, eps z) is linear, so it lies in both discrete spaces: scikit-fem's error is its
    solve's residual (measured 2e-18 m of 3e-5 m at n = 3), MCA's its relaxation's (4e-11 m, 1.5e-6 of the largest
    displacement; measured 4e-11 m at n = 2 to 8).  The bounds: 1e-12 and 1e-5 of the largest displacement, a
    wrong sign of the lateral contraction or a rigid shift misses them by five orders."""
    scene = make_scene("bar-compression")
    sol = solver.solve(scene, Resolution(3))
    largest = np.abs(np.asarray(sol.samples["nodes"]["values"])).max()
    assert largest == pytest.approx(1e-3 * 0.03, rel=1e-6)  # eps L at the displaced face
    found = errors(scene, sol.samples)
    assert set(found) == {"nodes", "front_top_edge", "bottom_back_edge"}
    assert all(e["linf"] <= bound * largest and e["reference"] == "analytic" for e in found.values()), found
    wrong = {k: {"points": v["points"], "values": np.asarray(v["values"]) * [-1, -1, 1]}
             for k, v in sol.samples.items()}  # the lateral contraction's sign flipped
    assert errors(scene, wrong)["nodes"]["linf"] > 0.5 * 0.33 * 1e-3 * 0.01


def test_a_work_precision_group_on_a_scene_without_a_reference_field_is_refused_at_load(tmp_path):
    path = tmp_path / "wp.toml"
    path.write_text('name = "wp"\n[[group]]\nid = "wp"\nanalysis = "work-precision"\nscene = "bar-modes"\n'
                    'solvers = ["skfem-elastic"]\nn = [2, 3]\n')
    with pytest.raises(SceneError, match="group wp: analysis work-precision draws err.nodes.l2 against the scene's "
                       "reference field, and scene bar-modes has none"):
        load_study(str(path))
