"""Conversion of lunarviz results to PyVista meshes, and the VTK/PLY writers of per-facet results.

The core (:mod:`lunarviz.methods.tracer.facets`) computes the arrays; only this module knows PyVista.
"""

from __future__ import annotations

import numpy as np
import pyvista as pv

from lunarviz.errors import LunarvizError
from lunarviz.outputs.writers import atomic_path, check_free_space


def facet_polydata(res) -> pv.PolyData:
    """The lunar mesh (Moon-centred metres, the Moon's body frame) with per-facet cell data."""
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


def multiblock(res, meta: str | None = None) -> pv.MultiBlock:
    """Every body of ``res``: blocks ``moon``, ``earth``, ``sun`` in scene coordinates [m]."""
    mb = pv.MultiBlock()
    moon = facet_polydata(res)
    rot = res.info.get("moon_rotation_body_to_scene")
    if rot is not None:  # body frame (MOON_ME) → scene axes
        moon.points = np.asarray(moon.points, dtype=float) @ np.asarray(rot).T
    moon.points += np.asarray(res.info["moon_centre_m"])
    mb["moon"] = moon
    for name, (v, fcs, cd) in res.bodies.items():
        mb[name] = body_polydata(v + np.asarray(res.info[f"{name}_m"]), fcs, cd)
    if meta is not None:
        mb.field_data["info_json"] = [meta]
    return mb


def write_multiblock(path, res, meta: str) -> None:
    """Every body of ``res`` as a .vtm multiblock (blocks ``moon``, ``earth``, ``sun`` in scene
    coordinates [m]). A .vtm is an index plus a folder of blocks: both are written beside a
    temporary name and moved into place (the folder first), so nothing half-written is left;
    the caller has checked that the folder holds nothing but an earlier multiblock's blocks."""
    import fcntl
    import os
    import shutil
    import tempfile
    from pathlib import Path
    mb = multiblock(res, meta)
    p = Path(path)
    folder = p.parent if str(p.parent) else Path(".")
    # a private temporary folder (never a name a user's folder could have), and the swap of the
    # block folder and the index under a lock on the output folder, so two runs writing the
    # same .vtm cannot leave an index without its blocks
    check_free_space(path, sum(mb[name].actual_memory_size for name in mb.keys()) * 1024)
    tmpdir = Path(tempfile.mkdtemp(dir=folder, prefix=f".{p.stem}.", suffix=".vtm-tmp"))
    lock = os.open(folder, os.O_RDONLY)
    quiet = _quiet_vtk()
    try:
        quiet.__enter__()
        mb.save(tmpdir / p.name)
        for name in mb.keys():  # each block read back (VTK's writers report no error on a full disk)
            _check_written(tmpdir / p.stem / f"{p.stem}_{list(mb.keys()).index(name)}.vtp", path, mb[name].n_cells)
        fcntl.flock(lock, fcntl.LOCK_EX)
        final_dir = p.parent / p.stem
        if final_dir.exists():
            shutil.rmtree(final_dir)
        (tmpdir / p.stem).rename(final_dir)
        (tmpdir / p.name).replace(p)
    except OSError as exc:
        raise LunarvizError(f"cannot write {str(path)!r}: {exc.strerror or exc}") from None
    finally:
        quiet.__exit__(None, None, None)
        os.close(lock)  # releases the lock
        shutil.rmtree(tmpdir, ignore_errors=True)


def check_vtm_target(path) -> None:
    """A .vtm is an index plus a folder of blocks beside it: refuse to replace a folder that
    holds anything but an earlier multiblock's block files (or a file of that name)."""
    import re
    from pathlib import Path
    p = Path(path)
    d = p.parent / p.stem
    if d.exists():
        if not d.is_dir():
            raise LunarvizError(f"--out {path}: {d} exists and is not a directory (a .vtm needs it for its blocks)")
        pat = re.compile(rf"{re.escape(p.stem)}_\d+\.vt[pu]$")
        other = [q.name for q in d.iterdir() if not pat.match(q.name)]
        if other:
            raise LunarvizError(f"--out {path}: folder {d} holds other files ({other[0]}); choose another name")


def write_facet_mesh(path, res) -> None:
    """Write the lunar mesh with its cell data (.vtp, .vtk or .ply), or every body as a
    multiblock (.vtm: blocks ``moon``, ``earth``, ``sun`` in scene coordinates [m]), atomically."""
    import json
    from pathlib import Path

    meta = json.dumps({**res.info, **res.totals})
    if Path(path).suffix.lower() == ".vtm":
        check_vtm_target(path)
        write_multiblock(path, res, meta)
        return
    poly = facet_polydata(res)
    if Path(path).suffix.lower() != ".ply":
        poly.field_data["info_json"] = [meta]
    check_free_space(path, poly.actual_memory_size * 1024)
    with atomic_path(path) as tmp, _quiet_vtk():
        poly.save(tmp)
        _check_written(tmp, path, poly.n_cells)


def _quiet_vtk():
    """VTK's and PyVista's own messages off while a file is written and read back: a failure
    is one LunarvizError line, not pages of VTK log."""
    import contextlib
    import warnings
    stack = contextlib.ExitStack()
    stack.enter_context(pv.vtk_verbosity("off"))
    stack.enter_context(warnings.catch_warnings())
    warnings.simplefilter("ignore")
    return stack


def _check_written(tmp, path, n_cells: int) -> None:
    """VTK's writers report no error on a full disk: read the file back and count its cells."""
    try:
        back = pv.read(tmp)
        ok = back.n_cells == n_cells
    except Exception:  # noqa: BLE001 (any reader failure means a broken file)
        ok = False
    if not ok:
        raise LunarvizError(f"writing {str(path)!r} left an incomplete file (is the disk full?)")
