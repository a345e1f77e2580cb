"""The solver registry.

The registry maps a solver name to "module:Class"; a new solver is one module plus
one line here.  Modules import lazily so a missing optional dependency gives a
clear error for that solver only.
"""

from __future__ import annotations

import importlib

from pcverify.harness.scene import SceneError

REGISTRY: dict[str, str] = {
    "skfem": "pcverify.solvers.continuum.skfem_heat:SkfemHeat",
    "fipy": "pcverify.solvers.continuum.fipy_heat:FipyHeat",
    "macromolecule": "pcverify.solvers.particles.macromolecule.solver:Macromolecule",
    "skfem-elastic": "pcverify.solvers.continuum.skfem_elastic:SkfemElastic",
    "mca": "pcverify.solvers.particles.mca.solver:Mca",
}


class SolverUnavailable(RuntimeError):
    """A registered solver whose module or dependency cannot be imported."""


def solver_names() -> list[str]:
    return sorted(REGISTRY)


def get_solver(name: str):
    """Instantiate the solver called `name` (SceneError if unknown, SolverUnavailable if not importable)."""
    if not isinstance(name, str) or name not in REGISTRY:
        raise SceneError(f"solver={name!r} is unknown; allowed: one of {', '.join(solver_names())}")
    module_name, cls_name = REGISTRY[name].split(":")
    try:
        module = importlib.import_module(module_name)
    except ImportError as exc:
        raise SolverUnavailable(f"solver {name!r} is unavailable: {exc}") from exc
    return getattr(module, cls_name)()
