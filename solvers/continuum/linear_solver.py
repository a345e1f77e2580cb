"""The SPD linear solver of the scikit-fem solvers: SuperLU factored once, or CG with an AMG preconditioner.

Both FE solvers (heat: K or M + theta dt K per time step; elasticity: static K, shift-invert K in the
modal solve) solve many right-hand sides with one constant SPD matrix.  They differ only in the AMG
hierarchy (scalar Laplacian aggregated on the grid graph; 3x3-block elasticity with rigid-body modes)
and in the exception a failed CG raises, so those two are arguments.  After every solve the true
relative residual ||b - A x|| / ||b|| is recomputed (CG's own estimate is preconditioned).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pyamg
import scipy.sparse as sp
from scipy.sparse.linalg import cg, splu

AMG_SEED = 20240607


def smoothed_aggregation(a: sp.spmatrix, **options: Any) -> Any:
    """pyamg's smoothed-aggregation solver, bit-reproducible.  pyamg's spectral-radius estimate (Jacobi
    prolongation smoothing) starts from numpy's legacy global generator: it is seeded here, and the
    caller's random state is restored afterwards."""
    state = np.random.get_state()  # noqa: NPY002  (pyamg draws from the legacy global generator)
    np.random.seed(AMG_SEED)  # noqa: NPY002
    try:
        return pyamg.smoothed_aggregation_solver(a, **options)
    finally:
        np.random.set_state(state)  # noqa: NPY002


class SpdSolver:
    """Solves A x = b for one constant SPD matrix A: "direct" (SuperLU) or "amg" (AMG-preconditioned CG).

    amg(A as CSR) builds the pyamg multilevel solver (method "amg" only); error is the exception raised
    when CG does not converge or stops above 10 * rtol true relative residual.  Counts: `solves` (non-zero
    right-hand sides), `iterations` (CG, summed), `worst_residual`.
    """

    def __init__(self, a: sp.spmatrix, method: str, rtol: float, amg: Callable[[sp.csr_matrix], Any] | None = None,
                 error: type[Exception] = ArithmeticError):
        self.a = a.tocsr()
        self.method = method
        self.rtol = rtol
        self.error = error
        self.iterations = 0
        self.solves = 0
        self.worst_residual = 0.0
        if method == "direct":
            self.lu = splu(self.a.tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                           options={"SymmetricMode": True})
        else:
            if amg is None:
                raise ValueError("method 'amg' needs an AMG set-up (amg=...)")
            self.ml = amg(self.a)
            self.prec = self.ml.aspreconditioner(cycle="V")

    def solve(self, b: np.ndarray, x0: np.ndarray | None = None) -> np.ndarray:
        """x with A x = b (x0: CG's start vector, e.g. the previous time step; ignored by SuperLU)."""
        bnorm = float(np.linalg.norm(b))
        if bnorm == 0.0:
            return np.zeros_like(b)
        self.solves += 1
        if self.method == "direct":
            x = self.lu.solve(b)
        else:
            count = [0]

            def tick(_xk):
                count[0] += 1

            x, info = cg(self.a, b, x0=x0, rtol=self.rtol, atol=0.0, maxiter=5000, M=self.prec, callback=tick)
            self.iterations += count[0]
            if info != 0:
                raise self.error(f"CG did not converge (info={info}, {count[0]} iterations)")
        res = float(np.linalg.norm(b - self.a @ x)) / bnorm
        self.worst_residual = max(self.worst_residual, res)
        if self.method != "direct" and res > 10.0 * self.rtol:
            raise self.error(f"CG stopped with true relative residual {res:.2e} > 10 * cg_rtol")
        return x
