"""Lunar samples: facets worth tracing, shadow-edge and lune refinement, sample albedo, the
detector's view.

A job of :class:`~lunarviz.methods.tracer.trace_scene.TraceScene` (one per module); its
collaborators (the traced bodies, the facets' surfaces, the other jobs it calls) are passed in."""

from __future__ import annotations

import numpy as np

from lunarviz.geometry.mapped_lune import mapped_lune_rule
from lunarviz.geometry.scene_geometry import angle_between, unit
from lunarviz.geometry.subdivision import sub_barycentric
from lunarviz.methods.analytic import hidden_view_cut, lunar_surface_rule
from lunarviz.methods.tracer import settings as tuning
from lunarviz.methods.tracer.facet_surfaces import FacetSurfaces
from lunarviz.methods.tracer.settings import (
    KINK_FREE_WIDTH,
    LUNE_SAMPLES,
    NORMAL_OFFSET,
    REFINE,
)
from lunarviz.methods.tracer.traced_bodies import TracedBodies
from lunarviz.methods.transport import detector_geometry
from lunarviz.surfaces.maps import map_frame
from lunarviz.surfaces.moon_map import moon_facet_values

#: the lune rule cut where the detector's view ends (a horizon, the Earth's limb) takes this many
#: times the order the error model chose for the whole lune: the model was measured uncut, and a
#: cut rule met it only at about twice the order (python scripts/off_centre_validation.py --view-cut 3)
VIEW_CUT_ORDER_FACTOR = 2

class LunarSampling:
    """Lunar samples: a job of :class:`~lunarviz.methods.tracer.trace_scene.TraceScene`, with its
    collaborators passed in."""

    def __init__(self, bodies: TracedBodies, surfaces: FacetSurfaces):
        self.bodies = bodies
        self.surfaces = surfaces
        self._cand_cache: dict = {}
        self._kinks = None
        #: per body: candidate facets that a shadow or hidden-view edge crosses (``candidates``)
        self._edge_cache: dict = {}
        self._mapped_lune_cache: dict = {}  # (body, cut at i = e) -> the mapped lune rule (or None: facets)
        #: per-facet arrays are being accumulated (:func:`~lunarviz.methods.tracer.estimators.trace_path`'s
        #: ``keep_facets``): lunar samples then come from the facets, never the lune rule
        self.per_facet = False
        #: the samples' light is only summed into rows (set by
        #: :func:`~lunarviz.methods.tracer.estimators.trace_path` without ``keep_facets``): samples
        #: whose horizon cuts the Earth may then take a coarser Earth rule
        #: (:func:`~lunarviz.methods.tracer.settings.horizon_band_order`); per-facet arrays and
        #: images (which shade each point for itself) keep the full order
        self.summed = False
        #: a BRDF being shaded has Hapke's roughness (its kink at i = e: the mapped lune rule cuts
        #: there); set by :func:`~lunarviz.methods.tracer.estimators.trace_path`
        self.rough_brdf = False
        self.albedo_scale = 0.0  # from the lunar map to the shaded BRDFs' w (trace_path sets both)


    def candidates(self, body: str) -> np.ndarray:
        """Lunar facets that the detector may see and the source may (partly) light.

        Tested on the facet's corners as well as its centroid, so a facet that a kink crosses
        is never dropped. Memoised per body (``self._kinks`` follows the last body asked).
        Computed in blocks of FACET_BLOCK facets, so memory stays bounded on any mesh.
        """
        if body in self._cand_cache:
            cand, self._kinks = self._cand_cache[body]
            return cand
        M = self.bodies.moon
        c, R, _ = self.bodies.source(body)
        x_all, n_all = M.facet_points(self.bodies.settings.shading)
        if M.mode(self.bodies.settings.shading) == "interp":
            M.corner_normals  # noqa: B018 (a cached property: built here, before the blocks' threads)
        F = M.n_faces
        keep = np.zeros(F, dtype=bool)
        kinks = np.zeros(F, dtype=bool)

        def block(i):
            blk = slice(i * tuning.FACET_BLOCK, min(F, (i + 1) * tuning.FACET_BLOCK))
            lit, vis = self._kink_values(x_all[blk], n_all[blk], c, R)
            tri = M.vertices[M.faces[blk]] + M.centre
            vn = self.bodies.corner_normals(M, blk)
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
        list(self.bodies.chunks_in_order(block, -(-F // tuning.FACET_BLOCK)))
        cand = np.flatnonzero(keep)
        self._kinks = kinks
        if self._edge_tests(body):
            def edges(i):
                return [self._shadow_edges(cand[i * tuning.FACET_BLOCK:(i + 1) * tuning.FACET_BLOCK], c)]
            found = np.concatenate([np.empty(0, np.int64), *self.bodies.chunks_in_order(
                edges, -(-len(cand) // tuning.FACET_BLOCK))])
            self._kinks[found] = True
            self._edge_cache[body] = found
        else:
            self._edge_cache[body] = np.empty(0, np.int64)
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
        M = self.bodies.moon
        s = self.bodies.settings
        if cand.size == 0:
            return cand
        tri = M.vertices[M.faces[cand]] + M.centre
        pts = np.concatenate([M.centroids[cand][:, None, :], tri], axis=1)  # (F, 4, 3)
        off = M.normals[cand][:, None, :] * (NORMAL_OFFSET * M.radius)
        p = (pts + off).reshape(-1, 3)
        mixed = np.zeros(len(cand), dtype=bool)
        det = self.bodies.scene.det
        for to_det, target in ((False, c), (True, det)):
            v = target - p
            dist = np.linalg.norm(v, axis=1)
            d = v / dist[:, None]
            blocked = np.zeros(len(p), dtype=bool)
            if self.bodies.self_shadows():
                blocked |= self.bodies.moon.occluded(p, d, dist)
                self.bodies.count(len(p))
            if to_det and self.bodies.scene.horizon_normal is not None:
                blocked |= ~self.bodies.scene.sight_lines_clear(p)
            elif (to_det and not self.bodies.scene.detector_inside("earth")) or (not to_det and s.occlusion):
                blocked |= self.bodies.earth.occluded(p, d, dist)
                self.bodies.count(len(p))
            b = blocked.reshape(-1, 4)
            mixed |= b.any(1) & ~b.all(1)
        return cand[mixed]

    def _kink_values(self, x, n, c, R):
        """``n·(c - x)/R`` (> 1 source wholly above the horizon, < -1 wholly below, between:
        penumbra; docs: derivations, §1) and μ toward the detector."""
        lit = np.einsum("ij,ij->i", n, c - x) / R
        w = self.bodies.scene.det - x
        return lit, np.einsum("ij,ij->i", n, w) / np.linalg.norm(w, axis=1)

    def lunar_refinement(self, body: str) -> int:
        """Sub-division of every lit-and-visible facet so ≥ LUNE_SAMPLES samples span the lune.

        The lit and visible region is a lune of width w = π - (source-Moon-detector angle);
        at a thin crescent it is only a few facets wide and the facet rule errs by
        ~(h/w)² (1 % at θ = 175° on level 6). Powers of two up to 16. Flat facets carry no
        kink inside (constant normal), so they are never split for this.
        """
        M = self.bodies.moon
        if M.mode(self.bodies.settings.shading) == "flat":
            return 1
        w = self._lune_width(body)
        h = np.sqrt(np.mean(M.areas)) / M.radius
        need = LUNE_SAMPLES * h / max(w, 1e-9)
        return int(min(16, 2 ** int(np.ceil(np.log2(max(need, 1.0))))))

    def _lune_width(self, body: str) -> float:
        sc = self.bodies.scene
        c, _, _ = self.bodies.source(body)
        return np.pi - float(np.arccos(np.clip(np.dot(unit(c - sc.moon), unit(sc.det - sc.moon)), -1, 1)))

    def sample_albedo(self, faces, sub: int):
        """The lunar map's value for each sample of ``M.surface_samples(faces, shading, sub)``,
        in its order: the map's area average over the sample's own sub-triangle (so refined
        facets, at terminators and limbs, see the map at their finer scale; ``sub = 1`` gives
        the facet averages of :meth:`moon_facet_albedo`). ``None`` without a map."""
        amap = self.bodies.settings.moon_map()
        if amap is None:
            return None
        if sub == 1 or len(faces) == 0:
            mean, sd = (a[faces] for a in self.surfaces.moon_facet_albedo(spread=True))
        else:
            M = self.bodies.moon
            _, tri_b = sub_barycentric(sub)
            corners = np.einsum("svk,fkj->fsvj", tri_b, M.vertices[M.faces[np.asarray(faces, dtype=np.int64)]])
            verts = corners.reshape(-1, 3)
            mean, sd = moon_facet_values(amap, M, map_frame(self.bodies.scene, "moon"),
                                         faces=(verts, np.arange(len(verts)).reshape(-1, 3)))  # (F·sub²,)
        per = 1 if self.bodies.moon.mode(self.bodies.settings.shading) == "flat" else 3
        return np.repeat(mean, per), np.repeat(sd, per)

    def lune_rule_applies(self, body: str) -> bool:
        """Whether ``body``'s lunar samples come from the lune rule (:meth:`lune_samples`): asked
        for (``lune_order``), no per-facet arrays being kept (:attr:`per_facet`), on the packaged
        exact sphere (never a user's mesh), a lunar map's contrast in its weights where the blocks
        allow (:meth:`_mapped_lune`), with no eclipse possible (:meth:`eclipse_possible`) and no shadow or
        hidden-view edge across the lit, visible lune (found on the facets, as for refinement:
        the Earth's limb hiding part of the Moon from an outside detector)."""
        s = self.bodies.settings
        if s.lune_order is None or self.per_facet or self.bodies.moon.mode(s.shading) != "exact":
            return False
        if body == "sun" and self.eclipse_possible():  # the penumbra's edges are kinks inside the lune
            return False
        contrast = self._moon_map_contrast()
        if self._edge_tests(body):  # a body may shade or hide a part of the lune: edges on the facets
            self.candidates(body)
            if self._edge_cache[body].size and not self._view_cut_alone(contrast):
                return False
        return not contrast or self._mapped_lune(body) is not None

    def _view_cut_alone(self, contrast: bool) -> bool:
        """Whether the only edges that can cross the lune are those of the detector's view, which
        the plain lune rule cuts itself where Embree found them (:meth:`lune_samples`,
        :func:`lunarviz.methods.analytic.hidden_view_cut`: a site's horizon, the Earth's limb as
        the exact sphere): no lunar map's contrast (its rule has no such cut), the Moon casting
        no shadow on itself, the Earth the packaged sphere (its limb; with its facets, facet by
        facet). (The Sun's eclipses never reach here.)"""
        s = self.bodies.settings
        return not contrast and not self.bodies.self_shadows() and self.bodies.earth.mode(s.shading) == "exact"

    def _mapped_lune(self, body: str):
        """The lune rule with the lunar map in its weights (:func:`lunarviz.geometry.mapped_lune.mapped_lune_rule`),
        cut where i = e for the Sun's path when a BRDF being shaded is rough (:attr:`rough_brdf`),
        once per body; ``None`` where its blocks are not smooth patches (the facets then)."""
        key = (body, self.rough_brdf and body == "sun", self.albedo_scale)
        if key not in self._mapped_lune_cache:
            c, R, _ = self.bodies.source(body)
            s = self.bodies.settings
            values = np.asarray(s.moon_map().values(), dtype=float)
            sc = self.bodies.scene
            self._mapped_lune_cache[key] = mapped_lune_rule(
                sc, c, R, s.lune_order[0 if body == "sun" else 1], values, map_frame(sc, "moon"),
                kink=key[1], albedo_scale=self.albedo_scale)
        return self._mapped_lune_cache[key]

    def mapped_rule_used(self, body: str):
        """The mapped lune rule (:meth:`_mapped_lune`: x, n, dA, AlbedoNodes) that ``body``'s
        deterministic samples came from, or ``None`` (no map contrast, the facets, Monte Carlo)."""
        s = self.bodies.settings
        if s.estimator != "deterministic" or not self.lune_rule_applies(body) or not self._moon_map_contrast():
            return None
        return self._mapped_lune(body)

    def edges_found(self, body: str) -> bool:
        """Whether :meth:`candidates` found a cast-shadow or hidden-view edge across the Moon."""
        return body in self._edge_cache and bool(self._edge_cache[body].size)

    def view_edge_missed(self, body: str) -> bool:
        """Whether the lune rule was taken whole although the exact spheres put the view's edge
        across the Moon's disc (:func:`~lunarviz.methods.analytic.hidden_view_cut`): the facets'
        sight lines found no edge, as where the Earth's limb cuts a sliver thinner than its mesh's
        sag (the level-6 facets lie up to ~0.2 km inside the sphere: seen from a 550 km orbit, 1.6 %
        of the Moon's radius). Such a row has no bound."""
        return self._view_cut_alone(self._moon_map_contrast()) and not self.edges_found(body) \
            and hidden_view_cut(self.bodies.scene) != (None, None)

    def earth_covers_moon(self) -> bool:
        """Whether the Earth's exact sphere hides the whole Moon from a detector outside it
        (:meth:`~lunarviz.geometry.scene_geometry.SceneGeometry.moon_wholly_hidden` without its
        margins) on a date that is computed (the skip test keeps its margins): the packaged
        Earth's facets lie inside its sphere, so its sight lines may still pass to a sliver of Moon
        that the exact scene hides (its rows then hold only that sliver's light, ~100 % off the
        exact zero). Such a row has no bound."""
        sc = self.bodies.scene
        return sc.horizon_normal is None and sc.moon_wholly_hidden(margin=0.0)

    def moon_shadow_on_earth_possible(self) -> bool:
        """With occlusion, whether the Moon's shadow may fall on the Earth (a solar eclipse, the
        earthshine's source partly dark): seen from the Earth's centre, the Moon's and the Sun's
        discs come closer than their radii plus the Earth's parallax, with a margin."""
        if not self.bodies.settings.occlusion:
            return False
        sc = self.bodies.scene
        vs, vm = sc.sun - sc.earth, sc.moon - sc.earth
        ds, dm = np.linalg.norm(vs), np.linalg.norm(vm)
        moon, earth = self.bodies.moon, self.bodies.earth
        reach = np.arcsin(min(1.0, sc.radii["sun"] / ds)) \
            + np.arcsin(min(1.0, moon.bound / (dm - earth.bound))) + 2.0 * earth.bound / dm
        return bool(angle_between(vs, vm) < reach * (1 + 1e-3))

    def eclipse_possible(self) -> bool:
        """With occlusion, whether the Earth's disc may overlap the Sun's from some lunar point
        (a lunar eclipse, penumbral included): seen from the Moon's centre, the two discs come
        closer than their radii plus the Moon's own parallax (its radius seen from the Earth),
        with a margin. Conservative: false only where no lunar point can be shaded."""
        if not self.bodies.settings.occlusion:
            return False
        sc = self.bodies.scene
        vs, ve = sc.sun - sc.moon, sc.earth - sc.moon
        ds, de = np.linalg.norm(vs), np.linalg.norm(ve)
        moon, earth = self.bodies.moon, self.bodies.earth
        reach = np.arcsin(min(1.0, sc.radii["sun"] / (ds - moon.bound))) \
            + np.arcsin(min(1.0, earth.bound / (de - moon.bound))) + 2.0 * moon.bound / de
        return bool(angle_between(vs, ve) < reach * (1 + 1e-3))

    def _edge_tests(self, body: str) -> bool:
        """Whether a cast-shadow or hidden-view edge can cross the lit, visible Moon: the Moon
        shadows itself, the Earth may shade it (moonshine, where an eclipse is possible:
        :meth:`eclipse_possible`), the detector is on the ground, or it is outside the Earth and
        the Earth's disc may cover part of the Moon's (:meth:`earth_may_hide_moon`)
        (:meth:`candidates` then traces the edges)."""
        sc = self.bodies.scene
        hidden_view = (not sc.detector_inside("earth") and self.earth_may_hide_moon()) or sc.horizon_normal is not None
        return self.bodies.self_shadows() or (body == "sun" and self.eclipse_possible()) or hidden_view

    def earth_may_hide_moon(self) -> bool:
        """From a detector outside the Earth, whether the Earth's disc may cover some of the
        Moon's: their bounding spheres' angular radii, grown by 0.1 %, against the angle between
        their centres (with a 0.1 % margin). Conservative: false only where no sight line from
        the Moon to the detector can meet the Earth, so no hidden-view edge needs tracing (from
        a 550 km orbit: all dates but those within ~0.3° of moonrise or moonset behind the Earth)."""
        sc = self.bodies.scene
        v, w = sc.moon - sc.det, sc.earth - sc.det
        if np.linalg.norm(w) <= self.bodies.earth.bound * (1 + 1e-3):  # within the mesh's bounding sphere: any way
            return True
        reach = np.arcsin(min(1.0, self.bodies.moon.bound * (1 + 1e-3) / np.linalg.norm(v))) \
            + np.arcsin(min(1.0, self.bodies.earth.bound * (1 + 1e-3) / np.linalg.norm(w)))
        return bool(angle_between(v, w) < reach * (1 + 1e-3))

    def lune_samples(self, body: str):
        """Lunar samples of the lune rule: product Gauss rules over the part of the exact sphere
        that the detector sees and the source lights (``n·(S - M) > R_M - ρ``), split where the
        source's disc crosses the horizon (``R_M ± ρ``) so the penumbra band is a segment of its
        own (:func:`lunarviz.methods.analytic.lunar_surface_rule`; the exact reference uses the
        same rule at a higher order). Every sample's light is still traced through Embree: the
        rule only places the samples. Owners are -1 (no facet: per-facet arrays need facet
        samples, see :func:`~lunarviz.methods.tracer.estimators.trace_path`). With a lunar map
        the map's part is :class:`~lunarviz.geometry.mapped_lune.AlbedoNodes` (each sample shaded
        at the map values it holds, weighted by the map's cells)."""
        if self._moon_map_contrast():  # the map's cells in the weights: AlbedoNodes
            x, n, dA, alb = self._mapped_lune(body)
            return x, n, dA, np.full(len(x), -1, dtype=np.int64), alb
        c, R, _ = self.bodies.source(body)
        sc = self.bodies.scene
        # cut where the view ends only where Embree found that edge across the Moon (its sight lines
        # then confirm every node; with no edge found, the rule is the whole lune), at VIEW_CUT_ORDER_FACTOR
        # times the order (the lune model was measured uncut: a horizon across a half Moon erred 8.3e-5
        # at the moonshine's order 10, 5.5e-6 at 16, 5.1e-7 at 24, against the exact reference)
        cut = self.edges_found(body)
        order = self.bodies.settings.lune_order[0 if body == "sun" else 1]
        x, n, dA = lunar_surface_rule(sc, c, R, order * VIEW_CUT_ORDER_FACTOR if cut else order, view_cut=cut)
        fa = self.surfaces.moon_facet_albedo(spread=True)  # a uniform map (no contrast): its one value everywhere
        alb = None if fa is None else (np.full(len(x), fa[0][0]), np.zeros(len(x)))
        return x, n, dA, np.full(len(x), -1, dtype=np.int64), alb

    def _moon_map_contrast(self) -> bool:
        """A lunar map whose facets differ (its cells are edges the lune rule does not know)."""
        fa = self.surfaces.moon_facet_albedo(spread=True)
        return fa is not None and bool(np.ptp(fa[0]) > 0 or np.any(fa[1] > 0))

    def lunar_samples(self, body: str):
        """Deterministic lunar samples: points, normals, areas, owning facets, and the lunar
        map's value per sample (``None`` without a map; :meth:`sample_albedo`); the lune rule's
        samples where it applies (:meth:`lune_rule_applies`)."""
        M = self.bodies.moon
        s = self.bodies.settings
        if self.lune_rule_applies(body):
            return self.lune_samples(body)
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
        sc = self.bodies.scene
        mu, geom, o = detector_geometry(x, n, dA, sc.det, sc.det_normal)
        # The Earth between the Moon and the detector always hides it, as in every method
        # (--no-occlusion removes shadows, i.e. bodies between a source and the Moon; it
        # does not make the observer's own Earth transparent)
        horizon = sc.horizon_normal is not None
        earth_blocks = not sc.detector_inside("earth") and not horizon
        if horizon:  # a site on the WGS84 Earth: its horizon plane, not the model sphere
            geom = np.where(sc.sight_lines_clear(x), geom, 0.0)
        if earth_blocks or self.bodies.self_shadows():
            idx = np.flatnonzero(geom > 0)
            xo = x[idx] + n[idx] * (NORMAL_OFFSET * self.bodies.moon.radius)
            dist = np.linalg.norm(sc.det - xo, axis=1)
            blocked = np.zeros(idx.size, dtype=bool)
            if earth_blocks:
                blocked |= self.bodies.earth.occluded(xo, o[idx], dist)
                self.bodies.count(idx.size)
            if self.bodies.self_shadows():
                blocked |= self.bodies.moon.occluded(xo, o[idx], dist)
                self.bodies.count(idx.size)
            geom = geom.copy()
            geom[idx[blocked]] = 0.0
        return mu, geom, o
