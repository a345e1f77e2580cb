"""The stick-slip scene's second reference, a rigid block on the slider's discrete Cundall-Strack contacts pulled
at the slider's centre of mass, and the typical cycles the measurement averages.

The block's geometry is checked against the MCA slider's own automata, its law against the closed-form rigid
block (one contact row, no moment: it is the closed form up to the contacts' compliance), the moment against
the pull at the interface (it breaks away at mu_s N there), and the measurement's stick time against a history
whose first breakaway is untypical.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from pcverify.harness.report.figures import _takes_summary
from pcverify.harness.study.catalogue import get_spec, make_scene
from pcverify.references import contact as ref
from pcverify.solvers.particles.mca import stick_slip as mss
from pcverify.solvers.particles.mca.automata import body_automata

SCENE = make_scene("stick-slip")
KT = 2.0 * 70e9 / (2.0 * 1.33)  # 2 G / h0 per h0: the scene's duralumin, times the spacing below


@pytest.mark.parametrize("n", [4, 6])
def test_the_contacts_are_the_mca_sliders_bottom_automata_and_its_centre_of_mass(n) -> None:
    """Rows, areas and the pull's height from the scene's geometry alone agree with the MCA slider's automata
    (round-off: both are sums of the same cells)."""
    aut, _ = body_automata(SCENE.box, n, SCENE.material.density, SCENE.contact)
    c = ref.slider_contacts(SCENE, float(aut.spacing[1]))
    slider = aut.body == 1
    y = aut.positions[slider, 1]
    bottom = slider & (aut.positions[:, 1] == y.min())
    z = aut.positions[bottom, 2] - 0.015
    area = aut.extent[bottom][:, [0, 2]].prod(axis=1)
    rows = {round(v, 9): 0.0 for v in z}
    for zi, ai in zip(z, area, strict=True):
        rows[round(zi, 9)] += ai
    assert np.allclose(sorted(rows), c.z, rtol=0, atol=1e-9)
    assert np.allclose([rows[k] for k in sorted(rows)], c.area, rtol=1e-12, atol=0)
    weight = aut.mass[slider] / aut.mass[slider].sum()
    assert c.height == pytest.approx(float((weight * (y - SCENE.contact.position)).sum()), rel=1e-12)


def test_one_row_without_moment_is_the_closed_form_block() -> None:
    """One contact row under the block, pulled at the interface's height: every contact reaches mu_s together,
    so the cycle is the closed form's; the contacts' compliance (1.6e9 N/m against the spring's 5e4) and the
    rest threshold's bias (0.4 %) leave at most 1 %."""
    s = ref.setting(SCENE)
    c = ref.Contacts(z=np.zeros(1), area=np.array([1e-4]), height=0.0)
    got = ref.cycle_of(ref.contact_block(s, c, KT / 0.01 * 3, SCENE.contact.duration, damping=1.0), s.speed)
    closed = ref.cycle(*s)
    assert got["first_peak_N"] == pytest.approx(closed.peak, rel=0.005)
    for name, value in (("spring_peak_N", closed.peak), ("spring_trough_N", closed.trough),
                        ("period_s", closed.period), ("slip_velocity_peak", closed.slip_velocity),
                        ("stick_s", closed.stick)):
        assert got[name] == pytest.approx(value, rel=0.01), name


@pytest.mark.parametrize("n", [4, 6])
def test_pulled_at_the_interface_the_block_breaks_away_at_mu_s_n_and_at_its_centre_of_mass_below(n) -> None:
    """Pulled at the interface the resting block's contacts are equally pressed and reach mu_s together (the
    first breakaway mu_s N within the step's 0.2 %); pulled at its centre of mass, the friction's moment unloads
    the trailing rows, which slip first: the first breakaway is below 0.9 mu_s N (measured 0.845 / 0.867)."""
    s = ref.setting(SCENE)
    a = 0.01 / (n - 1)
    c = ref.slider_contacts(SCENE, a)
    at_interface = ref.cycle_of(ref.contact_block(s, c, KT / a, 2.5e-3, pull_height=0.0), s.speed)
    assert at_interface["first_peak_N"] == pytest.approx(40.0, rel=0.002)
    at_height = ref.cycle_of(ref.contact_block(s, c, KT / a, 2.5e-3), s.speed)
    assert at_height["first_peak_N"] < 0.9 * 40.0


def _block_rows(first_peak: float, every: int = 20) -> np.ndarray:
    """Rows (t, F, v, x) of a rigid block that breaks away first at first_peak, later at mu_s N (leapfrog at
    0.05 us, rows every `every` steps): a history whose stick after the first slip is untypical."""
    s = ref.setting(SCENE)
    dt, n = 5e-8, int(SCENE.contact.duration / 5e-8)
    limit, x, v, stuck, rows = first_peak, 0.0, 0.0, True, []
    for i in range(n):
        t = i * dt
        f = s.stiffness * (s.speed * t - x)
        if stuck and f > limit:
            stuck = False
        if not stuck:
            v += dt * (f - s.mu_kinetic * s.normal_force) / s.mass
            if v <= 0.0:
                v, stuck, limit = 0.0, True, s.mu_static * s.normal_force
            x += dt * v
        if i % every == 0:
            rows.append((t, f, v, x))
    return np.array(rows)


def test_stick_time_is_the_typical_cycles() -> None:
    """A first breakaway at 0.85 mu_s N leaves the stick after it 0.56 ms against the typical 2 (mu_s - mu_k) N /
    (k V) = 0.8 ms: the measured stick is the typical one within the rest threshold's bias (0.35 %, twice)."""
    got = mss.measure(_block_rows(0.85 * 40.0), 0.5)
    closed = ref.cycle(*ref.setting(SCENE))
    assert got["stick_slip_cycles"] >= 3
    assert got["stick_s"] == pytest.approx(closed.stick, rel=0.007)
    assert got["period_s"] == pytest.approx(closed.period, rel=0.007)
    assert math.isfinite(got["stick_s_spread"])


def test_the_compare_step_holds_the_contact_blocks_cycle() -> None:
    """With the run's lattice spacing in the summary the reference gives the contact block's cycle under the
    summary's names (NAME_given_contacts), and nothing of it without."""
    from pcverify.harness.judge.compare import scalar_errors

    summary = {"spring_peak_N": 36.0, "lattice_spacing": 0.01 / 3, "contact_stiffness_Pa_per_m": KT / (0.01 / 3)}
    errs = scalar_errors(SCENE, summary)
    got = errs["spring_peak_N_given_contacts"]
    assert got["expected"] == pytest.approx(ref.contact_cycle(SCENE, 0.01 / 3)["spring_peak_N"], rel=1e-12)
    assert got["error"] == pytest.approx(abs(36.0 / got["expected"] - 1.0), rel=1e-12)
    assert not any(k.endswith("_given_contacts") for k in scalar_errors(SCENE, {"spring_peak_N": 36.0}))


def test_the_history_figure_draws_the_block_on_the_runs_contacts() -> None:
    """Under a run the history figure draws the reference the contact-block claims judge: given the run's
    lattice spacing (n = 4: 10 mm / 3) and contact stiffness, the block on the slider's contacts at that
    spacing (its first cycle tops out at 35.6 N: the pull's moment above the interface), not the closed form's
    mu_s N = 40 N, which it draws without a summary; and the figure passes the cell's summary on."""
    curve = get_spec("stick-slip").reference.history
    assert _takes_summary(curve) and not _takes_summary(lambda scene, t: None)
    a = 0.01 / 3
    t = np.linspace(0.0, SCENE.contact.duration, 7001)
    block, label = curve(SCENE, t, {"lattice_spacing": a, "contact_stiffness_Pa_per_m": KT / a})
    closed, closed_label = curve(SCENE, t)
    first = t < 2.1e-3  # the first cycle of both
    contacts = ref.contact_cycle(SCENE, a, KT / a)  # the contact-block claims' numbers
    assert contacts["first_peak_N"] <= block[first].max() < 36.0  # rises a little past the slip's onset
    closed_cycle = ref.cycle(*ref.setting(SCENE))  # the closed form overshoots mu_s N while it slips
    assert closed[first].max() == pytest.approx(closed_cycle.largest, rel=1e-4)
    assert "contacts" in label and "analytic" in closed_label
