"""Scene model and catalogue: validated construction, stable hashes, sample sets."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from pcverify.harness.study.catalogue import CATALOGUE, make_scene, spec_from_table
from pcverify.scene import (
    ALUMINIUM,
    Box,
    Conduction,
    FaceTemperature,
    InterfaceFlux,
    Param,
    Resolution,
    Scene,
    SceneError,
)
from pcverify.solvers.protocol import skipped
from pcverify.solvers.registry import get_solver


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


# -- heat released inside the body: the volumetric source and the interface flux ----------------------------


def _heat_scene(physics, **conduction):
    cons = (FaceTemperature("z0", 0.0), FaceTemperature("zL", 0.0))
    return Scene("s", "s", Box(), ALUMINIUM, frozenset(physics), cons, conduction=Conduction(**conduction))


def test_interface_flux_is_validated_and_hashed():
    plane = InterfaceFlux(1e4, 0.01)
    scene = _heat_scene({"conduction", "interface-flux"}, interface=plane)
    assert scene.conduction.interface.axis == "z"
    moved = _heat_scene({"conduction", "interface-flux"}, interface=InterfaceFlux(1e4, 0.02))
    stronger = _heat_scene({"conduction", "interface-flux"}, interface=InterfaceFlux(2e4, 0.01))
    hashes = {s.content_hash() for s in (scene, moved, stronger, _heat_scene({"conduction"}))}
    assert len(hashes) == 4
    assert scene.content_hash() == _heat_scene({"conduction", "interface-flux"}, interface=plane).content_hash()
    # a zero flux is no load: the physics word goes with a non-zero flux, as "heat-source" with source != 0
    assert _heat_scene({"conduction"}, interface=InterfaceFlux(0.0, 0.01)).physics == {"conduction"}


@pytest.mark.parametrize(
    "build, word",
    [
        (lambda: InterfaceFlux(math.inf, 0.01), "flux"),
        (lambda: InterfaceFlux(1e4, math.nan), "position"),
        (lambda: InterfaceFlux(1e4, 0.01, "w"), "axis"),
        (lambda: InterfaceFlux(True, 0.01), "flux"),
        (lambda: Conduction(interface=(1e4, 0.01)), "interface"),
        (lambda: _heat_scene({"conduction", "interface-flux"}, interface=InterfaceFlux(1e4, 0.03)), "position"),
        (lambda: _heat_scene({"conduction", "interface-flux"}, interface=InterfaceFlux(1e4, 0.0)), "position"),
        (lambda: _heat_scene({"conduction", "interface-flux"}, interface=InterfaceFlux(1e4, 0.012, "x")), "position"),
        (lambda: _heat_scene({"conduction"}, interface=InterfaceFlux(1e4, 0.01)), "interface-flux"),
        (lambda: _heat_scene({"conduction", "interface-flux"}), "interface-flux"),
        (lambda: _heat_scene({"conduction"}, source=1e6), "heat-source"),
    ],
)
def test_bad_loads_name_the_field(build, word):
    with pytest.raises(SceneError, match=word) as info:
        build()
    assert "allowed" in str(info.value)


def test_scene_table_with_source_and_interface():
    table = {"name": "slab", "box": {"length": 0.06}, "source": 1e6, "interface": {"flux": 5e3, "position": 0.02},
             "held": [{"face": "z0", "temperature": 0}, {"face": "zL", "temperature": 0}], "t_max": 1.0}
    scene = spec_from_table(table, "test").make()
    assert scene.physics == {"conduction", "heat-source", "interface-flux"}
    assert scene.conduction.interface == InterfaceFlux(5e3, 0.02, "z")
    assert scene.box.length == 0.06 and scene.conduction.source == 1e6
    # the box is a parameter of the spec: a plane outside a shorter box is refused when that box is asked for
    with pytest.raises(SceneError, match="position"):
        spec_from_table(table, "test").make(length=0.015)


@pytest.mark.parametrize("interface, word", [({"flux": 1.0}, "interface.position is missing; allowed: number"),
                                             ({"flux": 1.0, "position": 0.01, "at": 1},
                                              "interface.at is not a field of interface; allowed: flux, position, "
                                              "axis"),
                                             ({"flux": "hot", "position": 0.01}, "flux"),
                                             ({"flux": 1.0, "position": 0.5}, "position")])
def test_bad_scene_table_interface(interface, word):
    table = {"name": "slab", "interface": interface, "held": [{"face": "z0", "temperature": 0}]}
    with pytest.raises(SceneError, match=word):
        spec_from_table(table, "test")


def test_param_kind_inferred_from_default_and_choices():
    """A plugin's Param with text choices, or a true/false default, parses --set values without kind=."""
    law = Param("law", "regularised", "", "friction law", choices=("regularised", "static"))
    assert law.kind is str and law.parse("static") == "static"
    with pytest.raises(SceneError, match=r"law='dry' is out of range; allowed: one of regularised, static"):
        law.parse("dry")
    flag = Param("fast", False, "", "a switch")
    assert flag.kind is bool and flag.parse("yes") is True
    assert Param("name", None, "", "optional text", choices=("a", "b"), optional=True).parse("b") == "b"
    assert Param("delta", 3, "", "an integer default stays a number").parse("2.5") == 2.5
    with pytest.raises(TypeError, match="kind=<class 'list'> is not valid"):
        Param("bad", 1, kind=list)


def test_a_skipped_solution_carries_its_scenes_quantity() -> None:
    """A skip on an elasticity scene said "T/t_max" (the heat default of a Solution)."""
    scene = make_scene("bar-compression")
    sol = skipped(scene, get_solver("skfem-elastic"), Resolution(2), "a reason")
    assert sol.quantity == scene.quantity != "T/t_max"
