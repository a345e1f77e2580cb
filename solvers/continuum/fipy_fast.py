"""Faster set-up of FiPy's own finite-volume discretisation for the heat solver.

Two small subclasses; the discretisation (mesh geometry, DiffusionTerm coefficients, constraint
handling, matrix) stays FiPy's, only work that gives the same numbers is done more cheaply or not at all:

- `TensorGrid3D(NonUniformGrid3D)`: FiPy's generic `Mesh._calcFaceAreas` / `_calcFaceCenters` gather the
  4 vertices of every face (3 x 4 x faces masked arrays, ~2 M faces at 673 501 cells) and take polygon
  cross products.  On FiPy's rectilinear grid (its builder's face order: XY faces, then XZ, then YZ, x
  fastest) a face's area is the product of two vertex-coordinate differences and its centre the sum of its
  4 vertex coordinates over 4; both are computed here on the three 1-D vertex axes with the same floating
  point operations in the same order, then broadcast to the faces, so they equal FiPy's bit for bit.
  Mesh._setGeometry also computes, eagerly, quantities nothing in the heat solve reads (cell-to-cell
  normals, face tangents, cell normals and areas, ...; `DEFERRED`): here each is computed on first access
  by the same FiPy method.  Topology, normals, cell centres and volumes, distances are FiPy's code.
  Tests compare every geometry array and the assembled system with the stock NonUniformGrid3D: identical.
- `DiffusionTerm` with `_constrainGradient` skipped when the variable's face gradient carries no
  constraint: FiPy then evaluates the full face-gradient field (tangential corrections included) only
  to multiply it by an all-False mask, a right-hand-side contribution of exactly zero.

FIPY_SOLVERS defaults to scipy (the package's __init__, before FiPy is first imported).
"""

from __future__ import annotations

import numpy as np
from fipy.meshes.nonUniformGrid3D import NonUniformGrid3D
from fipy.terms.diffusionTerm import DiffusionTerm as FipyDiffusionTerm

# vertex offsets (x, y, z) of the 4 corners of XY, XZ and YZ faces in the order of FiPy's Grid3D builder
_FACE_CORNERS = (((0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)),
                 ((0, 0, 0), (1, 0, 0), (1, 0, 1), (0, 0, 1)),
                 ((0, 0, 0), (0, 1, 0), (0, 1, 1), (0, 0, 1)))


class TensorGrid3D(NonUniformGrid3D):
    """NonUniformGrid3D: face areas and centres from the vertex axes (the same values, bit for bit), and the
    geometry the heat solve never reads computed on first access (`DEFERRED`), by FiPy's own methods."""

    def _setGeometry(self, scaleLength=1.0):
        # Mesh._setGeometry without the DEFERRED quantities (same order, same FiPy _calc methods)
        for name in DEFERRED:
            self.__dict__.pop(name, None)
        self._faceCenters = self._calcFaceCenters()
        self._faceAreas = self._calcFaceAreas()
        self._cellCenters = self._calcCellCenters()
        self._internalFaceToCellDistances, self._cellToFaceDistanceVectors = self._calcFaceToCellDistAndVec()
        self._internalCellDistances, self._cellDistanceVectors = self._calcCellDistAndVec()
        self.faceNormals = self._calcFaceNormals()
        self._orientedFaceNormals = self._calcOrientedFaceNormals()
        self._cellVolumes = self._calcCellVolumes()
        self._setScaledGeometry(self.scale["length"])

    def _setFaceDependentScaledValues(self):
        # Mesh's version without the scale-dependent DEFERRED ones (dropped, so they follow a new scale)
        for name in ("_scaledCellToCellDistances", "_faceAspectRatios"):
            self.__dict__.pop(name, None)
        self._areaProjections = self._calcAreaProjections()
        self._orientedAreaProjections = self._calcOrientedAreaProjections()
        self._faceToCellDistanceRatio = self._calcFaceToCellDistanceRatio()

    def __getattr__(self, name):
        # only reached when `name` is not set: compute a DEFERRED quantity once, as Mesh would have
        calc = DEFERRED.get(name)
        if calc is None:
            raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")
        value = calc(self)
        setattr(self, name, value)
        return value

    def _axes(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The vertex coordinates along x, y and z (FiPy's own: cumulative sums of dx, dy, dz)."""
        v = np.asarray(self.vertexCoords)
        nx1, nxy1 = self.nx + 1, (self.nx + 1) * (self.ny + 1)
        return v[0, :nx1], v[1, :nxy1:nx1], v[2, ::nxy1]

    def _shapes(self) -> tuple[tuple[int, int, int], ...]:
        """(z, y, x) index shapes of the XY, XZ and YZ faces, in FiPy's face order."""
        nx, ny, nz = self.nx, self.ny, self.nz
        return (nz + 1, ny, nx), (nz, ny + 1, nx), (nz, ny, nx + 1)

    def _calcFaceAreas(self):
        x, y, z = self._axes()
        dx, dy, dz = np.diff(x), np.diff(y), np.diff(z)
        s_xy, s_xz, s_yz = self._shapes()
        return np.concatenate([np.broadcast_to(dx[None, None, :] * dy[None, :, None], s_xy).ravel(),
                               np.broadcast_to(dx[None, None, :] * dz[:, None, None], s_xz).ravel(),
                               np.broadcast_to(dy[None, :, None] * dz[:, None, None], s_yz).ravel()])

    def _calcFaceCenters(self):
        # FiPy: mean of the face's 4 vertices, summed in vertex order, for all faces at once; here the same
        # sums on the 1-D axes (the builder's vertex order per face kind), broadcast to the faces
        axes = self._axes()
        out = np.empty((3, self.numberOfFaces))
        start = 0
        for corners, shp in zip(_FACE_CORNERS, self._shapes(), strict=True):
            n = int(np.prod(shp))
            for axis in range(3):
                m = shp[2 - axis]  # faces along this axis
                total = sum(axes[axis][c[axis]:c[axis] + m] for c in corners)  # ((v0 + v1) + v2) + v3
                view = [None, None, None]
                view[2 - axis] = slice(None)
                out[axis, start:start + n] = np.broadcast_to((total / 4)[tuple(view)], shp).ravel()
            start += n
        return out

# Mesh._setGeometry computes these eagerly; FiPy's DiffusionTerm (no correction), its value constraints and
# the solver's own code never read them (faceGrad, advection, least-squares gradients, periodic meshes do).
DEFERRED = {
    "_faceCellToCellNormals": lambda m: m._calcFaceCellToCellNormals(),
    "_faceTangents1": lambda m: m._calcFaceTangents()[0],
    "_faceTangents2": lambda m: m._calcFaceTangents()[1],
    "_cellToCellDistances": lambda m: m._calcCellToCellDist(),
    "_cellAreas": lambda m: m._calcCellAreas(),
    "_cellNormals": lambda m: m._calcCellNormals(),
    "_scaledCellToCellDistances": lambda m: m.scale["length"] * m._cellToCellDistances,
    "_faceAspectRatios": lambda m: m._calcFaceAspectRatios(),
}

class DiffusionTerm(FipyDiffusionTerm):
    """FiPy's DiffusionTerm without the face-gradient evaluation when no gradient is constrained."""

    def _constrainGradient(self, var):
        if not var.faceGrad.constraints:  # FiPy's b = -(all-False mask * Gamma grad).divergence V = 0
            return 0, 0
        return super()._constrainGradient(var)


def tensor_grid3d(dx: np.ndarray, dy: np.ndarray, dz: np.ndarray):
    """FiPy NonUniformGrid3D (as `fipy.Grid3D(dx=..., dy=..., dz=...)` builds) with cheap face geometry."""
    return TensorGrid3D(dx=np.asarray(dx, float), dy=np.asarray(dy, float), dz=np.asarray(dz, float))


def diffusion_term(coeff):
    """FiPy DiffusionTerm(coeff) that skips the zero face-gradient constraint contribution."""
    return DiffusionTerm(coeff=coeff)
