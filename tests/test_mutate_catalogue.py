"""The mutants CI runs (under two minutes on two cores): five mutants of pcverify's own code (an analytic
reference, the verdict's bound, the order fit, scikit-fem's heat capacity, FiPy's held face) on a small study
of the continuum heat solvers, tests/mutate/continuum-heat-ci.toml; every one must be killed, each by the
claims it names as expected.  The example plugin's three mutants run in tests/test_plugins.py, with the plugin
installed.  `tox -e mutate` runs the whole catalogue."""

from __future__ import annotations

import json
import time
from pathlib import Path

from pcverify.fingerprint import installed
from pcverify.harness.cli import main
from pcverify.harness.study.mutants import (
    Mutant,
    beside_file,
    catalogue,
    read_mutants_file,
    select_mutants,
    solver_packages,
)
from pcverify.harness.study.shipped import study_files
from pcverify.harness.study.study import load_study

STUDY = Path(__file__).resolve().parent / "mutate" / "continuum-heat-ci.toml"


def test_every_catalogued_mutant_of_the_ci_study_is_killed(tmp_path, capsys) -> None:
    t0 = time.perf_counter()
    code = main(["mutate", str(STUDY), "--out", str(tmp_path / "out"), "--jobs", "2", "--strict", "--json"])
    out, err = capsys.readouterr()
    assert code == 0, err[-3000:]
    (doc,) = json.loads(out)
    assert len(doc["mutants"]) >= 5 and doc["counts"]["killed"] == len(doc["mutants"])
    for m in doc["mutants"]:
        assert set(m["expect"]) <= set(m["caught_by"]), (m["name"], m["caught_by"])
    assert not [c for c, v in doc["claims"].items() if v["descriptive"]]
    print(f"\n{len(doc['mutants'])} mutants in {time.perf_counter() - t0:.1f} s: "
          + ", ".join(f"{m['name']} {m['wall_s']:.1f} s" for m in doc["mutants"]))


def test_every_shipped_catalogue_loads_and_each_edit_applies_to_code() -> None:
    """The shipped studies' mutants files: every mutant names a module of pcverify, its find text occurs as
    declared (or its diff applies) and the edit changes code, not only comments; names are unique per study."""
    total = 0
    for name, path in sorted(study_files().items()):
        if not beside_file(path).is_file():
            continue
        mutants = read_mutants_file(beside_file(path))
        assert len({m.name for m in mutants}) == len(mutants) >= 2, name
        for m in mutants:
            source, edited = m.edited()
            assert edited != source and m.changes_code(source, edited), (name, m.name)
        total += len(mutants)
    assert total >= 30


def test_a_mutant_of_an_installed_distribution_is_never_seeded_from_the_baseline() -> None:
    """A cell key counts an installed distribution by its version, which a mutant's edit leaves: seeded, the
    mutant's cells were read back from the baseline and it survived without running (numpy's interp, say)."""
    numpy_mutant = Mutant(name="numpy-init", file="__init__.py", breaks="x", package="numpy")
    assert installed(str(numpy_mutant.path()))
    assert not numpy_mutant.seedable()
    assert Mutant(name="kernel", file="solvers/particles/mca/kernel.py", breaks="x").seedable()


USER_STUDY = '''
name = "mine"
shipped_mutants = ["mca"]

[[group]]
id = "compression"
scene = "bar-compression"
solvers = ["mca"]
n = [2]

[[claim]]
id = "modulus"
text = "the MCA's effective Young's modulus"
table = "compression-cells"
metric = "E_eff"
reference = "analytic"
target = 70e9
tolerance_rel = 1e-6
tolerance_basis = "derived: the many-body identity holds to round-off"
'''


def test_a_users_study_opts_in_to_the_shipped_catalogue_of_a_solver_it_runs(tmp_path, capsys) -> None:
    """`shipped_mutants = ["mca"]`: the shipped studies' mutants of modules the MCA reaches are run against the
    user's claims (named <study>.<mutant>, without the shipped study's expectations); without it a user's claims
    on a shipped solver could only be called descriptive."""
    (tmp_path / "mine.toml").write_text(USER_STUDY)
    study = load_study(str(tmp_path / "mine.toml"))
    found = catalogue(study.mutants, study.path, solver_packages(study), [c.id for c in study.claims],
                      study.shipped_mutants)
    names = {m.name for m in found}
    assert "elasticity.mca-normal-modulus-doubled" in names and "contact-friction.friction-sign" in names
    assert not any("richardson" in n or "skfem" in n for n in names)  # the judge's and scikit-fem's are not the MCA's
    assert all(m.expect == () and m.module().startswith("pcverify.") for m in found)
    # run by `pcverify mutate` as any mutant (measured: elasticity.mca-normal-modulus-doubled is killed by
    # "modulus", 137 s, most of it numba compiling the mutated kernel; not repeated here)
    assert select_mutants(found, ["elasticity.mca-normal-modulus-doubled"], "mine")[0].edited()[1] != \
        select_mutants(found, ["elasticity.mca-normal-modulus-doubled"], "mine")[0].edited()[0]
    (tmp_path / "bad.toml").write_text(USER_STUDY.replace('shipped_mutants = ["mca"]', 'shipped_mutants = ["mcaa"]'))
    assert main(["mutate", str(tmp_path / "bad.toml")]) == 2
    assert "shipped_mutants = 'mcaa' is not a shipped solver; allowed: one of" in capsys.readouterr().err
