"""The table of fixed-pair-list kernels of the macromolecule model: one signature, chosen by name.

Every entry integrates the same scheme (`kernel_reference`'s docstring) and takes the structures of
`kernel_state`; they differ in layout and compilation only and are equal to rounding.  An entry may hold
one compiled function per envelope: the (a/r)^2 envelope has a vectorised loop of its own, any other
exponent p goes through pow.  Numba compiles a function the first time it is called (or loads it from
its cache), so a run compiles only the entry and the envelope it uses.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from pcverify.scene import SceneError

from . import kernel_fast, kernel_reference
from .force import SevenRoot


@dataclass(frozen=True)
class KernelEntry:
    """A kernel: what it is, its function for the envelope (a/r)^2 and for any other exponent."""

    description: str
    square: Any
    other: Any

    def for_model(self, model: SevenRoot) -> Any:
        """The compiled function (numba dispatcher) for the model's envelope exponent."""
        return self.square if float(model.p) == 2.0 else self.other


KERNELS: dict[str, KernelEntry] = {
    "fast": KernelEntry("stencil layout, vectorised pair loop (kernel_fast)", kernel_fast.run_p2,
                        kernel_fast.run_any),
    "fastmath": KernelEntry("the fast kernel compiled with FMA contraction and approximate reciprocals (envelope "
                            "(a/r)^2; other exponents use the exact fast kernel)", kernel_fast.run_p2_fastmath,
                            kernel_fast.run_any),
    "reference": KernelEntry("the plain pair-list kernel the others are tested against (kernel_reference)",
                             kernel_reference.run, kernel_reference.run),
}


def select(name: str, model: SevenRoot) -> Any:
    """The kernel `name` for `model`; SceneError naming the allowed names if there is none."""
    entry = KERNELS.get(name)
    if entry is None:
        raise SceneError(f"kernel={name!r} is not allowed; allowed: {', '.join(KERNELS)}")
    return entry.for_model(model)
