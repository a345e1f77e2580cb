"""Analytic references: the Fourier series satisfies its own PDE, BCs and steady limit."""

import math

import numpy as np
import pytest

from pcverify.harness.catalogue import make_scene
from pcverify.references import analytic, heat_faces

L, ALPHA = 0.03, 237.0 / (2700.0 * 897.0)


def test_series_tail_bound_meets_tolerance():
    # doubling the number of terms changes the sum by less than the stated tolerance
    z = np.linspace(0, L, 41)
    for t in (1e-3, 0.05, 1.0):
        k = heat_faces.terms_needed(t, L, ALPHA, 1e-12)
        c = ALPHA * math.pi**2 * t / L**2
        kk = np.arange(k + 1, 4 * k + 50)
        tail = np.abs(np.sin(np.multiply.outer(z, kk) * math.pi / L) @ (2 / (kk * math.pi) * np.exp(-c * kk**2)))
        assert tail.max() < 1e-12


def test_transient_satisfies_heat_equation_and_boundaries():
    z = np.linspace(0.002, L - 0.002, 7)
    t, dt, dz = 0.2, 1e-5, 1e-5
    f = lambda zz, tt: heat_faces.transient(zz, tt, L, ALPHA, 1.0)  # noqa: E731
    dTdt = (f(z, t + dt) - f(z, t - dt)) / (2 * dt)
    d2T = (f(z + dz, t) - 2 * f(z, t) + f(z - dz, t)) / dz**2
    # central differences: truncation ~1e-9 relative, round-off ~1e-16/dz^2 = 1e-6 in d2T (scaled by alpha ~1e-4)
    assert np.max(np.abs(dTdt - ALPHA * d2T)) < 1e-6
    assert f(np.array([0.0]), t)[0] == pytest.approx(1.0, abs=1e-12)
    assert f(np.array([L]), t)[0] == pytest.approx(0.0, abs=1e-12)


def test_transient_limits():
    z = np.linspace(0, L, 31)
    # long times: the steady linear profile
    assert np.allclose(heat_faces.transient(z, 200.0, L, ALPHA, 500.0), heat_faces.steady(z, L, 500.0), atol=1e-9)
    # very short times: the interior is still at the initial 0 K
    early = heat_faces.transient(np.array([L / 2]), 1e-3, L, ALPHA, 500.0)
    assert abs(early[0]) < 1e-10
    with pytest.raises(ValueError, match="t="):
        heat_faces.terms_needed(0.0, L, ALPHA)


def test_analytic_dispatch():
    pts = make_scene("bar-heat-faces").sample_sets(3)["front_top_edge"]
    assert np.allclose(analytic(make_scene("bar-heat-faces"), pts), 1 - pts[:, 2] / L)
    tr = make_scene("bar-heat-faces", mode="transient", t_end=0.5, dt=0.01)
    assert np.allclose(analytic(tr, pts), heat_faces.transient(pts[:, 2], 0.5, L, ALPHA, 1.0))
    assert analytic(make_scene("bar-heat-paper"), pts) is None
    assert analytic(make_scene("bar-heat-patch"), pts) is None
