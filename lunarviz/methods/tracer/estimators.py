"""Moonshine and earthshine by Embree ray tracing: deterministic and Monte Carlo estimators.

Both estimators build the same BRDF-independent :class:`~lunarviz.methods.transport.Transport` as the
analytic method and the exact reference, so one trace per phase serves every BRDF.

Paths (paper Table 1, Sec. 2.1): moonshine Sun → Moon → detector, earthshine
Sun → Earth → Moon → detector. The detector is reached by next-event estimation (Eq. 2):
from every lunar sample a beam toward the detector, weighted by μ cosδ dA / d².

* Lunar samples. ``deterministic``: one sample per facet (centroid), 16 per facet on the
  facets that straddle the terminator, its penumbra or the detector's limb (where the
  integrand has a kink), and up to 256 per facet across a thin crescent so that ≥ 64 samples
  span the lit and visible lune (adaptive refinement, ``lunar_refinement``). ``montecarlo``: N
  uniform points on facets drawn with probability ∝ a proxy of each facet's contribution,
  defensively mixed with 10 % ∝ area so the estimator stays unbiased.
* Source beams, restricted to the source's solid angle (Table 1). ``deterministic``: for the
  Sun, a Gauss rule over its 0.27° cone where the whole disc is above the horizon, and the
  sphere-surface rule of :mod:`lunarviz.geometry.sphere_quadrature` cut at the horizon elsewhere; for
  the Earth, the sphere-surface rule cut at the horizon and at the Earth's terminator.
  ``montecarlo``: one direction per sample, uniform in the Sun's cone, or drawn over the
  Earth's lit, visible part (scripts/derivations.md §4). Every beam is a ray traced
  against the source's mesh. The Sun's radiance is uniform, Φ/(4π² R_S²); the Earth's is
  Lambertian, (A/π) E_sun μ_s at the hit, times the fraction of the Sun that the hit facet sees
  (the Moon's shadow, with occlusion on).
* Shading (``shading``): ``smooth`` (default) takes points, normals and areas from the smooth
  surface the mesh tessellates (the exact sphere for icospheres; interpolated vertex normals
  for other meshes) while the mesh decides hits and shadows; ``flat`` uses the facets.
* Occlusion (on by default; ``occlusion=False`` is the paper's assumption): the Earth blocks
  Sun beams (lunar eclipse); the Moon blocks the Sun for Earth facets; a non-convex Moon mesh
  shadows itself (convex meshes skip those rays: the sample's own horizon decides exactly).
* The observer's own Earth: whatever the occlusion setting, the Earth hides lunar samples from
  a detector outside it (traced with Embree; a site on the ground uses its geodetic horizon
  plane), as in the analytic and reference methods.

Neglected physics: refraction and extinction in the Earth's atmosphere (the umbra is darker
than a real eclipse's red Moon), solar limb darkening, polarisation, multiple Moon-Earth
bounces, the Sun's extent when it lights the Earth (O(ρ²) ≈ 2e-5, see reference.py).
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from lunarviz.bodies.meshes import DEFAULT_LEVELS
from lunarviz.caches import memoize
from lunarviz.errors import LunarvizError
from lunarviz.geometry.scene_geometry import Scene, angle_between, half_angle_sin_cos, unit
from lunarviz.geometry.sphere_quadrature import orthonormal_basis
from lunarviz.geometry.subdivision import sub_barycentric
from lunarviz.methods.sources import earth_radiance, horizon_cuts_source, source_beams, source_sphere_rule, sun_radiance
from lunarviz.methods.tracer import ray_kernels
from lunarviz.methods.tracer.embree_bodies import EmbreeBody
from lunarviz.methods.transport import Transport, detector_geometry
from lunarviz.options import SHADINGS, compose, validate

#: Shadow-ray origins are offset along the normal by this fraction of the body radius
#: (0.17 m on the Moon: above float32's 0.125 m step at the lunar radius, far below any facet).
NORMAL_OFFSET = 1e-7
#: Share of Monte Carlo lunar samples drawn ∝ facet area (defensive mixture).
UNIFORM_SHARE = 0.1
#: Facets straddling a kink (terminator, penumbra edge, limb) are split REFINE² ways.
REFINE = 4
#: Samples wanted across the width of the lit-and-visible lune (see ``lunar_refinement``).
LUNE_SAMPLES = 16
#: Order of the sphere rule for lunar samples that see the Sun partly below the horizon.
#: Sun-cone Gauss order (radial × 2·order azimuthal) where the Earth's disc overlaps the Sun's
#: (lunar eclipses): the Earth's limb is a discontinuity inside the cone; order 16 puts
#: 512 beams across it (the penumbra then agrees with the exact disc overlap to ~1e-3).
ECLIPSE_ORDER = 16
PENUMBRA_ORDER = 6
#: Kink refinement is skipped when the lune is within this angle [rad] of a hemisphere.
KINK_FREE_WIDTH = 0.05
PATHS = {"moonshine": "sun", "earthshine": "earth"}
#: Gauss order (radial; twice that in azimuth) of the beams over the bounding cone of a source
#: that is a user mesh (not an analytic sphere): its silhouette is resolved by the beams.
MESH_SOURCE_ORDER = 16
#: Lunar samples per batch: bounds memory (≈ CHUNK × beams × 30 doubles) for any ray count.
CHUNK = 1 << 14
#: Facets per block in the per-facet passes (candidate tests, shadow edges): bounds their
#: temporaries (≈ 100 doubles per facet) on multi-million-facet meshes.
FACET_BLOCK = 1 << 18
#: Facets of a mapped Earth that its terminator crosses are split this many ways per side.
TERMINATOR_SUB = 8
#: A mapped Earth's facets are grouped into at most this many cells per side of its disc seen
#: from the Moon (its beams; ``mapped_earth_transport``).
EARTH_CELLS = 24


@dataclass(frozen=True)
@compose("earth", "meshes", "trace", "surfaces")
class TraceSettings:
    """The ray tracer's settings: the options of the ``earth``, ``meshes``, ``trace`` and
    ``surfaces`` groups of :mod:`lunarviz.options` (icosphere levels ``None`` resolve to
    :data:`~lunarviz.bodies.meshes.DEFAULT_LEVELS`, the Earth's rotation ``None`` to 0), and:"""

    #: the option groups whose fields this class takes from the schema
    GROUPS: ClassVar[tuple] = ("earth", "meshes", "trace", "surfaces")
    #: split facets that a terminator, limb, penumbra or cast-shadow edge crosses (lune refinement)
    refine: bool = True
    #: threads per trace (``None``: the machine's cores); no number depends on it
    threads: int | None = None
    #: per-body shading overriding ``shading``, e.g. ``(("earth", "flat"),)`` (mesh studies)
    body_shading: tuple = ()
    #: a mapped Earth's earthlight: ``facets`` (default: summed per facet into disc cells,
    #: :meth:`TraceScene.mapped_earth_transport`) or ``beams`` (the uniform Earth's Gauss beams
    #: with each hit facet's albedo: ~2 % off at a map's edges; a diagnostic for comparisons)
    mapped_earth: str = "facets"

    def moon_map(self):
        """The parsed lunar albedo map, or ``None``."""
        if self.moon_albedo_map is None:
            return None
        from lunarviz.bodies.surfaces import MoonAlbedoMap
        return MoonAlbedoMap.parse(self.moon_albedo_map)

    def surface(self):
        """The Earth's :class:`~lunarviz.bodies.surfaces.EarthSurface`."""
        from lunarviz.bodies.surfaces import EarthSurface
        return EarthSurface.from_options(self)

    def __post_init__(self):
        for body in ("moon", "earth", "sun"):  # None: the mesh study's default level
            if getattr(self, f"{body}_level") is None:
                object.__setattr__(self, f"{body}_level", DEFAULT_LEVELS[body])
        if self.earth_rotation_deg is None:
            object.__setattr__(self, "earth_rotation_deg", 0.0)
        validate(self)
        for body, mode in self.body_shading:
            if body not in ("moon", "earth", "sun") or mode not in SHADINGS:
                raise LunarvizError(f"body shading {body}={mode} is not valid")
        if not isinstance(self.refine, (bool, np.bool_)):
            raise LunarvizError(f"refine={self.refine!r} must be True or False")
        self.surface()
        self.moon_map()
        if self.mapped_earth not in ("facets", "beams"):
            raise LunarvizError(f"mapped_earth {self.mapped_earth!r} is not one of facets, beams")


@memoize(maxsize=16)
def body_mesh_m(body: str, level, path, units: str = "m", radius: float | None = None):
    """The mesh of ``body`` in metres, body frame: a user mesh (``path``, read in ``units``)
    or the packaged icosphere at ``level`` tagged as an analytic sphere of ``radius``."""
    from lunarviz.bodies.meshes import NOMINAL_RADII, analytic_sphere, load_user_mesh
    nominal = NOMINAL_RADII[body] if radius is None else radius
    if path is not None:
        return load_user_mesh(path, body=body, units=units, nominal_radius=nominal)
    return analytic_sphere(body, level, nominal)


class TraceScene:
    """The three bodies of a :class:`~lunarviz.geometry.scene_geometry.Scene` as Embree meshes."""

    def __init__(self, scene: Scene, settings: TraceSettings = TraceSettings()):
        self.scene = scene
        self.settings = settings
        th = settings.threads
        k = scene.scale
        s = settings
        nominal = {"moon": scene.r_moon, "earth": scene.r_earth, "sun": scene.r_sun}
        self.moon = EmbreeBody(body_mesh_m("moon", s.moon_level, s.moon_mesh, s.mesh_units, nominal["moon"]),
                               scene.moon, th, k, scene.rotation("moon"))
        self.earth = EmbreeBody(body_mesh_m("earth", s.earth_level, s.earth_mesh, s.mesh_units, nominal["earth"]),
                                scene.earth, th, k, scene.rotation("earth"))
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
        self._moon_albedo = self._earth_albedo = None

    # ---- surfaces ----------------------------------------------------------------------------
    def moon_facet_albedo(self, spread: bool = False):
        """Per-facet values of the lunar albedo map (area averages, :mod:`lunarviz.bodies.surfaces`),
        or ``None`` without a map; ``spread``: ``(mean, std)`` over each facet."""
        amap = self.settings.moon_map()
        if amap is None:
            return None
        if self._moon_albedo is None:
            from lunarviz.bodies.surfaces import map_frame, moon_facet_values
            self._moon_albedo = moon_facet_values(amap, self.moon, map_frame(self.scene, "moon"))
        return self._moon_albedo if spread else self._moon_albedo[0]

    def earth_facet_albedo(self):
        """Per-facet Lambert albedo of the Earth (area averages of its surface and clouds), or
        ``None`` for a uniform Earth (then :meth:`earth_albedo_value`; a map whose facets all
        have one value is that uniform Earth, bit for bit)."""
        surf = self.settings.surface()
        if surf.uniform:
            return None
        if self._earth_albedo is None:
            from lunarviz.bodies.surfaces import map_frame
            frame = map_frame(self.scene, "earth", self.settings.earth_rotation_deg)
            fa = surf.facet_albedo(self.earth, frame)
            self._earth_albedo = float(fa[0]) if np.all(fa == fa[0]) else fa
        return None if isinstance(self._earth_albedo, float) else self._earth_albedo

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

    def candidates(self, body: str) -> np.ndarray:
        """Lunar facets that the detector may see and the source may (partly) light.

        Tested on the facet's corners as well as its centroid, so a facet that a kink crosses
        is never dropped. Memoised per body (``self._kinks`` follows the last body asked).
        Computed in blocks of FACET_BLOCK facets, so memory stays bounded on any mesh.
        """
        if body in self._cand_cache:
            cand, self._kinks = self._cand_cache[body]
            return cand
        M = self.moon
        c, R, _ = self._source(body)
        x_all, n_all = M.facet_points(self.settings.shading)
        if M.mode(self.settings.shading) == "interp":
            M.corner_normals  # noqa: B018 (a cached property: built here, before the blocks' threads)
        F = M.n_faces
        keep = np.zeros(F, dtype=bool)
        kinks = np.zeros(F, dtype=bool)

        def block(i):
            blk = slice(i * FACET_BLOCK, min(F, (i + 1) * FACET_BLOCK))
            lit, vis = self._kink_values(x_all[blk], n_all[blk], c, R)
            tri = M.vertices[M.faces[blk]] + M.centre
            vn = self._corner_normals(M, blk)
            lit_v, vis_v = self._kink_values(tri.reshape(-1, 3), vn.reshape(-1, 3), c, R)
            lit_v, vis_v = lit_v.reshape(-1, 3), vis_v.reshape(-1, 3)
            up = (lit > -1) | (lit_v > -1).any(1)
            seen = (vis > 0) | (vis_v > 0).any(1)
            kinks[blk] = (np.sign(lit_v + 1) != np.sign(lit_v[:, :1] + 1)).any(1) | \
                (np.sign(lit_v - 1) != np.sign(lit_v[:, :1] - 1)).any(1) | \
                (np.sign(vis_v) != np.sign(vis_v[:, :1])).any(1) | (up & ~(lit > -1)) | (seen & ~(vis > 0))
            keep[blk] = up & seen
            return []
        # blocks on the trace's threads (numpy and Embree release the GIL); each writes its own slice
        list(self._chunks_in_order(block, -(-F // FACET_BLOCK)))
        cand = np.flatnonzero(keep)
        self._kinks = kinks
        hidden_view = not self.scene.detector_inside("earth") or self.scene.horizon_normal is not None
        if self._self_shadows() or (self.settings.occlusion and body == "sun") or hidden_view:
            def edges(i):
                return [self._shadow_edges(cand[i * FACET_BLOCK:(i + 1) * FACET_BLOCK], c)]
            for found in self._chunks_in_order(edges, -(-len(cand) // FACET_BLOCK)):
                self._kinks[found] = True
        self._cand_cache[body] = (cand, self._kinks)
        return cand

    def _shadow_edges(self, cand: np.ndarray, c: np.ndarray) -> np.ndarray:
        """Facets that a cast-shadow or hidden-view boundary crosses, found by ray tracing.

        From each candidate facet's centroid and corners (offset along the facet normal) one
        ray to the source's centre and one to the detector are traced against the Moon (when it
        shadows itself) and the Earth (toward the source when occlusion is on; toward a
        detector outside the Earth always). A facet whose four points
        disagree is a kink facet and gets refined like a terminator facet. Returns those
        facets (indices).
        """
        M = self.moon
        s = self.settings
        if cand.size == 0:
            return cand
        tri = M.vertices[M.faces[cand]] + M.centre
        pts = np.concatenate([M.centroids[cand][:, None, :], tri], axis=1)  # (F, 4, 3)
        off = M.normals[cand][:, None, :] * (NORMAL_OFFSET * M.radius)
        p = (pts + off).reshape(-1, 3)
        mixed = np.zeros(len(cand), dtype=bool)
        det = self.scene.det
        for to_det, target in ((False, c), (True, det)):
            v = target - p
            dist = np.linalg.norm(v, axis=1)
            d = v / dist[:, None]
            blocked = np.zeros(len(p), dtype=bool)
            if self._self_shadows():
                blocked |= self.moon.occluded(p, d, dist)
                self._count(len(p))
            if to_det and self.scene.horizon_normal is not None:
                blocked |= ~self.scene.sight_lines_clear(p)
            elif (to_det and not self.scene.detector_inside("earth")) or (not to_det and s.occlusion):
                blocked |= self.earth.occluded(p, d, dist)
                self._count(len(p))
            b = blocked.reshape(-1, 4)
            mixed |= b.any(1) & ~b.all(1)
        return cand[mixed]

    def _kink_values(self, x, n, c, R):
        """``n·(c - x)/R`` (> 1 source wholly above the horizon, < -1 wholly below, between:
        penumbra; scripts/derivations.md §1) and μ toward the detector."""
        lit = np.einsum("ij,ij->i", n, c - x) / R
        w = self.scene.det - x
        return lit, np.einsum("ij,ij->i", n, w) / np.linalg.norm(w, axis=1)

    def lunar_refinement(self, body: str) -> int:
        """Sub-division of every lit-and-visible facet so ≥ LUNE_SAMPLES samples span the lune.

        The lit and visible region is a lune of width w = π - (source-Moon-detector angle);
        at a thin crescent it is only a few facets wide and the facet rule errs by
        ~(h/w)² (1 % at θ = 175° on level 6). Powers of two up to 16. Flat facets carry no
        kink inside (constant normal), so they are never split for this.
        """
        M = self.moon
        if M.mode(self.settings.shading) == "flat":
            return 1
        w = self._lune_width(body)
        h = np.sqrt(np.mean(M.areas)) / M.radius
        need = LUNE_SAMPLES * h / max(w, 1e-9)
        return int(min(16, 2 ** int(np.ceil(np.log2(max(need, 1.0))))))

    def _lune_width(self, body: str) -> float:
        sc = self.scene
        c, _, _ = self._source(body)
        return np.pi - float(np.arccos(np.clip(np.dot(unit(c - sc.moon), unit(sc.det - sc.moon)), -1, 1)))

    def sample_albedo(self, faces, sub: int):
        """The lunar map's value for each sample of ``M.surface_samples(faces, shading, sub)``,
        in its order: the map's area average over the sample's own sub-triangle (so refined
        facets, at terminators and limbs, see the map at their finer scale; ``sub = 1`` gives
        the facet averages of :meth:`moon_facet_albedo`). ``None`` without a map."""
        amap = self.settings.moon_map()
        if amap is None:
            return None
        if sub == 1 or len(faces) == 0:
            mean, sd = (a[faces] for a in self.moon_facet_albedo(spread=True))
        else:
            from lunarviz.bodies.surfaces import map_frame, moon_facet_values
            M = self.moon
            _, tri_b = sub_barycentric(sub)
            corners = np.einsum("svk,fkj->fsvj", tri_b, M.vertices[M.faces[np.asarray(faces, dtype=np.int64)]])
            verts = corners.reshape(-1, 3)
            mean, sd = moon_facet_values(amap, M, map_frame(self.scene, "moon"),
                                         faces=(verts, np.arange(len(verts)).reshape(-1, 3)))  # (F·sub²,)
        per = 1 if self.moon.mode(self.settings.shading) == "flat" else 3
        return np.repeat(mean, per), np.repeat(sd, per)

    def lunar_samples(self, body: str):
        """Deterministic lunar samples: points, normals, areas, owning facets, and the lunar
        map's value per sample (``None`` without a map; :meth:`sample_albedo`)."""
        M = self.moon
        s = self.settings
        cand = self.candidates(body)
        if not s.refine:
            return (*M.surface_samples(cand, s.shading), self.sample_albedo(cand, 1))
        sub = self.lunar_refinement(body)
        kink = self._kinks[cand]
        if self._lune_width(body) > np.pi - KINK_FREE_WIDTH and M.mode(s.shading) == "exact":
            # source ≈ detector seen from the Moon (earthshine with the detector on the Earth):
            # the terminator and the limb coincide and the integrand vanishes quadratically
            # there (μ0 ≈ μ), so there is no kink to resolve on the smooth sphere.
            kink = np.zeros_like(kink)
        a = M.surface_samples(cand[~kink], s.shading, sub=sub)
        b = M.surface_samples(cand[kink], s.shading, sub=max(REFINE, sub))
        out = tuple(np.concatenate([u, v]) for u, v in zip(a, b))
        va, vb = self.sample_albedo(cand[~kink], sub), self.sample_albedo(cand[kink], max(REFINE, sub))
        return (*out, None if va is None else tuple(np.concatenate([u, v]) for u, v in zip(va, vb)))

    def detector_view(self, x, n, dA):
        """mu, geom and unit directions to the detector, with the sight line's occlusion (the
        Earth, for a detector outside it; the Moon itself, with ``self_shadow`` on a non-convex
        Moon)."""
        sc = self.scene
        mu, geom, o = detector_geometry(x, n, dA, sc.det, sc.det_normal)
        # The Earth between the Moon and the detector always hides it, as in every method
        # (--no-occlusion removes shadows, i.e. bodies between a source and the Moon; it
        # does not make the observer's own Earth transparent)
        horizon = sc.horizon_normal is not None
        earth_blocks = not sc.detector_inside("earth") and not horizon
        if horizon:  # a site on the WGS84 Earth: its horizon plane, not the model sphere
            geom = np.where(sc.sight_lines_clear(x), geom, 0.0)
        if earth_blocks or self._self_shadows():
            idx = np.flatnonzero(geom > 0)
            xo = x[idx] + n[idx] * (NORMAL_OFFSET * self.moon.radius)
            dist = np.linalg.norm(sc.det - xo, axis=1)
            blocked = np.zeros(idx.size, dtype=bool)
            if earth_blocks:
                blocked |= self.earth.occluded(xo, o[idx], dist)
                self._count(idx.size)
            if self._self_shadows():
                blocked |= self.moon.occluded(xo, o[idx], dist)
                self._count(idx.size)
            geom = geom.copy()
            geom[idx[blocked]] = 0.0
        return mu, geom, o

    # ---- source beams ------------------------------------------------------------------------
    def source_nodes(self, x, n, body: str, order: int, eclipse: bool = True):
        """Deterministic beams from points x (B,3) with normals n: unit directions (B,K,3)
        and solid angles (B,K) [sr]. Where the horizon does not cut the source (most points),
        the Sun gets a Gauss rule over its cone and the Earth a rule without the horizon cap.
        A source shaded on its facets (a user mesh, or ``flat`` shading) gets a Gauss rule over
        its bounding sphere's cone (order ≥ MESH_SOURCE_ORDER); Embree then decides which
        beams meet the mesh and which facet each meets."""
        sc = self.scene
        c, R, B = self._source(body)
        if B.mode(self.settings.shading) != "exact":
            xc = x - c
            dxc = np.linalg.norm(xc, axis=1)
            o = max(order, MESH_SOURCE_ORDER)
            om, w = ray_kernels.cone_rule(-xc / dxc[:, None], np.clip(R / dxc, 0, 1 - 1e-12), o, 2 * o)
            return om, w
        cut = horizon_cuts_source(sc, x, n, body)
        parts = []
        for rows, with_horizon in ((np.flatnonzero(~cut), False), (np.flatnonzero(cut), True)):
            if rows.size == 0:
                continue
            if body == "sun" and not with_horizon:
                xc = x[rows] - c
                dxc = np.linalg.norm(xc, axis=1)
                # (points on the Earth itself: its own limb is their horizon, no eclipse rule)
                ecl = self._earth_crosses_sun(x[rows], dxc) if eclipse else np.zeros(len(rows), dtype=bool)
                for sub, o_s in ((~ecl, order), (ecl, max(order, ECLIPSE_ORDER))):
                    if sub.any():
                        om, w = ray_kernels.cone_rule(-xc[sub] / dxc[sub, None], R / dxc[sub], o_s, 2 * o_s)
                        parts.append((rows[sub], om, w))
                continue
            # The Sun partly below the horizon (penumbra rows, few) needs a finer sphere rule
            # than its cone rule (tests/test_trace.py checks the moonshine against the reference).
            o_s = max(order, PENUMBRA_ORDER) if body == "sun" else order
            if (body == "earth" and not with_horizon) or (body == "sun" and with_horizon):
                # rules with one cap (compiled): the Earth's terminator where the horizon does not
                # cut the Earth (nearly every lunar point), the horizon across the Sun (penumbra)
                from lunarviz.methods.tracer.ray_kernels import sphere_cap_beams
                if body == "earth":
                    cs = sc.sun - c
                    cap = unit(cs), R / np.linalg.norm(cs)
                else:
                    cap = n[rows], np.einsum("ij,ij->i", x[rows] - c, n[rows]) / R
                fast = sphere_cap_beams(x[rows], c, R, *cap, o_s, o_s)
                if fast is not None:
                    parts.append((rows, *fast))
                    continue
            m, w = source_sphere_rule(sc, x[rows], n[rows], body, o_s, horizon=with_horizon)
            _, om, omega = source_beams(sc, x[rows], body, m, w)
            parts.append((rows, om, omega))
        K = max(p[2].shape[1] for p in parts)
        om = np.zeros((len(x), K, 3))
        om[..., 2] = 1.0
        w = np.zeros((len(x), K))
        for rows, op, wp in parts:
            om[rows, :op.shape[1]] = op
            w[rows, :wp.shape[1]] = wp
        return om, w

    def _earth_crosses_sun(self, x, d_sun) -> np.ndarray:
        """Points from which the Earth's disc overlaps the Sun's (a lunar eclipse's penumbra and
        umbra), when occlusion is on. There the Earth's limb cuts the solar cone and its
        default rule (a few beams) would round the partial Sun to all or nothing: those
        points get the ECLIPSE_ORDER rule (tests/test_sky.py checks the penumbra against the
        exact overlap of the two discs)."""
        if not self.settings.occlusion:
            return np.zeros(len(x), dtype=bool)
        sc = self.scene
        ve = sc.earth - x
        de = np.linalg.norm(ve, axis=1)
        rho_e = np.arcsin(np.clip(self.earth.bound / de, 0, 1))
        rho_s = np.arcsin(np.clip(sc.radii["sun"] / d_sun, 0, 1))
        gamma = angle_between(sc.sun - x, ve)
        return gamma < (rho_s + rho_e) * (1 + 1e-6)

    def sun_visibility_of_earth(self) -> np.ndarray:
        """Fraction of the Sun each Earth facet sees past the Moon (with occlusion) and past
        the Earth itself (a non-convex Earth mesh, with self-shadowing); 1 otherwise."""
        if self._sun_vis_earth is not None:
            return self._sun_vis_earth
        E = self.earth
        vis = np.ones(E.n_faces)
        earth_self = self.settings.self_shadow and not E.convex
        if self.settings.occlusion or earth_self:
            n = E.normals_for(self.settings.shading)
            x = E.centroids
            c, R, _ = self._source("sun")
            idx = np.flatnonzero(np.einsum("ij,ij->i", n, c - x) > -R)
            xo = x[idx] + n[idx] * (NORMAL_OFFSET * E.radius)
            dirs, w = self.source_nodes(xo, n[idx], "sun", 2, eclipse=False)
            B, K = w.shape
            occ = np.zeros(B * K, dtype=bool)
            rep_o, rep_d = np.repeat(xo, K, 0), dirs.reshape(-1, 3)
            if self.settings.occlusion:
                occ |= self.moon.occluded(rep_o, rep_d)
                self._count(B * K)
            if earth_self:
                occ |= E.occluded(rep_o, rep_d)
                self._count(B * K)
            occ = occ.reshape(B, K)
            tot = w.sum(1)
            vis[idx] = np.where(tot > 0, (w * ~occ).sum(1) / np.where(tot > 0, tot, 1), 1.0)
            if self.settings.occlusion:
                # facets from which the Moon's disc overlaps the Sun's (the Moon's shadow and
                # penumbra on the Earth, a solar eclipse): the Moon's limb cuts the solar cone,
                # and 8 beams round the partial Sun to steps; ECLIPSE_ORDER beams resolve it
                sc = self.scene
                vs, vm = sc.sun - xo, sc.moon - xo
                ds, dm = np.linalg.norm(vs, axis=1), np.linalg.norm(vm, axis=1)
                rho = np.arcsin(np.clip(R / ds, 0, 1)) + np.arcsin(np.clip(self.moon.bound / dm, 0, 1))
                pen = np.flatnonzero(angle_between(vs, vm) < rho * (1 + 1e-6))
                if pen.size:
                    d2, w2 = self.source_nodes(xo[pen], n[idx[pen]], "sun", ECLIPSE_ORDER, eclipse=False)
                    K2 = w2.shape[1]
                    o2 = np.repeat(xo[pen], K2, 0)
                    occ2 = self.moon.occluded(o2, d2.reshape(-1, 3)).reshape(-1, K2)
                    self._count(o2.shape[0])
                    if earth_self:
                        occ2 |= E.occluded(o2, d2.reshape(-1, 3)).reshape(-1, K2)
                        self._count(o2.shape[0])
                    t2 = w2.sum(1)
                    vis[idx[pen]] = np.where(t2 > 0, (w2 * ~occ2).sum(1) / np.where(t2 > 0, t2, 1), 1.0)
        self._sun_vis_earth = vis
        return vis

    def sun_surface_radiance(self) -> float:
        """Radiance of the Sun's surface [W m⁻² sr⁻¹]: a Lambertian emitter of total power Φ
        over its surface A, L = Φ/(πA); Φ/(4π²R²) on the exact sphere. A Sun mesh of another
        size or shape therefore still emits Φ (the Earth is lit by a point Sun of power Φ)."""
        S = self.sun
        if S.mode(self.settings.shading) == "exact":
            return sun_radiance(self.scene)
        return self.scene.phi / (np.pi * float(S.areas.sum()))

    def source_radiance(self, x, n, dirs, body: str):
        """Radiance [W m⁻² sr⁻¹] reaching x (n,3) along dirs (n,3) from ``body``'s mesh:
        ``(L, L_free, L_unit)``, zero where the ray misses the source; ``L`` is also zero where
        another body (``occlusion``) or the Moon itself (``self_shadow``) blocks it, ``L_free`` is
        not. ``L_unit`` (Earth only, else ``None``) is ``L`` for an Earth of albedo 1: the Earth's
        albedo at a hit is its facet's (a map) or the scalar."""
        sc = self.scene
        s = self.settings
        xo = x + n * (NORMAL_OFFSET * self.moon.radius)
        target = self.sun if body == "sun" else self.earth
        if target.mode(s.shading) == "exact":
            hits = target.sphere_hits(xo, dirs)
        else:
            hits = target.intersect(xo, dirs)
        self._count(len(xo))
        per_facet = np.bincount(hits.prim[hits.hit], minlength=target.n_faces)
        with self._lock:
            self.source_hits[body] += per_facet
        if body == "sun":
            L = np.where(hits.hit, self.sun_surface_radiance(), 0.0)
            L_free = L.copy()
            if s.occlusion:
                live = np.flatnonzero(L > 0)
                blocked = self.earth.occluded(xo[live], dirs[live], hits.t[live])
                self._count(live.size)
                L[live[blocked]] = 0.0
        else:
            L, L_unit = np.zeros(len(xo)), np.zeros(len(xo))
            h, y, nrm = self.earth.shade_hits(hits, s.shading)
            vis = self.sun_visibility_of_earth()
            prim = np.maximum(hits.prim[h], 0)
            shade = np.where(hits.prim[h] >= 0, vis[prim], 1.0)
            fa = self.earth_facet_albedo()
            L_unit[h] = earth_radiance(sc, y, nrm, 1.0) * shade
            L[h] = L_unit[h] * (self.earth_albedo_value() if fa is None else fa[prim])
            L_free = L.copy()
        if self._self_shadows():
            live = np.flatnonzero((L > 0) | (L_unit > 0)) if body == "earth" else np.flatnonzero(L > 0)
            blocked = self.moon.occluded(xo[live], dirs[live], hits.t[live])
            self._count(live.size)
            L[live[blocked]] = 0.0
            if body == "earth":
                L_unit[live[blocked]] = 0.0
        return L, L_free, (L_unit if body == "earth" else None)

    # ---- transports --------------------------------------------------------------------------
    def deterministic_transport(self, body: str):
        """Yield ``(Transport, owning facets)`` for chunks of ≤ CHUNK lunar samples, in order.

        With ``threads`` > 1 the chunks are traced on that many threads, a few ahead of the
        consumer: Embree and the compiled kernels release the GIL, so one chunk's Embree
        queries run while another's rules and beams are built (issue 13: "use both cores").
        The chunks and their order are the same for any thread count, so are the results,
        bit for bit (tests/test_trace.py)."""
        s = self.settings
        x_all, n_all, dA_all, owner_all, alb_all = self.lunar_samples(body)
        self._warm_shared(body)

        def chunk(a):
            sl = slice(a, a + CHUNK)
            x, n, dA, owner = x_all[sl], n_all[sl], dA_all[sl], owner_all[sl]
            mu, geom, o = self.detector_view(x, n, dA)
            keep = geom > 0
            x, n, owner, mu, geom, o = x[keep], n[keep], owner[keep], mu[keep], geom[keep], o[keep]
            out = []
            if len(x) == 0:
                return out
            order = s.sun_order if body == "sun" else s.earth_order
            for g in self._rule_groups(x, n, body):
                tr = self.beam_transport(x[g], n[g], o[g], mu[g], geom[g], body, order)
                if alb_all is not None:
                    self.with_moon_albedo(tr, values=(alb_all[0][sl][keep][g], alb_all[1][sl][keep][g]))
                out.append((tr, owner[g]))
            return out

        starts = list(range(0, len(x_all), CHUNK))
        yield from self._chunks_in_order(lambda i: chunk(starts[i]), len(starts))

    def _warm_shared(self, body: str) -> None:
        """Fill the scene's lazy caches before chunks are traced on several threads."""
        if body == "earth":
            self.earth_facet_albedo()
            self.sun_visibility_of_earth()
            if self.earth_facet_albedo() is not None and self.settings.mapped_earth == "facets":
                self._earth_elements()
        self.moon_facet_albedo()
        for b in (self.sun, self.earth):
            if b.mode(self.settings.shading) == "exact":
                b.outer_scene()
            elif b.mode(self.settings.shading) == "interp":
                b.corner_normals  # noqa: B018 (a cached property: built here, once)

    def _rule_groups(self, x, n, body: str) -> list:
        """Rows of x grouped by the size of their source rule (:meth:`source_nodes`): the few
        rows whose horizon cuts the source (or, for the Sun, whose view the Earth's limb cuts)
        take rules of 72-512 beams, the rest 8 (the Sun's cone) or ~60 (the Earth). Transports
        are padded to their longest row, so tracing the groups apart spares ~10x padded beams
        in a moonshine chunk. Each group keeps the rows' order; results only change by the
        order of the sums (rounding)."""
        c, R, B = self._source(body)
        if B.mode(self.settings.shading) != "exact" or body == "earth" and self.earth_facet_albedo() is not None \
                and self.settings.mapped_earth == "facets":
            return [slice(None)]
        cut = horizon_cuts_source(self.scene, x, n, body)
        if body == "sun":
            ecl = ~cut & self._earth_crosses_sun(x, np.linalg.norm(x - c, axis=1))
            groups = [~cut & ~ecl, cut, ecl]
        else:
            groups = [~cut, cut]
        return [np.flatnonzero(g) for g in groups if g.any()]

    def _earth_elements(self):
        """The mapped Earth as surface elements, one per facet: points y, normals m, areas
        [m²] (spherical areas on the exact sphere), radiance for albedo 1 (point Sun, the
        Moon's shadow traced per facet) and the facet's albedo; sorted into the cells of a
        grid over the Earth's disc seen from the Moon's centre, with each cell's
        flux-weighted centre point. Elements neither lit nor possibly seen from the Moon are
        dropped; on a non-convex Earth, those the Earth itself hides from the Moon's centre
        (traced)."""
        if getattr(self, "_earth_el", None) is not None:
            return self._earth_el
        sc, s, E = self.scene, self.settings, self.earth
        # three points per facet (the degree-2 rule of surface_samples; on the packaged sphere
        # they lie on the exact sphere): the terminator crosses facets, and a one-point rule
        # there costs 6e-4 where the lit part is a thin band (tests/test_surfaces.py)
        # facets the terminator crosses (corners lit and unlit) are split TERMINATOR_SUB² ways:
        # the lit edge is a kink the map's light ends at, coherently along the whole terminator
        corners = E.vertices[E.faces] + E.centre  # (F, 3, 3)
        cn = self._corner_normals(E)
        mu_c = np.einsum("fkj,fkj->fk", cn, sc.sun - corners)
        term = (mu_c > 0).any(1) & (mu_c <= 0).any(1)
        parts = [E.surface_samples(np.flatnonzero(~term), s.shading),
                 E.surface_samples(np.flatnonzero(term), s.shading, sub=TERMINATOR_SUB)]
        y, m, area_f, owner = (np.concatenate([u, v]) for u, v in zip(*parts))
        L1 = earth_radiance(sc, y, m, 1.0) * self.sun_visibility_of_earth()[owner]
        a = self.earth_facet_albedo()[owner]
        rm = sc.radii["moon"]
        keep = (L1 > 0) & (np.einsum("ij,ij->i", m, sc.moon - y) > -rm)
        if self.settings.self_shadow and not E.convex:
            idx = np.flatnonzero(keep)
            yo = y[idx] + m[idx] * (NORMAL_OFFSET * E.radius)
            v = sc.moon - yo
            dist = np.linalg.norm(v, axis=1)
            hid = E.occluded(yo, v / dist[:, None], dist - rm)
            self._count(idx.size)
            keep[idx[hid]] = False
        idx = np.flatnonzero(keep)
        y, m, L1A, a = y[idx], m[idx], L1[idx] * area_f[idx], a[idx]
        axis = unit(sc.moon - sc.earth)
        e1, e2 = orthonormal_basis(axis[None, :])
        bound = E.bound if E.mode(s.shading) != "exact" else E.radius
        g = EARTH_CELLS
        u = np.clip(((y - sc.earth) @ e1[0] / bound + 1) * 0.5 * g, 0, g - 1).astype(int)
        w = np.clip(((y - sc.earth) @ e2[0] / bound + 1) * 0.5 * g, 0, g - 1).astype(int)
        cell = u * g + w
        order = np.argsort(cell, kind="stable")
        y, m, L1A, a, cell = y[order], m[order], L1A[order], a[order], cell[order]
        starts = np.flatnonzero(np.r_[True, cell[1:] != cell[:-1]]) if len(cell) else np.zeros(0, int)
        # each cell's centre: its elements' mean weighted by their unit flux toward the Moon's centre
        v = sc.moon - y
        r = np.linalg.norm(v, axis=1)
        wt = L1A * np.clip(np.einsum("ij,ij->i", m, v) / r, 1e-12, None) / r**2
        wsum = np.add.reduceat(wt, starts) if len(starts) else np.zeros(0)
        centre = (np.add.reduceat(y * wt[:, None], starts, axis=0) / wsum[:, None]) if len(starts) else np.zeros((0, 3))
        # first-order expansion about the Moon's centre x0 of each cell's sum of
        # g_f(x) = m_f·(x - y_f)/|x - y_f|³ over the elements x0 sees: g(x0) and ∇g(x0) =
        # m/r³ - 3 (m·v) v/r⁵; the neglected terms are O((R_M/r)²) ≈ 2e-5 relative, and the
        # elements within 0.26° of the Earth's limb that a lunar point sees but x0 does not
        mv = np.einsum("ij,ij->i", m, v)
        vis0 = mv > 0
        g0 = np.where(vis0, mv / r**3, 0.0)
        grad = np.where(vis0[:, None], m / r[:, None] ** 3 - 3 * (mv / r**5)[:, None] * v, 0.0)
        lin = {}
        for name, wgt in (("unit", L1A), ("map", L1A * a)):
            lin[name] = (np.add.reduceat(wgt * g0, starts) if len(starts) else np.zeros(0),
                         np.add.reduceat(wgt[:, None] * grad, starts, axis=0) if len(starts) else np.zeros((0, 3)))
        self._earth_el = dict(y=y, m=m, L1A=L1A, a=a, starts=starts, centre=centre, lin=lin)
        return self._earth_el

    def mapped_earth_transport(self, x, n, o, mu, geom, chunk: int = 32) -> Transport:
        """Earthshine :class:`Transport` at lunar points x from an Earth with an albedo map.

        The earthlight of every Earth facet reaching x is summed exactly per facet,
        ``a_f · L1_f · A_f · cos_f(x) / r_f(x)²`` (zero below x's horizon or behind the Earth's
        limb seen from x), and gathered into one beam per cell of the Earth's disc
        (:data:`EARTH_CELLS`² cells, each ≤ 0.08° across seen from the Moon) along the cell's
        flux-weighted centre. A map's edges are thus integrated by the facets' area averages
        (second order), not by a few Gauss beams across the disc, which leave ~1 % errors
        (tests/test_surfaces.py). The BRDF sees each cell's light from one direction: the
        error is second order in the cell's angular size. Lunar points whose horizon does not
        cut the Earth (nearly all) take each cell's sum from its first-order expansion about the
        Moon's centre (error ~(R_M/D)² ≈ 2e-5); the others sum the elements one by one.
        Traced with Embree: the Moon's
        shadow on each facet, a non-convex Earth hiding facets, a non-convex Moon shadowing
        each beam. Neglected: the Sun's extent lighting the Earth (as for the uniform Earth).
        """
        el = self._earth_elements()
        B, C = len(x), len(el["starts"])
        e_map, e_unit = np.zeros((B, C)), np.zeros((B, C))
        if C:
            y, m, L1A, a, st = el["y"], el["m"], el["L1A"], el["a"], el["starts"]
            # points whose horizon does not cut the Earth see every element: the cell sums are
            # smooth in x there and their first-order expansion about the Moon's centre serves
            cut = np.einsum("ij,ij->i", n, self.scene.earth - x) < self.earth.bound * (1 + 1e-6)
            far = np.flatnonzero(~cut)
            dx = x[far] - self.scene.moon
            for name, out in (("unit", e_unit), ("map", e_map)):
                s0, s1 = el["lin"][name]
                out[far] = np.clip(s0[None, :] + dx @ s1.T, 0.0, None)
            rows = np.flatnonzero(cut)
            for c0 in range(0, len(rows), chunk):
                sel = rows[c0:c0 + chunk]
                xs, ns = x[sel], n[sel]
                v = xs[:, None, :] - y[None, :, :]  # Earth element → lunar point
                r2 = np.einsum("bkj,bkj->bk", v, v)
                r = np.sqrt(r2)
                cos_y = np.clip(np.einsum("bkj,kj->bk", v, m) / r, 0.0, None)
                up = np.einsum("bkj,bj->bk", v, ns) < 0.0  # the element above x's horizon
                f = np.where(up, L1A * cos_y / r2, 0.0)
                e_unit[sel] = np.add.reduceat(f, st, axis=1)
                e_map[sel] = np.add.reduceat(f * a, st, axis=1)
        dirs = unit(el["centre"][None, :, :] - x[:, None, :]) if C else np.zeros((B, 0, 3))
        mu0 = np.einsum("bkj,bj->bk", dirs, n)
        e_free = e_map.copy()
        if self._self_shadows() and C:
            bi, ki = np.nonzero((e_unit > 0) & (mu0 > 0))
            xo = x[bi] + n[bi] * (NORMAL_OFFSET * self.moon.radius)
            blocked = self.moon.occluded(xo, dirs[bi, ki])
            self._count(bi.size)
            e_map[bi[blocked], ki[blocked]] = 0.0
            e_unit[bi[blocked], ki[blocked]] = 0.0
        sh, ch = half_angle_sin_cos(dirs, o[:, None, :])
        return Transport(mu0=np.clip(mu0, 0.0, 1.0), sin_hg=sh, cos_hg=ch, e_beam=e_map, mu=mu, geom=geom,
                         e_beam_free=e_free, e_beam_unit=e_unit)

    def beam_transport(self, x, n, o, mu, geom, body: str, order: int) -> Transport:
        """The :class:`Transport` of points x (B,3) with normals n, unit directions o to the
        detector, ``mu`` and ``geom``: ``body``'s deterministic beams (:meth:`source_nodes`),
        each traced to the source (:meth:`source_radiance`). Shared by the detector transport
        and the synthetic camera (lunarviz.methods.camera). An Earth with an albedo map takes
        :meth:`mapped_earth_transport` instead."""
        if body == "earth" and self.earth_facet_albedo() is not None and self.settings.mapped_earth == "facets":
            return self.mapped_earth_transport(x, n, o, mu, geom)
        if ray_kernels.available() and self._source(body)[2].mode(self.settings.shading) == "exact":
            return self._fused_beam_transport(x, n, o, mu, geom, body, order)
        from lunarviz.methods.tracer.ray_kernels import beam_angles, live_beams
        dirs, omega = self.source_nodes(x, n, body, order)
        mu0, sh, ch = beam_angles(dirs, n, o)
        bi, ki, xb, nb, db = live_beams(x, n, dirs, omega, mu0)
        Lb, Lb_free, lu = self.source_radiance(xb, nb, db, body)
        flat = bi * omega.shape[1] + ki  # scatter through flat indices (2-D fancy indexing is slower)
        om_b = omega.reshape(-1)[flat]

        def beams(values):
            e = np.zeros(omega.shape)
            e.reshape(-1)[flat] = values * om_b
            return e
        return Transport(mu0=np.clip(mu0, 0.0, 1.0), sin_hg=sh, cos_hg=ch, e_beam=beams(Lb),
                         mu=mu, geom=geom, e_beam_free=beams(Lb_free),
                         e_beam_unit=None if lu is None else beams(lu))

    def _fused_beam_transport(self, x, n, o, mu, geom, body: str, order: int) -> Transport:
        """:meth:`beam_transport` toward an exact-sphere source, compiled (issue 13): one pass
        from the rule to Embree's rays (:func:`lunarviz.methods.tracer.ray_kernels.cap_beam_rays` for the Earth's
        one-cap rule, else :meth:`source_nodes` then ``beam_rays``), one from Embree's facets to
        each beam's radiance (``source_hits``), one per shadow test (``occluder_rays``) and one
        into the (B, K) arrays (``scatter_beams``); Python only calls Embree between them. The
        same rays, counts and numbers as the numpy path (:meth:`source_radiance`) to rounding
        (the kernel tests)."""
        from lunarviz.methods.tracer.embree_bodies import ENTRY_MARGIN
        K = ray_kernels
        sc, s = self.scene, self.settings
        src = self.sun if body == "sun" else self.earth
        outer = src.outer_scene()  # (built once per body; sets its bounding radius)
        off, Rb = NORMAL_OFFSET * self.moon.radius, src.outer_bound * (1.0 + ENTRY_MARGIN)
        c, R, _ = self._source(body)
        if body == "earth" and not horizon_cuts_source(sc, x, n, body).any():
            cs = sc.sun - c  # the rule's one cap: the Earth's sunlit hemisphere (as in source_nodes)
            rays = K.cap_beam_rays(x, n, o, c, R, unit(cs), R / np.linalg.norm(cs), order, off, Rb)
        else:
            dirs, omega = self.source_nodes(x, n, body, order)
            rays = K.beam_rays(x, n, o, dirs, omega, off, c, Rb)
        self._count(len(rays.bi))
        prim = src.run_rays(rays.o32, rays.d32, "INTERSECT", scene=outer) if len(rays.idx) else np.empty(0, np.int64)
        if body == "sun":
            t, L, L_unit, counts = K.source_hits(rays, prim, src.radius, src.centre, src.n_faces,
                                                 sun_radiance=self.sun_surface_radiance())
        else:
            fa = self.earth_facet_albedo()
            alb = np.array([self.earth_albedo_value()]) if fa is None else fa
            t, L, L_unit, counts = K.source_hits(rays, prim, src.radius, src.centre, src.n_faces,
                                                 earth=(sc.sun, sc.phi, self.sun_visibility_of_earth(), alb))
        with self._lock:
            self.source_hits[body] += counts
        L_free = L.copy()
        if body == "sun" and s.occlusion:  # the Earth between the Moon and the Sun
            live = L > 0
            self._count(int(np.count_nonzero(live)))
            L[self.earth.occluded_beams(rays, t, live)] = 0.0
        if self._self_shadows():
            live = (L > 0) | (L_unit > 0) if body == "earth" else L > 0
            self._count(int(np.count_nonzero(live)))
            blocked = self.moon.occluded_beams(rays, t, live)
            L[blocked] = 0.0
            L_unit[blocked] = 0.0
        e, e_free, e_unit = K.scatter_beams(rays, L, L_free, L_unit if body == "earth" else None)
        return Transport(mu0=np.clip(rays.mu0, 0.0, 1.0), sin_hg=rays.sin_hg, cos_hg=rays.cos_hg, e_beam=e,
                         mu=mu, geom=geom, e_beam_free=e_free, e_beam_unit=e_unit)

    def montecarlo_transport(self, body: str, key):
        """Yield ``(Transport, owning facets)`` for chunks of ≤ CHUNK of the N Monte Carlo
        samples; each sample's weight already carries the 1/N of the estimator.

        Chunk i draws from its own generator, ``default_rng([*key, i])`` (``key`` = seed, run,
        path), so the chunks are independent of each other and of the thread count: with
        ``threads`` > 1 they are traced on that many threads, in order, with the same numbers."""
        s = self.settings
        sizes = [min(CHUNK, s.rays - a) for a in range(0, s.rays, CHUNK)]
        self._warm_shared(body)
        self._facet_pdf(body)  # memoised here (with the candidates), before any thread asks

        def chunk(i):
            return [self._montecarlo_chunk(body, np.random.default_rng([*key, i]), sizes[i], s.rays)]
        yield from self._chunks_in_order(chunk, len(sizes))

    def _chunks_in_order(self, chunk, n: int):
        """``chunk(0), chunk(1), …`` (each a list of ``(Transport, owner)``), flattened in order;
        on ``threads`` threads a few ahead of the consumer when there are several."""
        threads = self.moon.threads
        if threads <= 1 or n <= 1:
            for i in range(n):
                yield from chunk(i)
            return
        from collections import deque
        from concurrent.futures import ThreadPoolExecutor

        from lunarviz.methods.tracer.embree_bodies import serial_embree

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

    def _facet_pdf(self, body: str):
        """Candidate facets, their areas and the probability of drawing each (memoised per
        body: every Monte Carlo chunk draws from the same distribution)."""
        key = ("pdf", body)
        if key in self._cand_cache:
            return self._cand_cache[key]
        sc = self.scene
        M = self.moon
        c, R, _ = self._source(body)
        cand = self.candidates(body)
        x, n = (a[cand] for a in M.facet_points(self.settings.shading))
        dA = M.areas[cand]
        _, g0, _ = detector_geometry(x, n, dA, sc.det, sc.det_normal)
        v = c - x
        d = np.linalg.norm(v, axis=1)
        # importance proxy: the contribution's shape for a Lambert (∝ μ0 μ) and a Hapke
        # (∝ μ0/(μ0+μ) μ) surface, mixed so neither has weights above ~2× its mean; μ0 is
        # softened by the source's angular radius so penumbra facets keep a positive share
        mu0 = np.clip(np.einsum("ij,ij->i", n, v) / d + R / d, 0.0, None)
        mu_det = np.clip(np.einsum("ij,ij->i", n, unit(sc.det - x)), 1e-6, None)
        proxy = g0 * (mu0 + mu0 / (mu0 + mu_det))
        p = UNIFORM_SHARE * dA / dA.sum()
        if proxy.sum() > 0:
            p = p + (1 - UNIFORM_SHARE) * proxy / proxy.sum()
        else:
            p = p / UNIFORM_SHARE
        self._cand_cache[key] = (cand, dA, p)
        return cand, dA, p

    def _montecarlo_chunk(self, body: str, rng: np.random.Generator, N: int, N_total: int):
        s = self.settings
        M = self.moon
        c, R, src = self._source(body)
        cand, dA, p = self._facet_pdf(body)
        mode = M.mode(s.shading)
        pick = rng.choice(len(cand), size=N, p=p)
        f = cand[pick]
        # a uniform point in each picked flat triangle (then shaded per ``shading``)
        r1, r2 = rng.random(N), rng.random(N)
        s1 = np.sqrt(r1)
        tri = M.vertices[M.faces[f]]
        pts = (1 - s1)[:, None] * tri[:, 0] + (s1 * (1 - r2))[:, None] * tri[:, 1] + (s1 * r2)[:, None] * tri[:, 2]
        area_w = dA[pick] / (N_total * p[pick])
        if mode == "exact":
            # uniform on the flat facet, projected on the sphere: weight by the projection's
            # Jacobian dA_sphere/dA_flat = R² (n_f·x)/|x|³, so the estimator stays unbiased
            r = np.linalg.norm(pts, axis=1)
            ns = pts / r[:, None]
            xs = M.centre + M.radius * ns
            area_w = area_w * M.radius**2 * np.abs(np.einsum("ij,ij->i", M.normals[f], pts)) / r**3
        elif mode == "interp":
            xs = pts + M.centre
            ns = M.shading_normals(f, xs)
        else:
            xs, ns = pts + M.centre, M.normals[f]
        mu, geom, o = self.detector_view(xs, ns, area_w)
        if body == "earth" and src.mode(s.shading) == "exact":
            dirs, omega = self._earth_lit_directions(xs, rng)
        else:
            dirs, omega = self._cone_directions(xs, c, R, rng)
        mu0 = np.einsum("ij,ij->i", dirs, ns)
        li = np.flatnonzero((mu0 > 0) & (geom > 0))
        L = np.zeros(N)
        L_unit = np.zeros(N) if body == "earth" else None
        L[li], _, lu = self.source_radiance(xs[li], ns[li], dirs[li], body)
        if L_unit is not None:
            L_unit[li] = lu
        sh, ch = half_angle_sin_cos(dirs, o)
        tr = Transport(mu0=np.clip(mu0, 0, 1)[:, None], sin_hg=sh[:, None], cos_hg=ch[:, None],
                       e_beam=(L * omega)[:, None], mu=mu, geom=geom,
                       e_beam_unit=None if L_unit is None else (L_unit * omega)[:, None])
        return self.with_moon_albedo(tr, f), f

    @staticmethod
    def _cone_directions(xs, c, R, rng):
        """One direction uniform in solid angle within the source's cone; weight = Ω_cone."""
        N = len(xs)
        vc = c - xs
        dc = np.linalg.norm(vc, axis=1)
        axis = vc / dc[:, None]
        sin_rho = R / dc
        one_m_cos = sin_rho**2 / (1 + np.sqrt(1 - sin_rho**2))  # 1 - cos ρ without cancellation
        um = rng.random(N) * one_m_cos
        cpsi = 1 - um
        spsi = np.sqrt(np.clip(um * (2 - um), 0, None))
        phi = 2 * np.pi * rng.random(N)
        e1, e2 = orthonormal_basis(axis)
        dirs = cpsi[:, None] * axis + spsi[:, None] * (np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2)
        return dirs, 2 * np.pi * one_m_cos

    def _earth_lit_directions(self, xs, rng, n_tab: int = 24):
        """One direction toward the Earth's lit, visible part per sample, and its weight [sr].

        Polar coordinates (t, φ) on the Earth's sphere about the sub-sample point: t is drawn
        from a tabulated pdf ∝ J(t)·2hw(t) (J = dΩ/dt dφ, exact; hw = half-width of the lit
        arc of ring t, the terminator being a cap), φ uniformly within the lit arc. The weight
        J·2hw/p(t) uses the pdf actually sampled (piecewise constant between table nodes,
        floored so every lit ring keeps a positive density), so the estimator is unbiased.
        Dark Earth is never sampled: at a crescent Earth this removes most of the variance.
        """
        sc = self.scene
        N = len(xs)
        R = sc.radii["earth"]
        us = unit(sc.sun - sc.earth)
        c_s = R / np.linalg.norm(sc.sun - sc.earth)
        if ray_kernels.available():  # compiled, the same two uniforms per sample in the same order
            return ray_kernels.earth_lit_directions(xs, sc.earth, R, us, c_s, n_tab, rng.random(N), rng.random(N))
        v = xs - sc.earth
        d = np.linalg.norm(v, axis=1)
        a = v / d[:, None]
        e1, e2 = orthonormal_basis(a)
        ctu = a @ us
        stu = np.sqrt(np.clip(1 - ctu**2, 0, None))
        phi_u = np.arctan2(e2 @ us, e1 @ us)
        t_max = np.arccos(R / d)

        def half_width(t):
            den = np.sin(t) * stu[:, None]
            num = c_s - np.cos(t) * ctu[:, None]
            with np.errstate(divide="ignore", invalid="ignore"):
                q = np.where(np.abs(den) > 1e-300, num / den, np.where(num < 0, -np.inf, np.inf))
            return np.arccos(np.clip(q, -1.0, 1.0))

        def jac(t):
            dd = d[:, None]
            r2 = dd * dd + R * R - 2 * dd * R * np.cos(t)
            return np.clip(dd * np.cos(t) - R, 0, None) * R * R * np.sin(t) / r2**1.5

        tk = t_max[:, None] * np.linspace(0.0, 1.0, n_tab + 1)[None, :]
        g = jac(tk) * 2 * half_width(tk)
        cell = 0.5 * (g[:, 1:] + g[:, :-1])
        cell = np.maximum(cell, 1e-3 * cell.mean(axis=1, keepdims=True) + 1e-300)
        dt = t_max / n_tab
        mass = cell * dt[:, None]
        cdf = np.cumsum(mass, axis=1)
        total = cdf[:, -1]
        u = rng.random(N) * total
        k = np.minimum((cdf < u[:, None]).sum(axis=1), n_tab - 1)
        lo = np.where(k > 0, cdf[np.arange(N), k - 1], 0.0)
        frac = (u - lo) / mass[np.arange(N), k]
        t = (k + np.clip(frac, 0, 1)) * dt
        pdf_t = cell[np.arange(N), k] / total
        hw = half_width(t[:, None])[:, 0]
        phi = phi_u + (2 * rng.random(N) - 1) * hw
        m = np.cos(t)[:, None] * a + np.sin(t)[:, None] * (np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2)
        y = sc.earth + R * m
        dirs = unit(y - xs)
        weight = np.where(hw > 0, jac(t[:, None])[:, 0] * 2 * hw / pdf_t, 0.0)
        return dirs, weight


@dataclass
class PathResult:
    """One path (moonshine or earthshine) at one phase, for every BRDF."""

    mean: dict  # brdf -> detector irradiance [W m-2]
    #: brdf -> standard deviation of one run [W m-2], pooled from the samples within every run
    #: (reliable at any number of runs; 0 for deterministic; NaN when undefined: one ray)
    std: dict
    run_values: dict  # brdf -> list of per-run values [W m-2]
    within_std: dict  # brdf -> list of per-run standard deviations estimated inside each run
    rays: int
    seconds: float
    facets: dict = field(default_factory=dict)  # per-facet arrays (last run)
    #: brdf -> standard deviation of the mean over runs [W m-2]: std / sqrt(runs)
    sem: dict = field(default_factory=dict)
    #: brdf -> spread (ddof 1) of the run values [W m-2]; NaN with one run (a diagnostic)
    spread: dict = field(default_factory=dict)
    #: earthshine only: brdf -> mean for an Earth of albedo 1 [W m-2] (same rays; the
    #: earthshine-weighted albedo of the Earth is ``mean / mean_unit``)
    mean_unit: dict = field(default_factory=dict)


def trace_path(ts: TraceScene, path: str, brdfs: dict, keep_facets: bool = False) -> PathResult:
    """Trace ``path`` once per run and shade every BRDF from the one transport."""
    s = ts.settings
    body = PATHS[path]
    t0 = time.perf_counter()
    r0 = ts.rays_cast
    runs = 1 if s.estimator == "deterministic" else s.runs
    vals = {k: [] for k in brdfs}
    units = {k: [] for k in brdfs}
    within = {k: [] for k in brdfs}
    facets = {}
    nf = ts.moon.n_faces
    for run in range(runs):
        if s.estimator == "deterministic":
            chunks = ts.deterministic_transport(body)
        else:
            chunks = ts.montecarlo_transport(body, [s.seed, run, 0 if path == "moonshine" else 1])
        tot = {k: 0.0 for k in brdfs}
        tot_unit = {k: 0.0 for k in brdfs}
        sq = {k: 0.0 for k in brdfs}
        count = 0
        keep = keep_facets and run == runs - 1
        fac = {}
        for tr, owner in chunks:
            count += len(owner)
            for k, b in brdfs.items():
                L, L_unit = tr.radiances(b)
                contrib = L * tr.geom
                if L_unit is not None:
                    tot_unit[k] += float(np.dot(L_unit, tr.geom))
                tot[k] += float(contrib.sum())
                sq[k] += float(np.dot(contrib, contrib))
                if keep:
                    key = f"{path}_contribution_{k}"
                    fac[key] = fac.get(key, 0.0) + np.bincount(owner, contrib, nf)
            if keep:
                lit_s, free_s = tr.lit_fraction_parts()
                for key, per_sample in ((f"{path}_irr_sum", tr.irradiance_on_sample()),
                                        (f"{path}_lit_sum", lit_s),
                                        (f"{path}_free_sum", free_s),
                                        (f"{path}_count", np.ones(len(owner))),
                                        (f"{path}_rays", (tr.e_beam > 0).sum(1).astype(float)),
                                        (f"{path}_geom", tr.geom)):
                    fac[key] = fac.get(key, 0.0) + np.bincount(owner, per_sample, nf)
        for k in brdfs:
            vals[k].append(tot[k])
            units[k].append(tot_unit[k])
            if s.estimator == "montecarlo" and count > 1:
                # contributions c_i = f_i / (N p_i): Var(Σ c) = N Var(c), Var(c) from the sums
                var_c = (sq[k] - tot[k] ** 2 / count) / (count - 1)
                within[k].append(float(np.sqrt(max(count * var_c, 0.0))))
            elif s.estimator == "montecarlo":
                within[k].append(float("nan"))  # one sample: no spread to estimate σ from
            else:
                within[k].append(0.0)
        if keep:
            zero = np.zeros(nf)
            for k in brdfs:
                facets[f"{path}_contribution_{k}"] = np.asarray(fac.get(f"{path}_contribution_{k}", zero))
            cnt = np.asarray(fac.get(f"{path}_count", zero))
            facets[f"{path}_irradiance"] = np.asarray(fac.get(f"{path}_irr_sum", zero)) / np.maximum(cnt, 1)
            facets[f"{path}_rays"] = np.asarray(fac.get(f"{path}_rays", zero))
            facets[f"{path}_geom"] = np.asarray(fac.get(f"{path}_geom", zero))
            facets[f"{path}_lit_sum"] = np.asarray(fac.get(f"{path}_lit_sum", zero))
            facets[f"{path}_free_sum"] = np.asarray(fac.get(f"{path}_free_sum", zero))
    std, sem, spread = {}, {}, {}
    for k in brdfs:
        if s.estimator == "deterministic":
            std[k] = sem[k] = spread[k] = 0.0
            continue
        # pooled: every run's σ is estimated from its own N samples, so the pooled value is as
        # good with one run as with many (the spread of a few runs is not: with 4 runs its
        # relative error is ~40 %, which made "7.9 σ" deviations in the quick report)
        std[k] = float(np.sqrt(np.mean(np.square(within[k]))))
        sem[k] = std[k] / np.sqrt(runs)
        spread[k] = float(np.std(vals[k], ddof=1)) if runs >= 2 else float("nan")
    return PathResult(mean={k: float(np.mean(v)) for k, v in vals.items()}, std=std,
                      run_values=vals, within_std=within, rays=ts.rays_cast - r0,
                      seconds=time.perf_counter() - t0, facets=facets, sem=sem, spread=spread,
                      mean_unit={k: float(np.mean(v)) for k, v in units.items()} if body == "earth" else {})
