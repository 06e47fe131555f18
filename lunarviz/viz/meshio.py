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


def write_multiblock(path, res, meta: str) -> None:
    """Every body of ``res`` as a .vtm multiblock (blocks ``moon``, ``earth``, ``sun`` in scene
    coordinates [m]). A .vtm is an index plus a folder of blocks: both are written beside a
    temporary name and moved into place (the folder first), so nothing half-written is left;
    the caller has checked that the folder holds nothing but an earlier multiblock's blocks."""
    import shutil
    from pathlib import Path
    mb = pv.MultiBlock()
    moon = facet_polydata(res)
    moon.points += np.asarray(res.info["moon_centre_m"])
    mb["moon"] = moon
    for name, (v, fcs, cd) in res.bodies.items():
        mb[name] = body_polydata(v + np.asarray(res.info[f"{name}_m"]), fcs, cd)
    mb.field_data["info_json"] = [meta]
    p = Path(path)
    tmpdir = p.parent / f".{p.stem}.tmp"
    if tmpdir.exists():
        shutil.rmtree(tmpdir)
    tmpdir.mkdir()
    try:
        mb.save(tmpdir / p.name)
        final_dir = p.parent / p.stem
        if final_dir.exists():
            shutil.rmtree(final_dir)
        (tmpdir / p.stem).rename(final_dir)
        (tmpdir / p.name).replace(p)
    finally:
        shutil.rmtree(tmpdir, ignore_errors=True)
