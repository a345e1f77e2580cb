"""The elastic family: the duralumin bar compressed, vibrating and pulled to fracture, its references and the
summary scalars an elasticity solver reports (`SCALARS`: names, units, signs).  Reference scalars: bar-compression's
E_eff = E and nu_eff = nu (uniaxial stress), bar-tension-fracture's failure_stress = sigma_c / k (the
Drucker-Prager equivalent stress of uniaxial tension is k sigma).

Formulas for the bar: analytic fields and frequencies, and the converged FE frequencies.

Analytic (docs/physics.md, "Continuum references"):
- `uniaxial_displacement`: the homogeneous uniaxial-stress field of bar-compression, sigma_zz = E eps,
  lateral strain -nu eps, u = (-nu eps (x - x0), -nu eps (y - y0), eps z) about a lateral origin (x0, y0).
- `thin_rod_axial_hz`: axial modes of a clamped-free thin rod, f_m = (2m - 1) c / (4 L), c = sqrt(E / rho)
  (one-dimensional; ignores the lateral inertia and the clamp's restraint of the Poisson contraction).
- `euler_bernoulli_cantilever_hz`: bending modes of a slender cantilever, f_m = (beta_m L)^2 / (2 pi L^2)
  sqrt(E I / (rho A)) — sanity only: the bar is 3:1, shear and rotary inertia lower the real values.
- `saint_venant_torsion_hz`: torsion modes of a clamped-free rod, f_m = (2m - 1) / (4 L) sqrt(G J / (rho Ip)),
  J of the rectangular section by its series (warping ignored at the clamp, so also sanity only).
- `roller_box_hz`: exact eigenfrequencies of the box with frictionless supports (zero normal displacement)
  on all six faces: separable modes u_x ~ sin(a x) cos(b y) cos(c z) (and cyclic), k = pi (l/W, m/H, n/L),
  one pressure mode omega = c_L |k| and (d - 1) shear modes omega = c_T |k| per index triple with d nonzero
  indices.  A smooth problem: it shows the elements' full convergence order.
- `mca_rotational_hz`: the lowest rotational mode of the MCA bar (nodes on the faces, spacing a, clamped at
  z = 0), from the model's potential by hand, not from its code: a rotational pair spring k_r = krot G S r0 on
  phi_j - phi_i, a shear spring that sees only phi_i + phi_j (a rotation about the pair's own axis is not
  seen), J = m (e_x^2 + e_y^2 + e_z^2) / 18.  Rotations about the bar's axis alternating across the section,
  phi_z = (-1)^(ix + iy) psi(z), cost no shear at all: the section's pairs see phi_i + phi_j = 0, the axial
  pairs turn about their own axis.  So only krot resists them: 2 krot G S r0 psi^2 per section pair, and
  krot G S r0 (dpsi)^2 / 2 per axial pair.  Deep inside a long bar with a wide section this is
  omega^2 = 48 krot G / (rho a^2), below the three-dimensional checkerboard's 72 krot G / (rho a^2) (whose
  axial pairs would also pay krot); the half-width automata on the section's faces carry less inertia per
  spring, omega^2 = 48 krot G / (rho a^2 (1 - (1/N_x + 1/N_y) / 4)) for N_x, N_y automata spacings across;
  along the bar the layers form a chain (plane z = 0 held, the last plane half thick), solved exactly.

Geometric (the MCA packing, `packing_second_moment_ratio`, `packing_bending_ratio`): the axial pairs of a
packing carry the bending moment as a quadrature of y^2 over the section's depth H with one spacing a.
"nodes" (centres on the faces, half cells there) is the trapezoid rule, whose error is +a^2 H / 6:
I_lattice / I = 1 + 2 (a/H)^2; "cells" (equal cubes, centres a/2 inside) is the midpoint rule, error
-a^2 H / 12: I_lattice / I = 1 - (a/H)^2.  A beam's bending frequency scales as sqrt(E I), so the
frequency ratio against the continuum is sqrt(I_lattice / I) if nothing else in the model changes.

The converged continuum reference of bar-modes (scikit-fem Q2 refined, Richardson with its GCI) is a study
group (`modes-q2-convergence` of the elasticity study), not a formula: it lives in the study's tables.
"""

from __future__ import annotations

import itertools
import math
from typing import Any

import numpy as np

from pcverify.references.shared import DIMENSIONS, box_of, params
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

# roots of 1 + cos(x) cosh(x) = 0 (clamped-free beam)
CANTILEVER_BETA_L = (1.8751040687119611, 4.694091132974175, 7.854757438237613, 10.995540734875467,
                     14.137168391046471)


def uniaxial_displacement(points: np.ndarray, strain: float, nu: float,
                          origin: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
    """Homogeneous uniaxial-stress displacement (k, 3) at `points`, u_z = 0 on z = 0, lateral centre `origin`."""
    x = np.asarray(points, dtype=float).reshape(-1, 3)
    return np.stack([-nu * strain * (x[:, 0] - origin[0]), -nu * strain * (x[:, 1] - origin[1]), strain * x[:, 2]],
                    axis=1)


def uniaxial_stress(youngs_modulus: float, strain: float) -> float:
    """Axial stress sigma_zz = E eps (Pa) of the uniaxial-stress state."""
    return youngs_modulus * strain


def bar_wave_speed(youngs_modulus: float, density: float) -> float:
    """Longitudinal wave speed of a thin bar, c = sqrt(E / rho) (m/s)."""
    return math.sqrt(youngs_modulus / density)


def thin_rod_axial_hz(youngs_modulus: float, density: float, length: float, modes: int = 1) -> np.ndarray:
    """Axial eigenfrequencies (Hz) of a clamped-free thin rod: (2m - 1) c / (4 L), m = 1..modes."""
    c = bar_wave_speed(youngs_modulus, density)
    return np.array([(2 * m - 1) * c / (4.0 * length) for m in range(1, modes + 1)])


def euler_bernoulli_cantilever_hz(youngs_modulus: float, density: float, width: float, height: float,
                                  length: float, modes: int = 1, axis: str = "x") -> np.ndarray:
    """Bending eigenfrequencies (Hz) of a slender rectangular cantilever, deflection along `axis` (x or y)."""
    if modes > len(CANTILEVER_BETA_L):
        raise ValueError(f"modes={modes} is out of range; allowed: integer in [1, {len(CANTILEVER_BETA_L)}]")
    area = width * height
    inertia = height * width**3 / 12.0 if axis == "x" else width * height**3 / 12.0
    scale = math.sqrt(youngs_modulus * inertia / (density * area)) / (2.0 * math.pi * length**2)
    return np.array([b**2 * scale for b in CANTILEVER_BETA_L[:modes]])


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


def torsion_constant(width: float, height: float, terms: int = 50) -> float:
    """Saint-Venant torsion constant J of a w x h rectangle (series of Timoshenko & Goodier)."""
    a, b = max(width, height), min(width, height)
    s = sum(math.tanh((2 * k + 1) * math.pi * a / (2 * b)) / (2 * k + 1) ** 5 for k in range(terms))
    return a * b**3 / 3.0 * (1.0 - 192.0 * b / (math.pi**5 * a) * s)


def saint_venant_torsion_hz(youngs_modulus: float, poisson_ratio: float, density: float, width: float,
                            height: float, length: float, modes: int = 1) -> np.ndarray:
    """Torsion eigenfrequencies (Hz) of a clamped-free rod, (2m - 1) / (4 L) sqrt(G J / (rho Ip))."""
    shear = youngs_modulus / (2.0 * (1.0 + poisson_ratio))
    polar = width * height * (width**2 + height**2) / 12.0
    c = math.sqrt(shear * torsion_constant(width, height) / (density * polar))
    return np.array([(2 * m - 1) * c / (4.0 * length) for m in range(1, modes + 1)])


def roller_box_hz(youngs_modulus: float, poisson_ratio: float, density: float, extent: tuple[float, float, float],
                  count: int) -> np.ndarray:
    """The `count` lowest eigenfrequencies (Hz, with multiplicity) of a box on rollers all round."""
    lam = youngs_modulus * poisson_ratio / ((1 + poisson_ratio) * (1 - 2 * poisson_ratio))
    mu = youngs_modulus / (2 * (1 + poisson_ratio))
    c_l, c_t = math.sqrt((lam + 2 * mu) / density), math.sqrt(mu / density)
    w, h, ell = extent
    top = count + 2
    freqs = []
    for idx in itertools.product(range(top + 1), repeat=3):
        d = sum(1 for i in idx if i)
        if d == 0:
            continue
        k = math.pi * math.sqrt((idx[0] / w) ** 2 + (idx[1] / h) ** 2 + (idx[2] / ell) ** 2)
        freqs.append(c_l * k / (2 * math.pi))
        freqs.extend([c_t * k / (2 * math.pi)] * (d - 1))
    freqs.sort()
    return np.array(freqs[:count])


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


def lowest_eigenvalue(diag: np.ndarray, off: np.ndarray) -> float:
    """The lowest eigenvalue of the symmetric tridiagonal matrix (diag, off) by bisection on its Sturm count (the
    number of negative pivots of A - s I is the number of eigenvalues below s), to the last bit; numpy only, so
    that the scene catalogue imports no scipy."""
    radius = np.abs(np.r_[0.0, off]) + np.abs(np.r_[off, 0.0])
    lo, hi = float((diag - radius).min()), float((diag + radius).max())
    squares = np.r_[0.0, off**2].tolist()
    while True:
        mid = 0.5 * (lo + hi)
        if not lo < mid < hi:
            return mid
        pivot, below = 1.0, False
        for d, e2 in zip(diag.tolist(), squares, strict=True):  # one pass down the chain of planes
            pivot = d - mid - e2 / pivot if pivot != 0.0 else d - mid - e2 / 1e-300
            if pivot < 0.0:
                below = True
                break
        lo, hi = (lo, mid) if below else (mid, hi)



SCALARS = (
    Scalar("reaction_force", "N", "axial force the support on face zL applies to the bar (negative in compression)"),
    Scalar("E_eff", "Pa", "reaction_force / (W H) / axial strain: positive for both signs of the strain"),
    Scalar("nu_eff", "", "-lateral strain / axial strain (face-averaged lateral displacements)"),
    Scalar("failure_stress", "Pa", "peak reaction / (W H) of the bar pulled to fracture (positive in tension)"),
    Scalar("energy_error", "", "energy balance of the elastic phase, relative to its largest elastic energy"),
    Scalar("f_bending_x_hz", "Hz", "lowest bending frequency, deflection along x (also f_bending_y_hz, f_torsion_hz, "
           "f_axial_hz, f_rotational_hz; the list frequencies_hz, spread into f1_hz, f2_hz, ... in tables)"),
)


def _hooke(scene: Scene, summary: dict[str, Any]) -> dict[str, float]:
    return {"E_eff": scene.material.youngs_modulus, "nu_eff": scene.material.poisson_ratio}


def _strength(scene: Scene, summary: dict[str, Any]) -> dict[str, float]:
    response = scene.elasticity.response
    return {"failure_stress": response.sigma_c / response.k}


def _compression(p: dict[str, Any]) -> Scene:
    box = box_of(p)
    cons = (FaceSupport("z0"), FaceSupport("zL", p["strain"] * box.length))
    return Scene("bar-compression", COMPRESSION.description, box, DURALUMIN, frozenset({"elasticity"}), cons,
                 elasticity=Elasticity(), params=params(p))


def _modes(p: dict[str, Any]) -> Scene:
    return Scene("bar-modes", MODES.description, box_of(p), DURALUMIN, frozenset({"elasticity", "modes"}),
                 (FaceClamp("z0"),), elasticity=Elasticity(modes=p["modes"]), params=params(p))


def _fracture(p: dict[str, Any]) -> Scene:
    if p["sigma_d"] >= p["sigma_c"] or p["sigma_y"] >= p["sigma_c"]:
        raise SceneError(f"sigma_d={p['sigma_d']:g}, sigma_y={p['sigma_y']:g} are out of range; "
                         f"allowed: below sigma_c={p['sigma_c']:g} Pa")
    response = Response(p["response"], p["sigma_c"], p["sigma_d"], p["sigma_y"], p["hardening"], p["k"])
    return Scene("bar-tension-fracture", FRACTURE.description, box_of(p), DURALUMIN,
                 frozenset({"elasticity", "fracture"}), (FaceSupport("z0"), FaceSupport("zL")),
                 elasticity=Elasticity(strain_rate=p["strain_rate"], response=response), params=params(p))


COMPRESSION = SceneSpec(
    "bar-compression",
    "Uniaxial stress of the duralumin bar (E = 70 GPa, nu = 0.33): face z=0 on frictionless supports, "
    "face z=L displaced by strain * L along z, lateral faces free (analytic: sigma = E eps, "
    "lateral strain -nu eps)",
    (*DIMENSIONS, Param("strain", -1e-3, "", "nominal axial strain (negative = compression; below 1e-12 in "
                        "magnitude the loads underflow in floating point)", low=-0.01, high=-1e-12)),
    _compression, Reference(scalars=_hooke), SCALARS)
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
    _fracture, Reference(scalars=_strength, kind="theory"), SCALARS)
SCENES = (COMPRESSION, MODES, FRACTURE)
