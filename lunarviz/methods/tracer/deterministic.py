"""The deterministic estimator's transport: lunar samples in chunks (on the trace's threads), rule
groups, beams through Embree (the fused compiled pass for exact-sphere sources).

A job of :class:`~lunarviz.methods.tracer.trace_scene.TraceScene` (one per module); its
collaborators (the traced bodies, the facets' surfaces, the other jobs it calls) are passed in."""

from __future__ import annotations

import numpy as np

from lunarviz.geometry.mapped_lune import AlbedoNodes
from lunarviz.geometry.scene_geometry import unit
from lunarviz.methods.sources import horizon_cuts_source
from lunarviz.methods.tracer import ray_kernels
from lunarviz.methods.tracer import settings as tuning
from lunarviz.methods.tracer.facet_surfaces import FacetSurfaces
from lunarviz.methods.tracer.lunar_sampling import LunarSampling
from lunarviz.methods.tracer.mapped_earth import MappedEarthTransport
from lunarviz.methods.tracer.ray_kernels import beam_angles, live_beams
from lunarviz.methods.tracer.settings import (
    NORMAL_OFFSET,
)
from lunarviz.methods.tracer.source_rules import SourceRules
from lunarviz.methods.tracer.traced_bodies import TracedBodies
from lunarviz.methods.transport import Transport


class DeterministicTransport:
    """The deterministic estimator's transport: a job of
    :class:`~lunarviz.methods.tracer.trace_scene.TraceScene`, with its collaborators passed in."""

    def __init__(self, bodies: TracedBodies, surfaces: FacetSurfaces, sampling: LunarSampling, sources: SourceRules,
                 mapped_earth: MappedEarthTransport):
        self.bodies = bodies
        self.surfaces = surfaces
        self.sampling = sampling
        self.sources = sources
        self.mapped_earth = mapped_earth


    # ---- transports --------------------------------------------------------------------------
    def transport(self, body: str):
        """Yield ``(Transport, owning facets)`` for chunks of ≤ CHUNK lunar samples, in order.

        With ``threads`` > 1 the chunks are traced on that many threads, a few ahead of the
        consumer: Embree and the compiled kernels release the GIL, so one chunk's Embree
        queries run while another's rules and beams are built (both cores busy).
        The chunks and their order are the same for any thread count, so are the results,
        bit for bit (docs: validation)."""
        x_all, n_all, dA_all, owner_all, alb_all = self.sampling.lunar_samples(body)
        self.warm_shared(body)

        def chunk(a):
            sl = slice(a, a + tuning.CHUNK)
            x, n, dA, owner = x_all[sl], n_all[sl], dA_all[sl], owner_all[sl]
            mu, geom, o = self.sampling.detector_view(x, n, dA)
            keep = geom > 0
            x, n, owner, mu, geom, o = x[keep], n[keep], owner[keep], mu[keep], geom[keep], o[keep]
            out = []
            if len(x) == 0:
                return out
            order = self.beam_order(body)
            for g in self._rule_groups(x, n, body):
                tr = self.beam_transport(x[g], n[g], o[g], mu[g], geom[g], body, order)
                if isinstance(alb_all, AlbedoNodes):  # the mapped lune rule: shaded at every map value
                    tr.albedo_nodes = (alb_all.values, alb_all.factors[sl][keep][g])
                    tr.albedo_absolute = self.bodies.settings.moon_map().absolute
                    out.append((tr, owner[g]))
                    continue
                if alb_all is not None:
                    self.surfaces.with_moon_albedo(tr, values=(alb_all[0][sl][keep][g], alb_all[1][sl][keep][g]))
                out.append((tr, owner[g]))
            return out

        starts = list(range(0, len(x_all), tuning.CHUNK))
        yield from self.bodies.chunks_in_order(lambda i: chunk(starts[i]), len(starts))

    def beam_order(self, body: str) -> int:
        """The Gauss order of ``body``'s beams: the lune rule's own (``lune_source_orders``) where
        its samples are used, else ``sun_order`` or ``earth_order``."""
        s = self.bodies.settings
        if s.lune_source_orders is not None and self.sampling.lune_rule_applies(body):
            return s.lune_source_orders[0 if body == "sun" else 1]
        return s.sun_order if body == "sun" else s.earth_order

    def warm_shared(self, body: str) -> None:
        """Fill the scene's lazy caches before chunks are traced on several threads."""
        if body == "earth":
            self.sources.sun_visibility_of_earth()
            if self.surfaces.earth_mapped() and self.bodies.settings.mapped_earth == "facets":
                self.mapped_earth.earth_elements()  # (the values of the facets it needs, alone)
            else:
                self.surfaces.earth_facet_albedo()
        self.surfaces.moon_facet_albedo()
        for b in (self.bodies.sun, self.bodies.earth):
            if b.mode(self.bodies.settings.shading) == "exact":
                b.outer_scene()
            elif b.mode(self.bodies.settings.shading) == "interp":
                b.corner_normals  # noqa: B018 (a cached property: built here, once)

    def _rule_groups(self, x, n, body: str) -> list:
        """Rows of x grouped by the size of their source rule (:meth:`source_nodes`): the few
        rows whose horizon cuts the source (or, for the Sun, whose view the Earth's limb cuts)
        take rules of 72-512 beams, the rest 8 (the Sun's cone) or ~60 (the Earth). Transports
        are padded to their longest row, so tracing the groups apart spares ~10x padded beams
        in a moonshine chunk. Each group keeps the rows' order; results only change by the
        order of the sums (rounding)."""
        c, R, B = self.bodies.source(body)
        s = self.bodies.settings
        if B.mode(s.shading) != "exact" or body == "earth" and self.surfaces.earth_mapped() \
                and s.mapped_earth == "facets":
            return [slice(None)]
        cut = horizon_cuts_source(self.bodies.scene, x, n, body)
        if body == "sun":
            ecl = ~cut & self.sources.earth_crosses_sun(x, np.linalg.norm(x - c, axis=1))
            groups = [~cut & ~ecl, cut, ecl]
        else:
            groups = [~cut, cut]
        rows = [np.flatnonzero(g) for g in groups if g.any()]
        if body == "earth" and s.earth_pole != "centre":  # rules of up to ~18·order² beams: batches that bound memory
            cuts = 3 if s.earth_pole == "detector-cut" else 1  # (the kinks' cuts: ~3x the beams a row)
            size = max(16, tuning.POLE_RULE_NODES // (cuts * self.beam_order(body) ** 2))
            rows = [r[a:a + size] for r in rows for a in range(0, len(r), size)]
        return rows

    def beam_transport(self, x, n, o, mu, geom, body: str, order: int) -> Transport:
        """The :class:`Transport` of points x (B,3) with normals n, unit directions o to the
        detector, ``mu`` and ``geom``: ``body``'s deterministic beams (:meth:`source_nodes`),
        each traced to the source (:meth:`source_radiance`). Shared by the detector transport
        and the synthetic camera (lunarviz.methods.camera). An Earth with an albedo map takes
        :meth:`~lunarviz.methods.tracer.mapped_earth.MappedEarthTransport.transport` instead."""
        if body == "earth" and self.surfaces.earth_mapped() \
                and self.bodies.settings.mapped_earth == "facets":
            return self.mapped_earth.transport(x, n, o, mu, geom)
        if ray_kernels.available() and self.bodies.source(body)[2].mode(self.bodies.settings.shading) == "exact":
            return self._fused_beam_transport(x, n, o, mu, geom, body, order)
        dirs, omega = self.sources.source_nodes(x, n, body, order)
        mu0, sh, ch = beam_angles(dirs, n, o)
        bi, ki, xb, nb, db = live_beams(x, n, dirs, omega, mu0)
        Lb, Lb_free, lu = self.sources.source_radiance(xb, nb, db, body)
        flat = bi * omega.shape[1] + ki  # scatter through flat indices (2-D fancy indexing is slower)
        om_b = omega.reshape(-1)[flat]

        def beams(values):
            e = np.zeros(omega.shape)
            e.reshape(-1)[flat] = values * om_b
            return e
        return Transport(mu0=np.clip(mu0, 0.0, 1.0), sin_hg=sh, cos_hg=ch, e_beam=beams(Lb),
                         mu=mu, geom=geom, e_beam_free=beams(Lb_free),
                         e_beam_unit=None if lu is None else beams(lu))

    def _facets_unneeded(self, earth_albedo, sun_visibility) -> bool:
        """Whether a source's beams may be traced against its coarse hit scene
        (:meth:`~lunarviz.methods.tracer.embree_bodies.EmbreeBody.hit_scene`): their facets feed
        nothing — the light is only summed into rows (no per-facet hit counts kept), and the Earth
        has one albedo and every facet the whole Sun (``sun_visibility`` all 1)."""
        if not self.sampling.summed or earth_albedo is not None:
            return False
        return sun_visibility is None or bool(np.all(sun_visibility == 1.0))

    def _fused_beam_transport(self, x, n, o, mu, geom, body: str, order: int) -> Transport:
        """:meth:`beam_transport` toward an exact-sphere source, compiled: one pass
        from the rule to Embree's rays (:func:`lunarviz.methods.tracer.ray_kernels.cap_beam_rays` for the Earth's
        one-cap rule, else :meth:`source_nodes` then ``beam_rays``), one from Embree's facets to
        each beam's radiance (``source_hits``), one per shadow test (``occluder_rays``) and one
        into the (B, K) arrays (``scatter_beams``); Python only calls Embree between them. The
        same rays, counts and numbers as the numpy path (:meth:`source_radiance`) to rounding
        (the kernel tests)."""
        from lunarviz.methods.tracer.embree_bodies import ENTRY_MARGIN
        K = ray_kernels
        sc, s = self.bodies.scene, self.bodies.settings
        src = self.bodies.sun if body == "sun" else self.bodies.earth
        fa = self.surfaces.earth_facet_albedo() if body == "earth" else None
        vis = self.sources.sun_visibility_of_earth() if body == "earth" else None
        hit = src.hit_scene() if self._facets_unneeded(fa, vis) else None
        coarse = hit is not None
        if coarse:  # whether and where each beam meets the sphere is all that counts
            outer, bound, n_faces = hit
        else:
            outer, n_faces = src.outer_scene(), src.n_faces  # (built once per body; sets its bounding radius)
            bound = src.outer_bound
        off, Rb = NORMAL_OFFSET * self.bodies.moon.radius, bound * (1.0 + ENTRY_MARGIN)
        c, R, _ = self.bodies.source(body)
        if body == "earth" and s.earth_pole == "centre" and not horizon_cuts_source(sc, x, n, body).any():
            cs = sc.sun - c  # the rule's one cap: the Earth's sunlit hemisphere (as in source_nodes)
            rays = K.cap_beam_rays(x, n, o, c, R, unit(cs), R / np.linalg.norm(cs), order, off, Rb)
        else:
            dirs, omega = self.sources.source_nodes(x, n, body, order)
            rays = K.beam_rays(x, n, o, dirs, omega, off, c, Rb)
        self.bodies.count(len(rays.bi))
        prim = src.run_rays(rays.o32, rays.d32, "INTERSECT", scene=outer) if len(rays.idx) else np.empty(0, np.int64)
        if body == "sun":
            t, L, L_unit, counts = K.source_hits(rays, prim, src.radius, src.centre, n_faces,
                                                 sun_radiance=self.sources.sun_surface_radiance())
        else:
            alb = np.array([self.surfaces.earth_albedo_value()]) if fa is None else fa
            t, L, L_unit, counts = K.source_hits(rays, prim, src.radius, src.centre, n_faces,
                                                 earth=(sc.sun, sc.phi, None if coarse else vis, alb))
        if not coarse:
            with self.bodies.lock:
                self.bodies.source_hits[body] += counts
        L_free = L.copy()
        if body == "sun" and s.occlusion:  # the Earth between the Moon and the Sun
            live = L > 0
            self.bodies.count(int(np.count_nonzero(live)))
            L[self.bodies.earth.occluded_beams(rays, t, live)] = 0.0
        if self.bodies.self_shadows():
            live = (L > 0) | (L_unit > 0) if body == "earth" else L > 0
            self.bodies.count(int(np.count_nonzero(live)))
            blocked = self.bodies.moon.occluded_beams(rays, t, live)
            L[blocked] = 0.0
            L_unit[blocked] = 0.0
        e, e_free, e_unit = K.scatter_beams(rays, L, L_free, L_unit if body == "earth" else None)
        return Transport(mu0=np.clip(rays.mu0, 0.0, 1.0), sin_hg=rays.sin_hg, cos_hg=rays.cos_hg, e_beam=e,
                         mu=mu, geom=geom, e_beam_free=e_free, e_beam_unit=e_unit)

