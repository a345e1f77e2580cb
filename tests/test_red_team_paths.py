"""Red team: names never become paths.  A plugin solver named `/../../../../ESCAPED` in a group with
`vtu = true` wrote `ESCAPED-n2-r1-<key>.vtu` above --out (the solver's name went into the VTU path and the writer
made its parents); a 300-character name aborted the report with "File name too long".  Every file a study writes
must lie under --out, each name reduced to a bounded stem with a hash (two names never share one)."""

from __future__ import annotations

import textwrap

import pytest
from red_team import check_tally, tally

from pcverify.harness.cli import main
from pcverify.harness.run.files import STEM_LIMIT, safe_stem

PLUGIN = '''
from pcverify.solvers.continuum.skfem_elastic import SkfemElastic


class Escaper(SkfemElastic):
    name = "/../../../../ESCAPED"


class Longer(SkfemElastic):
    name = "L" * 300
'''


@pytest.mark.parametrize("solver", ["/../../../../ESCAPED", "L" * 300])
def test_a_hostile_or_long_solver_name_writes_every_file_under_out(solver, tmp_path, capsys) -> None:
    study = tmp_path / "deep" / "er" / "s.toml"
    study.parent.mkdir(parents=True)
    (study.parent / "hostile_solvers.py").write_text(PLUGIN)
    study.write_text(textwrap.dedent(f'''
        name = "paths"
        plugins = ["hostile_solvers"]

        [[group]]
        id = "compression"
        scene = "bar-compression"
        solvers = ["{solver}"]
        n = [2]
        vtu = true
    '''))
    out = study.parent / "out"
    before = {p for p in tmp_path.rglob("*")}
    assert main(["study", str(study), "--out", str(out)]) == 0, capsys.readouterr().err
    written = {p for p in tmp_path.rglob("*")} - before
    outside = [p for p in written if out not in p.parents and p != out
               and "__pycache__" not in p.parts]  # the plugin's bytecode beside it
    assert outside == []
    vtus = sorted((out / "paths" / "vtu").glob("*.vtu"))
    assert len(vtus) == 1 and len(vtus[0].name) < 200
    assert vtus[0].name.startswith(f"compression-{safe_stem(solver)}-n2-r1-")
    tally("paths", "accepted")


def test_a_safe_stem_is_bounded_and_names_never_share_one() -> None:
    assert safe_stem("skfem-elastic") == "skfem-elastic"  # a plain name is itself
    hostile = ["/../../../../ESCAPED", "../ESCAPED", "..", ".hidden", "a/b", "a_b", "a\x00b", "é", "", "L" * 300,
               "L" * 301]
    stems = [safe_stem(n) for n in hostile]
    assert len(set(stems)) == len(stems)
    for stem in stems:
        assert "/" not in stem and "\x00" not in stem and not stem.startswith(".") and stem
        assert len(stem) <= STEM_LIMIT + 11
    tally("paths", "accepted")


def test_zz_paths_tally() -> None:
    check_tally({"paths": 3})
