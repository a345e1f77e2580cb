"""The MCA solver's table of analyses: one entry per kind of run, chosen by what a scene declares.

- no scene kind (physics words x conduction mode x sliding, every combination) matches two entries, and every
  entry is some shipped scene's analysis;
- a scene outside every entry is refused with the reason (supports, estimate and solve alike), one its entry
  refuses keeps the entry's reason;
- the work estimates are those of the switch the table replaced (golden values from it);
- the glue reads the scene's physics in one place only (SceneKind.of), the stability probe none.
"""

from __future__ import annotations

import dataclasses
import inspect
import itertools

import pytest

from pcverify.harness.study.catalogue import make_scene
from pcverify.scene import PHYSICS, Conduction, Resolution, Scene, SceneError
from pcverify.solvers.particles.mca import probe as mca_probe
from pcverify.solvers.particles.mca import solver as mca_solver
from pcverify.solvers.particles.mca.solver import ANALYSES, Mca, SceneKind, analysis_of

SHIPPED = [  # (scene, scene parameters, its analysis)
    ("bar-heat-faces", {}, "steady heat"),
    ("bar-heat-paper", {}, "steady heat"),
    ("bar-heat-patch", {}, "steady heat"),
    ("bar-heat-faces", {"mode": "transient"}, "transient heat"),
    ("frictional-heating", {"source": "flux"}, "transient heat"),
    ("bar-compression", {}, "static elasticity"),
    ("bar-modes", {}, "modes"),
    ("bar-tension-fracture", {}, "fracture"),
    ("block-contact-compression", {}, "contact compression"),
    ("block-sliding", {}, "sliding contact"),
    ("frictional-heating", {}, "frictional heating"),
    ("stick-slip", {}, "stick-slip"),
    ("incline", {}, "incline"),
]


def test_no_scene_kind_matches_two_analyses_and_each_entry_is_reached():
    words = sorted(PHYSICS)
    reached = set()
    kinds = 0
    for r in range(len(words) + 1):
        for physics in itertools.combinations(words, r):
            for conduction, sliding in itertools.product((None, "steady", "transient"), (None, False, True)):
                kind = SceneKind(frozenset(physics), conduction, sliding)
                hits = [a.name for a in ANALYSES if a.matches(kind)]
                assert len(hits) <= 1, (kind, hits)
                reached.update(hits)
                kinds += 1
    assert kinds == 2 ** len(words) * 9 and reached == {a.name for a in ANALYSES}
    assert len({a.name for a in ANALYSES}) == len(ANALYSES) == 10


def test_every_shipped_scene_has_its_analysis_and_the_probe_steps_what_it_declares():
    mca = Mca()
    assert {name for _, _, name in SHIPPED} == {a.name for a in ANALYSES}
    for scene_name, params, expected in SHIPPED:
        scene = make_scene(scene_name, **params)
        assert mca.supports(scene) == (True, "") and mca.analysis(scene).name == expected
        ok, why = mca.stability_probe().supports(scene)
        assert ok == bool(mca.analysis(scene).stepping), scene_name
        if not ok:
            assert why == mca.analysis(scene).no_stepping and why


def _modes_and_fracture() -> Scene:
    base = make_scene("bar-tension-fracture")
    return dataclasses.replace(base, physics=base.physics | {"modes"},
                               elasticity=dataclasses.replace(base.elasticity, modes=4))


def _thermo_elastic() -> Scene:
    base = make_scene("bar-compression")
    return dataclasses.replace(base, physics=base.physics | {"conduction"}, conduction=Conduction(),
                               material=make_scene("frictional-heating").material)


def _sliding_with_conduction() -> Scene:
    base = make_scene("block-sliding")
    return dataclasses.replace(base, physics=base.physics | {"conduction"}, conduction=Conduction(),
                               material=make_scene("frictional-heating").material)


def _heating_without_sliding() -> Scene:
    base = make_scene("frictional-heating")
    return dataclasses.replace(base, contact=dataclasses.replace(base.contact, speed=0.0))


def _heating_with_a_source() -> Scene:
    base = make_scene("frictional-heating")
    return dataclasses.replace(base, physics=base.physics | {"heat-source"},
                               conduction=dataclasses.replace(base.conduction, source=1e6))


def _nothing() -> Scene:
    base = make_scene("bar-compression")
    return Scene("empty", "no physics", base.box, base.material, frozenset(), ())


OUTSIDE = [  # scenes no entry runs, and the reason
    (_modes_and_fracture, "mca's modes does not model ['fracture']; mca's fracture does not model ['modes']"),
    (_thermo_elastic, "mca's steady heat does not model ['elasticity']; mca's static elasticity does not model "
                      "['conduction']"),
    (_sliding_with_conduction, "mca's sliding contact does not model ['conduction']"),
    (_heating_without_sliding, "mca's frictional heating needs a sliding contact"),
    (_heating_with_a_source, "mca's frictional heating does not model ['heat-source']"),
    (_nothing, "mca does conduction and elasticity; scene needs []"),
]


@pytest.mark.parametrize(("build", "reason"), OUTSIDE, ids=[b.__name__.strip("_") for b, _ in OUTSIDE])
def test_a_scene_outside_every_analysis_is_refused_with_its_reason(build, reason):
    scene = build()
    mca = Mca()
    assert not any(a.matches(SceneKind.of(scene)) for a in ANALYSES)
    assert mca.supports(scene) == (False, reason)
    with pytest.raises(SceneError) as est:
        mca.estimate(scene, Resolution(4))
    with pytest.raises(SceneError) as sol:
        mca.solve(scene, Resolution(4))
    assert str(est.value) == str(sol.value) == reason


def test_a_scene_its_analysis_refuses_keeps_the_analysis_reason():
    faces = make_scene("bar-heat-faces")
    assert analysis_of(dataclasses.replace(faces, constraints=())) == (
        None, "steady conduction without any prescribed temperature is singular")
    assert analysis_of(dataclasses.replace(faces, constraints=(), conduction=dataclasses.replace(
        faces.conduction, mode="transient", t_end=1.0, dt=0.01)))[0].name == "transient heat"
    for name in ("bar-compression", "bar-modes", "bar-tension-fracture"):
        assert Mca().supports(dataclasses.replace(make_scene(name), constraints=())) == (
            False, "an unsupported elastic bar is singular: no FaceSupport or FaceClamp")


# (scene, scene params, n, solver params) -> (unknowns, steps, bytes) of the estimate the table replaced
GOLDEN = [
    ("bar-heat-faces", {}, 4, {}, (160, 1, 655360)),
    ("bar-heat-faces", {"mode": "transient"}, 6, {"heat_cfl": 0.5}, (576, 294, 2359296)),
    ("frictional-heating", {"source": "flux"}, 6, {}, (576, 42, 2359296)),
    ("bar-compression", {}, 4, {}, (960, 9000, 655360)),
    ("bar-compression", {}, 4, {"max_steps": 1000}, (960, 1000, 655360)),
    ("bar-modes", {}, 4, {}, (960, 1, 15400960)),
    ("bar-modes", {}, 8, {}, (8448, 1, 5767168)),
    ("bar-tension-fracture", {}, 4, {}, (960, 10315, 655360)),
    ("bar-tension-fracture", {"response": "plastic-degradation"}, 6, {}, (3456, 364321, 2359296)),
    ("block-contact-compression", {}, 4, {}, (1920, 9000, 1310720)),
    ("block-sliding", {}, 4, {}, (1920, 22154, 1310720)),
    ("block-sliding", {}, 4, {"slide_ramp": 1e-4}, (1920, 22202, 1310720)),
    ("frictional-heating", {}, 4, {}, (1920, 13768, 1310720)),
    ("frictional-heating", {}, 4, {"cfl": 0.3, "heat_cfl": 0.5, "max_steps": 1000}, (1920, 8949, 1310720)),
]


@pytest.mark.parametrize(("scene_name", "scene_params", "n", "params", "expected"), GOLDEN)
def test_estimates_are_those_of_the_switch_the_table_replaced(scene_name, scene_params, n, params, expected):
    work = Mca().estimate(make_scene(scene_name, **scene_params), Resolution(n), **params)
    assert (work.unknowns, work.steps, work.bytes) == expected


def test_the_glue_reads_the_physics_in_one_place_and_the_probe_in_none():
    assert inspect.getsource(mca_solver).count("scene.physics") == 1  # SceneKind.of
    assert "scene.physics" not in inspect.getsource(mca_probe)
