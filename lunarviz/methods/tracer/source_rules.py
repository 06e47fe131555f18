"""Source rules and visibility: beams toward the Sun and the Earth per lunar sample, eclipses, the
Moon's shadow on the Earth, the sources' radiance at the hits.

A job of :class:`~lunarviz.methods.tracer.trace_scene.TraceScene` (one per module); its
collaborators (the traced bodies, the facets' surfaces, the other jobs it calls) are passed in."""

from __future__ import annotations

import numpy as np

from lunarviz.geometry.scene_geometry import angle_between, unit
from lunarviz.methods.sources import (
    earth_radiance,
    horizon_cuts_source,
    source_sphere_beams,
    sun_radiance,
    zero_phase_points,
)
from lunarviz.methods.tracer import ray_kernels
from lunarviz.methods.tracer.facet_surfaces import FacetSurfaces
from lunarviz.methods.tracer.lunar_sampling import LunarSampling
from lunarviz.methods.tracer.ray_kernels import sphere_cap_beams
from lunarviz.methods.tracer.settings import (
    ECLIPSE_ORDER,
    MESH_SOURCE_ORDER,
    NORMAL_OFFSET,
    PENUMBRA_ORDER,
    horizon_band_order,
)
from lunarviz.methods.tracer.traced_bodies import TracedBodies


class SourceRules:
    """Source rules and visibility: a job of
    :class:`~lunarviz.methods.tracer.trace_scene.TraceScene`, with its collaborators passed in."""

    def __init__(self, bodies: TracedBodies, surfaces: FacetSurfaces, sampling: LunarSampling):
        self.bodies = bodies
        self.surfaces = surfaces
        self.sampling = sampling
        self._sun_vis_earth = None


    # ---- source beams ------------------------------------------------------------------------
    def source_nodes(self, x, n, body: str, order: int, eclipse: bool = True):
        """Deterministic beams from points x (B,3) with normals n: unit directions (B,K,3)
        and solid angles (B,K) [sr]. Where the horizon does not cut the source (most points),
        the Sun gets a Gauss rule over its cone and the Earth a rule without the horizon cap.
        A source shaded on its facets (a user mesh, or ``flat`` shading) gets a Gauss rule over
        its bounding sphere's cone (order ≥ MESH_SOURCE_ORDER); Embree then decides which
        beams meet the mesh and which facet each meets."""
        sc = self.bodies.scene
        c, R, B = self.bodies.source(body)
        if B.mode(self.bodies.settings.shading) != "exact":
            xc = x - c
            dxc = np.linalg.norm(xc, axis=1)
            o = max(order, MESH_SOURCE_ORDER)
            om, w = ray_kernels.cone_rule(-xc / dxc[:, None], np.clip(R / dxc, 0, 1 - 1e-12), o, 2 * o)
            return om, w
        cut = horizon_cuts_source(sc, x, n, body)
        # the Earth's rule about each row's zero-phase point (numpy's product rule: the visible cap,
        # the lit cap and, where it cuts the Earth, x's horizon as its caps)
        s = self.bodies.settings
        pole_kind = s.earth_pole if body == "earth" else "centre"
        pole = zero_phase_points(sc, x) if pole_kind != "centre" else None
        parts = []
        for rows, with_horizon in ((np.flatnonzero(~cut), False), (np.flatnonzero(cut), True)):
            if rows.size == 0:
                continue
            if pole is not None:  # (summed samples whose horizon cuts the Earth: horizon_band_order)
                coarse = with_horizon and self.sampling.summed
                o_p = horizon_band_order(order, s.earth_horizon_order, pole_kind == "detector-cut",
                                         view_cut=self.sampling.edges_found("earth")) if coarse else order
                parts.append((rows, *source_sphere_beams(sc, x[rows], n[rows], body, o_p, horizon=with_horizon,
                                                         pole=pole[rows], roughness_cuts=pole_kind == "detector-cut")))
                continue
            if body == "sun" and not with_horizon:
                xc = x[rows] - c
                dxc = np.linalg.norm(xc, axis=1)
                # (points on the Earth itself: its own limb is their horizon, no eclipse rule)
                ecl = self.earth_crosses_sun(x[rows], dxc) if eclipse else np.zeros(len(rows), dtype=bool)
                for sub, o_s in ((~ecl, order), (ecl, max(order, ECLIPSE_ORDER))):
                    if sub.any():
                        om, w = ray_kernels.cone_rule(-xc[sub] / dxc[sub, None], R / dxc[sub], o_s, 2 * o_s)
                        parts.append((rows[sub], om, w))
                continue
            # The Sun partly below the horizon (penumbra rows, few) needs a finer sphere rule
            # than its cone rule (its moonshine is checked against the exact reference: docs, validation).
            o_s = max(order, PENUMBRA_ORDER) if body == "sun" else order
            if (body == "earth" and not with_horizon) or (body == "sun" and with_horizon):
                # rules with one cap (compiled): the Earth's terminator where the horizon does not
                # cut the Earth (nearly every lunar point), the horizon across the Sun (penumbra)
                if body == "earth":
                    cs = sc.sun - c
                    cap = unit(cs), R / np.linalg.norm(cs)
                else:
                    cap = n[rows], np.einsum("ij,ij->i", x[rows] - c, n[rows]) / R
                fast = sphere_cap_beams(x[rows], c, R, *cap, o_s, o_s)
                if fast is not None:
                    parts.append((rows, *fast))
                    continue
            parts.append((rows, *source_sphere_beams(sc, x[rows], n[rows], body, o_s, horizon=with_horizon)))
        K = max((p[2].shape[1] for p in parts), default=1)
        om = np.zeros((len(x), K, 3))
        om[..., 2] = 1.0
        w = np.zeros((len(x), K))
        for rows, op, wp in parts:
            om[rows, :op.shape[1]] = op
            w[rows, :wp.shape[1]] = wp
        return om, w

    def earth_crosses_sun(self, x, d_sun) -> np.ndarray:
        """Points from which the Earth's disc overlaps the Sun's (a lunar eclipse's penumbra and
        umbra), when occlusion is on. There the Earth's limb cuts the solar cone and its
        default rule (a few beams) would round the partial Sun to all or nothing: those
        points get the ECLIPSE_ORDER rule (the penumbra within 1.5e-4 of the exact overlap of the
        two discs: docs, the real sky)."""
        if not self.bodies.settings.occlusion:
            return np.zeros(len(x), dtype=bool)
        sc = self.bodies.scene
        ve = sc.earth - x
        de = np.linalg.norm(ve, axis=1)
        rho_e = np.arcsin(np.clip(self.bodies.earth.bound / de, 0, 1))
        rho_s = np.arcsin(np.clip(sc.radii["sun"] / d_sun, 0, 1))
        gamma = angle_between(sc.sun - x, ve)
        return gamma < (rho_s + rho_e) * (1 + 1e-6)

    def sun_visibility_of_earth(self) -> np.ndarray:
        """Fraction of the Sun each Earth facet sees past the Moon (with occlusion, where its
        shadow may fall on the Earth: :meth:`moon_shadow_on_earth_possible`) and past the Earth
        itself (a non-convex Earth mesh, with self-shadowing); 1 otherwise."""
        if self._sun_vis_earth is not None:
            return self._sun_vis_earth
        E = self.bodies.earth
        vis = np.ones(E.n_faces)
        earth_self = self.bodies.settings.self_shadow and not E.convex
        moon_shadow = self.bodies.settings.occlusion and self.sampling.moon_shadow_on_earth_possible()
        if moon_shadow or earth_self:
            n = E.normals_for(self.bodies.settings.shading)
            x = E.centroids
            c, R, _ = self.bodies.source("sun")
            idx = np.flatnonzero(np.einsum("ij,ij->i", n, c - x) > -R)
            xo = x[idx] + n[idx] * (NORMAL_OFFSET * E.radius)
            if earth_self:  # the Earth's own relief (the Moon is traced below, where it can matter)
                dirs, w = self.source_nodes(xo, n[idx], "sun", 2, eclipse=False)
                B, K = w.shape
                occ = E.occluded(np.repeat(xo, K, 0), dirs.reshape(-1, 3)).reshape(B, K)
                self.bodies.count(B * K)
                tot = w.sum(1)
                vis[idx] = np.where(tot > 0, (w * ~occ).sum(1) / np.where(tot > 0, tot, 1), 1.0)
            if moon_shadow:
                # facets from which the Moon's disc overlaps the Sun's (the Moon's shadow and
                # penumbra on the Earth, a solar eclipse): the Moon's limb cuts the solar cone,
                # and 8 beams round the partial Sun to steps; ECLIPSE_ORDER beams resolve it.
                # Elsewhere no beam toward the Sun can meet the Moon (its bounding sphere's disc
                # is off the Sun's, with a margin): nothing to trace (most dates, every phase
                # but new Moon)
                sc = self.bodies.scene
                vs, vm = sc.sun - xo, sc.moon - xo
                ds, dm = np.linalg.norm(vs, axis=1), np.linalg.norm(vm, axis=1)
                rho = np.arcsin(np.clip(R / ds, 0, 1)) + np.arcsin(np.clip(self.bodies.moon.bound / dm, 0, 1))
                pen = np.flatnonzero(angle_between(vs, vm) < rho * (1 + 1e-6))
                if pen.size:
                    d2, w2 = self.source_nodes(xo[pen], n[idx[pen]], "sun", ECLIPSE_ORDER, eclipse=False)
                    K2 = w2.shape[1]
                    o2 = np.repeat(xo[pen], K2, 0)
                    occ2 = self.bodies.moon.occluded(o2, d2.reshape(-1, 3)).reshape(-1, K2)
                    self.bodies.count(o2.shape[0])
                    if earth_self:
                        occ2 |= E.occluded(o2, d2.reshape(-1, 3)).reshape(-1, K2)
                        self.bodies.count(o2.shape[0])
                    t2 = w2.sum(1)
                    vis[idx[pen]] = np.where(t2 > 0, (w2 * ~occ2).sum(1) / np.where(t2 > 0, t2, 1), 1.0)
        self._sun_vis_earth = vis
        return vis

    def sun_surface_radiance(self) -> float:
        """Radiance of the Sun's surface [W m⁻² sr⁻¹]: a Lambertian emitter of total power Φ
        over its surface A, L = Φ/(πA); Φ/(4π²R²) on the exact sphere. A Sun mesh of another
        size or shape therefore still emits Φ (the Earth is lit by a point Sun of power Φ)."""
        S = self.bodies.sun
        if S.mode(self.bodies.settings.shading) == "exact":
            return sun_radiance(self.bodies.scene)
        return self.bodies.scene.phi / (np.pi * float(S.areas.sum()))

    def source_radiance(self, x, n, dirs, body: str):
        """Radiance [W m⁻² sr⁻¹] reaching x (n,3) along dirs (n,3) from ``body``'s mesh:
        ``(L, L_free, L_unit)``, zero where the ray misses the source; ``L`` is also zero where
        another body (``occlusion``) or the Moon itself (``self_shadow``) blocks it, ``L_free`` is
        not. ``L_unit`` (Earth only, else ``None``) is ``L`` for an Earth of albedo 1: the Earth's
        albedo at a hit is its facet's (a map) or the scalar."""
        sc = self.bodies.scene
        s = self.bodies.settings
        xo = x + n * (NORMAL_OFFSET * self.bodies.moon.radius)
        target = self.bodies.sun if body == "sun" else self.bodies.earth
        if target.mode(s.shading) == "exact":
            hits = target.sphere_hits(xo, dirs, refine_from=x)
        else:
            hits = target.intersect(xo, dirs)
        self.bodies.count(len(xo))
        per_facet = np.bincount(hits.prim[hits.hit], minlength=target.n_faces)
        with self.bodies.lock:
            self.bodies.source_hits[body] += per_facet
        if body == "sun":
            L = np.where(hits.hit, self.sun_surface_radiance(), 0.0)
            L_free = L.copy()
            if s.occlusion:
                live = np.flatnonzero(L > 0)
                blocked = self.bodies.earth.occluded(xo[live], dirs[live], hits.t[live])
                self.bodies.count(live.size)
                L[live[blocked]] = 0.0
        else:
            L, L_unit = np.zeros(len(xo)), np.zeros(len(xo))
            h, y, nrm = self.bodies.earth.shade_hits(hits, s.shading)
            vis = self.sun_visibility_of_earth()
            prim = np.maximum(hits.prim[h], 0)
            shade = np.where(hits.prim[h] >= 0, vis[prim], 1.0)
            fa = self.surfaces.earth_facet_albedo()
            L_unit[h] = earth_radiance(sc, y, nrm, 1.0) * shade
            L[h] = L_unit[h] * (self.surfaces.earth_albedo_value() if fa is None else fa[prim])
            L_free = L.copy()
        if self.bodies.self_shadows():
            live = np.flatnonzero((L > 0) | (L_unit > 0)) if body == "earth" else np.flatnonzero(L > 0)
            blocked = self.bodies.moon.occluded(xo[live], dirs[live], hits.t[live])
            self.bodies.count(live.size)
            L[live[blocked]] = 0.0
            if body == "earth":
                L_unit[live[blocked]] = 0.0
        return L, L_free, (L_unit if body == "earth" else None)
