"""Red team: a plugin's scene is never reported under a shipped scene's name.

Results, tables and verdicts are labelled by the scene's name; a plugin whose SceneSpec (an entry point, or a
plugin module's spec) builds a scene named `bar-heat-faces` had its results reported as the shipped scene's.
Each case must be one error line naming the spec and the name it built.
"""

from __future__ import annotations

from red_team import TALLY, tally

from pcverify.harness.cli import main
from pcverify.harness.study.catalogue import SCENES
from pcverify.solvers.registry import Entry

IMPOSTOR = '''
import dataclasses
from pcverify.harness.study.catalogue import get_spec

_faces = get_spec("bar-heat-faces")
# a spec of its own name whose scene is the shipped one, name included
LOOKALIKE = dataclasses.replace(_faces, name="my-faces")
# a spec that calls itself the shipped scene, offered under another entry point name
NAMED_AS_SHIPPED = _faces
'''

STUDY = """
name = "names"
title = "a plugin scene named like a shipped one"
[[group]]
id = "g"
title = "g"
analysis = "table"
scene = "SCENE"
solvers = ["skfem"]
n = [2]
"""


def _error(capsys, argv: list[str]) -> str:
    code = main(argv)
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and err[0].startswith("pcverify: error: "), err
    return err[0]


def test_a_spec_whose_scene_carries_a_shipped_name_is_refused(tmp_path, monkeypatch, capsys) -> None:
    (tmp_path / "impostor.py").write_text(IMPOSTOR)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setitem(SCENES.__dict__, "entry_points", {
        "my-faces": Entry("my-faces", "impostor:LOOKALIKE", "entry point of impostor 1.0"),
        "ep-faces": Entry("ep-faces", "impostor:NAMED_AS_SHIPPED", "entry point of impostor 1.0")})
    line = _error(capsys, ["run", "my-faces", "--solver", "skfem", "--n", "2", "--json"])
    assert "built a scene named 'bar-heat-faces'" in line and "my-faces" in line
    tally("names", "rejected")
    line = _error(capsys, ["run", "ep-faces", "--solver", "skfem", "--n", "2"])
    assert "is a SceneSpec named 'bar-heat-faces'" in line and "ep-faces" in line
    tally("names", "rejected")
    for scene in ("my-faces", "ep-faces"):
        path = tmp_path / f"{scene}.toml"
        path.write_text(STUDY.replace("SCENE", scene))
        line = _error(capsys, ["study", str(path), "--out", str(tmp_path / "out")])
        assert scene in line and "bar-heat-faces" in line
        tally("names", "rejected")


def test_a_plugin_module_cannot_register_a_shipped_scene_name(tmp_path, monkeypatch, capsys) -> None:
    (tmp_path / "shadow.py").write_text(
        "from pcverify.harness.study.catalogue import get_spec\nimport dataclasses\n"
        "SHADOW = dataclasses.replace(get_spec('bar-heat-paper'), name='bar-heat-faces')\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    path = tmp_path / "shadow.toml"
    path.write_text('plugins = ["shadow"]\n' + STUDY.replace("SCENE", "bar-heat-faces"))
    line = _error(capsys, ["study", str(path), "--out", str(tmp_path / "out")])
    assert "'bar-heat-faces' is registered twice" in line and "shadow" in line
    tally("names", "rejected")


def test_zz_names_tally() -> None:
    print(f"\nnames: tried {TALLY['names tried']}, rejected cleanly {TALLY['names rejected']}")
    assert TALLY["names tried"] == TALLY["names rejected"] == 5
