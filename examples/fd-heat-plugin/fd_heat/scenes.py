"""A scene of the plugin's own, built from pcverify's building blocks: a bar twice as long as the paper's
(1 : 1 : 6), its z = 0 face held at t_max and its z = L face at 0 K from t = 0, all other faces insulated.
pcverify knows its analytic solution (the Fourier series of the face-heated bar), so studies report
errors against it."""

from __future__ import annotations

from typing import Any

from pcverify import ALUMINIUM, Box, Conduction, FaceTemperature, Param, Scene, SceneSpec


def _build(p: dict[str, Any]) -> Scene:
    heat = Conduction(t_max=p["t_max"], mode="transient", t_end=p["t_end"], dt=p["dt"])
    return Scene("long-bar-faces", LONG_BAR_FACES.description, Box(0.01, 0.01, 0.06), ALUMINIUM,
                 frozenset({"conduction"}), (FaceTemperature("z0", p["t_max"]), FaceTemperature("zL", 0.0)),
                 conduction=heat, params=tuple(sorted(p.items())))


LONG_BAR_FACES = SceneSpec(
    "long-bar-faces",
    "Aluminium bar 0.01 x 0.01 x 0.06 m: face z=0 at t_max and z=L at 0 K from t = 0, transient (analytic: "
    "Fourier series)",
    (Param("t_max", 500.0, "K", "hot face temperature", low=1e-3, high=1e5),
     Param("t_end", 2.0, "s", "end time of the transient", low=0.0, high=1e4, low_open=True),
     Param("dt", 0.01, "s", "time step of the continuum solvers that take one", low=0.0, high=1e3, low_open=True)),
    _build,
)
