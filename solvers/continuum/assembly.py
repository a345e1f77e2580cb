"""Fast assembly of scikit-fem's Q1 operators on structured (possibly locally warped) hexahedral grids.

Why: scikit-fem's general assembly takes ~18 s on a 673 000-node grid of (almost all) equal boxes; Kronecker
sums of scikit-fem's 1-D P1 operators give its matrix up to round-off (tested 1e-12, plain and warped), with the
warped band corrected (docs/physics.md, "Continuum references", scikit-fem).  `tensor_csr` (numba) builds straight
into sorted CSR, `grid_graph` is the AMG's 27-point node graph, `split_free` condenses Dirichlet nodes in one pass.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
import scipy.sparse as sp
from skfem import Basis, ElementHex1, ElementLineP1, MeshHex, MeshLine
from skfem.models.poisson import laplace, mass, unit_load

from pcverify.solvers.continuum.grid import HEX_CORNERS, StructuredGrid

DROP_RTOL = 1e-12  # entries |a_ij| <= DROP_RTOL * |a_ii| are round-off of exact zeros (27 -> 21 points)


@numba.njit(cache=True)
def _tensor_csr_kernel(shape, bands, drop_rtol):
    """CSR arrays of sum_t bands[t,0] (x) bands[t,1] (x) bands[t,2]; bands[t, d, i, o] = A_td[i, i + o - 1]."""
    nx, ny, nz = shape[0], shape[1], shape[2]
    nterms = bands.shape[0]
    n = nx * ny * nz
    indptr = np.zeros(n + 1, dtype=np.int64)
    indices = np.empty(n * 27, dtype=np.int32)
    data = np.empty(n * 27, dtype=np.float64)
    vals = np.empty(27)
    cols = np.empty(27, dtype=np.int64)
    pos = 0
    row = 0
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                m = 0
                diag = 0.0
                for di in range(-1, 2):
                    ii = i + di
                    if ii < 0 or ii >= nx:
                        continue
                    for dj in range(-1, 2):
                        jj = j + dj
                        if jj < 0 or jj >= ny:
                            continue
                        for dk in range(-1, 2):
                            kk = k + dk
                            if kk < 0 or kk >= nz:
                                continue
                            v = 0.0
                            for t in range(nterms):
                                v += bands[t, 0, i, di + 1] * bands[t, 1, j, dj + 1] * bands[t, 2, k, dk + 1]
                            vals[m] = v
                            cols[m] = (ii * ny + jj) * nz + kk
                            if di == 0 and dj == 0 and dk == 0:
                                diag = abs(v)
                            m += 1
                for q in range(m):  # columns are already ascending (x slowest, z fastest)
                    if drop_rtol < 0.0 or abs(vals[q]) > drop_rtol * diag:
                        indices[pos] = cols[q]
                        data[pos] = vals[q]
                        pos += 1
                row += 1
                indptr[row] = pos
    return indptr, indices[:pos].copy(), data[:pos].copy()


def tensor_csr(factors: list[tuple[sp.spmatrix, sp.spmatrix, sp.spmatrix]],
               drop_rtol: float | None = DROP_RTOL) -> sp.csr_matrix:
    """Sum over terms of Ax (x) Ay (x) Az for tridiagonal 1-D matrices, as a sorted CSR matrix, without the
    entries |a_ij| <= drop_rtol * |a_ii| (0 keeps every nonzero; None the whole 27-point pattern, zeros included)."""
    shape = tuple(int(a.shape[0]) for a in factors[0])
    nmax = max(shape)
    bands = np.zeros((len(factors), 3, nmax, 3))
    for t, term in enumerate(factors):
        if tuple(int(a.shape[0]) for a in term) != shape:
            raise ValueError("all terms must have the same 1-D sizes")
        for d, a in enumerate(term):
            a = sp.dia_matrix(a)
            if np.any(np.abs(a.offsets) > 1):
                raise ValueError("1-D factors must be tridiagonal")
            dense = a.tocsr()
            m = shape[d]
            bands[t, d, :m, 1] = dense.diagonal(0)
            bands[t, d, 1:m, 0] = dense.diagonal(-1)
            bands[t, d, : m - 1, 2] = dense.diagonal(1)
    indptr, indices, data = _tensor_csr_kernel(np.asarray(shape, dtype=np.int64), bands,
                                               -1.0 if drop_rtol is None else float(drop_rtol))
    n = int(np.prod(shape))
    if indptr[-1] < np.iinfo(np.int32).max:
        indptr = indptr.astype(np.int32)
    return sp.csr_matrix((data, indices, indptr), shape=(n, n))


def grid_graph(shape: tuple[int, int, int]) -> sp.csr_matrix:
    """Node adjacency of a structured hex grid (27-point pattern): the AMG strength-of-connection graph, because
    the Laplacian's own pattern lacks the edge neighbours (~40 % more CG iterations, measured)."""
    ones = [sp.diags([np.ones(m - 1), np.ones(m), np.ones(m - 1)], [-1, 0, 1]) for m in shape]
    return tensor_csr([tuple(ones)], drop_rtol=None)


@dataclass(frozen=True)
class LineOperators:
    """scikit-fem's 1-D P1 operators on one axis: global matrices and per-element 2x2 (2,2,ne) / (2,ne)."""

    stiffness: sp.csr_matrix
    mass: sp.csr_matrix
    load: np.ndarray
    stiffness_el: np.ndarray
    mass_el: np.ndarray
    load_el: np.ndarray


def line_operators(coords: np.ndarray) -> LineOperators:
    """Assemble the 1-D Laplacian, mass and load with scikit-fem (ElementLineP1, intorder=2)."""
    basis = Basis(MeshLine(np.asarray(coords, dtype=float)), ElementLineP1(), intorder=2)
    return LineOperators(
        laplace.assemble(basis).tocsr(), mass.assemble(basis).tocsr(), unit_load.assemble(basis),
        *(np.moveaxis(f.elemental(basis).tolocal(), 0, -1) for f in (laplace, mass, unit_load)),  # -> (..., ne)
    )


@dataclass
class Q1Operators:
    """Assembled Q1 operators of a grid with unit coefficients: K = int grad u . grad v, M = int u v, w = int phi."""

    stiffness: sp.csr_matrix
    weights: np.ndarray
    mass: sp.csr_matrix | None
    warped_cells: int


def _box_cell_local(lines: list[LineOperators], cells: np.ndarray, shape) -> tuple[np.ndarray, ...]:
    """Element matrices (8, 8, nc) of K and M and load vectors (8, nc) of undistorted box cells `cells`."""
    nx, ny, nz = shape
    ci = np.unravel_index(cells, (nx - 1, ny - 1, nz - 1))
    oa = [HEX_CORNERS[:, d][:, None, None] for d in range(3)]
    ob = [HEX_CORNERS[:, d][None, :, None] for d in range(3)]
    kk = [lines[d].stiffness_el[oa[d], ob[d], ci[d]] for d in range(3)]  # (8, 8, nc) each
    mm = [lines[d].mass_el[oa[d], ob[d], ci[d]] for d in range(3)]
    ke = kk[0] * mm[1] * mm[2] + mm[0] * kk[1] * mm[2] + mm[0] * mm[1] * kk[2]
    me = mm[0] * mm[1] * mm[2]
    we = np.prod([lines[d].load_el[HEX_CORNERS[:, d][:, None], ci[d]] for d in range(3)], axis=0)  # (8, nc)
    return ke, me, we


def assemble_q1(grid: StructuredGrid, with_mass: bool = False, full_pattern: bool = False) -> Q1Operators:
    """Q1 stiffness, load (and mass) of a `StructuredGrid` with unit coefficients, = scikit-fem's intorder=2.
    full_pattern keeps the stiffness's exact zeros: SuperLU's ordering on the 21-point pattern fills in far
    more (6x slower at 19 855 nodes, measured)."""
    shape = grid.shape
    axes = [np.linspace(0.0, float(e), m) for e, m in zip(grid.extent, shape, strict=True)]
    lines = [line_operators(a) for a in axes]
    stiff = tensor_csr([(lines[0].stiffness, lines[1].mass, lines[2].mass),
                        (lines[0].mass, lines[1].stiffness, lines[2].mass),
                        (lines[0].mass, lines[1].mass, lines[2].stiffness)],
                       drop_rtol=None if full_pattern else DROP_RTOL)
    mass_m = tensor_csr([(lines[0].mass, lines[1].mass, lines[2].mass)]) if with_mass else None
    weights = np.einsum("i,j,k->ijk", lines[0].load, lines[1].load, lines[2].load).ravel()
    warped = grid.warped_cells() if grid.warps else np.zeros(0, dtype=np.int64)
    if warped.size:
        sub = grid.cells[:, warped]
        nodes, local = np.unique(sub, return_inverse=True)
        local = local.reshape(sub.shape)
        basis = Basis(MeshHex(np.ascontiguousarray(grid.points[nodes].T), local.astype(np.int32)), ElementHex1(),
                      intorder=2)
        ke, me, we = _box_cell_local(lines, warped, shape)
        rows = np.broadcast_to(local[:, None, :], ke.shape).ravel()
        cols = np.broadcast_to(local[None, :, :], ke.shape).ravel()
        nloc = nodes.size

        def correction(skfem_matrix: sp.spmatrix, box: np.ndarray) -> sp.csr_matrix:
            box_m = sp.csr_matrix((box.ravel(), (rows, cols)), shape=(nloc, nloc))
            d = (skfem_matrix - box_m).tocoo()
            return sp.csr_matrix((d.data, (nodes[d.row], nodes[d.col])), shape=stiff.shape)

        corr = correction(laplace.assemble(basis), ke)
        if full_pattern:  # scipy's sparse sum drops entries that cancel to 0.0: sum as COO to keep the pattern
            a, c = stiff.tocoo(), corr.tocoo()
            stiff = sp.csr_matrix((np.concatenate([a.data, c.data]), (np.concatenate([a.row, c.row]),
                                   np.concatenate([a.col, c.col]))), shape=stiff.shape)
            stiff.sum_duplicates()
        else:
            stiff = (stiff + corr).tocsr()
        if with_mass:
            mass_m = (mass_m + correction(mass.assemble(basis), me)).tocsr()
        w_box = np.bincount(local.ravel(), weights=we.ravel(), minlength=nloc)
        weights[nodes] += unit_load.assemble(basis) - w_box
    return Q1Operators(stiff, weights, mass_m, int(warped.size))


def plane_load(grid: StructuredGrid, axis: int, position: float) -> np.ndarray:
    """Surface load f_i = integral of phi_i over the plane {x_axis = position}, exact for Q1 on box cells: the
    product of the 1-D loads on the two other axes and the 1-D hat values at `position`.  The caller makes sure
    the plane crosses no warped cell (ValueError if it lies outside the grid)."""
    coords = np.linspace(0.0, float(grid.extent[axis]), grid.shape[axis])
    if not coords[0] <= position <= coords[-1]:
        raise ValueError(f"plane position {position!r} lies outside the grid along axis {axis}")
    j = min(int(np.searchsorted(coords, position, side="right")) - 1, coords.size - 2)
    t = (position - coords[j]) / (coords[j + 1] - coords[j])
    hat = np.zeros(coords.size)
    hat[j], hat[j + 1] = 1.0 - t, t
    factors = [hat if d == axis else line_operators(np.linspace(0.0, float(grid.extent[d]), grid.shape[d])).load
               for d in range(3)]
    return np.einsum("i,j,k->ijk", *factors).ravel()


@numba.njit(cache=True)
def _split_kernel(indptr, indices, data, new_index, is_free, n_free):
    """Rows of free nodes, split into the free-free and free-fixed column blocks (order kept)."""
    nnz_ff = 0
    nnz_fb = 0
    for r in range(indptr.size - 1):
        if is_free[r]:
            for q in range(indptr[r], indptr[r + 1]):
                if is_free[indices[q]]:
                    nnz_ff += 1
                else:
                    nnz_fb += 1
    ptr_ff = np.zeros(n_free + 1, dtype=np.int64)
    ptr_fb = np.zeros(n_free + 1, dtype=np.int64)
    ind_ff = np.empty(nnz_ff, dtype=np.int32)
    ind_fb = np.empty(nnz_fb, dtype=np.int32)
    dat_ff = np.empty(nnz_ff)
    dat_fb = np.empty(nnz_fb)
    a = 0
    b = 0
    row = 0
    for r in range(indptr.size - 1):
        if not is_free[r]:
            continue
        for q in range(indptr[r], indptr[r + 1]):
            c = indices[q]
            if is_free[c]:
                ind_ff[a] = new_index[c]
                dat_ff[a] = data[q]
                a += 1
            else:
                ind_fb[b] = new_index[c]
                dat_fb[b] = data[q]
                b += 1
        row += 1
        ptr_ff[row] = a
        ptr_fb[row] = b
    return ptr_ff, ind_ff, dat_ff, ptr_fb, ind_fb, dat_fb


def split_free(a: sp.csr_matrix, free: np.ndarray) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """(A[free][:, free], A[free][:, ~free]) for a boolean mask `free`, in one O(nnz) pass (scipy's fancy
    indexing, without its two copies); with every row free, `a` itself and a matrix of no columns."""
    a = sp.csr_matrix(a)
    free = np.asarray(free, dtype=bool)
    n_free = int(free.sum())
    if n_free == free.size:
        return a, sp.csr_matrix((n_free, 0))
    new_index = np.empty(free.size, dtype=np.int64)
    new_index[free] = np.arange(n_free)
    new_index[~free] = np.arange(free.size - n_free)
    pf, jf, df, pb, jb, db = _split_kernel(a.indptr.astype(np.int64), a.indices.astype(np.int32, copy=False),
                                           np.asarray(a.data, dtype=np.float64), new_index, free, n_free)
    shape_b = (n_free, free.size - n_free)
    return (sp.csr_matrix((df, jf, pf.astype(np.int32)), shape=(n_free, n_free)),
            sp.csr_matrix((db, jb, pb.astype(np.int32)), shape=shape_b))
