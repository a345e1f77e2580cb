"""scikit-fem (FEM) and FiPy (FV) on the well-posed bar-heat-patch: independent discretisations must agree."""

import numpy as np
import pytest

from pcverify.harness.study.catalogue import make_scene
from pcverify.scene import Resolution
from pcverify.solvers.registry import get_solver


@pytest.fixture(scope="module")
def patch_pair():
    scene = make_scene("bar-heat-patch")
    samples = scene.sample_sets(4)  # the 160-particle lattice's points, evaluated on finer grids
    # n = 4 refined 16: h = 0.208 mm, ~348 000 unknowns each. skfem's conforming warp snaps the patch's cube
    # to whole cells (s1 = 0.833 mm here, the same at refine 8, 12, 16); levels with another s1 (e.g. n = 2,
    # refine 32) move skfem by up to 1.7e-3 at points 3.3 mm from the hot patch, so the comparison uses these
    res = Resolution(4, 16)
    return scene, {name: get_solver(name).solve(scene, res, samples=samples) for name in ("skfem", "fipy")}


def test_patch_volume_mean_agrees(patch_pair):
    _, sol = patch_pair
    # measured: 0.3175909 (skfem) vs 0.3176446 (fipy); refine 12: 0.3175864 vs 0.3176657 (the gap shrinks);
    # the criterion is 1e-3 in T/t_max
    assert abs(sol["skfem"].summary["volume_mean"] - sol["fipy"].summary["volume_mean"]) < 1e-3


def test_patch_fields_agree_away_from_patches(patch_pair):
    scene, sol = patch_pair
    centres = np.array([c.centre for c in scene.constraints])
    rho = scene.constraints[0].radius
    checked = 0
    for name in ("nodes", "front_top_edge", "bottom_back_edge"):
        pts = sol["skfem"].samples[name]["points"]
        far = np.min(np.linalg.norm(pts[:, None, :] - centres[None], axis=2), axis=1) >= 2 * rho
        diff = np.abs(sol["skfem"].samples[name]["values"] - sol["fipy"].samples[name]["values"])[far]
        # measured max 6.3e-4 (refine 12: 8.9e-4), at the nodes 3.3 mm from the hot patch; FiPy's cut-cell patch
        # converges towards skfem there (0.49732 -> 0.49757 vs 0.49820); the criterion is 1e-3
        assert diff.max() < 1e-3, (name, diff.max())
        checked += far.sum()
    assert checked > 150  # nearly all of the 160 nodes plus the edges are far from the three patches
