"""Conversion of lunarviz results to PyVista meshes."""

from __future__ import annotations

import numpy as np
import pyvista as pv


def facet_polydata(res) -> pv.PolyData:
    """The lunar mesh (Moon-centred metres) with per-facet cell data."""
    faces = np.hstack([np.full((res.n_faces, 1), 3), res.faces]).astype(np.int64).ravel()
    poly = pv.PolyData(np.asarray(res.vertices, dtype=float), faces)
    for k, v in res.cell_data.items():
        poly.cell_data[k] = np.asarray(v, dtype=float)
    return poly


def body_polydata(vertices, faces, cell_data) -> pv.PolyData:
    """Any body's mesh [m] with its per-facet cell data."""
    f = np.hstack([np.full((len(faces), 1), 3), faces]).astype(np.int64).ravel()
    poly = pv.PolyData(np.asarray(vertices, dtype=float), f)
    for k, v in cell_data.items():
        poly.cell_data[k] = np.asarray(v, dtype=float)
    return poly
