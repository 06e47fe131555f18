"""The traced bodies: the Sun, the Earth and the Moon of a scene as Embree meshes in their own centred
frames, with what every job of the tracer shares about them (the rays cast, the source facets hit,
the sources' spheres, the shading normals, the trace's threads)."""

from __future__ import annotations

import threading
from collections import deque
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from lunarviz.geometry.scene_geometry import SceneGeometry
from lunarviz.methods.tracer.embree_bodies import EmbreeBody, serial_embree
from lunarviz.methods.tracer.settings import TraceSettings, body_mesh_m


class TracedBodies:
    """The three bodies of a :class:`~lunarviz.geometry.scene_geometry.SceneGeometry` as Embree
    meshes (``moon``, ``earth``, ``sun``), the scene and the tracer's settings they were built with.

    Parameters
    ----------
    scene : SceneGeometry
        The bodies' positions and the detector [m].
    settings : TraceSettings
        Meshes, levels, shading and threads.
    """

    def __init__(self, scene: SceneGeometry, settings: TraceSettings):
        self.scene = scene
        self.settings = settings
        th = settings.threads
        k = scene.scale
        s = settings
        nominal = {"moon": scene.r_moon, "earth": scene.r_earth, "sun": scene.r_sun}
        self.moon = EmbreeBody(body_mesh_m("moon", s.moon_level, s.moon_mesh, s.mesh_units, nominal["moon"]),
                               scene.moon, th, k, scene.rotation("moon"))
        earth_mesh = body_mesh_m("earth", s.earth_level, s.earth_mesh, s.mesh_units, nominal["earth"])
        # the packaged Earth is an exact sphere: turning its tessellation with the date changes
        # nothing it computes but where its facets lie on a map, so a uniform Earth keeps one
        # orientation and one Embree scene for every date; a mapped one turns with the Earth on
        # dates, so that each facet covers the same part of the map at every date and its map
        # values are computed once per process (earth_spectra.facet_weight_fields)
        packaged = bool(earth_mesh.metadata.get("lunarviz_analytic"))
        turned = not packaged or scene.general and not s.surface().uniform
        self.earth = EmbreeBody(earth_mesh, scene.earth, th, k, scene.rotation("earth") if turned else None)
        self.sun = EmbreeBody(body_mesh_m("sun", s.sun_level, s.sun_mesh, s.mesh_units, nominal["sun"]),
                              scene.sun, th, k)
        # ``shading`` is for the Moon and for user meshes; the packaged Sun and Earth spheres
        # keep the exact-sphere path unless ``body_shading`` names them (mesh studies)
        named = dict(s.body_shading)
        for name in ("earth", "sun"):
            if getattr(self, name).is_sphere and name not in named:
                getattr(self, name).shading_override = "auto"
        for body, mode in s.body_shading:
            getattr(self, body).shading_override = mode
        #: beams that hit each source facet (per body), accumulated over the trace
        self.source_hits = {"sun": np.zeros(self.sun.n_faces), "earth": np.zeros(self.earth.n_faces)}
        #: rays traced so far (every job counts its own through :meth:`count`)
        self.rays_cast = 0
        #: guards the counters and the jobs' lazily filled caches across the trace's threads
        self.lock = threading.Lock()

    def count(self, n):
        with self.lock:  # chunks may be traced on several threads (deterministic_transport)
            self.rays_cast += int(n)

    def source(self, body):
        """Centre [m], radius of the sphere the source's beams cover [m], and its Embree body.

        Analytic spheres: the sphere itself. Other meshes: the bounding sphere (beams that
        miss the mesh inside it carry nothing)."""
        sc = self.scene
        B = {"sun": self.sun, "earth": self.earth}[body]
        R = sc.radii[body] if B.mode(self.settings.shading) == "exact" else B.bound
        return {"sun": sc.sun, "earth": sc.earth}[body], R, B

    def self_shadows(self) -> bool:
        """The Moon can shadow itself (non-convex mesh) and self-shadowing is on."""
        return self.settings.self_shadow and not self.moon.convex

    def corner_normals(self, M, rows=slice(None)) -> np.ndarray:
        """Shading normals (F, 3, 3) at the corners of facets ``rows`` (all by default)."""
        mode = M.mode(self.settings.shading)
        if mode == "flat":
            return np.repeat(M.normals[rows][:, None, :], 3, axis=1)
        if mode == "exact":
            v = M.vertices[M.faces[rows]]
            return v / np.linalg.norm(v, axis=2, keepdims=True)
        return M.corner_normals[rows]

    def chunks_in_order(self, chunk, n: int):
        """``chunk(0), chunk(1), …`` (each a list of ``(Transport, owner)``), flattened in order;
        on ``threads`` threads a few ahead of the consumer when there are several."""
        threads = self.moon.threads
        if threads <= 1 or n <= 1:
            for i in range(n):
                yield from chunk(i)
            return
        def job(i):
            with serial_embree():  # the chunks share the cores; Embree calls are not split again
                return chunk(i)
        with ThreadPoolExecutor(threads) as ex:
            ahead = deque()
            for i in range(n):
                ahead.append(ex.submit(job, i))
                if len(ahead) > threads:  # bounded: ≤ threads + 2 chunks in memory (one being consumed)
                    yield from ahead.popleft().result()
            while ahead:
                yield from ahead.popleft().result()
