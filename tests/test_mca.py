"""MCA solver: elastic constants, the many-body coefficient, response functions, fracture, heat, modes.

Tolerances: static runs relax to a residual force of 1e-9 E |strain| a^2, so constants and fields of the
homogeneous uniaxial state are exact to ~1e-8 (measured); the assertions leave two to three orders of
margin and are still far inside the issue's 2 %.  Block tests are quasi-static to within the measured
dynamic lag (0.5 % at ramp_periods = 8, 0.13 % at 32); the issue's 2 % is asserted.
"""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from mca_block import block_curve

from pcverify.harness.study.catalogue import make_scene
from pcverify.references.heat import analytic, semi_infinite_rise
from pcverify.scene import (
    ALUMINIUM,
    Box,
    Conduction,
    FaceTemperature,
    InterfaceFlux,
    Resolution,
    Response,
    Scene,
    SceneError,
)
from pcverify.solvers.particles.mca import kernel as mk
from pcverify.solvers.particles.mca import response as rf
from pcverify.solvers.registry import get_solver

E, NU = 70e9, 0.33


@pytest.fixture(scope="module")
def mca():
    return get_solver("mca")


@pytest.mark.parametrize("n", [4, 5])
def test_compression_many_body_returns_input_constants_and_the_continuum_field(mca, n):
    scene = make_scene("bar-compression")
    sol = mca.solve(scene, Resolution(n))
    assert sol.status == "ok"
    assert sol.summary["E_eff"] == pytest.approx(E, rel=1e-6)
    assert sol.summary["nu_eff"] == pytest.approx(NU, rel=1e-6)
    ref = get_solver("skfem-elastic").solve(scene, Resolution(n), samples={"nodes": sol.samples["nodes"]["points"]},
                                            element="q1")
    um, uf = sol.samples["nodes"]["values"], ref.samples["nodes"]["values"]
    assert um.shape == uf.shape == (sol.samples["nodes"]["points"].shape[0], 3)
    assert np.linalg.norm(um - uf) / np.linalg.norm(uf) < 1e-3  # issue: 2 %; measured 3e-5
    assert sol.work["pair_steps"] > 0 and sol.work["kernel_s"] > 0


def test_compression_pair_only_has_zero_poisson_ratio(mca):
    """Central normal pairs along the cube axes cannot couple lateral and axial strain: nu_eff = 0."""
    scene = make_scene("bar-compression")
    sol = mca.solve(scene, Resolution(4), many_body=False)
    assert sol.status == "ok"
    assert sol.summary["E_eff"] == pytest.approx(E, rel=1e-6)
    assert abs(sol.summary["nu_eff"]) < 1e-6
    ref = get_solver("skfem-elastic").solve(scene, Resolution(4), samples={"nodes": sol.samples["nodes"]["points"]},
                                            element="q1")
    um, uf = sol.samples["nodes"]["values"], ref.samples["nodes"]["values"]
    assert np.linalg.norm(um - uf) / np.linalg.norm(uf) > 0.1  # the lateral field is missing


def test_many_body_coefficient_is_settled_by_the_uniaxial_test():
    """D = 1 - 2G/(3K) gives Hooke's law; D = 1 - 2G/K gives lambda' = K - 2G and its E', nu'."""
    g, k = E / (2 * (1 + NU)), E / (3 * (1 - 2 * NU))
    lam2 = k - 2 * g
    nu2 = lam2 / (2 * (lam2 + g))
    e2 = g * (3 * lam2 + 2 * g) / (lam2 + g)
    eps = 1e-3
    for coef, (e_exp, nu_exp) in (("hooke", (E, NU)), ("psakhie-2G/K", (e2, nu2))):
        out = block_curve(None, E, NU, np.array([eps]), coefficient=coef, fracture=False)
        assert out["stress"][0] / out["strain"][0] == pytest.approx(e_exp, rel=1e-5)
        assert -out["lateral"][0] / out["strain"][0] == pytest.approx(nu_exp, rel=1e-5)
    assert abs(nu2 - NU) > 0.1  # the two forms are far apart: the test discriminates


PATHS = {
    "elastic": [0.002, 0.004, 0.0055, 0.003, 0.0, 0.004, 0.0056],
    "degradation": [0.003, 0.005, 0.008, 0.004, 0.0, 0.006, 0.01, 0.014],
    "plastic": [0.002, 0.004, 0.006, 0.008, 0.004, 0.0, 0.005, 0.01],
    "plastic-degradation": [0.003, 0.006, 0.01, 0.005, 0.0, 0.006, 0.012],
}


def _reference(resp: Response, path: np.ndarray) -> np.ndarray:
    """Exact curve at the path's points, integrated on a fine sub-path (return mapping is path dependent)."""
    starts = np.r_[0.0, path[:-1]]
    fine = np.concatenate([np.linspace(a, b, 100, endpoint=False) for a, b in zip(starts, path, strict=True)]
                          + [path[-1:]])
    return rf.uniaxial_curve(resp, E, fine)[np.r_[np.arange(1, len(path)) * 100, len(fine) - 1]]


@pytest.mark.parametrize("kind", list(PATHS))
def test_block_loading_unloading_follows_the_response_function(kind):
    resp = Response(kind)
    path = np.array(PATHS[kind])
    out = block_curve(resp, E, NU, path, ramp_periods=8.0)
    ref = _reference(resp, path)
    assert np.all(np.isfinite(ref)) and np.all(out["linked"] == 1.0)
    dev = np.max(np.abs(out["stress"] - ref)) / np.max(np.abs(ref))
    assert dev < 0.02
    if kind in ("degradation", "plastic-degradation"):
        # reduced unloading modulus: the slope of the unloading branch is below E
        i = int(np.flatnonzero(np.diff(path) < 0)[0])  # first unloading step
        slope = (out["stress"][i] - out["stress"][i + 1]) / (path[i] - path[i + 1])
        ref_slope = (ref[i] - ref[i + 1]) / (path[i] - path[i + 1])
        assert ref_slope < 0.99 * E
        assert slope == pytest.approx(ref_slope, rel=0.02)
    if kind.startswith("plastic"):
        assert out["stress"][path.tolist().index(0.0)] < -0.1 * np.max(ref)  # plastic strain left at eps = 0


def test_block_quasi_static_limit_is_approached_as_the_loading_slows():
    resp = Response("plastic")
    path = np.array([0.004, 0.008, 0.004])
    ref = _reference(resp, path)
    devs = [np.max(np.abs(block_curve(resp, E, NU, path, ramp_periods=r)["stress"] - ref)) for r in (2.0, 8.0)]
    assert devs[1] < 0.5 * devs[0]


@pytest.mark.parametrize("k", [1.0, 2.0])
def test_uniform_bar_fails_at_the_strength_and_conserves_energy(mca, k):
    scene = make_scene("bar-tension-fracture", k=k)
    sol = mca.solve(scene, Resolution(3))
    assert sol.status == "ok", sol.reason
    strength = 400e6 / k
    assert sol.summary["failure_stress"] == pytest.approx(strength, rel=0.05)
    assert sol.summary["energy_error"] < 1e-4
    assert sol.summary["linked_fraction"] < 1.0
    assert sol.summary["E_eff"] == pytest.approx(E, rel=0.02)


@pytest.mark.parametrize("gamma", [1e6, 3e6])
def test_a_damped_pulls_held_faces_carry_the_drag_the_integrator_transmits(mca, gamma):
    # steady overdamped pull: v = V z / L exactly, so the held faces' net force is the free automata's drag,
    # rho V (L - a) / 2 per area times the rate the exact half-step factors transmit, (2 / dt) tanh(gamma dt / 2);
    # the start-up's residual is measured at 6e-4 of it (n = 3), held at 3e-3
    scene = make_scene("bar-tension-fracture")
    sol = mca.solve(scene, Resolution(3), damping=gamma)
    dt, length = sol.summary["dt"], scene.box.length
    rate = 2.0 / dt * np.tanh(0.5 * gamma * dt)
    drag = scene.material.density * rate * scene.elasticity.strain_rate * length * (length - 0.005) / 2
    assert sol.summary["drag_stress"] == pytest.approx(drag, rel=3e-3)
    assert abs(sol.summary["drag_stress"] / drag - 1) < 0.5 * (gamma * dt) ** 2 / 12  # the deficit is resolved


def test_fracture_run_is_deterministic(mca):
    scene = make_scene("bar-tension-fracture")
    a = mca.solve(scene, Resolution(2))
    b = mca.solve(scene, Resolution(2))
    assert np.array_equal(a.diagnostics["history"]["rows"], b.diagnostics["history"]["rows"])
    assert np.array_equal(a.samples["nodes"]["values"], b.samples["nodes"]["values"])


def test_too_large_a_time_step_is_reported_unstable_with_the_history_kept(mca):
    sol = mca.solve(make_scene("bar-tension-fracture"), Resolution(3), cfl=3.0)
    assert sol.status == "unstable"
    assert len(sol.diagnostics["history"]["rows"]) > 0


def test_heat_faces_steady_is_the_exact_linear_profile(mca):
    scene = make_scene("bar-heat-faces")
    sol = mca.solve(scene, Resolution(4))
    pts = sol.samples["nodes"]["points"]
    assert np.max(np.abs(sol.samples["nodes"]["values"] - analytic(scene, pts))) < 1e-12


def test_heat_faces_transient_converges_at_second_order(mca):
    scene = make_scene("bar-heat-faces", mode="transient", t_end=1.0)
    hs, errs = [], []
    for n in (4, 5, 6, 8):
        sol = mca.solve(scene, Resolution(n))
        v = sol.samples["nodes"]["values"]
        errs.append(np.sqrt(np.mean((v - analytic(scene, sol.samples["nodes"]["points"])) ** 2)))
        hs.append(scene.box.width / (n - 1))
    order = np.polyfit(np.log(hs), np.log(errs), 1)[0]
    assert order == pytest.approx(2.0, abs=0.2)


def test_heat_paper_bulk_tends_to_one_third_like_the_continuum(mca):
    """Point constraints: the bulk level approaches 1/3 from below (docs/physics.md, "The heating scenes"),
    as skfem on the lattice."""
    scene = make_scene("bar-heat-paper")
    med = [mca.solve(scene, Resolution(n)).summary["bulk_median"] for n in (4, 8)]
    assert med[0] < med[1] < 1 / 3
    fem = get_solver("skfem").solve(scene, Resolution(8)).summary["bulk_median"]
    assert abs(med[1] - fem) < 0.01


def test_modes_converge_to_the_continuum_and_need_rotations(mca):
    scene = make_scene("bar-modes", modes=4)
    f = {n: mca.solve(scene, Resolution(n)).summary for n in (4, 6)}
    fem = get_solver("skfem-elastic").solve(scene, Resolution(2, refine=4), element="q2").summary
    for key in ("f_bending_x_hz", "f_torsion_hz"):
        e4 = abs(f[4][key] / fem[key] - 1)
        e6 = abs(f[6][key] / fem[key] - 1)
        assert e6 < 0.7 * e4 and e6 < 0.1
    stiff = mca.solve(scene, Resolution(4), rotations=False).summary
    assert stiff["frequencies_hz"][0] > 3 * f[4]["frequencies_hz"][0]  # locked rotations: bending far too stiff


@pytest.mark.parametrize("bad", [{"many_body": "yes"}, {"cfl": 0.0}, {"coefficient": "other"}, {"krot": -1.0}])
def test_bad_parameters_raise_scene_error_naming_them(mca, bad):
    with pytest.raises(SceneError, match=next(iter(bad))):
        mca.solve(make_scene("bar-compression"), Resolution(2), **bad)


def test_linearised_stiffness_gives_hooke_and_the_macromolecule_lattice_is_scaled_to_E():
    """The assembled MCA stiffness (used for modes and the time step) solved directly in the uniaxial test
    returns E and nu to round-off; the macromolecule lattice scaled to E returns E (by construction) and
    its own central-force Poisson's ratio, far from 0.33."""
    from pcverify.scene import Box
    from pcverify.solvers.particles.macromolecule.elastic_modes import macromolecule_modes, uniaxial_constants
    from pcverify.solvers.particles.mca.automata import bar_automata
    from pcverify.solvers.particles.mca.model import Elastic
    from pcverify.solvers.particles.mca.stiffness import stiffness

    box = Box()
    aut = bar_automata(box, 4, 2800.0)
    el = Elastic(E, NU)
    e_eff, nu_eff = uniaxial_constants(stiffness(aut, el.shear, el.lam, el.kn, rotations=False), aut.positions, box)
    assert e_eff == pytest.approx(E, rel=1e-9) and nu_eff == pytest.approx(NU, rel=1e-9)
    mm = macromolecule_modes(box, 3, E, 2800.0, modes=3)
    assert abs(mm["nu_eff"] - NU) > 0.2
    assert np.all(np.diff(mm["frequencies_hz"]) >= 0) and mm["frequencies_hz"][0] > 0


def test_kernel_seconds_of_a_fresh_process_leave_out_the_dispatcher_and_cache_load():
    """In a fresh process the first heat solve loads numba's dispatcher and cache (0.1-0.5 s); kernel_s counts
    the steps alone, so it is that of a warm solve (~1e-4 s at n = 4), not the load's (measured before the
    fix: 0.39 s against 60-80 us).  The bound 0.05 s leaves room for a loaded machine's preemptions."""
    code = ("from pcverify.harness.study.catalogue import make_scene\n"
            "from pcverify.scene import Resolution\n"
            "from pcverify.solvers.registry import get_solver\n"
            "s = make_scene('bar-heat-faces', mode='transient', t_end=1.0)\n"
            "m = get_solver('mca')\n"
            "a, b = (m.solve(s, Resolution(4)) for _ in range(2))\n"
            "print(a.work['kernel_s'], b.work['kernel_s'], a.wall_s)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    first, warm, wall = map(float, out.stdout.split())
    assert first < 0.05 and warm < 0.05  # the load alone takes 0.1-0.5 s; the steps take ~1e-4 s (1000x margin)
    assert first < 0.5 * wall  # the first solve's wall time holds the load; its kernel time does not


def test_a_scene_without_rotation_runs_a_kernel_compiled_without_rotation_terms(mca):
    scene = make_scene("bar-compression")
    sol = mca.solve(scene, Resolution(3), rotations=False)
    assert sol.status == "ok"
    rot_types = {str(sig[0].types[mk.State._fields.index("rot")]) for sig in mk.advance.signatures}
    assert "none" in rot_types  # a specialisation with the rotation part absent (its branches pruned)
    ref = mca.solve(scene, Resolution(3), rotations=True)
    assert sol.summary["E_eff"] == pytest.approx(ref.summary["E_eff"], rel=1e-6)  # uniaxial: rotations do not act


def _slab_scene(mode="steady", t_end=0.0, dt=0.0, source=0.0, interface=None, held=True, box=None, initial=0.0,
                t_max=1.0):
    """Faces z = 0 and z = L at 0 K (held) or every face insulated, with a volumetric source and/or a plane."""
    physics = {"conduction"} | ({"heat-source"} if source else set()) | ({"interface-flux"} if interface else set())
    cons = (FaceTemperature("z0", 0.0), FaceTemperature("zL", 0.0)) if held else ()
    heat = Conduction(t_max=t_max, mode=mode, t_end=t_end, dt=dt, source=source, interface=interface,
                      initial_temperature=initial)
    return Scene("slab", "test scene", box or Box(), ALUMINIUM, frozenset(physics), cons, conduction=heat)


def test_heat_steady_source_is_nodally_exact(mca):
    """T = s z (L - z) / (2k) between faces at 0 K: the three-point balance of the node-centred cells is exact
    for a quadratic, so MCA heat is exact at its automata (as scikit-fem's P1 on the lattice)."""
    scene = _slab_scene(source=1e6)
    for n in (2, 4):
        sol = mca.solve(scene, Resolution(n))
        pts = sol.samples["nodes"]["points"]
        assert np.max(np.abs(sol.samples["nodes"]["values"] - analytic(scene, pts))) < 1e-12


def test_heat_interface_flux_and_source_converge_at_second_order(mca):
    """An insulated bar with a source and a plane source at z = L/3 (a node plane at every n): the explicit
    scheme's error against the slab's cosine series falls at second order in a (dt ~ a^2): measured L-inf
    1.77e-3, 6.4e-4, 3.3e-4, 1.6e-4 of t_max = 1 K at n = 4, 6, 8, 11, order 2.00."""
    scene = _slab_scene("transient", 1.0, 0.01, source=1e5, interface=InterfaceFlux(1e4, 0.01), held=False)
    hs, errs = [], []
    for n in (4, 6, 8, 11):
        sol = mca.solve(scene, Resolution(n))
        pts = sol.samples["nodes"]["points"]
        errs.append(np.max(np.abs(sol.samples["nodes"]["values"] - analytic(scene, pts))))
        hs.append(sol.resolution["h"])
    order = np.polyfit(np.log(hs), np.log(errs), 1)[0]
    assert order == pytest.approx(2.0, abs=0.2)


@pytest.mark.parametrize("position", [0.01, 0.0123])
def test_heat_of_an_insulated_bar_grows_by_the_heat_released(mca, position):
    """No temperature held: the heat content grows by exactly (s V + q A) t, also with the plane between two
    node planes (its load shared by hat weights)."""
    s, q, t_end, initial = 2e5, 3e4, 0.5, 300.0
    scene = _slab_scene("transient", t_end, 0.05, source=s, interface=InterfaceFlux(q, position), held=False,
                        initial=initial, t_max=500.0)
    sol = mca.solve(scene, Resolution(3))
    box, mat = scene.box, scene.material
    content = mat.density * mat.heat_capacity * box.volume * (sol.summary["volume_mean"] * 500.0 - initial)
    assert content == pytest.approx((s * box.volume + q * box.width * box.height) * t_end, rel=1e-11)


def test_heat_short_time_rise_at_the_plane_nodes_is_the_semi_infinite_one(mca):
    """A plane source midway between two node planes, at short times: each side takes q/2 and the nodes at
    a/2 from the plane rise by (2 (q/2) / k) sqrt(alpha t) ierfc(a / (4 sqrt(alpha t))), to second order
    (measured relative deviations 8.3e-2, 2.1e-2, 1.0e-2, 3.7e-3, 1.9e-3 at n = 4, 6, 8, 12, 16)."""
    q, t_end = 1e5, 0.05
    scene = _slab_scene("transient", t_end, t_end / 50, interface=InterfaceFlux(q, 0.015), held=False)
    alpha, devs = scene.material.diffusivity, []
    for n in (8, 12):
        sol = mca.solve(scene, Resolution(n))
        a = sol.resolution["h"]
        pts = sol.samples["nodes"]["points"]
        near = np.abs(pts[:, 2] - 0.015) < 0.51 * a
        expect = semi_infinite_rise(q / 2, ALUMINIUM.conductivity, alpha, t_end, depth=a / 2)
        devs.append(abs(sol.samples["nodes"]["values"][near].mean() / expect - 1))
    assert devs[1] < devs[0] and devs[1] < 0.02
