"""A scene specification: a named, parameterised recipe for a scene (what the catalogue and plugins hold)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from .model import Scene
from .params import Param, resolve_params


@dataclass(frozen=True)
class SceneSpec:
    """A named scene: one-line description, its parameters (default, unit, range) and the builder that
    turns their effective values into a `Scene`."""

    name: str
    description: str
    parameters: tuple[Param, ...]
    build: Callable[[dict[str, Any]], Scene]

    def make(self, **given: Any) -> Scene:
        """The scene for parameter overrides `given`; unknown names or bad values raise SceneError."""
        values = resolve_params(self.parameters, given, f"scene {self.name!r}")
        return self.build(values)
