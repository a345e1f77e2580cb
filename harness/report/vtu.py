"""VTU (VTK XML unstructured grid) files of sampled fields, for ParaView.

Particles and the continuum solutions sampled at the lattice nodes are point clouds: one
VTK_VERTEX cell per point, point data = the fields.  Plain ASCII XML, no extra dependency.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from pcverify.harness.run.files import atomic_write

VTK_VERTEX = 1


def _array(name: str, values: np.ndarray, components: int = 1, kind: str = "Float64") -> str:
    text = " ".join(repr(float(v)) if kind == "Float64" else str(int(v)) for v in np.ravel(values))
    comp = f' NumberOfComponents="{components}"' if components > 1 else ""
    return f'<DataArray type="{kind}" Name="{name}"{comp} format="ascii">{text}</DataArray>'


def write_vtu(path: Path, points: np.ndarray, fields: dict[str, np.ndarray]) -> Path:
    """Write `points` (k, 3) with point fields (k,) or (k, 3) to `path` (.vtu)."""
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    k = len(points)
    data = []
    for name, values in fields.items():
        values = np.asarray(values, dtype=float)
        if values.shape[0] != k:
            raise ValueError(f"field {name!r} has {values.shape[0]} values for {k} points")
        data.append(_array(name, values, 1 if values.ndim == 1 else values.shape[1]))
    body = (
        '<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid" version="0.1" byte_order="LittleEndian">'
        f'<UnstructuredGrid><Piece NumberOfPoints="{k}" NumberOfCells="{k}">'
        f"<PointData>{''.join(data)}</PointData>"
        f"<Points>{_array('Points', points, 3)}</Points>"
        f"<Cells>{_array('connectivity', np.arange(k), kind='Int64')}"
        f"{_array('offsets', np.arange(1, k + 1), kind='Int64')}"
        f"{_array('types', np.full(k, VTK_VERTEX), kind='UInt8')}</Cells>"
        "</Piece></UnstructuredGrid></VTKFile>\n"
    )
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(path, body)
    return path
