"""Analytic references: the Fourier series satisfy their own PDE, boundary and jump conditions, steady limits and
energy balance; the short-time limit of the interface flux is the semi-infinite solution."""

import dataclasses
import math

import heat_faces
import numpy as np
import pytest

from pcverify.harness.study.catalogue import make_scene
from pcverify.references.heat import Slab, analytic, effusivity, effusivity_shares, semi_infinite_rise
from pcverify.scene import ALUMINIUM, Box, Conduction, FaceTemperature, InterfaceFlux, Scene

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


# ---------------------------------------------------------------------------------------------------
# the slab: held or insulated faces, a uniform source and an interface flux (references/heat.py)

K_AL = 237.0
HELD_SOURCE = Slab(L, K_AL, ALPHA, held=(0.0, 0.0), source=1e6)
HELD_ALL = Slab(L, K_AL, ALPHA, held=(40.0, -10.0), initial=15.0, source=1e6, flux=2e4, plane=0.011)
INSULATED = Slab(L, K_AL, ALPHA, held=None, initial=15.0, source=1e5, flux=2e4, plane=0.011)


def _residual(slab: Slab, z: np.ndarray, t: float) -> np.ndarray:
    """dT/dt - alpha T'' - alpha s / k by central differences (away from the plane)."""
    dt, dz = 1e-4, 1e-5
    f = slab.transient
    dTdt = (f(z, t + dt) - f(z, t - dt)) / (2 * dt)
    d2T = (f(z + dz, t) - 2 * f(z, t) + f(z - dz, t)) / dz**2
    return dTdt - ALPHA * d2T - ALPHA * slab.source / K_AL


@pytest.mark.parametrize("slab", [HELD_SOURCE, HELD_ALL, INSULATED], ids=["source", "held-all", "insulated"])
def test_slab_satisfies_its_equation_jump_and_boundaries(slab):
    z = np.array([0.002, 0.006, 0.0105, 0.0115, 0.02, 0.028])
    rate = ALPHA * (slab.source + abs(slab.flux) / 1e-3) / K_AL  # a scale of dT/dt
    # central differences: truncation ~1e-9 relative, round-off ~1e-16/dz^2 * T ~ 1e-5 K/m^2 times alpha
    assert np.max(np.abs(_residual(slab, z, 0.3))) < 1e-6 * rate
    e, t = 1e-5, 0.3
    f = lambda zz: slab.transient(np.array([zz]), t)[0]  # noqa: E731
    if slab.flux:  # the plane releases q: the conductive fluxes on its two sides differ by q
        # second-order one-sided slopes (truncation O(e^2)); the series tolerance adds 1e-12 K / e * k = 2e-5 W/m^2
        p = slab.plane
        below = (3 * f(p) - 4 * f(p - e) + f(p - 2 * e)) / (2 * e)
        above = (-3 * f(p) + 4 * f(p + e) - f(p + 2 * e)) / (2 * e)
        assert K_AL * (below - above) == pytest.approx(slab.flux, rel=1e-4)
    if slab.held is None:  # insulated ends: zero slope (second-order one-sided; T is even about an insulated end)
        assert abs(-3 * f(0.0) + 4 * f(e) - f(2 * e)) / (2 * e) < 1e-6 * slab.flux / K_AL
        assert abs(3 * f(L) - 4 * f(L - e) + f(L - 2 * e)) / (2 * e) < 1e-6 * slab.flux / K_AL
    else:
        assert f(0.0) == pytest.approx(slab.held[0], abs=1e-11) and f(L) == pytest.approx(slab.held[1], abs=1e-11)
    # at t -> 0, away from the faces and the plane (sqrt(alpha t) = 0.1 mm): the initial temperature plus s t / (rho c)
    early = slab.initial + slab.source * 1e-4 * ALPHA / K_AL
    assert slab.transient(np.array([0.005, 0.02]), 1e-4) == pytest.approx(early, abs=1e-9)


def test_slab_limits_and_the_faces_series():
    z = np.linspace(0, L, 31)
    # s = q = 0, T0 = 1, TL = Ti = 0 is bar-heat-faces: the same series as heat_faces (summed to 1e-12)
    faces = Slab(L, K_AL, ALPHA, held=(1.0, 0.0))
    assert np.allclose(faces.transient(z, 0.5), heat_faces.transient(z, 0.5, L, ALPHA, 1.0), atol=3e-12, rtol=0)
    # the source between faces at 0 K: T = s z (L - z) / (2k), reached at long times
    assert np.allclose(HELD_SOURCE.steady(z), 1e6 * z * (L - z) / (2 * K_AL), rtol=1e-14, atol=0)
    assert np.allclose(HELD_SOURCE.transient(z, 200.0), HELD_SOURCE.steady(z), atol=1e-12)
    assert np.allclose(HELD_ALL.transient(z, 200.0), HELD_ALL.steady(z), atol=1e-12)
    with pytest.raises(ValueError, match="held"):
        INSULATED.steady(z)
    with pytest.raises(ValueError, match="t="):
        INSULATED.transient(z, 0.0)


def test_insulated_slab_energy_balance_and_closed_form():
    """The heat content rises by (s L + q) t per unit area; the closed form of the time-independent cosine sum
    equals the plain series (summed to 2e5 terms: tail < 2 q L / (k pi^2) / 2e5 = 1.3e-7 K)."""
    zq = np.linspace(0.0, L, 300001)
    for t in (0.01, 0.3, 5.0):
        content = np.trapezoid(K_AL / ALPHA * (INSULATED.transient(zq, t) - INSULATED.initial), zq)
        assert content == pytest.approx((INSULATED.source * L + INSULATED.flux) * t, rel=1e-8)
    z = np.array([0.0, 0.004, 0.011, 0.02, L])
    m = np.arange(1, 200001, dtype=float)
    a = INSULATED.plane / L
    plain = np.cos(np.multiply.outer(z, m) * math.pi / L) @ (2 * INSULATED.flux * L / (K_AL * m**2 * math.pi**2)
                                                              * np.cos(m * math.pi * a))
    long_time = 1e3  # every mode has decayed: T = Ti + (s + q/L) t / (rho c) + the time-independent sum
    ramp = INSULATED.initial + (INSULATED.source + INSULATED.flux / L) * long_time * ALPHA / K_AL
    assert np.allclose(INSULATED.transient(z, long_time) - ramp, plain, atol=2e-7)


def test_short_times_semi_infinite_with_the_effusivity_split():
    """At short times each side of the plane takes q / 2 (one material: equal effusivities) and the plane rises
    as the surface of a semi-infinite solid taking q / 2; the heat in each side is q t / 2."""
    q, t = 2e4, 0.02  # sqrt(alpha t) = 1.4 mm, the nearest end 11 mm away (images ~ erfc(3.9) = 2e-8)
    slab = Slab(L, K_AL, ALPHA, held=None, flux=q, plane=0.011)
    depth = np.array([0.0, 0.001, 0.003])
    e = effusivity(K_AL, 2700.0, 897.0)
    assert effusivity_shares(e, e) == (0.5, 0.5)
    expect = semi_infinite_rise(q * 0.5, K_AL, ALPHA, t, depth)
    assert expect[0] == pytest.approx(2 * (q / 2) * math.sqrt(ALPHA * t / math.pi) / K_AL, rel=1e-15)
    for side in (-1, 1):
        assert np.allclose(slab.transient(slab.plane + side * depth, t), expect, rtol=1e-6, atol=0)
    zq = np.linspace(0.0, slab.plane, 100001)
    below = np.trapezoid(K_AL / ALPHA * slab.transient(zq, t), zq)
    assert below == pytest.approx(q * t / 2, rel=1e-6)
    shares = effusivity_shares(2.0 * e, e)
    assert shares[0] == pytest.approx(2 / 3) and sum(shares) == pytest.approx(1.0)


def test_analytic_dispatch_of_slab_scenes():
    box = Box(0.01, 0.02, 0.04)
    ends = {"x": ("x0", "xW"), "y": ("y0", "yH"), "z": ("z0", "zL")}
    for axis, (lo, hi) in ends.items():
        cons = (FaceTemperature(lo, 2.0), FaceTemperature(hi, 1.0))
        heat = Conduction(t_max=2.0, source=1e6, interface=InterfaceFlux(1e4, 0.005, axis))
        scene = Scene("s", "s", box, ALUMINIUM, frozenset({"conduction", "heat-source", "interface-flux"}), cons,
                      conduction=heat)
        ax = "xyz".index(axis)
        pts = box.lattice_points(3)
        slab = Slab(float(box.extent[ax]), K_AL, ALPHA, held=(2.0, 1.0), source=1e6, flux=1e4, plane=0.005)
        assert np.allclose(analytic(scene, pts), slab.steady(pts[:, ax]) / 2.0, rtol=1e-14, atol=0)
        # a plane across another axis is not one-dimensional
        other = Conduction(t_max=2.0, interface=InterfaceFlux(1e4, 0.005, "xyz"[(ax + 1) % 3]))
        scene = Scene("s", "s", box, ALUMINIUM, frozenset({"conduction", "interface-flux"}), cons, conduction=other)
        assert analytic(scene, pts) is None
    # an insulated body has no steady state; its transient is the cosine series
    heat = Conduction(t_max=1.0, mode="transient", t_end=0.2, dt=0.01, interface=InterfaceFlux(1e4, 0.01))
    scene = Scene("s", "s", Box(), ALUMINIUM, frozenset({"conduction", "interface-flux"}), (), conduction=heat)
    z = np.array([[0.0, 0.0, 0.01]])
    assert analytic(scene, z)[0] == pytest.approx(Slab(L, K_AL, ALPHA, flux=1e4, plane=0.01).transient(
        np.array([0.01]), 0.2)[0], rel=1e-14)
    assert analytic(dataclasses.replace(scene, conduction=dataclasses.replace(heat, mode="steady")), z) is None
    # one held face only: not a slab reference
    one = Scene("s", "s", Box(), ALUMINIUM, frozenset({"conduction"}), (FaceTemperature("z0", 1.0),),
                conduction=Conduction(t_max=1.0))
    assert analytic(one, z) is None
