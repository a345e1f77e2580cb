"""Model notes: where a solver departs from its source, shown by `pcverify solvers` and beside every study that
runs it; the MCA notes' numbers are the model's own (they fail when the model changes, not when the text does)."""

import json
import math

import pytest

from pcverify.harness.cli import main
from pcverify.harness.report.page import notes_details
from pcverify.harness.report.write import solver_notes
from pcverify.scene import Box
from pcverify.solvers.particles.mca.automata import bar_automata
from pcverify.solvers.particles.mca.model import Elastic, Model
from pcverify.solvers.particles.mca.solver import Mca
from pcverify.solvers.protocol import model_notes, read_notes
from pcverify.solvers.registry import get_solver

DURALUMIN = Elastic(70e9, 0.33)
RHO = 2800.0


def test_solvers_listing_shows_the_mca_notes(capsys):
    assert main(["solvers", "--json"]) == 0
    rows = {r["name"]: r for r in json.loads(capsys.readouterr().out)}
    assert rows["mca"]["notes"] == list(Mca().notes) and len(Mca().notes) >= 4
    assert rows["skfem"]["notes"] == []
    assert main(["solvers"]) == 0
    out = capsys.readouterr().out
    with_notes = [name for name, r in rows.items() if r["notes"]]  # the MCA and LAMMPS's bonded particle model
    assert "mca" in with_notes and out.count("model notes (departures from the source") == len(with_notes)
    assert "    1. Many-body transfer without the paper's delay" in out


def test_notes_of_a_solver_must_be_sentences():
    class Bad:
        name = "bad"
        notes = "one string, not a tuple"

    with pytest.raises(TypeError, match="solver 'bad': notes='one string"):
        model_notes(Bad())

    class Blank:
        name = "blank"
        notes = ("  ", "a note ")

    assert model_notes(Blank()) == ("a note",)
    assert model_notes(get_solver("fipy")) == ()


def test_report_notes_per_solver_escaped():
    assert solver_notes(["fipy", "mca", "skfem"]) == {"mca": list(Mca().notes)}
    html = notes_details("study-a", {"mca": ["x < y & z", "second"]})
    assert "Model notes (2)" in html and "x &lt; y &amp; z" in html and html.count("<li>") == 3
    assert "id='study-a-model-notes'" in html and "where mca departs from the source or chooses" in html
    assert notes_details("study-a", {}) == ""


def test_delay_note_one_step_is_a_fifth_of_the_p_wave_transit():
    """The note's 0.19 a / c_p: the many-body term acts within one step, dt = 2 cfl / omega_max."""
    cp = math.sqrt(DURALUMIN.contact / RHO)
    assert "dt = 0.19 a / c_p" in Mca().notes[0] and f"{cp:.0f}"[:3] == "608"
    for n in (3, 6):
        aut = bar_automata(Box(0.01, 0.01, 0.03), n, RHO)
        model = Model(aut, DURALUMIN, krot=0.01, cfl=0.5)
        assert model.dt * cp / float(aut.spacing.min()) == pytest.approx(0.1922, abs=5e-4)


def test_contact_law_note_confined_and_uniaxial_moduli():
    """The pair law the contact uses: sig = kn eps + lam theta.  Confined (theta = eps): M = K + 4G/3 = 103.7
    GPa; uniaxial stress (theta = (1 - 2 nu) eps): E = 70 GPa -- eq. 10 gives E in both."""
    el = DURALUMIN
    confined = el.kn + el.lam
    uniaxial = el.kn + el.lam * (1 - 2 * el.poisson)
    assert confined == pytest.approx(103.715e9, rel=1e-4) and "M = K + 4G/3 = 103.7 GPa" in Mca().notes[1]
    assert uniaxial == pytest.approx(el.youngs, rel=1e-12)


def test_notes_file_paragraphs_and_comments(tmp_path):
    path = tmp_path / "notes.txt"
    path.write_text("# a comment\n\nFirst note,\n  wrapped.\n\n\n# between\nSecond note.\n", encoding="utf-8")
    assert read_notes(path) == ("First note, wrapped.", "Second note.")
