"""Resolution-coupled parameters: a numeric scene or solver parameter written in a study file as an expression of
the cell's resolution, e.g. `delta = "3 * h"` (a horizon of three spacings) or `dt = "0.1 * h**2"`.

The names an expression may use: `n` (the lattice resolution), `refine`, `a` (the lattice spacing of the scene's
box at n, m) and `h` (= a / refine, m).  Numbers, + - * / ** and parentheses, and the functions sqrt, exp, log,
min, max, abs, round (and, for a claim's target, the closed forms mca_rotational_hz, rod_axial_hz and
saint_venant_torsion_hz).  A text is an expression only where the
parameter is a number (a text parameter keeps its text).
Each cell gets the value of its own resolution, checked against the parameter's range like any value; the
expression itself travels with the cell (its key, its tables) so a reader sees "delta=0.0015 (= 3 * h)".
"""

from __future__ import annotations

import ast
import math
import operator
from collections.abc import Callable
from typing import Any

from pcverify.references.elastic import mca_rotational_hz, rod_axial_hz, saint_venant_torsion_hz
from pcverify.scene import Param, SceneError, shown

NAMES = ("n", "refine", "a", "h")
FUNCTIONS: dict[str, Callable[..., float]] = {
    "sqrt": math.sqrt, "exp": math.exp, "log": math.log, "min": min, "max": max, "abs": abs, "round": round,
    # the analytic chain of the MCA bar's lowest rotational mode (a target: shear modulus, density, spacing, krot,
    # and the spacings across, across and along)
    "mca_rotational_hz": lambda g, rho, a, krot, nx, ny, nz: mca_rotational_hz(g, rho, a, krot, (nx, ny, nz)),
    # the clamped bar's lowest axial (E, rho, length) and torsional (G, rho, width, height, length) frequencies in
    # elementary rod and Saint-Venant theory: references independent of any mesh and of the mode classifier
    "rod_axial_hz": rod_axial_hz,
    "saint_venant_torsion_hz": saint_venant_torsion_hz,
}
_BINARY = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul, ast.Div: operator.truediv,
           ast.Pow: operator.pow}
_UNARY = {ast.USub: operator.neg, ast.UAdd: operator.pos}
MAX_LENGTH = 200


def is_expression(spec: Param | None, value: Any) -> bool:
    """Whether `value` is an expression for the parameter `spec`: a text given for a number."""
    return spec is not None and spec.kind in (int, float) and isinstance(value, str)


def variables(n: int, refine: int, spacing: float) -> dict[str, float]:
    """The names an expression sees at a cell's resolution (`spacing`: the lattice spacing a at n)."""
    return {"n": float(n), "refine": float(refine), "a": float(spacing), "h": float(spacing) / refine}


def evaluate(name: str, text: str, names: dict[str, float]) -> float:
    """The value of the expression `text` given for parameter `name`; SceneError (one line naming the parameter,
    the expression and what is allowed) for anything else than the grammar above."""
    allowed = (f"an expression of {', '.join(names)} with numbers, + - * / ** and "
               f"{', '.join(FUNCTIONS)}")
    if len(text) > MAX_LENGTH:
        raise SceneError(f"{name}={shown(text)} is not valid; allowed: {allowed} (at most {MAX_LENGTH} characters)")
    try:
        tree = ast.parse(text.strip(), mode="eval")
        value = _value(tree.body, names)
    except SceneError as exc:
        raise SceneError(f"{name}={shown(text)} is not valid: {exc}; allowed: {allowed}") from None
    except (SyntaxError, ValueError, ArithmeticError, TypeError, RecursionError) as exc:
        raise SceneError(f"{name}={shown(text)} is not valid ({type(exc).__name__}: {exc}); allowed: {allowed}"
                         ) from None
    if not math.isfinite(value):
        raise SceneError(f"{name}={shown(text)} gives {value!r} at {_where(names)}; allowed: a finite number")
    return value


def _where(names: dict[str, float]) -> str:
    return f"n={names['n']:g}, refine={names['refine']:g}, h={names['h']:g} m"


def _value(node: ast.AST, names: dict[str, float]) -> float:
    if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) and not isinstance(node.value, bool):
        return float(node.value)
    if isinstance(node, ast.Name):
        if node.id not in names:
            raise SceneError(f"unknown name {node.id!r}")
        return names[node.id]
    if isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
        left, right = _value(node.left, names), _value(node.right, names)
        if isinstance(node.op, ast.Pow) and abs(right) > 64:
            raise SceneError("an exponent beyond 64")
        return float(_BINARY[type(node.op)](left, right))
    if isinstance(node, ast.UnaryOp) and type(node.op) in _UNARY:
        return float(_UNARY[type(node.op)](_value(node.operand, names)))
    if (isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in FUNCTIONS
            and not node.keywords and node.args):
        return float(FUNCTIONS[node.func.id](*[_value(a, names) for a in node.args]))
    raise SceneError(f"{type(node).__name__} is not allowed")


def resolve(given: dict[str, Any], specs: tuple[Param, ...], names: dict[str, float]
            ) -> tuple[dict[str, Any], dict[str, str]]:
    """(values, expressions) of `given` at one resolution: every expression replaced by its value (an int
    parameter's value rounded when it is within 1e-9 of an integer), and the expressions by parameter name."""
    spec = {p.name: p for p in specs}
    values, expressions = dict(given), {}
    for key, value in given.items():
        if is_expression(spec.get(key), value):
            number = evaluate(key, value, names)
            if spec[key].kind is int and abs(number - round(number)) <= 1e-9 * max(1.0, abs(number)):
                number = int(round(number))
            values[key] = number
            expressions[key] = " ".join(value.split())
    return values, expressions
