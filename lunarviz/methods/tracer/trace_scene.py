"""The traced scene: the three bodies of a scene as Embree meshes, set up once, with the
caches every job of the tracer shares (facet albedos, candidates, rule groups).

The jobs live in their own modules and are mixed in: lunar sampling and refinement
(:mod:`~lunarviz.methods.tracer.lunar_sampling`), source rules and visibility
(:mod:`~lunarviz.methods.tracer.source_rules`), the deterministic transport
(:mod:`~lunarviz.methods.tracer.deterministic`), the mapped Earth
(:mod:`~lunarviz.methods.tracer.mapped_earth`) and Monte Carlo
(:mod:`~lunarviz.methods.tracer.montecarlo`)."""

from __future__ import annotations

import threading

import numpy as np

from lunarviz.caches import BoundedCache, file_key, mesh_digest
from lunarviz.geometry.scene_geometry import SceneGeometry
from lunarviz.methods.tracer.deterministic import DeterministicTransport
from lunarviz.methods.tracer.embree_bodies import EmbreeBody
from lunarviz.methods.tracer.lunar_sampling import LunarSampling
from lunarviz.methods.tracer.mapped_earth import MappedEarthTransport
from lunarviz.methods.tracer.montecarlo import MonteCarloTransport
from lunarviz.methods.tracer.settings import (
    TraceSettings,
    body_mesh_m,
)
from lunarviz.methods.tracer.source_rules import SourceRules
from lunarviz.methods.transport import Transport
from lunarviz.surfaces.earth_spectra import facet_weights
from lunarviz.surfaces.maps import map_frame
from lunarviz.surfaces.moon_map import moon_facet_values
from lunarviz.surfaces.physical_earth import facet_reflectance

#: per-facet lunar map values per (map, mesh, frame) (:meth:`TraceScene.moon_map_values`)
MOON_MAP_VALUES = BoundedCache(8)


class TraceScene(LunarSampling, SourceRules, DeterministicTransport, MappedEarthTransport, MonteCarloTransport):
    """The three bodies of a :class:`~lunarviz.geometry.scene_geometry.SceneGeometry` as Embree meshes."""

    def __init__(self, scene: SceneGeometry, settings: TraceSettings = TraceSettings()):
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
        # nothing it computes (maps are read through their frame at each facet's own position),
        # so it keeps one orientation and one Embree scene for every date
        packaged = bool(earth_mesh.metadata.get("lunarviz_analytic"))
        self.earth = EmbreeBody(earth_mesh, scene.earth, th, k, None if packaged else scene.rotation("earth"))
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
        self.rays_cast = 0
        self._lock = threading.Lock()
        self._sun_vis_earth = None
        self._cand_cache: dict = {}
        #: per-facet arrays are being accumulated (:func:`~lunarviz.methods.tracer.estimators.trace_path`'s
        #: ``keep_facets``): lunar samples then come from the facets, never the lune rule
        self.per_facet = False
        #: per body: candidate facets that a shadow or hidden-view edge crosses (``candidates``)
        self._edge_cache: dict = {}
        self._mapped_lune_cache: dict = {}  # (body, cut at i = e) -> the mapped lune rule (or None: facets)
        #: a BRDF being shaded has Hapke's roughness (its kink at i = e: the mapped lune rule cuts
        #: there); set by :func:`~lunarviz.methods.tracer.estimators.trace_path`
        self.rough_brdf = False
        self.albedo_scale = 0.0  # from the lunar map to the shaded BRDFs' w (trace_path sets both)
        self._moon_albedo = self._earth_albedo = None
        #: a spectral run's Earth components (:func:`lunarviz.surfaces.earth_spectra.components`): the
        #: mapped Earth's transports then carry one beam array each (``e_beam_parts``)
        self.earth_parts: tuple | None = None
        #: a physical Earth's spectral run: the node wavelengths [nm] its components are
        self.earth_part_wavelengths = None
        self._earth_parts_w = None

    # ---- surfaces ----------------------------------------------------------------------------
    def moon_facet_albedo(self, spread: bool = False):
        """Per-facet values of the lunar albedo map (area averages, :mod:`lunarviz.surfaces.maps`),
        or ``None`` without a map; ``spread``: ``(mean, std)`` over each facet."""
        amap = self.settings.moon_map()
        if amap is None:
            return None
        if self._moon_albedo is None:
            self._moon_albedo = self.moon_map_values()
        return self._moon_albedo if spread else self._moon_albedo[0]

    def moon_map_values(self):
        """(mean, std) of the lunar map over each facet (:func:`lunarviz.surfaces.moon_map.moon_facet_values`
        over the whole mesh). On dates the Moon's mesh turns with the Moon, so a facet covers the
        same part of the map at every date: the values are kept per map, mesh and frame for the
        process (:data:`MOON_MAP_VALUES`), and a time series computes them once."""
        M, amap = self.moon, self.settings.moon_map()
        frame = map_frame(self.scene, "moon")
        turned = M.rotation is not None and np.array_equal(frame, M.rotation)  # body frame: date-independent
        mesh = M.geometry["mesh"]
        key = (file_key(amap.source()), amap.mean, mesh_digest(mesh), float(M.radius),
               "body" if turned else frame.tobytes())
        got = MOON_MAP_VALUES.get(key)
        if got is None:
            got = moon_facet_values(amap, M, frame)
            MOON_MAP_VALUES[key] = got
        return got

    def earth_facet_albedo(self):
        """Per-facet Lambert albedo of the Earth (area averages of its surface and clouds), or
        ``None`` for a uniform Earth (then :meth:`earth_albedo_value`; a map whose facets all
        have one value is that uniform Earth, bit for bit)."""
        surf = self.settings.surface()
        if surf.uniform:
            return None
        if self._earth_albedo is None:
            frame = map_frame(self.scene, "earth", self.settings.earth_rotation_deg)
            if surf.physical:  # each facet's reflectance toward the Moon as its albedo (earth_optics.planet)
                self._earth_albedo = facet_reflectance(surf, self.earth, frame, self.scene.sun, self.scene.moon,
                                                       [surf.wavelength_nm])[:, 0]
                return self._earth_albedo
            fa = surf.facet_albedo(self.earth, frame)
            self._earth_albedo = float(fa[0]) if np.all(fa == fa[0]) else fa
        return None if isinstance(self._earth_albedo, float) else self._earth_albedo

    def earth_facet_parts(self):
        """(F, C) per-facet weights of :attr:`earth_parts` for a mapped Earth, or ``None`` (a grey
        run, or a uniform Earth: its one component is the unit-albedo beams)."""
        if self.earth_parts is None or self.earth_facet_albedo() is None:
            return None
        if self._earth_parts_w is None:
            frame = map_frame(self.scene, "earth", self.settings.earth_rotation_deg)
            surf = self.settings.surface()
            if surf.physical:  # one component per node wavelength: the facets' reflectance there
                self._earth_parts_w = facet_reflectance(surf, self.earth, frame, self.scene.sun, self.scene.moon,
                                                        self.earth_part_wavelengths)
            else:
                self._earth_parts_w = facet_weights(surf, self.earth, frame)
        return self._earth_parts_w

    def earth_albedo_value(self) -> float:
        """The uniform Earth's albedo: ``earth_albedo``, or a uniform map's one value."""
        return self._earth_albedo if self.earth_facet_albedo() is None and isinstance(self._earth_albedo, float) \
            else float(self.settings.earth_albedo)

    def with_moon_albedo(self, tr: Transport, owner=None, values=None) -> Transport:
        """``tr`` with the lunar map's (mean, spread) per sample: ``values`` as given, or the
        facet values at the samples' owning facets ``owner``; unchanged without a map."""
        if values is None and owner is not None:
            v = self.moon_facet_albedo(spread=True)
            values = None if v is None else (v[0][owner], v[1][owner])
        if values is not None:
            tr.albedo, tr.albedo_std = values
            tr.albedo_absolute = self.settings.moon_map().absolute
        return tr

    def _count(self, n):
        with self._lock:  # chunks may be traced on several threads (deterministic_transport)
            self.rays_cast += int(n)

    def _source(self, body):
        """Centre [m], radius of the sphere the source's beams cover [m], and its Embree body.

        Analytic spheres: the sphere itself. Other meshes: the bounding sphere (beams that
        miss the mesh inside it carry nothing)."""
        sc = self.scene
        B = {"sun": self.sun, "earth": self.earth}[body]
        R = sc.radii[body] if B.mode(self.settings.shading) == "exact" else B.bound
        return {"sun": sc.sun, "earth": sc.earth}[body], R, B

    def _self_shadows(self) -> bool:
        """The Moon can shadow itself (non-convex mesh) and self-shadowing is on."""
        return self.settings.self_shadow and not self.moon.convex

    # ---- lunar samples -----------------------------------------------------------------------
    def _corner_normals(self, M, rows=slice(None)) -> np.ndarray:
        """Shading normals (F, 3, 3) at the corners of facets ``rows`` (all by default)."""
        mode = M.mode(self.settings.shading)
        if mode == "flat":
            return np.repeat(M.normals[rows][:, None, :], 3, axis=1)
        if mode == "exact":
            v = M.vertices[M.faces[rows]]
            return v / np.linalg.norm(v, axis=2, keepdims=True)
        return M.corner_normals[rows]
