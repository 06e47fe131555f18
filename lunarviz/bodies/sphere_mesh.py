"""The packaged icospheres without trimesh: a body's analytic sphere as plain arrays.

Importing trimesh costs ~0.5 s, more than a whole ray-traced paper sweep's work per core, and the
packaged spheres need none of it: their binary PLY files (``data/meshes``, written by
:func:`lunarviz.bodies.meshes.write_packaged_meshes`) are read here with numpy, checked against
the manifest's sha256, and put back on the unit sphere in float64 exactly as
:func:`lunarviz.bodies.meshes.body_mesh` does through trimesh (the same vertices and faces). A
level that is not packaged is built by trimesh (:func:`lunarviz.bodies.meshes.analytic_sphere`).
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from lunarviz.caches import memoize
from lunarviz.resources import MESH_DIR


@dataclass(frozen=True, eq=False)
class SphereMesh:
    """Vertices (V, 3) [m, body frame], faces (F, 3) and metadata: what the tracer reads of a
    mesh (:class:`lunarviz.methods.tracer.embree_bodies.EmbreeBody`)."""

    vertices: np.ndarray
    faces: np.ndarray
    metadata: dict = field(default_factory=dict)


#: the header the packaged files have (trimesh's binary PLY export of an icosphere)
_HEADER = ["ply", "format binary_little_endian 1.0", "element vertex {V}", "property float x", "property float y",
           "property float z", "element face {F}", "property list uchar int vertex_indices", "end_header"]


def read_packaged_ply(data: bytes) -> tuple[np.ndarray, np.ndarray] | None:
    """(vertices float32 (V, 3), faces int64 (F, 3)) of a packaged binary PLY, or ``None`` if the
    file is not laid out as the packaged ones are (then trimesh reads it)."""
    end = data.find(b"end_header\n")
    if end < 0:
        return None
    lines = [ln for ln in data[:end + 10].decode("ascii", "replace").splitlines() if not ln.startswith("comment")]
    try:
        nv = int(lines[2].split()[-1])
        nf = int(lines[6].split()[-1])
    except (IndexError, ValueError):
        return None
    if [ln.strip() for ln in lines] != [h.format(V=nv, F=nf) for h in _HEADER]:
        return None
    body = memoryview(data)[end + 11:]
    if len(body) != nv * 12 + nf * 13:
        return None
    v = np.frombuffer(body[:nv * 12], dtype="<f4").reshape(nv, 3)
    rec = np.frombuffer(body[nv * 12:], dtype=np.dtype([("n", "u1"), ("i", "<i4", (3,))]))
    if not np.all(rec["n"] == 3):
        return None
    return v, rec["i"].astype(np.int64)


def packaged_file(body: str, level: int) -> tuple[Path, bytes] | None:
    """The packaged unit mesh file of ``body`` at ``level`` and its bytes, if the manifest lists it
    and its sha256 matches; else ``None``."""
    manifest = MESH_DIR / "manifest.json"
    if not manifest.is_file():
        return None
    for entry in json.loads(manifest.read_text())["meshes"]:
        if entry["body"] == body and entry["level"] == level:
            p = MESH_DIR / entry["file"]
            if not p.is_file():
                return None
            data = p.read_bytes()
            return (p, data) if hashlib.sha256(data).hexdigest() == entry["sha256"] else None
    return None


@memoize(maxsize=16)
def unit_sphere_arrays(body: str, level: int) -> tuple[np.ndarray, np.ndarray] | None:
    """Unit-sphere vertices (float64, renormalised) and faces of the packaged mesh of ``body`` at
    ``level``, or ``None`` where none is packaged, intact and readable here."""
    found = packaged_file(body, level)
    got = None if found is None else read_packaged_ply(found[1])
    if got is None:
        return None
    v = np.asarray(got[0], dtype=float)
    v = v / np.linalg.norm(v, axis=1, keepdims=True)  # PLY stores float32: back on the sphere
    v.flags.writeable = False
    f = got[1]
    f.flags.writeable = False
    return v, f


def packaged_sphere(body: str, level: int, radius: float) -> SphereMesh | None:
    """The packaged icosphere of ``body`` at ``level`` in metres, tagged as an analytic sphere
    (the tag ``metadata["lunarviz_analytic"]`` allows the exact-sphere fast path; it is set only
    for meshes generated as spheres, never inferred from a user's vertices), or ``None`` where
    that level is not packaged (:func:`lunarviz.bodies.meshes.analytic_sphere` builds it)."""
    got = unit_sphere_arrays(body, int(level))
    if got is None:
        return None
    v, f = got
    vertices, faces = v * radius, np.array(f, dtype=np.int64, order="C")  # (owning their data)
    for a in (vertices, faces):  # (shared through the mesh cache: nothing may change them)
        a.setflags(write=False)
    return SphereMesh(vertices, faces, {"lunarviz_analytic": {"shape": "sphere", "radius": float(radius)}})
