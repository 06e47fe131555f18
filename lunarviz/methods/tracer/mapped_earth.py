"""Earthlight from a mapped Earth (land, ocean, clouds): the Earth's facets grouped into cells of
its disc seen from the Moon, summed per facet.

A job of :class:`~lunarviz.methods.tracer.trace_scene.TraceScene` (one per module); its
collaborators (the traced bodies, the facets' surfaces, the other jobs it calls) are passed in."""

from __future__ import annotations

import numpy as np

from lunarviz.geometry.scene_geometry import half_angle_sin_cos, unit
from lunarviz.geometry.sphere_quadrature import orthonormal_basis
from lunarviz.methods.sources import earth_radiance
from lunarviz.methods.tracer import earth_kernels
from lunarviz.methods.tracer.facet_surfaces import FacetSurfaces
from lunarviz.methods.tracer.settings import (
    EARTH_CELLS,
    LIMB_SUB,
    NORMAL_OFFSET,
    TERMINATOR_SUB,
)
from lunarviz.methods.tracer.source_rules import SourceRules
from lunarviz.methods.tracer.traced_bodies import TracedBodies
from lunarviz.methods.transport import Transport


class MappedEarthTransport:
    """Earthlight from a mapped Earth (land, ocean, clouds): a job of
    :class:`~lunarviz.methods.tracer.trace_scene.TraceScene`, with its collaborators passed in."""

    def __init__(self, bodies: TracedBodies, surfaces: FacetSurfaces, sources: SourceRules):
        self.bodies = bodies
        self.surfaces = surfaces
        self.sources = sources
        self._earth_el = None


    def earth_elements(self):
        """The mapped Earth as surface elements, one per facet: points y, normals m, areas
        [m²] (spherical areas on the exact sphere), radiance for albedo 1 (point Sun, the
        Moon's shadow traced per facet) and the albedo there (its facet's linear field of the map:
        :meth:`FacetSurfaces.earth_element_values`); sorted into the cells of a
        grid over the Earth's disc seen from the Moon's centre, with each cell's
        flux-weighted centre point, its four points (:func:`_cell_spread`) and each light's tilt
        across them (:func:`_point_tilts`). Elements neither lit nor possibly seen from the Moon are
        dropped; on a non-convex Earth, those the Earth itself hides from the Moon's centre
        (traced)."""
        if getattr(self, "_earth_el", None) is not None:
            return self._earth_el
        sc, s, E = self.bodies.scene, self.bodies.settings, self.bodies.earth
        # three points per facet (the degree-2 rule of surface_samples; on the packaged sphere
        # they lie on the exact sphere): the terminator crosses facets, and a one-point rule
        # there costs 6e-4 where the lit part is a thin band (docs: surfaces)
        # facets the terminator crosses (corners lit and unlit) are split TERMINATOR_SUB² ways:
        # the lit edge is a kink the map's light ends at, coherently along the whole terminator
        corners = E.vertices[E.faces] + E.centre  # (F, 3, 3)
        cn = self.bodies.corner_normals(E)
        mu_c = np.einsum("fkj,fkj->fk", cn, sc.sun - corners)
        term = (mu_c > 0).any(1) & (mu_c <= 0).any(1)
        # ... and so are the lit facets that the Earth's limb seen from some lunar point crosses
        # (m·(x - y) = 0 for some x: within R_M of 0 at x0), where cos_y kinks: a thin crescent's
        # light lies along the limb (level 6 erred by 4.5e-5 at θ = 20° without: docs, accuracy)
        rb = max(sc.radii["moon"], self.bodies.moon.bound)
        facing = np.einsum("fkj,fkj->fk", cn, sc.moon - corners)
        limb = (mu_c > 0).any(1) & (facing.min(1) < rb) & (facing.max(1) > -rb)
        split = term | limb
        parts = [E.surface_samples(np.flatnonzero(~split), s.shading),
                 E.surface_samples(np.flatnonzero(term), s.shading, sub=TERMINATOR_SUB),
                 E.surface_samples(np.flatnonzero(limb & ~term), s.shading, sub=LIMB_SUB)]
        y, m, area_f, owner = (np.concatenate(p) for p in zip(*parts))
        L1 = earth_radiance(sc, y, m, 1.0) * self.sources.sun_visibility_of_earth()[owner]
        rm = sc.radii["moon"]
        keep = (L1 > 0) & (np.einsum("ij,ij->i", m, sc.moon - y) > -rm)
        if self.bodies.settings.self_shadow and not E.convex:
            idx = np.flatnonzero(keep)
            yo = y[idx] + m[idx] * (NORMAL_OFFSET * E.radius)
            v = sc.moon - yo
            dist = np.linalg.norm(v, axis=1)
            hid = E.occluded(yo, v / dist[:, None], dist - rm)
            self.bodies.count(idx.size)
            keep[idx[hid]] = False
        idx = np.flatnonzero(keep)
        y, m, L1A = y[idx], m[idx], L1[idx] * area_f[idx]
        # the albedo (and a spectral run's component weights) at the elements kept, from the fields of
        # their facets alone: a date needs the lit face the Moon sees, not the whole Earth's map
        faces, at = np.unique(owner[idx], return_inverse=True)
        a, comp = self.surfaces.earth_element_values(faces, at, y, m)  # comp: (n, C) a spectral run's components
        axis = unit(sc.moon - sc.earth)
        e1, e2 = orthonormal_basis(axis[None, :])
        bound = E.bound if E.mode(s.shading) != "exact" else E.radius
        g = EARTH_CELLS
        u = np.clip(((y - sc.earth) @ e1[0] / bound + 1) * 0.5 * g, 0, g - 1).astype(int)
        w = np.clip(((y - sc.earth) @ e2[0] / bound + 1) * 0.5 * g, 0, g - 1).astype(int)
        cell = u * g + w
        order = np.argsort(cell, kind="stable")
        y, m, L1A, a, cell = y[order], m[order], L1A[order], a[order], cell[order]
        comp = None if comp is None else comp[order]
        starts = np.flatnonzero(np.r_[True, cell[1:] != cell[:-1]]) if len(cell) else np.zeros(0, int)
        # each cell's centre: its elements' mean weighted by their unit flux toward the Moon's centre
        v = sc.moon - y
        r = np.linalg.norm(v, axis=1)
        wt = L1A * np.clip(np.einsum("ij,ij->i", m, v) / r, 1e-12, None) / r**2
        wsum = np.add.reduceat(wt, starts) if len(starts) else np.zeros(0)
        centre = (np.add.reduceat(y * wt[:, None], starts, axis=0) / wsum[:, None]) if len(starts) else np.zeros((0, 3))
        # the cell each element is in (the band's elements' sums go to that cell's beam)
        cell_of = np.repeat(np.arange(len(starts)), np.diff(np.r_[starts, len(y)])) if len(starts) else \
            np.zeros(0, int)
        d = y - centre[cell_of]
        radius = np.maximum.reduceat(np.linalg.norm(d, axis=1), starts) if len(starts) else np.zeros(0)
        spread = _cell_spread(d, wt, wsum, starts, e1[0], e2[0])
        band, (g0, grad, hess) = _expansion_terms(m, v, r, max(rm, self.bodies.moon.bound))
        band_el = np.flatnonzero(band)  # (sorted by cell, as all are)
        # each element's light for the unit, the map and a spectral run's components (the order of
        # the transport's outputs) as a share of the unit's, and its position relative to the
        # Moon's centre: m·(x - y) and |x - y|² as products there, without cancellation (the exact
        # sums' inputs)
        per_unit = np.stack([np.ones_like(L1A), a] + ([] if comp is None else list(comp.T)))
        weights = L1A * per_unit
        names = ["unit", "map"] + [("part", c) for c in range(len(weights) - 2)]
        taylor = {name: tuple(np.add.reduceat(wgt.reshape((-1,) + (1,) * (t.ndim - 1)) * t, starts, axis=0)
                              if len(starts) else np.zeros((0,) + t.shape[1:]) for t in (g0, grad, hess))
                  for name, wgt in zip(names, weights)}
        # each light's tilt across its cell's four points: their mean at the light's own centre (a
        # map's edge across a cell puts its light off the cell's centre)
        tilts = {name: _point_tilts(d, wt * share, starts, spread) for name, share in zip(names, per_unit)}
        yr = y - sc.moon
        self._earth_el = dict(y=y, m=m, L1A=L1A, a=a, starts=starts, centre=centre, radius=radius, spread=spread,
                              tilts=tilts, wsum=wsum, taylor=taylor, comp=comp, band=band_el, cell=cell_of,
                              weights=weights, rel=(yr, np.einsum("ij,ij->i", m, yr), np.einsum("ij,ij->i", yr, yr)))
        return self._earth_el

    def _band_sums(self, x, el, chunk: int = 256) -> np.ndarray:
        """(P, B, C): the light of the elements of the limb's band (:meth:`earth_elements`) at lunar
        points x whose horizon does not cut the Earth, summed exactly per point and cell for each of
        the elements' weights (zero where an element is behind the limb seen from x)."""
        idx = el["band"]
        w, cell, m = el["weights"][:, idx], el["cell"][idx], el["m"][idx]
        yr, my, yy = (r[idx] for r in el["rel"])
        C = len(el["starts"])
        if idx.size == 0:
            return np.zeros((len(w), len(x), C))
        xr = x - self.bodies.scene.moon
        if earth_kernels.available():  # one compiled pass
            return earth_kernels.element_sums(xr, m, yr, my, yy, w, cell, C)
        runs = np.flatnonzero(np.r_[True, cell[1:] != cell[:-1]])  # (each cell's run of elements)
        out = np.zeros((len(w), len(x), C))
        for c0 in range(0, len(x), chunk):
            xc = xr[c0:c0 + chunk]
            num = np.clip(xc @ m.T - my[None, :], 0.0, None)
            r2 = np.einsum("ij,ij->i", xc, xc)[:, None] - 2.0 * (xc @ yr.T) + yy[None, :]
            f = num / (r2 * np.sqrt(r2))
            for p, wp in enumerate(w):
                out[p][c0:c0 + chunk, cell[runs]] = np.add.reduceat(f * wp, runs, axis=1)
        return out

    def _expanded_sums(self, x, el) -> np.ndarray:
        """(P, B, C): the lights (the unit, the map, a spectral run's components: the order of
        the transport's outputs) of every cell at lunar points x that see all of it but the
        elements along the limb: each cell's second-order expansion about the Moon's centre
        (:func:`_expansion_terms`) and the limb's band summed exactly (:meth:`_band_sums`)."""
        dx = x - self.bodies.scene.moon
        dxx = 0.5 * (dx[:, :, None] * dx[:, None, :]).reshape(-1, 9)  # (the Hessian's term as one product)
        band = self._band_sums(x, el)
        out = np.empty_like(band)
        for p, name in enumerate(el["taylor"]):
            s0, s1, s2 = el["taylor"][name]
            v = s0[None, :] + dx @ s1.T + dxx @ s2.reshape(-1, 9).T + band[p]
            # the unit and the map are lights: clipped at 0 where the expansion dips below it. A
            # spectral run's components are not clipped one by one (a component's value may dip
            # where their albedo-weighted sum, the map, does not: clipping each would break the
            # sum), only where the unit's light is gone
            out[p] = np.clip(v, 0.0, None) if not isinstance(name, tuple) else np.where(out[0] > 0, v, 0.0)
        return out

    def _cut_sums(self, x, n, el, chunk: int = 32) -> np.ndarray:
        """(P, B, C): the cells' lights at lunar points x (normals n) whose horizon cuts the Earth:
        in a cell wholly above a point's horizon (its elements' bounding sphere) the expansion of
        :meth:`_expanded_sums`, in one wholly below nothing, in one the horizon crosses every
        element above it summed one by one (compiled: those cells' alone; numpy: every cell's,
        those cells' kept)."""
        centre, radius = el["centre"], el["radius"]
        height = np.einsum("bj,bcj->bc", n, centre[None, :, :] - x[:, None, :])  # n·(centre - x)
        reach = radius[None, :] * (1.0 + 1e-6)  # (a cell within rounding of a horizon: crossed)
        above, crossed = height > reach, np.abs(height) <= reach
        out = np.where(above[None], self._expanded_sums(x, el), 0.0)
        yr, my, yy = el["rel"]
        if earth_kernels.available():  # one compiled pass over the crossed cells' elements
            return out + earth_kernels.cell_sums(x - self.bodies.scene.moon, n, el["m"], yr, my, yy, el["weights"],
                                                 el["starts"], crossed)
        y, m, st, w = el["y"], el["m"], el["starts"], el["weights"]
        for c0 in range(0, len(x), chunk):
            xs, ns = x[c0:c0 + chunk], n[c0:c0 + chunk]
            v = xs[:, None, :] - y[None, :, :]  # Earth element → lunar point
            r2 = np.einsum("bkj,bkj->bk", v, v)
            cos_y = np.clip(np.einsum("bkj,kj->bk", v, m) / np.sqrt(r2), 0.0, None)
            up = np.einsum("bkj,bj->bk", v, ns) < 0.0  # the element above x's horizon
            f = np.where(up, cos_y / r2, 0.0)
            for p in range(len(w)):
                out[p, c0:c0 + chunk] += np.where(crossed[c0:c0 + chunk], np.add.reduceat(f * w[p], st, axis=1), 0.0)
        return out

    def transport(self, x, n, o, mu, geom) -> Transport:
        """Earthshine :class:`Transport` at lunar points x from an Earth with an albedo map.

        The earthlight of every Earth facet reaching x is summed exactly per facet,
        ``a_f · L1_f · A_f · cos_f(x) / r_f(x)²`` (zero below x's horizon or behind the Earth's
        limb seen from x), and gathered into the cells of the Earth's disc (:data:`EARTH_CELLS`
        × :data:`EARTH_CELLS` cells, each about 0.12° across seen from the Moon). A map's edges are
        thus integrated by the facets' linear fields of the map (its zeroth and first moments over
        each facet), not by a few Gauss beams across the disc, which leave ~1 % errors (docs:
        surfaces). The BRDF sees each cell's
        light from four directions, the cell's points (:func:`_cell_spread`): their mean and
        spread across the line of sight are those of the cell's light, and each light (the unit,
        the map, a spectral run's components) is tilted across them (:func:`_point_tilts`), so
        that their mean is the light's own centre in the cell (linear in the light). One
        direction a cell (its centre) erred by 8.2e-5 under Hapke's opposition surge, whose
        curvature across the disc the cells do not resolve, and by more where a map's edge puts a
        component's light off the cell's centre (docs: accuracy, "A mapped Earth").
        Lunar points whose horizon does not cut the Earth take each cell's sum from its
        second-order expansion about the Moon's centre (error ~(R_M/D)³ ≈ 1e-7) but for the
        elements near the Earth's limb, which some of them see and others not (summed one by
        one); the others take the same in the cells wholly above their horizon and sum the
        elements one by one in the cells their horizon crosses (:meth:`_cut_sums`).
        Traced with Embree: the Moon's
        shadow on each facet, a non-convex Earth hiding facets, a non-convex Moon shadowing
        each beam. Neglected: the Sun's extent lighting the Earth (as for the uniform Earth).
        """
        el = self.earth_elements()
        B, C = len(x), len(el["starts"])
        comp = el["comp"]
        n_parts = 0 if comp is None else comp.shape[1]
        lights = np.zeros((2 + n_parts, B, C))  # the unit's, the map's, each component's
        # the points whose horizon cuts the Earth
        cut = np.einsum("ij,ij->i", n, self.bodies.scene.earth - x) < self.bodies.earth.bound * (1 + 1e-6)
        if C:
            far, rows = np.flatnonzero(~cut), np.flatnonzero(cut)
            lights[:, far] = self._expanded_sums(x[far], el)
            if len(rows):
                lights[:, rows] = self._cut_sums(x[rows], n[rows], el)
        e_unit, e_map, e_parts = lights[0], lights[1], lights[2:]
        dirs, e_map, e_unit, e_parts = _four_point_beams(el, x, cut, e_map, e_unit, e_parts)
        C = 4 * C
        mu0 = np.einsum("bkj,bj->bk", dirs, n)
        e_free = e_map.copy()
        if self.bodies.self_shadows() and C:
            bi, ki = np.nonzero((e_unit > 0) & (mu0 > 0))
            xo = x[bi] + n[bi] * (NORMAL_OFFSET * self.bodies.moon.radius)
            blocked = self.bodies.moon.occluded(xo, dirs[bi, ki])
            self.bodies.count(bi.size)
            e_map[bi[blocked], ki[blocked]] = 0.0
            e_unit[bi[blocked], ki[blocked]] = 0.0
            e_parts[:, bi[blocked], ki[blocked]] = 0.0
        sh, ch = half_angle_sin_cos(dirs, o[:, None, :])
        parts = None if comp is None else dict(zip(self.surfaces.earth_parts, e_parts))
        return Transport(mu0=np.clip(mu0, 0.0, 1.0), sin_hg=sh, cos_hg=ch, e_beam=e_map, mu=mu, geom=geom,
                         e_beam_free=e_free, e_beam_unit=e_unit, e_beam_parts=parts)


def _four_point_beams(el, x, cut, e_map, e_unit, e_parts):
    """Directions (B, 4C, 3) from lunar points x toward the cells' four points and the lights on
    them (the map's, the unit's (B, 4C), the components' (P, B, 4C)), from each cell's lights
    (B, C) (:meth:`MappedEarthTransport.earth_elements`' ``spread``, ``tilts``, ``wsum``;
    ``cut``: the points whose horizon cuts the Earth)."""
    B, C = e_map.shape
    n_parts = len(e_parts)
    # each cell's light along its four points (its spread across the line of sight), each light
    # tilted across them to its own centre in the cell, scaled at x as the unit's light (so
    # the lights stay linear: the components' beams sum to the map's). A point whose horizon
    # cuts the Earth sums only the elements above it, whose spread is not the cell's: its four
    # points collapse to the cell's centre, untilted (else light below its horizon is lost
    # twice). Those points see the cells' light along one direction, and under DHG at θ = 90°
    # err by 1.5 % of their earthshine (0.85 % with 24 cells a side, 2.0 % on four points);
    # seen from the Earth they lie on the Moon's limb (μ ≈ 0), so a row barely moves
    scale = np.where(cut[:, None], 0.0, e_unit / np.where(el["wsum"] > 0, el["wsum"], 1.0))  # (B, C)
    tilts = el["tilts"]
    e_map, e_unit = (_four_points(e, scale, tilts[k]) for e, k in ((e_map, "map"), (e_unit, "unit")))
    e_parts = np.stack([_four_points(e_parts[c], scale, tilts[("part", c)])
                        for c in range(n_parts)]) if n_parts else np.zeros((0, B, 4 * C))
    points = (el["centre"][:, None, :] + el["spread"]).reshape(-1, 3)  # (4C, 3)
    dirs = unit(points[None, :, :] - x[:, None, :])
    if cut.any() and C:
        dirs[cut] = np.repeat(unit(el["centre"][None, :, :] - x[cut][:, None, :]), 4, axis=1)
    return dirs, e_map, e_unit, e_parts


def _cell_spread(d, wt, wsum, starts, e1, e2):
    """(C, 4, 3): offsets from each cell's centre of four points with weights 1/4 whose mean and
    covariance across the line of sight (the plane of e1, e2) are the cell's elements' (offsets
    ``d`` from their cell's centre, weights ``wt``): ±√(2λ) v along the covariance's eigenvectors."""
    C = len(starts)
    if C == 0:
        return np.zeros((0, 4, 3))
    u1, u2 = d @ e1, d @ e2
    s11, s12, s22 = (np.add.reduceat(wt * p, starts) / wsum for p in (u1 * u1, u1 * u2, u2 * u2))
    cov = np.stack([np.stack([s11, s12], -1), np.stack([s12, s22], -1)], -2)
    lam, vec = np.linalg.eigh(cov)  # (C, 2), (C, 2, 2) columns
    a = np.sqrt(2.0 * np.clip(lam, 0.0, None))
    axes = vec[:, 0, :, None] * e1 + vec[:, 1, :, None] * e2  # (C, 2, 3): eigenvectors in 3-D
    off = a[:, :, None] * axes
    return np.stack([off[:, 0], -off[:, 0], off[:, 1], -off[:, 1]], 1)


def _point_tilts(d, w, starts, spread):
    """(C, 2): a light's tilt across its cells' four points (:func:`_cell_spread`) along each of
    their two axes, per unit of the unit light's flux: the light's first moment in the cell
    (elements' offsets ``d`` from the cell's centre, the light's weights ``w``, flux toward the
    Moon's centre) along the axis (half-length a), over 2a². A light E with the cell's unit flux
    W puts E/4 ± (E_unit/W)·tilt on the points ±a: their mean is the light's own centre where its
    flux at x is in the proportion of its flux at the Moon's centre, and the tilt is linear in the
    light."""
    C = len(starts)
    if C == 0:
        return np.zeros((0, 2))
    moment = np.add.reduceat(d * w[:, None], starts, axis=0)  # (C, 3)
    out = np.zeros((C, 2))
    for i in range(2):
        ax = spread[:, 2 * i]
        a2 = np.einsum("ij,ij->i", ax, ax)
        out[:, i] = np.where(a2 > 0, np.einsum("ij,ij->i", moment, ax) / (2.0 * np.where(a2 > 0, a2, 1.0)), 0.0)
    return out


def _four_points(e, scale, tilt):
    """(B, 4C): a light's beams ``e`` (B, C) on its cells' four points, E/4 ± scale·tilt
    (:func:`_point_tilts`; ``scale`` (B, C): the unit light's flux at each point over its flux
    toward the Moon's centre)."""
    q = e / 4.0
    t0, t1 = scale * tilt[:, 0], scale * tilt[:, 1]
    return np.stack([q + t0, q - t0, q + t1, q - t1], axis=2).reshape(e.shape[0], 4 * e.shape[1])


def _expansion_terms(m, v, r, moon_radius: float):
    """Second-order expansion about the Moon's centre x0 of each element's
    g(x) = m·(x - y)/|x - y|³ (normals m, v = x0 - y, r = |v|), for the elements every lunar
    point sees (m·(x0 - y) > R_M: m·(x - x0) is at most R_M): g(x0), ∇g(x0) = m/r³ - 3 (m·v) v/r⁵
    and the Hessian -3 (m vᵀ + v mᵀ + (m·v) I)/r⁵ + 15 (m·v) v vᵀ/r⁷, zero for the others. The
    numerator m·(x - y) is linear in x, so the neglected terms are those of 1/r³ alone,
    O((R_M/r)³) ≈ 1e-7 relative (the first order left (R_M/r)² ≈ 3e-5: docs, accuracy). Returns
    ``(band, (g0, grad, hess))``: ``band`` marks the elements within R_M of the Earth's limb seen
    from x0 (a band of 0.26°, seen by some lunar points and not by others: 1e-4 of a thin
    crescent's light), which are summed exactly per lunar point instead."""
    mv = np.einsum("ij,ij->i", m, v)
    band = mv <= moon_radius * (1.0 + 1e-9)
    inner = ~band
    g0 = np.where(inner, mv / r**3, 0.0)
    grad = np.where(inner[:, None], m / r[:, None] ** 3 - 3 * (mv / r**5)[:, None] * v, 0.0)
    mvT = m[:, :, None] * v[:, None, :]
    hess = (-3.0 * (mvT + mvT.transpose(0, 2, 1) + mv[:, None, None] * np.eye(3)) / r[:, None, None] ** 5
            + 15.0 * (mv / r**7)[:, None, None] * v[:, :, None] * v[:, None, :])
    return band, (g0, grad, np.where(inner[:, None, None], hess, 0.0))
