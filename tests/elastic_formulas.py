"""Elasticity formulas the tests check scikit-fem against (tests only).

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
"""

from __future__ import annotations

import itertools
import math

import numpy as np

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
