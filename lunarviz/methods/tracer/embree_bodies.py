"""A body (mesh at real scale) traced by Embree in its own centred frame.

Embree works in float32: one float32 step is 0.125 m at 1.7e6 m, 32 m at 3.8e8 m and 16 km at
1.5e11 m (paper notes, "Embree at real scale"). So every body is a separate Embree scene with vertices relative to its
own centre; a ray given in float64 world coordinates is translated into that frame in float64,
and its origin is advanced (in float64) to just outside the body's bounding sphere before the
float32 cast, so Embree only ever sees numbers of the body's size. Rays that miss the bounding
sphere are answered without calling Embree. Hit points are recomputed in float64 from the
primitive's plane.

One ``EmbreeScene.run`` call is single-threaded but releases the GIL, so batches are split
over a thread pool (``threads``).
"""

from __future__ import annotations

import os
import threading
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np
import trimesh
from embreex import rtcore_scene
from embreex.mesh_construction import TriangleMesh

from lunarviz.bodies.sphere_mesh import unit_sphere_arrays
from lunarviz.caches import BoundedCache, mesh_digest
from lunarviz.geometry.subdivision import sub_barycentric
from lunarviz.methods.tracer.ray_kernels import occluder_rays, ray_batch32, ray_starts, sphere_refine

#: Embree's coordinate type.
EMBREE_DTYPE = np.float32
#: Ray origins start this far (× body radius) outside the bounding sphere.
ENTRY_MARGIN = 1e-3
#: the icosphere level of :meth:`EmbreeBody.hit_scene`: 0, the icosahedron (20 facets; Embree
#: searches it ~2.5x faster per ray than the packaged level-6 sphere's 81,920 and ~1.3x faster
#: than level 3's 1,280: 167,000 rays toward the Earth, scripts/hit_scene_speed.py)
HIT_SCENE_LEVEL = 0
#: how far [× radius] a circumscribing polyhedron's facet planes are pushed out beyond the sphere:
#: float32 vertices move them by up to ~1e-7 of it (the icosahedron's 0.11 m inside the Earth's
#: sphere and 1.6 m inside the Sun's at 1e-9), so every plane stays outside after rounding
CIRCUMSCRIBE_MARGIN = 1e-6
#: Batch size of one Embree call (bounds memory for any ray count).
BATCH = 1 << 18


def default_threads() -> int:
    return max(1, min(2, os.cpu_count() or 1))


_SERIAL = threading.local()
_SCENE_LOCK = threading.Lock()


@contextmanager
def serial_embree():
    """Within this block (per thread), Embree batches are not split over the body's threads:
    the caller already runs several chunks on the cores (TraceScene.deterministic.transport)."""
    _SERIAL.on = True
    try:
        yield
    finally:
        _SERIAL.on = False


@dataclass
class Hits:
    """Result of :meth:`EmbreeBody.intersect` for n rays."""

    hit: np.ndarray  # (n,) bool
    prim: np.ndarray  # (n,) int, -1 where no hit
    t: np.ndarray  # (n,) float64 distance along the ray [m], inf where no hit
    point: np.ndarray  # (n, 3) float64 world hit point (NaN where no hit)


#: Interpolated shading normals never cross an edge whose dihedral angle exceeds this [deg]:
#: across a sharper edge the facets keep their own normals (a cube stays a cube). 30° passes
#: the ~1° facet-to-facet turn of any usable body mesh and stops at crater rims and box edges.
CREASE_DEG = 30.0
#: Shading modes a body resolves ``TraceSettings.shading`` to (see :meth:`EmbreeBody.mode`).
MODES = ("exact", "flat", "interp")


class EmbreeBody:
    """A closed mesh (vertices in metres about the body's centre, times ``scale``) placed at
    ``centre`` [m].

    ``mesh.metadata["lunarviz_analytic"]`` (set only by :func:`lunarviz.bodies.meshes.analytic_sphere`)
    marks a mesh generated as a sphere: only such a body may be shaded on the exact sphere
    (the documented fast path). Every other mesh is shaded on its facets.
    """

    def __init__(self, mesh, centre, threads: int | None = None, scale: float = 1.0,
                 rotation: np.ndarray | None = None):
        self.centre = np.asarray(centre, dtype=float)
        #: body-to-scene rotation (``None``: mesh axes are scene axes); vertices below are turned
        self.rotation = None if rotation is None else np.asarray(rotation, dtype=float)
        geo = _body_geometry(mesh, float(scale), self.rotation)
        self.geometry = geo
        self.vertices, self.faces = geo["vertices"], geo["faces"]  # body frame [m]
        self.bound, self.areas, self.normals = geo["bound"], geo["areas"], geo["normals"]
        self.centroids_local = geo["centroids_local"]
        self.convex = geo["convex"]
        #: generated as an analytic sphere (explicit tag, never a tolerance test)
        self.is_sphere = geo["sphere_radius"] is not None
        #: the exact sphere's radius for analytic spheres, else the mean vertex distance [m]
        self.radius = geo["sphere_radius"] if self.is_sphere else geo["mean_radius"]
        self.threads = threads or default_threads()
        #: shading for this body regardless of the scene-wide setting (``TraceSettings.body_shading``)
        self.shading_override: str | None = None
        #: when a list, every float32 batch sent to Embree is appended (benchmarks only)
        self.recorder: list | None = None

    @property
    def _scene(self):
        """The mesh's Embree scene, built on first use (once per geometry): a dated sweep turns
        the Moon at every time, and the lune rule on its exact sphere never traces its mesh
        (~20 ms a date on a level-6 Moon)."""
        geo = self.geometry
        if geo["scene"] is None:
            with _SCENE_LOCK:  # (chunks are traced on several threads)
                if geo["scene"] is None:
                    scene = rtcore_scene.EmbreeScene()
                    TriangleMesh(scene=scene, vertices=geo["vertices"].astype(EMBREE_DTYPE),
                                 indices=geo["faces"].astype(np.int32))
                    geo["scene"] = scene
        return geo["scene"]

    def mode(self, shading: str) -> str:
        """Resolve ``auto|flat|smooth`` for this body to ``exact|flat|interp``.

        ``auto`` (default): the exact sphere for analytic spheres, the facets otherwise.
        ``smooth``: the exact sphere for analytic spheres, crease-limited interpolated normals
        (:data:`CREASE_DEG`) otherwise. ``flat``: the facets.
        """
        shading = self.shading_override or shading
        if shading == "flat":
            return "flat"
        if self.is_sphere:
            return "exact"
        return "interp" if shading == "smooth" else "flat"

    @property
    def corner_normals(self) -> np.ndarray:
        """(F, 3, 3) unit shading normals at each face's corners, crease-limited."""
        geo = self.geometry
        if geo.get("corner_normals") is None:
            geo["corner_normals"] = _crease_corner_normals(self.faces, self.normals, self.areas, len(self.vertices))
        return geo["corner_normals"]

    @property
    def centroid_normals(self) -> np.ndarray:
        """Unit interpolated normals at the centroids (crease-limited)."""
        cn = self.corner_normals.sum(axis=1)
        return cn / np.linalg.norm(cn, axis=1, keepdims=True)

    def facet_points(self, shading: str) -> tuple[np.ndarray, np.ndarray]:
        """One world point and unit normal per facet for ``shading``: the centroid, or its
        projection on the exact sphere for the exact-sphere path."""
        n = self.normals_for(shading)
        if self.mode(shading) == "exact":
            return self.centre + self.radius * n, n
        return self.centroids, n

    def normals_for(self, shading: str) -> np.ndarray:
        """Per-facet normals at the centroids for ``shading`` (flat or interpolated/exact)."""
        m = self.mode(shading)
        if m == "flat":
            return self.normals
        if m == "exact":
            return self.centroids_local / np.linalg.norm(self.centroids_local, axis=1, keepdims=True)
        return self.centroid_normals

    def shading_normals(self, prim, points) -> np.ndarray:
        """Interpolated vertex normals at world ``points`` on primitives ``prim`` (unit).

        Barycentric interpolation of the crease-limited corner normals (Phong shading): the
        mesh decides visibility, the smooth surface it tessellates decides the local normal.
        """
        tri = self.vertices[self.faces[prim]]
        p = np.asarray(points, dtype=float) - self.centre
        v0, v1, v2 = tri[:, 0], tri[:, 1], tri[:, 2]
        e1, e2, ep = v1 - v0, v2 - v0, p - v0
        d11, d12, d22 = (np.einsum("ij,ij->i", a, b) for a, b in ((e1, e1), (e1, e2), (e2, e2)))
        dp1, dp2 = np.einsum("ij,ij->i", ep, e1), np.einsum("ij,ij->i", ep, e2)
        den = d11 * d22 - d12 * d12
        b1 = (d22 * dp1 - d12 * dp2) / den
        b2 = (d11 * dp2 - d12 * dp1) / den
        b0 = 1.0 - b1 - b2
        vn = self.corner_normals[prim]
        n = b0[:, None] * vn[:, 0] + b1[:, None] * vn[:, 1] + b2[:, None] * vn[:, 2]
        return n / np.linalg.norm(n, axis=1, keepdims=True)

    def surface_samples(self, faces, shading: str, sub: int = 1):
        """Quadrature samples on ``faces``; each face split into ``sub²`` equal sub-triangles.

        Returns world points (n, 3), unit normals (n, 3), areas (n,) [m²] and the owning face
        (n,). By :meth:`mode`:

        * ``flat``: one sample at each sub-triangle's centroid, the facet normal, flat areas.
          On a flat facet the integrand varies only with the distance and direction to the
          source and detector (relative change ~R/D ≈ 5e-3 across the body), so the centroid
          is exact to second order in that.
        * ``exact`` (analytic spheres): Strang & Fix's 3-point degree-2 rule in each
          sub-triangle, its points projected on the exact sphere, weighted by the projection's
          Jacobian and normalised to the spherical triangle's area (spherical excess, Van
          Oosterom & Strackee 1983, so the areas sum to 4πR² exactly). A centroid rule here
          has an O(h²) bias of the opposite sign to the terminator's, and refinement then
          exposes it (refinement must never make a result worse).
        * ``interp``: the same 3-point rule on the flat facets with interpolated normals.
        """
        faces = np.asarray(faces, dtype=np.int64)
        mode = self.mode(shading)
        tri = self.vertices[self.faces[faces]]  # (F, 3, 3) body frame
        if mode == "flat":
            cen_b, _ = sub_barycentric(sub)
            ns = len(cen_b)
            pts = np.einsum("sk,fkj->fsj", cen_b, tri).reshape(-1, 3)
            owner = np.repeat(faces, ns)
            area = np.repeat(self.areas[faces] / ns, ns)
            return pts + self.centre, np.repeat(self.normals[faces], ns, axis=0), area, owner
        _, tri_b = sub_barycentric(sub)
        nsub = len(tri_b)
        pts_b = np.einsum("pv,svk->spk", _STRANG_FIX3, tri_b).reshape(-1, 3)  # (nsub·3, 3)
        owner = np.repeat(faces, 3 * nsub)
        pts = np.einsum("sk,fkj->fsj", pts_b, tri).reshape(-1, 3)
        if mode == "exact":
            corners = np.einsum("svk,fkj->fsvj", tri_b, tri).reshape(-1, 3, 3)
            corners /= np.linalg.norm(corners, axis=2, keepdims=True)
            a, b, c = corners[:, 0], corners[:, 1], corners[:, 2]
            num = np.abs(np.einsum("ij,ij->i", a, np.cross(b, c)))
            den = 1.0 + np.einsum("ij,ij->i", a, b) + np.einsum("ij,ij->i", b, c) + np.einsum("ij,ij->i", c, a)
            sph_area = 2.0 * np.arctan2(num, den) * self.radius**2  # (F·nsub,)
            # Jacobian of the radial projection flat → sphere at each point: (n_f·x)/|x|³
            nf = np.repeat(self.normals[faces], 3 * nsub, axis=0)
            r = np.linalg.norm(pts, axis=1)
            jac = np.abs(np.einsum("ij,ij->i", nf, pts)) / r**3
            jac = jac.reshape(-1, 3)
            area = (sph_area[:, None] * jac / jac.sum(axis=1, keepdims=True)).reshape(-1)
            nrm = pts / r[:, None]
            return self.centre + self.radius * nrm, nrm, area, owner
        area = np.repeat(self.areas[faces] / (3 * nsub), 3 * nsub)
        nrm = self.shading_normals(owner, pts + self.centre)
        return pts + self.centre, nrm, area, owner

    def outer_scene(self):
        """Embree scene of the mesh scaled to circumscribe its sphere (every facet plane at
        distance ≥ R from the centre, after float32 rounding: :data:`CIRCUMSCRIBE_MARGIN`), so every
        ray that meets the sphere meets this mesh. Built once per mesh and radius (cached with the body's geometry)."""
        geo = self.geometry
        if geo.get("outer") is None:
            plane_dist = np.einsum("ij,ij->i", self.normals, self.vertices[self.faces[:, 0]])
            k = self.radius / float(plane_dist.min()) * (1.0 + CIRCUMSCRIBE_MARGIN)
            outer = rtcore_scene.EmbreeScene()
            TriangleMesh(scene=outer, vertices=(self.vertices * k).astype(EMBREE_DTYPE),
                         indices=self.faces.astype(np.int32))
            geo["outer"], geo["outer_bound"] = outer, self.bound * k
        self.outer_bound = geo["outer_bound"]
        return geo["outer"]

    def hit_scene(self):
        """``(scene, bound)``: an icosphere of level :data:`HIT_SCENE_LEVEL` circumscribing this
        body's exact sphere (every facet plane at distance ≥ R), for rays whose facet is not
        needed, only whether and where they meet the sphere (a uniform source summed into rows):
        every ray that meets the sphere meets it, and the hit is refined onto the exact sphere as
        with :meth:`outer_scene`, whose 20·4⁶ facets Embree takes ~2x longer to search. Exact
        spheres only (a mesh's own facets are its shape). Built once per radius from the unit
        icosphere of that level (:func:`_unit_icosphere`); ``None`` where it is not packaged intact
        (then :meth:`outer_scene`)."""
        if not self.is_sphere:
            raise ValueError("a coarse hit scene stands for an exact sphere only")
        geo = self.geometry
        if "hit_scene" not in geo:
            unit = _unit_icosphere(HIT_SCENE_LEVEL)
            built = None if unit is None else _circumscribing_scene(*unit, self.radius)
            geo["hit_scene"] = None if built is None else built[:3]
            geo["hit_mesh"] = None if built is None else built[3:]  # (its float32 vertices and faces: a replay's)
        return geo["hit_scene"]

    def sphere_hits(self, origins, dirs, refine_from=None) -> Hits:
        """First hits on the exact sphere this mesh tessellates.

        Embree traces every ray against the circumscribing copy of the mesh (which facet the
        ray meets); the hit point is then refined in float64 onto the exact sphere. Seen from
        the Moon, rays to the outer ~0.5° of the Earth's sphere pass *outside* an inscribed
        level-6 mesh, and a crescent Earth's light lives exactly there: the circumscribed
        copy keeps them (docs/user_guide/meshes.md).

        ``refine_from`` (n, 3): the points the rays' directions were aimed from, where the
        ``origins`` are those points lifted off a surface (against self-intersection). The
        exact hit is then found from them, not from the lifted origins: a lift of 0.17 m across
        a ray grazing the Earth's limb moves its hit by ~1.5 km (√(2Rδ)) or drops it, an error
        of up to 2e-5 on a crescent Earth's light that no rule order removes.
        """
        scene = self.outer_scene()
        o, d, t0, live = self._prepare(origins, dirs, None, bound=self.outer_bound)
        n = len(o)
        prim = np.full(n, -1, dtype=np.int64)
        idx = np.flatnonzero(live)
        if idx.size:
            prim[idx] = self.run_rays(*ray_batch32(o, d, t0, idx), "INTERSECT", scene=scene)
        if refine_from is not None:
            o = np.asarray(refine_from, dtype=float) - self.centre
        prim, tt, point = sphere_refine(o, d, self.radius, prim, self.centre)
        return Hits(prim >= 0, prim, tt, point)

    def shade_hits(self, hits: "Hits", shading: str):
        """Rows with a hit, their shading points and unit normals."""
        h = np.flatnonzero(hits.hit)
        p, y = hits.prim[h], hits.point[h]
        mode = self.mode(shading)
        if mode == "flat":
            return h, y, self.normals[p]
        if mode == "exact":
            return h, y, (y - self.centre) / self.radius
        return h, y, self.shading_normals(p, y)

    @property
    def centroids(self) -> np.ndarray:
        """Facet centroids in world coordinates [m] (float64)."""
        return self.centroids_local + self.centre

    @property
    def n_faces(self) -> int:
        return len(self.faces)

    # ------------------------------------------------------------------------------------
    def _prepare(self, origins, dirs, tmax, bound=None):
        """Body-frame float64 origins advanced to the bounding sphere (radius ``bound``, the
        mesh's by default); culled rays flagged."""
        d = np.asarray(dirs, dtype=float)
        R = (self.bound if bound is None else bound) * (1.0 + ENTRY_MARGIN)
        o, t0, live = ray_starts(origins, d, self.centre, R, tmax)
        return o, d, t0, live

    def run_rays(self, o32, d32, query, dists=None, scene=None):
        """Embree ``run`` on float32 rays against ``scene`` (the body's mesh by default),
        batched and split over the thread pool."""
        scene = self._scene if scene is None else scene
        n = len(o32)
        if n == 0:
            return np.empty(0, np.int32)
        chunks = [slice(a, min(n, a + BATCH)) for a in range(0, n, BATCH)]
        if len(chunks) == 1 and n > 4096 and self.threads > 1 and not getattr(_SERIAL, "on", False):
            step = -(-n // self.threads)
            chunks = [slice(a, min(n, a + step)) for a in range(0, n, step)]

        if self.recorder is not None:
            self.recorder.append((scene, query, o32, d32, dists))

        def one(sl):
            kw = {} if dists is None else {"dists": dists[sl]}
            return scene.run(o32[sl], d32[sl], query=query, **kw)

        if len(chunks) == 1 or self.threads == 1 or getattr(_SERIAL, "on", False):
            parts = [one(s) for s in chunks]
        else:
            with ThreadPoolExecutor(self.threads) as ex:
                parts = list(ex.map(one, chunks))
        return np.concatenate(parts)

    def intersect(self, origins, dirs, tmax=None) -> Hits:
        """First hit of rays (float64 world origins (n,3), unit directions (n,3))."""
        o, d, t0, live = self._prepare(origins, dirs, tmax)
        n = len(o)
        prim = np.full(n, -1, dtype=np.int64)
        idx = np.flatnonzero(live)
        if idx.size:
            prim[idx] = self.run_rays(*ray_batch32(o, d, t0, idx), "INTERSECT")
        hit = prim >= 0
        t = np.full(n, np.inf)
        point = np.full((n, 3), np.nan)
        if hit.any():
            h = np.flatnonzero(hit)
            p = prim[h]
            nrm = self.normals[p]
            v0 = self.vertices[self.faces[p, 0]]
            # float64 re-intersection with the hit primitive's plane
            th = np.einsum("ij,ij->i", v0 - o[h], nrm) / np.einsum("ij,ij->i", d[h], nrm)
            if tmax is not None:
                keep = th < np.broadcast_to(tmax, (n,))[h]
                hit[h[~keep]] = False
                prim[h[~keep]] = -1
                h, th = h[keep], th[keep]
            t[h] = th
            point[h] = o[h] + th[:, None] * d[h] + self.centre
        return Hits(hit, prim, t, point)

    def occluded(self, origins, dirs, tmax=None) -> np.ndarray:
        """True where the segment [origin, origin + tmax·dir) hits the body (any hit)."""
        o, d, t0, live = self._prepare(origins, dirs, tmax)
        n = len(o)
        out = np.zeros(n, dtype=bool)
        idx = np.flatnonzero(live)
        if idx.size:
            dists = None
            if tmax is not None:
                tm = np.broadcast_to(np.asarray(tmax, dtype=float), (n,))[idx] - t0[idx]
                dists = np.clip(tm, 0.0, np.finfo(np.float32).max).astype(EMBREE_DTYPE)
            res = self.run_rays(*ray_batch32(o, d, t0, idx), "OCCLUDED", dists)
            out[idx] = res != -1
        return out

    def occluded_beams(self, rays, tmax, mask) -> np.ndarray:
        """:meth:`occluded` for the live beams of ``rays`` (a :class:`lunarviz.methods.tracer.ray_kernels.BeamRays`)
        in ``mask``, from their origins up to ``tmax``; False outside ``mask``. The same rays,
        gathered and culled in one compiled pass (numba only)."""
        rows, o32, d32, dists = occluder_rays(rays, tmax, mask, self.centre, self.bound * (1.0 + ENTRY_MARGIN))
        out = np.zeros(len(mask), dtype=bool)
        if rows.size:
            out[rows] = self.run_rays(o32, d32, "OCCLUDED", dists) != -1
        return out


#: body geometries kept (the least recently used dropped first): a θ sweep needs three entries
#: (one per body), a dated sweep turns the Moon at every time and never reuses it (the packaged
#: Earth keeps one orientation unless a map turns it too; the Sun, used at every date, stays; a
#: turned body's unturned entry, from which each turn is made, is read at every date and stays);
#: each Earth at level 6 holds ~100 MB with its Embree scenes (16 entries would hold 3 GB in a
#: dated sweep)
GEOMETRY_CACHE_SIZE = 6
_GEOMETRY_CACHE = BoundedCache(GEOMETRY_CACHE_SIZE)


def _unit_icosphere(level: int):
    """Unit vertices and faces of the icosphere of ``level``: the icosahedron for 0 (trimesh's,
    exact to rounding), else the packaged sphere (any body's will do; ``None`` where it is not
    packaged intact)."""
    if level == 0:
        ico = trimesh.creation.icosahedron()
        v = np.asarray(ico.vertices, dtype=float)
        return v / np.linalg.norm(v, axis=1, keepdims=True), np.asarray(ico.faces)
    return unit_sphere_arrays("moon", level)


def _circumscribing_scene(vertices: np.ndarray, faces: np.ndarray, radius: float) -> tuple:
    """``(scene, bound, facets, vertices32, faces32)``: the unit polyhedron ``vertices``, ``faces``
    scaled so that every facet plane lies at ≥ ``radius`` from the centre (it then holds the sphere
    of that radius): its Embree scene, its bounding radius, its number of facets and the arrays
    Embree was given."""
    tri = vertices[faces]
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    k = radius / float(np.abs(np.einsum("ij,ij->i", normals, tri[:, 0])).min()) * (1.0 + CIRCUMSCRIBE_MARGIN)
    v32, f32 = (vertices * k).astype(EMBREE_DTYPE), np.asarray(faces, np.int32)
    scene = rtcore_scene.EmbreeScene()
    TriangleMesh(scene=scene, vertices=v32, indices=f32)
    return scene, float(np.linalg.norm(vertices, axis=1).max()) * k, len(faces), v32, f32


def _body_geometry(mesh, scale: float, rotation: np.ndarray | None = None) -> dict:
    """Body-centred geometry and Embree scene of ``mesh`` (vertices × ``scale`` [m], turned by
    ``rotation`` into scene axes), cached.

    Body-centred frames make them independent of where the body is, so a θ sweep builds each
    scene once per process, not once per phase (a dated sweep turns the Moon, so once per
    time). Keyed by the mesh's content (vertices, faces, analytic tag), the scale and the rotation.
    """
    tag = mesh.metadata.get("lunarviz_analytic") if mesh.metadata else None
    key = (mesh_digest(mesh), repr(tag), float(scale),
           None if rotation is None else rotation.tobytes())
    hit = _GEOMETRY_CACHE.get(key)
    if hit is not None:
        return hit
    if rotation is not None:  # a turn moves the facets, not their sizes: the unturned geometry, turned
        base = _body_geometry(mesh, scale)  # (its scenes and other lazy keys are built afresh for the turn)
        geo = {k: base[k] for k in ("mesh", "body_vertices", "faces", "bound", "areas", "convex", "mean_radius",
                                    "sphere_radius")}
        geo.update({k: base[k] @ rotation.T for k in ("vertices", "normals", "centroids_local")},
                   scene=None, outer=None, corner_normals=None)
        _GEOMETRY_CACHE[key] = geo
        return geo
    vertices = body_vertices = np.asarray(mesh.vertices, dtype=float) * scale
    faces = np.asarray(mesh.faces, dtype=np.int64)
    F = len(faces)
    areas, normals, centroids = np.empty(F), np.empty((F, 3)), np.empty((F, 3))
    for a in range(0, F, 1 << 18):  # in blocks: (F, 3, 3) temporaries are 0.4 GB at 5 M facets
        b = slice(a, min(F, a + (1 << 18)))
        tri = vertices[faces[b]]
        cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        areas[b] = 0.5 * np.linalg.norm(cross, axis=1)
        normals[b] = cross / (2.0 * areas[b, None])
        centroids[b] = tri.mean(axis=1)
    rad = np.linalg.norm(vertices, axis=1)
    sphere_radius = float(tag["radius"]) * scale if tag and tag.get("shape") == "sphere" else None
    convex = bool(tag is not None or _is_convex(mesh))
    # (``body_vertices``: the mesh's own axes, unturned, where its facets' map fields are fitted)
    geo = {"mesh": mesh, "vertices": vertices, "body_vertices": body_vertices, "faces": faces,
           "bound": float(rad.max()), "areas": areas, "normals": normals, "centroids_local": centroids,
           "convex": convex, "mean_radius": float(rad.mean()),
           "sphere_radius": sphere_radius, "scene": None, "outer": None, "corner_normals": None}
    _GEOMETRY_CACHE[key] = geo
    return geo


def _is_convex(mesh) -> bool:
    """Convexity by :func:`lunarviz.bodies.meshes.is_convex` (trimesh's test without its caches,
    which would take ~3 GB on a 5-million-facet mesh and stay alive with the cached mesh)."""
    from lunarviz.bodies.meshes import is_convex
    return is_convex(mesh.vertices, mesh.faces, checked=bool(mesh.metadata.get("lunarviz_validated")))


def _crease_corner_normals(faces, normals, areas, n_vertices, crease_deg: float = CREASE_DEG) -> np.ndarray:
    """Shading normal at every face corner: the area-weighted mean of the normals of the faces
    around that vertex whose normal is within ``crease_deg`` of the face's own (so smoothing
    never crosses a sharp edge). Returns (F, 3, 3)."""
    F = len(faces)
    cos_c = np.cos(np.radians(crease_deg))
    vf = faces.reshape(-1)  # corner -> vertex
    order = np.argsort(vf, kind="stable")
    counts = np.bincount(vf, minlength=n_vertices)
    start = np.concatenate([[0], np.cumsum(counts)[:-1]])
    kmax = int(counts.max())
    out = np.zeros((F * 3, 3))
    corner_face = np.repeat(np.arange(F), 3)
    own = normals[corner_face]
    for k in range(kmax):  # k-th face around each corner's vertex
        has = counts[vf] > k
        idx = np.flatnonzero(has)
        nb = corner_face[order[start[vf[idx]] + k]]
        ok = np.einsum("ij,ij->i", normals[nb], own[idx]) >= cos_c
        out[idx[ok]] += normals[nb[ok]] * areas[nb[ok], None]
    out /= np.linalg.norm(out, axis=1, keepdims=True)
    return out.reshape(F, 3, 3)


#: Strang & Fix (1973) 3-point rule, degree 2: barycentrics (2/3, 1/6, 1/6) and permutations,
#: equal weights.
_STRANG_FIX3 = np.array([[2 / 3, 1 / 6, 1 / 6], [1 / 6, 2 / 3, 1 / 6], [1 / 6, 1 / 6, 2 / 3]])


