"""Tessellated bodies: icospheres at a chosen subdivision level, packaged meshes, user meshes.

Packaged default meshes live in the package's ``data/meshes/`` folder with ``manifest.json``
(body, level, facets, sha256); :func:`body_mesh` uses them when present and intact, otherwise
builds the same icosphere with trimesh (identical vertices: trimesh's icosphere is
deterministic). A user mesh (OBJ, PLY, STL, OFF, GLB ... through trimesh) is read in metres
(or ``--mesh-units``), never rescaled, and checked by :func:`validate_mesh` (watertight,
outward normals, no degenerate faces) and for a plausible size.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import trimesh

import lunarviz.constants as C
from lunarviz.bodies.sphere_mesh import packaged_file
from lunarviz.errors import LunarvizError, unknown_choice
from lunarviz.options import BODIES, DEFAULT_LEVELS, MAX_LEVEL, MESH_UNITS
from lunarviz.resources import MESH_DIR

#: Default subdivision levels, chosen from the mesh-resolution study
#: (the documentation's *Bodies as meshes* page, "Choosing the mesh levels").


def _nominal_radii() -> dict:
    return {"moon": C.R_MOON_M, "earth": C.R_EARTH_M, "sun": C.R_SUN_M}


#: The paper's body radii [m] (lunarviz.constants): what ``--mesh-units radius`` and the size
#: checks of user meshes refer to.
NOMINAL_RADII = _nominal_radii()


class MeshError(LunarvizError):
    """A mesh that cannot represent a body."""


def unit_icosphere(level: int) -> trimesh.Trimesh:
    """Unit-radius icosphere with 20·4^level faces (vertices exactly on the sphere)."""
    if not (isinstance(level, (int, np.integer)) and 0 <= level <= MAX_LEVEL):
        raise MeshError(f"mesh level {level!r} must be an integer in [0, {MAX_LEVEL}]")
    return trimesh.creation.icosphere(subdivisions=int(level), radius=1.0)


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def packaged_mesh_path(body: str, level: int) -> Path | None:
    """Path of the packaged unit mesh for ``body`` at ``level`` if listed and intact."""
    found = packaged_file(body, level)
    return None if found is None else found[0]


def body_mesh(body: str, level: int | None = None) -> trimesh.Trimesh:
    """Unit-radius mesh of ``body`` (scaled and placed by the tracer)."""
    if body not in BODIES:
        raise MeshError(str(unknown_choice("body", body, BODIES)))
    level = DEFAULT_LEVELS[body] if level is None else level
    p = packaged_mesh_path(body, level) if isinstance(level, (int, np.integer)) else None
    if p is not None:
        m = trimesh.load(p, process=False, force="mesh")
        # PLY stores float32: put the icosphere's vertices back on the unit sphere in float64
        v = np.asarray(m.vertices, dtype=float)
        return trimesh.Trimesh(v / np.linalg.norm(v, axis=1, keepdims=True), m.faces, process=False)
    return unit_icosphere(level)


#: Faces per block in the mesh checks below (bounds their temporaries on multi-million-facet meshes).
CHECK_BLOCK = 1 << 20


def _face_blocks(n: int):
    return (slice(a, min(n, a + CHECK_BLOCK)) for a in range(0, n, CHECK_BLOCK))


def face_areas(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Facet areas, computed in blocks of faces."""
    out = np.empty(len(faces))
    for b in _face_blocks(len(faces)):
        t = vertices[faces[b]]
        out[b] = 0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1)
    return out


def edge_checks(faces: np.ndarray, n_vertices: int) -> tuple[bool, bool]:
    """``(watertight, winding consistent)`` of a triangle mesh, as trimesh defines them: every
    edge shared by exactly two faces, which traverse it in opposite directions (the second is
    meaningful, and used, only for watertight meshes).

    Computed on int64 edge keys (``a·V + b``) instead of trimesh's edge caches, which take
    ~3 GB on a 5-million-facet mesh ; both are checked against
    trimesh on good and broken meshes."""
    f = np.asarray(faces, dtype=np.int64)
    a = f.reshape(-1)
    b = f[:, [1, 2, 0]].reshape(-1)
    V = np.int64(n_vertices)
    undirected = np.sort(np.minimum(a, b) * V + np.maximum(a, b))
    pairs = len(undirected) % 2 == 0 and bool(np.all(undirected[0::2] == undirected[1::2]))
    watertight = pairs and (len(undirected) < 4 or bool(np.all(undirected[2::2] != undirected[1:-1:2])))
    del undirected
    directed = np.sort(a * V + b)
    consistent = not bool(np.any(directed[1:] == directed[:-1]))
    return watertight, consistent


def _refutes_convexity(v: np.ndarray, f: np.ndarray, lowest: int = 4, faces: int = 32,
                       depth: float = 1e-3) -> bool:
    """True where some vertex stands above the plane of a face at one of the ``lowest``
    vertices nearest the centroid (at most ``faces`` of them) by ≥ ``depth`` × the mesh's scale.
    A closed convex mesh has every vertex on or below every face's plane, so this proves the
    mesh non-convex; ``depth`` (a dent 1/1000 of the body's size, 3.5 km on the Moon) is far
    above rounding, so a convex mesh stored in float32 with sliver faces (4.7e-5 × its scale
    above a sliver's plane) is not refuted. A cratered or DEM Moon is (its
    lowest faces lie 7e-3 to 3e-2 × its scale below the terrain around them). False proves
    nothing: :func:`is_convex` then runs the full edge test. Memory: (CHECK_BLOCK, ``faces``)."""
    scale = float(np.linalg.norm(np.ptp(v, axis=0)))
    r2 = np.einsum("ij,ij->i", v - v.mean(0), v - v.mean(0))
    low = np.argpartition(r2, min(lowest, len(v) - 1))[:lowest]
    sel = np.flatnonzero(np.isin(f, low).any(1))[:faces]  # (a pole may carry hundreds of faces)
    tri = v[f[sel]]
    nrm = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(nrm, axis=1)
    ok = length > 0
    nrm, tri = nrm[ok] / length[ok, None], tri[ok]
    off = np.einsum("ij,ij->i", tri[:, 0], nrm)
    for b in _face_blocks(len(v)):
        if ((v[b] @ nrm.T) - off).max(initial=-np.inf) >= depth * scale:
            return True
    return False

def is_convex(vertices: np.ndarray, faces: np.ndarray, checked: bool = False) -> bool:
    """trimesh's convexity test (``Trimesh.is_convex``) without its caches: a closed mesh is
    convex when, across every edge, the far vertex of one face lies on or below the other
    face's plane (projection < 1e-5 × the mesh's scale, trimesh's ``tol.planar``).

    On sorted undirected edge keys, as :func:`edge_checks`; ~0.5 GB on a 5 M-facet mesh where
    trimesh's face adjacency takes ~3 GB; the two agree on good and broken meshes.
    ``checked``: the mesh already passed :func:`validate_mesh` (closed, one body), whose edge
    passes are then not run again.

    First a quick refutation (:func:`_refutes_convexity`): the faces at the vertices nearest the
    centre (a crater floor, a valley) tested against every vertex, a proof of non-convexity
    where a vertex stands well above (1e-3 × the scale) one of their planes; it spares a cratered
    or DEM Moon the edge sort (1.3 s of a 1.3 M-facet load)."""
    v = np.asarray(vertices, dtype=float)
    f = np.asarray(faces, dtype=np.int64)
    if len(f) and _refutes_convexity(v, f):
        return False
    if not checked and (not edge_checks(f, len(v))[0] or body_count(f, len(v)) != 1):
        return False
    a = f.reshape(-1)
    b = f[:, [1, 2, 0]].reshape(-1)
    order = np.argsort(np.minimum(a, b) * np.int64(len(v)) + np.maximum(a, b), kind="stable")
    del a, b
    c1, c2 = order[0::2], order[1::2]  # the two face corners that start each shared edge
    del order
    scale = float(np.linalg.norm(np.ptp(v, axis=0)))
    for blk in _face_blocks(len(c1)):
        f1, e2 = c1[blk] // 3, c2[blk]
        far = f[e2 // 3, (e2 % 3 + 2) % 3]  # the vertex of the other face off the edge
        tri = v[f[f1]]
        n1 = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        n1 /= np.linalg.norm(n1, axis=1, keepdims=True)
        if np.einsum("ij,ij->i", v[far] - tri[:, 0], n1).max() >= 1e-5 * scale:
            return False
    return True


def volume_and_centroid(vertices: np.ndarray, faces: np.ndarray) -> tuple[float, np.ndarray]:
    """Enclosed (signed) volume and centre of mass of a closed, uniformly dense mesh: the
    divergence theorem as a sum of tetrahedra (origin, face), in blocks of faces."""
    vol, moment = 0.0, np.zeros(3)
    for blk in _face_blocks(len(faces)):
        t = vertices[faces[blk]]
        v6 = np.einsum("ij,ij->i", t[:, 0], np.cross(t[:, 1], t[:, 2]))  # 6 × tetra volume
        vol += float(v6.sum()) / 6.0
        moment += (v6[:, None] * t.sum(axis=1)).sum(axis=0) / 24.0  # tetra centroid = Σv/4
    return vol, (moment / vol if vol != 0 else np.zeros(3))


def body_count(faces: np.ndarray, n_vertices: int) -> int:
    """Connected parts of a watertight mesh, faces joined through shared *edges*: two closed
    surfaces that touch at a single vertex are two bodies (trimesh, joining through vertices,
    counts one; such a pinched pair is not one closed surface, and its convexity test would
    pass). Faces of a mesh that is not watertight count through every shared edge."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    f = np.asarray(faces, dtype=np.int64)
    a = f.reshape(-1)
    b = f[:, [1, 2, 0]].reshape(-1)
    key = np.minimum(a, b) * np.int64(n_vertices) + np.maximum(a, b)
    del a, b
    order = np.argsort(key, kind="stable")
    same = np.flatnonzero(key[order][1:] == key[order][:-1])  # consecutive corners on one edge
    del key
    f1, f2 = (order[same] // 3).astype(np.int32), (order[same + 1] // 3).astype(np.int32)
    del order, same
    F = len(f)
    g = coo_matrix((np.ones(len(f1), dtype=np.int8), (f1, f2)), shape=(F, F))
    return int(connected_components(g, directed=False, return_labels=False))


def validate_mesh(mesh: trimesh.Trimesh, name: str = "mesh") -> trimesh.Trimesh:
    """Check that ``mesh`` can stand for a body; raise :class:`MeshError` naming the defect.

    Same criteria as trimesh's ``is_watertight``, ``is_winding_consistent`` and ``volume``,
    computed without filling the mesh's caches (:func:`edge_checks`)."""
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise MeshError(f"{name}: not a triangle mesh with faces")
    _check_arrays(np.asarray(mesh.vertices, dtype=float), np.asarray(mesh.faces), name)
    return mesh


#: the largest vertex coordinate a mesh may have [its units; metres after conversion]: 1e15 m is
#: 7000 au, far beyond any body, and far below where squares overflow float64
MAX_VERTEX_M = 1e15


def _check_extent(v: np.ndarray, name: str) -> None:
    """Refuse vertices [m] farther than :data:`MAX_VERTEX_M` from the origin (squares of such
    coordinates overflow float64 in the checks and in trimesh's vertex merge)."""
    extent = float(np.max(np.abs(v))) if v.size else 0.0
    if extent > MAX_VERTEX_M:
        raise MeshError(f"{name}: a vertex lies {extent:.3g} m from the origin; no body is larger than "
                        f"{MAX_VERTEX_M:.0e} m (check the mesh units)")


def _check_arrays(v: np.ndarray, f: np.ndarray, name: str, edges: tuple | None = None):
    """:func:`validate_mesh` on arrays; ``edges``: :func:`edge_checks` already computed.
    Returns the enclosed volume and the centre of mass (:func:`volume_and_centroid`)."""
    if not np.all(np.isfinite(v)):
        raise MeshError(f"{name}: vertices contain NaN or inf")
    _check_extent(v, name)
    areas = face_areas(v, f)
    scale = float(np.max(np.ptp(v, axis=0)))
    bad = np.flatnonzero(areas <= 1e-12 * scale**2)
    if bad.size:
        raise MeshError(f"{name}: {bad.size} degenerate (zero-area) faces, first is face {bad[0]}")
    watertight, consistent = edge_checks(f, len(v)) if edges is None else edges
    if not watertight:
        raise MeshError(f"{name}: not watertight (has holes or open edges)")
    if not consistent:
        raise MeshError(f"{name}: inconsistent face winding")
    vol, com = volume_and_centroid(v, f)
    if vol <= 0:
        raise MeshError(f"{name}: normals point inward (negative enclosed volume)")
    return vol, com


#: ``--mesh-units``: what one unit of a user mesh's coordinates is.
#: A mesh's mean vertex distance from the body's centre must lie within this factor range of
#: the body's nominal radius (the 2 R cube reaches √3 R; a cratered or triaxial body ~1 R).
PLAUSIBLE_SIZE = (0.3, 3.0)
#: A mesh's centre of mass may sit this fraction of its mean radius from the origin (the real
#: Moon's centre of figure is ~2 km, 1e-3 R, from its centre of mass; 2 % is 35 km on the Moon).
CENTRE_TOLERANCE = 0.02


def units_factor(units: str, nominal_radius: float) -> float:
    """Metres per mesh unit for ``--mesh-units`` (``radius``: the body's nominal radius)."""
    if units not in MESH_UNITS:
        raise MeshError(str(unknown_choice("mesh units", units, MESH_UNITS)))
    return {"m": 1.0, "km": 1e3, "radius": float(nominal_radius)}[units]


#: mesh formats read (plain files only: trimesh's compressed and archive loaders, .bz2 .gz .zip
#: .tar ..., would decompress whatever they are given before anything could be checked)
MESH_SUFFIXES = (".ply", ".obj", ".stl", ".off", ".glb", ".gltf")
#: the largest mesh file read [bytes]: 2 GiB holds a 40 M-facet binary PLY
MAX_MESH_FILE_BYTES = 2 << 30


def check_mesh_file(p: Path, name: str) -> None:
    """Refuse, in one line, what must not be handed to a loader: a missing path, a FIFO,
    device or directory (a read would block or never end), a compressed or unknown format, an
    oversized file, and a .gltf whose buffers are not plain files beside it."""
    import stat
    try:
        st = p.stat()
    except OSError:
        raise MeshError(f"{name}: file not found") from None
    if not stat.S_ISREG(st.st_mode):
        raise MeshError(f"{name}: not a regular file (a directory, FIFO or device)")
    if p.suffix.lower() not in MESH_SUFFIXES:
        raise MeshError(f"{name}: unsupported mesh format {p.suffix or '(no suffix)'!r}: use one of "
                        f"{', '.join(MESH_SUFFIXES)} (compressed files and archives are not read)")
    if st.st_size > MAX_MESH_FILE_BYTES:
        raise MeshError(f"{name}: {st.st_size / 2**30:.1f} GiB is larger than the {MAX_MESH_FILE_BYTES >> 30} GiB "
                        f"a mesh file may have")
    if p.suffix.lower() == ".gltf":
        try:
            doc = json.loads(p.read_text(encoding="utf-8"))
        except (OSError, ValueError, UnicodeDecodeError, RecursionError) as exc:
            raise MeshError(f"{name}: unreadable glTF ({type(exc).__name__})") from None
        for buf in doc.get("buffers", []) if isinstance(doc, dict) else []:
            uri = buf.get("uri", "") if isinstance(buf, dict) else ""
            if uri and not uri.startswith("data:"):
                ref = (p.parent / uri)
                try:
                    ok = stat.S_ISREG(ref.stat().st_mode) and ref.stat().st_size <= MAX_MESH_FILE_BYTES
                except OSError:
                    ok = False
                if not ok:
                    raise MeshError(f"{name}: glTF buffer {uri!r} is not a readable regular file beside it")


def load_user_mesh(path, body: str = "moon", units: str = "m", nominal_radius: float | None = None,
                   name: str | None = None) -> trimesh.Trimesh:
    """Load a closed user mesh for ``body`` with trimesh and return it in metres.

    Vertices are taken as given: body-fixed frame, centred on the body's centre, in ``units``
    (``m``, ``km`` or ``radius`` = multiples of the body's nominal radius). Nothing is moved
    or rescaled beyond that unit conversion. A mesh whose size is implausible for the body
    (kilometres read as metres, say) or whose centre is far from the origin is refused with
    one line that names the likely unit. Any format trimesh reads: PLY, OBJ, STL, OFF, GLB/GLTF.
    """
    p = Path(path)
    name = name or f"{body} mesh {path}"
    if nominal_radius is None:
        nominal_radius = NOMINAL_RADII[body]
    factor = units_factor(units, nominal_radius)
    check_mesh_file(p, name)
    import warnings
    try:
        with warnings.catch_warnings(), np.errstate(all="ignore"):  # the checks below speak for a bad file
            warnings.simplefilter("ignore")
            mesh = trimesh.load(p, force="mesh", process=False)
    except Exception as exc:  # trimesh raises many types for unreadable files
        raise MeshError(f"{name}: unreadable mesh ({type(exc).__name__}: {exc})") from None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise MeshError(f"{name}: not a triangle mesh with faces")
    if not np.all(np.isfinite(mesh.vertices)):
        raise MeshError(f"{name}: vertices contain NaN or inf")
    _check_extent(np.asarray(mesh.vertices) * factor, name)  # before any merge: squares would overflow
    v, f = np.asarray(mesh.vertices, dtype=float), np.asarray(mesh.faces, dtype=np.int64)
    if f.min() < 0 or f.max() >= len(v):
        bad = int(f.min()) if f.min() < 0 else int(f.max())
        raise MeshError(f"{name}: face index {bad} out of range for {len(v)} vertices")
    # A file whose faces already close up (PLY, OFF, most OBJ) is used as read. Otherwise merge
    # duplicated vertices (STL stores three per face; an OBJ may split a seam) so watertightness
    # can be judged; positions are not changed. (Merging a closed mesh could only join distinct
    # vertices at one place, where the surface touches itself: a pinch between two parts is
    # refused either way; a body touching itself keeps its two vertex copies, each with its
    # own smooth normal. At 5 M facets the merge is 2.4 s.)
    edges = edge_checks(f, len(v))
    if not all(edges) or np.bincount(f.reshape(-1), minlength=len(v)).min(initial=1) == 0:
        mesh = trimesh.Trimesh(mesh.vertices, mesh.faces, process=True, validate=False)
        mesh.remove_unreferenced_vertices()
        v, f = np.asarray(mesh.vertices, dtype=float), np.asarray(mesh.faces, dtype=np.int64)
        edges = None
    com = _check_arrays(v, f, name, edges)[1] * factor
    parts = body_count(f, len(v))
    if parts != 1:
        raise MeshError(f"{name}: {parts} disconnected parts (joined at most at single vertices); a body must be "
                        f"one closed surface")
    v = v * factor
    radius_about_com = float(np.mean(np.linalg.norm(v - com, axis=1)))
    off = float(np.linalg.norm(com))
    if off > CENTRE_TOLERANCE * radius_about_com:
        raise MeshError(f"{name}: centre of mass {off:.4g} m from the origin (> {CENTRE_TOLERANCE:.0%} of its "
                        f"{radius_about_com:.4g} m radius); vertices must be centred on the {body}'s centre "
                        f"(body-fixed frame)")
    size = float(np.mean(np.linalg.norm(v, axis=1)))  # about the origin, as the tracer will place it
    lo, hi = PLAUSIBLE_SIZE
    if not (lo * nominal_radius <= size <= hi * nominal_radius):
        guess = [u for u in MESH_UNITS
                 if lo * nominal_radius <= size / factor * units_factor(u, nominal_radius) <= hi * nominal_radius]
        words = {"km": "kilometres", "m": "metres", "radius": "body radii"}
        hint = f"; the vertices look like {words[guess[0]]}: pass --mesh-units {guess[0]}" if guess else ""
        raise MeshError(f"{name}: mean vertex radius {size:.4g} m (as --mesh-units {units}) is implausible for the "
                        f"{body} (nominal radius {nominal_radius:.4g} m){hint}")
    out = trimesh.Trimesh(v, f, process=False)
    out.metadata["lunarviz_source"] = str(path)
    out.metadata["lunarviz_validated"] = True  # closed, one body: is_convex need not check again
    return out


def analytic_sphere(body: str, level: int, radius: float) -> trimesh.Trimesh:
    """The icosphere of ``body`` at ``level`` in metres, tagged as an analytic sphere.

    The tag (``metadata["lunarviz_analytic"]``) is what allows the exact-sphere fast path
    (shading on the exact sphere); it is set only here and in
    :func:`lunarviz.bodies.sphere_mesh.packaged_sphere` (the packaged levels, read without
    trimesh), for meshes generated as spheres, and never inferred from a user's vertices.
    """
    m = body_mesh(body, level)
    out = trimesh.Trimesh(np.asarray(m.vertices) * radius, m.faces, process=False)
    out.metadata["lunarviz_analytic"] = {"shape": "sphere", "radius": float(radius)}
    return out


def write_packaged_meshes(levels: dict[str, list[int]]) -> Path:
    """(Re)write the packaged meshes and their manifest (the documentation's *Bodies as meshes* page)."""
    MESH_DIR.mkdir(exist_ok=True)
    entries = []
    for body, lv in levels.items():
        for level in lv:
            m = unit_icosphere(level)
            f = MESH_DIR / f"{body}_L{level}.ply"
            f.write_bytes(trimesh.exchange.ply.export_ply(m, encoding="binary"))
            entries.append({"body": body, "level": level, "facets": int(len(m.faces)),
                            "radius": 1.0, "file": f.name, "sha256": _sha256(f)})
    out = MESH_DIR / "manifest.json"
    out.write_text(json.dumps({"units": "unit radius; scaled to the body radius at load",
                               "meshes": entries}, indent=2) + "\n")
    return out
