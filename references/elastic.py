"""The elastic family: the duralumin bar compressed, vibrating and pulled to fracture, its reference scalars (E_eff =
E, nu_eff = nu; failure_stress = sigma_c / k: uniaxial tension's Drucker-Prager stress is k sigma) and the summary
scalars an elasticity solver reports (`SCALARS`: names, units, signs).  The MCA bar's rotational modes and its
packing's bending ratios, derived by hand from the model's potential (docs/physics.md, "Analytic references",
"The elastic family").
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from pcverify.references.shared import DIMENSIONS, box_of
from pcverify.scene import (
    DURALUMIN,
    RESPONSES,
    Elasticity,
    FaceClamp,
    FaceSupport,
    Param,
    Reference,
    Response,
    Scalar,
    Scene,
    SceneError,
    SceneSpec,
)


def packing_second_moment_ratio(packing: str, spacings: float) -> float:
    """I_lattice / I of a section `spacings` = H / a lattice spacings deep: 1 + 2 (a/H)^2 for "nodes"
    (trapezoid rule), 1 - (a/H)^2 for "cells" (midpoint rule)."""
    if packing not in ("nodes", "cells"):
        raise ValueError(f"packing={packing!r} is out of range; allowed: nodes or cells")
    if not spacings >= 1:
        raise ValueError(f"spacings={spacings!r} is out of range; allowed: number >= 1")
    r = 1.0 / spacings
    return 1.0 + 2.0 * r * r if packing == "nodes" else 1.0 - r * r


def packing_bending_ratio(packing: str, n: int) -> float:
    """Predicted bending frequency ratio lattice / continuum of a square section at resolution n:
    sqrt(I_lattice / I) with H / a = n - 1 ("nodes", n nodes across) or n ("cells", n automata across)."""
    return math.sqrt(packing_second_moment_ratio(packing, n - 1 if packing == "nodes" else n))


def mca_rotational_hz(shear_modulus: float, density: float, spacing: float, krot: float,
                      cells: tuple[int, int, int]) -> float:
    """Lowest rotational eigenfrequency (Hz) of the MCA bar: `cells` = (N_x, N_y, N_z) spacings `spacing` (m)
    across, across and along, face z = 0 clamped; the section-alternating rotation about the bar's axis, psi_k
    per node plane k = 1..N_z, as a chain: per unit section area the plane's pairs give stiffness 8 krot G t_k
    (t_k its thickness: a, a / 2 for the last), the axial pairs springs krot G a between planes, the plane's
    inertia rho t_k (a^2 (2 - 3 / (4 N_x) - 3 / (4 N_y)) + t_k^2) / 18."""
    nx, ny, nz = (int(c) for c in cells)
    if min(nx, ny, nz) < 1:
        raise ValueError(f"cells={cells!r} is out of range; allowed: three integers >= 1")
    a = float(spacing)
    t = np.full(nz, a)
    t[-1] = a / 2
    inertia = density * t * (a**2 * (2 - 0.75 / nx - 0.75 / ny) + t**2) / 18.0
    spring = krot * shear_modulus * a
    diag = 8 * krot * shear_modulus * t + spring * np.r_[np.full(nz - 1, 2.0), 1.0]
    scale = 1.0 / np.sqrt(inertia)
    return math.sqrt(lowest_eigenvalue(diag * scale**2, -spring * scale[:-1] * scale[1:])) / (2 * math.pi)


def rod_axial_hz(youngs_modulus: float, density: float, length: float) -> float:
    """Lowest axial eigenfrequency (Hz) of a rod clamped at one end, free at the other, in elementary rod theory
    (plane sections, no lateral inertia): c / (4 L), c = sqrt(E / rho).  The 3-D bar clamped over its face is
    stiffer (the clamp stops the face's Poisson contraction) and its lateral inertia makes it softer; both are
    of order (nu a / L)^2."""
    if min(youngs_modulus, density, length) <= 0:
        raise ValueError("youngs_modulus, density and length must be positive")
    return math.sqrt(youngs_modulus / density) / (4.0 * length)


def saint_venant_torsion_hz(shear_modulus: float, density: float, width: float, height: float,
                            length: float) -> float:
    """Lowest torsional eigenfrequency (Hz) of a prismatic bar of w x h section clamped at one end, free at the
    other, in Saint-Venant's theory (free warping): sqrt(G J / (rho I_p)) / (4 L), J = beta b c^3 (b >= c the
    sides, beta from the series of the stress function), I_p = w h (w^2 + h^2) / 12.  A clamp that stops the
    warping of its face makes the 3-D bar a little stiffer."""
    if min(shear_modulus, density, width, height, length) <= 0:
        raise ValueError("shear_modulus, density, width, height and length must be positive")
    b, c = max(width, height), min(width, height)
    odd = np.arange(1, 400, 2, dtype=float)
    beta = (1.0 - 192.0 / math.pi**5 * (c / b) * float(np.sum(np.tanh(odd * math.pi * b / (2 * c)) / odd**5))) / 3
    torsion_constant = beta * b * c**3
    polar = width * height * (width**2 + height**2) / 12.0
    return math.sqrt(shear_modulus * torsion_constant / (density * polar)) / (4.0 * length)


def lowest_eigenvalue(diag: np.ndarray, off: np.ndarray) -> float:
    """The lowest eigenvalue of the symmetric tridiagonal matrix (diag, off), to the last bit, by bisection on the
    Sturm count (a negative pivot of A - s I: an eigenvalue below s); numpy only (the catalogue imports no scipy)."""
    radius = np.abs(np.r_[0.0, off]) + np.abs(np.r_[off, 0.0])
    lo, hi, squares = float((diag - radius).min()), float((diag + radius).max()), np.r_[0.0, off**2].tolist()
    while lo < (mid := 0.5 * (lo + hi)) < hi:
        pivot = 1.0
        for d, e2 in zip(diag.tolist(), squares, strict=True):  # down the chain of planes
            pivot = d - mid - e2 / (pivot or 1e-300)
            if pivot < 0.0:
                break
        lo, hi = (lo, mid) if pivot < 0.0 else (mid, hi)
    return mid


def _strain_sign(scene: Scene) -> int:
    """The sign of the bar's axial strain: its `strain` (negative in compression), pulled (+1) when it is
    stretched at a strain rate, else either (0)."""
    p = scene.param_dict
    if "strain" in p:
        return int(np.sign(p["strain"]))
    return 1 if "strain_rate" in p else 0


def fracture_scalars(resp: Response, youngs: float) -> dict[str, float]:
    """The bar pulled in uniaxial tension, in closed form: it fails at sigma_t = sigma_c / k (the Drucker-Prager
    stress of uniaxial tension is k sigma).  A plastic response (linear isotropic hardening) leaves the elastic
    line at sigma_y, a degradation response at sigma_d (damage 1 - g(kappa)/kappa with g = sigma_d + H/E (kappa -
    sigma_d) transmits sigma = sigma_d + H (eps - sigma_d / E)); both then rise with the uniaxial tangent H, the
    hardening, and fail at the strain where that line reaches sigma_t."""
    out = {"failure_stress": resp.sigma_c / resp.k}
    knee = {"plastic": resp.sigma_y, "degradation": resp.sigma_d}.get(resp.kind)
    if knee is not None and knee < out["failure_stress"] and resp.hardening > 0:
        out.update(yield_stress=knee, post_linear_modulus=resp.hardening,
                   failure_strain=knee / youngs + (out["failure_stress"] - knee) / resp.hardening)
    return out


SCALARS = (
    Scalar("reaction_force", "N", "axial force the support on face zL applies to the bar (negative in compression)",
           sign=_strain_sign),
    Scalar("E_eff", "Pa", "reaction_force / (W H) / axial strain: positive for both signs of the strain",
           sign=lambda scene: 1),
    Scalar("nu_eff", "", "-lateral strain / axial strain (face-averaged lateral displacements)"),
    Scalar("failure_stress", "Pa", "peak reaction / (W H) of the bar pulled to fracture (positive in tension)",
           sign=lambda scene: 1),
    Scalar("failure_strain", "", "the driven face's displacement / L at the peak reaction"),
    Scalar("first_unlink_z", "", "mean rest z / L of the pairs' midpoints that unlinked in the first step with an "
           "unlink (also first_unlink_pairs, first_unlink_step)"),
    Scalar("drag_stress", "Pa", "net force of the two held faces / (W H) of a damped pull, averaged over 30-90 % of "
           "the time to the peak: what the viscous damping of the moving body takes"),
    Scalar("yield_stress", "Pa", "where the pulled bar's stress-strain curve leaves its elastic line: the meeting "
           "point of the lines fitted to its elastic and its post-linear part (plastic and degradation responses)"),
    Scalar("post_linear_modulus", "Pa", "slope of the stress-strain curve after the yield stress (the uniaxial "
           "tangent H)"),
    Scalar("f_bending_x_hz", "Hz", "lowest bending frequency along x (also f_bending_y_hz, f_torsion_hz, f_axial_hz, "
           "f_rotational_hz; the list frequencies_hz: f1_hz, f2_hz, ... in tables)", sign=lambda scene: 1),
)


def uniaxial_displacement(scene: Scene, points: np.ndarray) -> np.ndarray:
    """The exact displacement (m) of the bar in uniaxial stress, (-nu eps x, -nu eps y, eps z): face z = 0 on its
    supports, the corner (0, 0, 0) held and (W, 0, 0) kept on the x axis (no rigid motion), as the solvers hold
    them; linear, so it lies in every discrete space."""
    eps, nu = scene.param_dict["strain"], scene.material.poisson_ratio
    p = np.asarray(points, dtype=float).reshape(-1, 3)
    return np.column_stack([-nu * eps * p[:, 0], -nu * eps * p[:, 1], eps * p[:, 2]])


def _compression(p: dict[str, Any]) -> Scene:
    box = box_of(p)
    cons = (FaceSupport("z0"), FaceSupport("zL", p["strain"] * box.length))
    return Scene("bar-compression", COMPRESSION.description, box, DURALUMIN, frozenset({"elasticity"}), cons,
                 elasticity=Elasticity(), params=tuple(sorted(p.items())))


def _modes(p: dict[str, Any]) -> Scene:
    return Scene("bar-modes", MODES.description, box_of(p), DURALUMIN, frozenset({"elasticity", "modes"}),
                 (FaceClamp("z0"),), elasticity=Elasticity(modes=p["modes"]), params=tuple(sorted(p.items())))


def _fracture(p: dict[str, Any]) -> Scene:
    if p["sigma_d"] >= p["sigma_c"] or p["sigma_y"] >= p["sigma_c"]:
        raise SceneError(f"sigma_d={p['sigma_d']:g}, sigma_y={p['sigma_y']:g} are out of range; "
                         f"allowed: below sigma_c={p['sigma_c']:g} Pa")
    elastic = Elasticity(strain_rate=p["strain_rate"], response=Response(
        p["response"], p["sigma_c"], p["sigma_d"], p["sigma_y"], p["hardening"], p["k"]))
    return Scene("bar-tension-fracture", FRACTURE.description, box_of(p), DURALUMIN,
                 frozenset({"elasticity", "fracture"}), (FaceSupport("z0"), FaceSupport("zL")),
                 elasticity=elastic, params=tuple(sorted(p.items())))


COMPRESSION = SceneSpec(
    "bar-compression",
    "Uniaxial stress of the duralumin bar (E = 70 GPa, nu = 0.33): face z=0 on frictionless supports, "
    "face z=L displaced by strain * L along z, lateral faces free (analytic: sigma = E eps, "
    "lateral strain -nu eps)",
    (*DIMENSIONS, Param("strain", -1e-3, "", "nominal axial strain (negative = compression; below 1e-12 in "
                        "magnitude the loads underflow in floating point)", low=-0.01, high=-1e-12)),
    _compression, Reference(field=lambda scene, points: uniaxial_displacement(scene, points),
                            scalars=lambda scene, summary: {"E_eff": scene.material.youngs_modulus,
                                                            "nu_eff": scene.material.poisson_ratio}), SCALARS)
MODES = SceneSpec(
    "bar-modes",
    "Free vibration of the duralumin bar clamped at z=0: lowest bending, torsion and axial "
    "eigenfrequencies (reference: scikit-fem Q2, converged)",
    (*DIMENSIONS, Param("modes", 8, "", "number of lowest eigenfrequencies reported", low=1, high=50, kind=int)),
    _modes, None, SCALARS)
FRACTURE = SceneSpec(
    "bar-tension-fracture",
    "Tension of the duralumin bar to failure: face z=0 on frictionless supports, face z=L pulled "
    "along z at strain_rate; material response function and strengths as given",
    (
        *DIMENSIONS,
        Param("response", "elastic", "", "response function", choices=RESPONSES, kind=str),
        Param("sigma_c", 400e6, "Pa", "strength (fracture stress)", low=0.0, high=1e10, low_open=True),
        Param("sigma_d", 320e6, "Pa", "start of degradation", low=0.0, high=1e10, low_open=True),
        Param("sigma_y", 300e6, "Pa", "yield stress", low=0.0, high=1e10, low_open=True),
        Param("hardening", 7e9, "Pa", "plastic hardening modulus", low=0.0, high=7e10),
        Param("k", 1.0, "", "sigma_c / sigma_t (Drucker-Prager)", low=0.1, high=20.0),
        Param("strain_rate", 10.0, "1/s", "nominal axial strain rate", low=0.0, high=1e4, low_open=True),
    ),
    _fracture, Reference(scalars=lambda scene, summary: fracture_scalars(scene.elasticity.response,
                                                                         scene.material.youngs_modulus),
                         kind="theory"), SCALARS)
SCENES = (COMPRESSION, MODES, FRACTURE)
