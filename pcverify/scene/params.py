"""Named parameters with a default, a unit and an allowed range, and the error every bad value raises.

Scenes, solvers and stability probes declare their parameters as `Param` specs; `resolve_params`
turns given values into effective ones.  Every refusal is a `SceneError` whose message names the
parameter, the value and the allowed range (one line, fit for the command line).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np


class SceneError(ValueError):
    """A scene or solver parameter outside its allowed range (message names it)."""


def is_real(value: Any) -> bool:
    """A finite real number, not a bool (True is an int in Python, and TOML and JSON read NaN and inf)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        return False
    try:
        return math.isfinite(value)
    except OverflowError:  # an int beyond the float range
        return False


@dataclass(frozen=True)
class Param:
    """Specification of one named parameter: default, unit, allowed range or choices."""

    name: str
    default: Any
    unit: str = ""
    description: str = ""
    low: float | None = None
    high: float | None = None
    low_open: bool = False
    high_open: bool = False
    choices: tuple[Any, ...] | None = None
    kind: type | None = None  # None: inferred (`_inferred_kind`)
    optional: bool = False  # None is an allowed value

    def __post_init__(self) -> None:
        if self.kind is None:
            object.__setattr__(self, "kind", _inferred_kind(self.default, self.choices))
        if self.kind not in (int, float, bool, str):
            raise TypeError(f"Param {self.name!r}: kind={self.kind!r} is not valid; allowed: int, float, bool, str")

    def allowed(self) -> str:
        """Human-readable allowed range, used in every error message."""
        if self.choices is not None:
            return "one of " + ", ".join(str(c) for c in self.choices)
        if self.kind is bool:
            return "true or false" + (" or none" if self.optional else "")
        lo = "-inf" if self.low is None else f"{self.low:g}"
        hi = "inf" if self.high is None else f"{self.high:g}"
        left = "(" if (self.low is None or self.low_open) else "["
        right = ")" if (self.high is None or self.high_open) else "]"
        what = {int: "integer", float: "number", bool: "true/false", str: "text"}[self.kind]
        suffix = " or none" if self.optional else ""
        return f"{what} in {left}{lo}, {hi}{right}{' ' + self.unit if self.unit else ''}{suffix}"

    def parse(self, text: str) -> Any:
        """Convert a command-line string to this parameter's type, then check it."""
        if self.optional and text.strip().lower() in ("none", "null", ""):
            return None
        try:
            if self.kind is bool:
                low = text.strip().lower()
                if low not in ("true", "false", "1", "0", "yes", "no", "on", "off"):
                    raise ValueError(text)
                value: Any = low in ("true", "1", "yes", "on")
            elif self.kind is int:
                value = int(text)
            elif self.kind is float:
                value = float(text)
            else:
                value = text
        except ValueError:
            raise SceneError(f"{self.name}={shown(text)} is not valid; allowed: {self.allowed()}") from None
        return self.check(value)

    def check(self, value: Any) -> Any:
        """Return the value (coerced to the declared kind) or raise SceneError."""
        if value is None and self.optional:
            return None
        bad = SceneError(f"{self.name}={shown(value)} is out of range; allowed: {self.allowed()}")
        if self.choices is not None:
            try:
                if not any(isinstance(value, type(c)) and value == c for c in self.choices):
                    raise bad
            except (TypeError, ValueError):  # e.g. an array: ambiguous truth value
                raise bad from None
            return value
        if self.kind is bool:
            if not isinstance(value, (bool, np.bool_)):
                raise bad
            return bool(value)
        if self.kind is str:
            if not isinstance(value, str):
                raise bad
            return value
        if not is_real(value):
            raise bad
        number = float(value)
        if self.kind is int:
            if isinstance(value, (float, np.floating)) and not number.is_integer():
                raise bad
            value = int(value)
        else:
            value = number
        if self.low is not None and (value < self.low or (self.low_open and value == self.low)):
            raise bad
        if self.high is not None and (value > self.high or (self.high_open and value == self.high)):
            raise bad
        return value


def _inferred_kind(default: Any, choices: tuple[Any, ...] | None) -> type:
    """The kind a Param takes when none is given: text or true/false when its default (or every choice) is; a
    number otherwise, a float (an integer default does not make an int parameter: give kind=int)."""
    values = [default] if default is not None else []
    values += list(choices or ())
    for kind in (bool, str):
        if values and all(isinstance(v, kind) for v in values):
            return kind
    return float


def shown(value: Any) -> str:
    """repr of a value for an error message, shortened (a hostile value may be huge or unprintable)."""
    try:
        text = repr(value)
    except Exception:  # noqa: BLE001 - e.g. an int beyond the str conversion limit
        text = f"<{type(value).__name__}>"
    text = " ".join(text.split())
    return text if len(text) <= 60 else text[:57] + "..."


def resolve_params(specs: tuple[Param, ...], given: dict[str, Any], owner: str) -> dict[str, Any]:
    """Effective values of `specs` given overrides; unknown names are an error."""
    names = {p.name for p in specs}
    unknown = sorted(set(given) - names)
    if unknown:
        raise SceneError(
            f"unknown parameter {unknown[0]!r} for {owner}; known: {', '.join(sorted(names)) or 'none'}"
        )
    return {p.name: p.check(given[p.name]) if p.name in given else p.default for p in specs}
