"""Scenes of the plugin's own, each registered with its reference: a bar twice as long as the paper's (1 : 1 : 6),
all faces insulated but z = 0 and z = L, from 0 K: `long-bar-faces` holds z = 0 at t_max and z = L at 0 K,
`long-bar-source` holds both at 0 K and heats the bar by a uniform volumetric source.  The reference is the
plugin's own exact solution (`exact`), so pcverify reports every solver's errors against it."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from pcverify import ALUMINIUM, Box, Conduction, FaceTemperature, Param, Reference, Scene, SceneSpec

BOX = Box(0.01, 0.01, 0.06)


def exact(scene: Scene, points: np.ndarray) -> np.ndarray:
    """T / t_max at `points` by separation of variables: faces z = 0 at T0 and z = L at 0 K, source s, from 0 K,
        T = T0 (1 - z/L) + s z (L - z) / (2 k) - sum_m b_m sin(m pi z / L) exp(-alpha (m pi / L)^2 t),
        b_m = 2 T0 / (m pi) + 2 s L^2 (1 - (-1)^m) / (k m^3 pi^3),
    summed until exp(-alpha (m pi / L)^2 t) < 1e-17."""
    heat, mat, length = scene.conduction, scene.material, scene.box.length
    hot, s, k = scene.constraints[0].value, heat.source, mat.conductivity
    z = np.asarray(points, dtype=float).reshape(-1, 3)[:, 2]
    rate = mat.diffusivity * (math.pi / length) ** 2 * heat.t_end
    m = np.arange(1, math.ceil(math.sqrt(40.0 / rate)) + 2, dtype=float)
    b = 2 * hot / (m * math.pi) + 2 * s * length**2 * (1 - (-1.0) ** m) / (k * (m * math.pi) ** 3)
    series = np.sin(np.multiply.outer(z, m) * math.pi / length) @ (b * np.exp(-rate * m**2))
    return (hot * (1 - z / length) + s * z * (length - z) / (2 * k) - series) / heat.t_max


def _build(name: str, p: dict[str, Any], hot: float) -> Scene:
    heat = Conduction(t_max=p["t_max"], mode="transient", t_end=p["t_end"], dt=p["dt"], source=p.get("source", 0.0))
    physics = {"conduction", "heat-source"} if heat.source else {"conduction"}
    return Scene(name, SPECS[name].description, BOX, ALUMINIUM, frozenset(physics),
                 (FaceTemperature("z0", hot), FaceTemperature("zL", 0.0)), conduction=heat,
                 params=tuple(sorted(p.items())))


TIME = (Param("t_end", 2.0, "s", "end time of the transient", low=0.0, high=1e4, low_open=True),
        Param("dt", 0.01, "s", "time step of the continuum solvers that take one", low=0.0, high=1e3, low_open=True))
LONG_BAR_FACES = SceneSpec(
    "long-bar-faces",
    "Aluminium bar 0.01 x 0.01 x 0.06 m: face z=0 at t_max and z=L at 0 K from t = 0, transient (analytic: "
    "Fourier series)",
    (Param("t_max", 500.0, "K", "hot face temperature", low=1e-3, high=1e5), *TIME),
    lambda p: _build("long-bar-faces", p, p["t_max"]), Reference(field=exact))
LONG_BAR_SOURCE = SceneSpec(
    "long-bar-source",
    "Aluminium bar 0.01 x 0.01 x 0.06 m: faces z=0 and z=L at 0 K, a uniform volumetric source from t = 0, "
    "transient (analytic: s z (L - z) / (2 k) less its Fourier series)",
    (Param("t_max", 1.0, "K", "temperature scale (results are T / t_max)", low=1e-3, high=1e5),
     Param("source", 2e6, "W/m^3", "volumetric heat source", low=0.0, high=1e12, low_open=True), *TIME),
    lambda p: _build("long-bar-source", p, 0.0), Reference(field=exact))
SPECS = {spec.name: spec for spec in (LONG_BAR_FACES, LONG_BAR_SOURCE)}
