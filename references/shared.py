"""What the scene families share: the paper's bar and its dimensions as parameters, the temperature scale, the
thermal duralumin of the contact scenes, and the scalar lookup a reference needs."""

from __future__ import annotations

import math
from typing import Any

from pcverify.scene import EXTENT_RANGE, Box, Material, Param

BOX = Box()  # the paper's bar, 0.01 x 0.01 x 0.03 m (the default dimensions of every shipped scene)

DIMENSIONS = (  # the box model's own range (EXTENT_RANGE), so `pcverify scenes` shows what is accepted
    Param("width", BOX.width, "m", "box width (x); the lattice spacing is a = width / (n - 1)", low=EXTENT_RANGE[0],
          high=EXTENT_RANGE[1]),
    Param("height", BOX.height, "m", "box height (y): a whole number of spacings at the resolutions used",
          low=EXTENT_RANGE[0], high=EXTENT_RANGE[1]),
    Param("length", BOX.length, "m", "box length (z): a whole number of spacings at the resolutions used",
          low=EXTENT_RANGE[0], high=EXTENT_RANGE[1]),
)
T_MAX = Param("t_max", 500.0, "K", "hot temperature (relative results are T/t_max)", low=1e-3, high=1e5)

# duralumin with its thermal constants (handbook values of 2024, the alloy of the bar's E and nu in
# docs/physics.md, "Conventions")
DURALUMIN_THERMAL = Material("duralumin-2024", density=2800.0, conductivity=121.0, heat_capacity=875.0,
                             youngs_modulus=70e9, poisson_ratio=0.33)


def box_of(p: dict[str, Any]) -> Box:
    """The box of the effective parameters `p` (width, height, length)."""
    return Box(p["width"], p["height"], p["length"])


def number(value: Any) -> float | None:
    """A summary value as a finite float, else None."""
    ok = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
    return float(value) if ok else None
