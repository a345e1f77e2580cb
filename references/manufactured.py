"""heat-manufactured: a manufactured solution of steady conduction (the method of MOOSE's mms module).

Pick a smooth exact temperature, derive the volumetric source it implies and hold the boundary at its values;
every heat solver must then converge to it at its theoretical order.  On the box [0, W] x [0, H] x [0, L]:

    T(x, y, z) = t_max sin(mx pi x / W) sin(my pi y / H) sin(mz pi z / L)        (0 on all six faces)
    S = -k laplacian(T) = k pi^2 (mx^2 / W^2 + my^2 / H^2 + mz^2 / L^2) T          (W/m^3)

so the source is one `SineSource` term with the same wave numbers and the six faces are held at 0 K.  A
product of sines is the simplest field that varies along all three axes with zero boundary values; the integer
half-wave counts mx, my, mz make it non-symmetric (mx != my tells x from y on the square cross-section).
"""

from __future__ import annotations

import math

import numpy as np

from pcverify.scene import (
    ALUMINIUM,
    EXTENT_RANGE,
    FACES,
    Box,
    Conduction,
    FaceTemperature,
    Param,
    Reference,
    Scene,
    SceneSpec,
    SineSource,
)

NAME = "heat-manufactured"
_BOX = Box()
PARAMETERS = (
    Param("width", _BOX.width, "m", "box width (x); the lattice spacing is a = width / (n - 1)", low=EXTENT_RANGE[0],
          high=EXTENT_RANGE[1]),
    Param("height", _BOX.height, "m", "box height (y): a whole number of spacings at the resolutions used",
          low=EXTENT_RANGE[0], high=EXTENT_RANGE[1]),
    Param("length", _BOX.length, "m", "box length (z): a whole number of spacings at the resolutions used",
          low=EXTENT_RANGE[0], high=EXTENT_RANGE[1]),
    Param("t_max", 500.0, "K", "amplitude of the exact temperature (relative results are T/t_max)", low=1e-3,
          high=1e5),
    *(Param(f"m{a}", 1, "", f"half waves of the exact temperature along {a}", low=1, high=8, kind=int)
      for a in "xyz"),
)


def wavenumbers(scene: Scene) -> tuple[float, float, float]:
    """k_a = m_a pi / extent_a (rad/m) of the scene's exact temperature."""
    p = scene.param_dict
    return tuple(p[f"m{a}"] * math.pi / float(e) for a, e in zip("xyz", scene.box.extent, strict=True))


def exact(scene: Scene, points: np.ndarray) -> np.ndarray:
    """The exact T / t_max at points of shape (k, 3)."""
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    return np.prod(np.sin(pts * np.asarray(wavenumbers(scene))), axis=1)


def source_amplitude(k: float, t_max: float, wave: tuple[float, float, float]) -> float:
    """Amplitude (W/m^3) of S = -k laplacian(T) for T = t_max prod_a sin(k_a x_a): k t_max sum_a k_a^2."""
    return k * t_max * sum(w * w for w in wave)


def _build(p: dict) -> Scene:
    box = Box(p["width"], p["height"], p["length"])
    wave = tuple(p[f"m{a}"] * math.pi / float(e) for a, e in zip("xyz", box.extent, strict=True))
    term = SineSource(source_amplitude(ALUMINIUM.conductivity, p["t_max"], wave), wave)
    return Scene(NAME, SPEC.description, box, ALUMINIUM, frozenset({"conduction", "heat-source-field"}),
                 tuple(FaceTemperature(face, 0.0) for face in FACES),
                 conduction=Conduction(t_max=p["t_max"], source_field=(term,)), params=tuple(sorted(p.items())))


SPEC = SceneSpec(
    NAME,
    "Steady conduction with the manufactured solution T = t_max sin(mx pi x/W) sin(my pi y/H) sin(mz pi z/L): the "
    "source S = -k laplacian(T) it implies, all six faces at 0 K (analytic reference)",
    PARAMETERS,
    _build,
    reference=Reference(field=exact, kind="analytic"),
)
