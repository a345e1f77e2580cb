"""Scene model and catalogue: validated construction, stable hashes, sample sets."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from pcverify.harness.catalogue import CATALOGUE, make_scene
from pcverify.scene import Param, Resolution, SceneError


@pytest.mark.parametrize("n, count", [(2, 16), (3, 63), (4, 160), (5, 325), (11, 3751)])
def test_lattice_family_sizes_and_spacing(n, count):
    scene = make_scene("bar-heat-paper")
    pts = scene.box.lattice_points(n)
    assert pts.shape == (count, 3)
    a = scene.box.lattice_spacing(n)
    # nodes on all faces, uniform spacing a in every direction (m = 3n - 2 makes L/(m-1) = a)
    for axis, ext in enumerate(scene.box.extent):
        vals = np.unique(pts[:, axis])
        assert vals[0] == 0.0 and vals[-1] == pytest.approx(ext)
        assert np.allclose(np.diff(vals), a)
    # ordering: x slowest, z fastest
    nx, ny, nz = scene.box.lattice_shape(n)
    i, j, k = 1, 1, 2
    assert np.allclose(pts[(i * ny + j) * nz + k], [i * a, j * a, k * a])


def test_sample_sets_are_lattice_edges():
    scene = make_scene("bar-heat-paper")
    s = scene.sample_sets(4)
    assert set(s) == {"nodes", "front_top_edge", "bottom_back_edge"}
    assert np.all(s["front_top_edge"][:, :2] == [0.0, 0.01])
    assert np.all(s["bottom_back_edge"][:, :2] == [0.01, 0.0])
    # every edge sample point is a lattice node
    nodes = {tuple(np.round(p, 12)) for p in s["nodes"]}
    assert all(tuple(np.round(p, 12)) in nodes for p in s["front_top_edge"])


def test_corner_placements():
    back = make_scene("bar-heat-paper")
    diag = make_scene("bar-heat-paper", placement="diagonal")
    assert [c.point for c in back.constraints] == [(0.0, 0.01, 0.0), (0.01, 0.0, 0.0), (0.01, 0.0, 0.03)]
    assert [c.point for c in diag.constraints][2] == (0.0, 0.0, 0.03)
    assert [c.value for c in back.constraints] == [500.0, 0.0, 0.0]


def test_content_hash_is_stable_and_discriminating():
    a, b = make_scene("bar-heat-patch"), make_scene("bar-heat-patch")
    assert a.content_hash() == b.content_hash()
    assert a.content_hash() != make_scene("bar-heat-patch", rho=0.002).content_hash()
    assert make_scene("bar-heat-paper").content_hash() != make_scene("bar-heat-patch").content_hash()
    # a known value: the hash must not depend on the process (no ids, no set ordering)
    assert len(a.content_hash()) == 16


@pytest.mark.parametrize(
    "scene, params, word",
    [
        ("bar-heat-paper", {"placement": "front"}, "placement"),
        ("bar-heat-paper", {"t_max": -1.0}, "t_max"),
        ("bar-heat-paper", {"t_max": math.nan}, "t_max"),
        ("bar-heat-patch", {"rho": 0.0}, "rho"),
        ("bar-heat-patch", {"rho": 0.01}, "rho"),
        ("bar-heat-faces", {"mode": "transient", "t_end": 0.1, "dt": 0.2}, "dt"),
        ("bar-heat-faces", {"colour": 1}, "colour"),
        ("bar-heat-nope", {}, "scene"),
    ],
)
def test_bad_scene_values_name_the_field(scene, params, word):
    with pytest.raises(SceneError, match=word) as info:
        make_scene(scene, **params)
    assert "allowed" in str(info.value) or "known" in str(info.value)


@given(st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(), st.text(), st.booleans(),
                 st.none()))
def test_hostile_t_max_is_rejected_or_in_range(value):
    try:
        scene = make_scene("bar-heat-paper", t_max=value)
    except SceneError as exc:
        assert "t_max" in str(exc)
    else:
        t_max = scene.conduction.t_max
        assert isinstance(t_max, float) and 0 < t_max <= 1e5 and math.isfinite(t_max)


@given(st.text(max_size=12))
def test_param_parse_rejects_garbage_with_a_named_error(text):
    p = Param("rho", 1e-3, "m", low=0.0, high=4e-3, low_open=True)
    try:
        v = p.parse(text)
    except SceneError as exc:
        assert str(exc).startswith("rho=")
    else:
        assert 0 < v <= 4e-3


@pytest.mark.parametrize("n, refine", [(1, 1), (0, 1), (2, 0), (2.5, 1), (True, 1), (4, -3)])
def test_bad_resolution(n, refine):
    with pytest.raises(SceneError, match="n=|refine="):
        Resolution(n, refine)


def test_catalogue_defaults_build():
    for name, spec in CATALOGUE.items():
        scene = spec.make()
        assert scene.name == name
        assert dict(scene.params) == {p.name: p.default for p in spec.parameters}
