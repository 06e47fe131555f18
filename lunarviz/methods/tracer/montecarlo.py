"""The Monte Carlo estimator's transport: lunar samples drawn by a facet pdf, one source direction
per sample (the Sun's cone, or the Earth's lit part), chunks with their own generators.

A job of :class:`~lunarviz.methods.tracer.trace_scene.TraceScene` (one per module); its
collaborators (the traced bodies, the facets' surfaces, the other jobs it calls) are passed in."""

from __future__ import annotations

import numpy as np

from lunarviz.geometry.scene_geometry import half_angle_sin_cos, unit
from lunarviz.geometry.sphere_quadrature import orthonormal_basis
from lunarviz.methods.tracer import ray_kernels
from lunarviz.methods.tracer import settings as tuning
from lunarviz.methods.tracer.deterministic import DeterministicTransport
from lunarviz.methods.tracer.facet_surfaces import FacetSurfaces
from lunarviz.methods.tracer.lunar_sampling import LunarSampling
from lunarviz.methods.tracer.settings import (
    UNIFORM_SHARE,
)
from lunarviz.methods.tracer.source_rules import SourceRules
from lunarviz.methods.tracer.traced_bodies import TracedBodies
from lunarviz.methods.transport import Transport, detector_geometry


class MonteCarloTransport:
    """The Monte Carlo estimator's transport: a job of
    :class:`~lunarviz.methods.tracer.trace_scene.TraceScene`, with its collaborators passed in."""

    def __init__(self, bodies: TracedBodies, surfaces: FacetSurfaces, sampling: LunarSampling, sources: SourceRules,
                 deterministic: DeterministicTransport):
        self.bodies = bodies
        self.surfaces = surfaces
        self.sampling = sampling
        self.sources = sources
        self.deterministic = deterministic


    def transport(self, body: str, key):
        """Yield ``(Transport, owning facets)`` for chunks of ≤ CHUNK of the N Monte Carlo
        samples; each sample's weight already carries the 1/N of the estimator.

        Chunk i draws from its own generator, ``default_rng([*key, i])`` (``key`` = seed, run,
        path), so the chunks are independent of each other and of the thread count: with
        ``threads`` > 1 they are traced on that many threads, in order, with the same numbers."""
        s = self.bodies.settings
        sizes = [min(tuning.CHUNK, s.rays - a) for a in range(0, s.rays, tuning.CHUNK)]
        self.deterministic.warm_shared(body)
        self._facet_pdf(body)  # memoised here (with the candidates), before any thread asks

        def chunk(i):
            return [self._montecarlo_chunk(body, np.random.default_rng([*key, i]), sizes[i], s.rays)]
        yield from self.bodies.chunks_in_order(chunk, len(sizes))

    def _facet_pdf(self, body: str):
        """Candidate facets, their areas and the probability of drawing each (memoised per
        body: every Monte Carlo chunk draws from the same distribution)."""
        key = ("pdf", body)
        if key in self.sampling._cand_cache:
            return self.sampling._cand_cache[key]
        sc = self.bodies.scene
        M = self.bodies.moon
        c, R, _ = self.bodies.source(body)
        cand = self.sampling.candidates(body)
        x, n = (a[cand] for a in M.facet_points(self.bodies.settings.shading))
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
        self.sampling._cand_cache[key] = (cand, dA, p)
        return cand, dA, p

    def _montecarlo_chunk(self, body: str, rng: np.random.Generator, N: int, N_total: int):
        s = self.bodies.settings
        M = self.bodies.moon
        c, R, src = self.bodies.source(body)
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
        mu, geom, o = self.sampling.detector_view(xs, ns, area_w)
        if body == "earth" and src.mode(s.shading) == "exact":
            dirs, omega = self._earth_lit_directions(xs, rng)
        else:
            dirs, omega = self._cone_directions(xs, c, R, rng)
        mu0 = np.einsum("ij,ij->i", dirs, ns)
        li = np.flatnonzero((mu0 > 0) & (geom > 0))
        L = np.zeros(N)
        L_unit = np.zeros(N) if body == "earth" else None
        L[li], _, lu = self.sources.source_radiance(xs[li], ns[li], dirs[li], body)
        if L_unit is not None:
            L_unit[li] = lu
        sh, ch = half_angle_sin_cos(dirs, o)
        tr = Transport(mu0=np.clip(mu0, 0, 1)[:, None], sin_hg=sh[:, None], cos_hg=ch[:, None],
                       e_beam=(L * omega)[:, None], mu=mu, geom=geom,
                       e_beam_unit=None if L_unit is None else (L_unit * omega)[:, None])
        return self.surfaces.with_moon_albedo(tr, f), f

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
        sc = self.bodies.scene
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
