"""Compiled ray kernels (numba) of the tracer: source rules to Embree's rays and back.

The one-cap and cone source rules, the live beams above a sample's horizon, ray starts on a
body's bounding sphere, float32 ray batches for Embree, the refinement of hits onto an exact
sphere, the Monte Carlo Earth-direction sampler, and the fused pass from a rule to Embree's rays
(``cap_beam_rays``/``beam_rays``), the source hits and their radiance (``source_hits``), the
shadow rays (``occluder_rays``) and the scatter of beams back to samples (``scatter_beams``).
Every kernel has a numpy twin that serves where numba is off (``LUNARVIZ_NUMBA=0``), with the
same numbers to rounding (checked in the test suite).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

import lunarviz.compiled as compiled
from lunarviz.geometry.scene_geometry import half_angle_sin_cos
from lunarviz.geometry.sphere_quadrature import cone_rule as numpy_rule
from lunarviz.geometry.sphere_quadrature import gauss_legendre
from lunarviz.photometry import rough_kernels, shading_kernels


def available() -> bool:
    """Whether the compiled ray kernels are in use."""
    return _NUMBA


def _beam_angles(dirs, n, o, mu0_out, sh_out, ch_out):
    """μ0 = dirs·n and the half-angle sine and cosine between dirs and o, per beam
    (:func:`lunarviz.geometry.scene_geometry.half_angle_sin_cos`: |a − b| = 2 sin(g/2), |a + b| = 2 cos(g/2))."""
    B, K = mu0_out.shape
    for i in range(B):
        n0, n1, n2 = n[i, 0], n[i, 1], n[i, 2]
        o0, o1, o2 = o[i, 0], o[i, 1], o[i, 2]
        for k in range(K):
            a0, a1, a2 = dirs[i, k, 0], dirs[i, k, 1], dirs[i, k, 2]
            mu0_out[i, k] = a0 * n0 + a1 * n1 + a2 * n2
            d0, d1, d2 = a0 - o0, a1 - o1, a2 - o2
            p0, p1, p2 = a0 + o0, a1 + o1, a2 + o2
            s2 = d0 * d0 + d1 * d1 + d2 * d2
            c2 = p0 * p0 + p1 * p1 + p2 * p2
            norm = np.sqrt(s2 + c2)
            sh_out[i, k] = np.sqrt(s2) / norm
            ch_out[i, k] = np.sqrt(c2) / norm


def _sphere_refine(o, d, radius, prim, t_out, point_out, centre):
    """First hit of rays (body-frame origins o, unit d) on the sphere of ``radius`` where Embree
    found a facet (prim ≥ 0): t, world point; prim set to -1 where the sphere is missed."""
    n = o.shape[0]
    for i in range(n):
        if prim[i] < 0:
            continue
        disc, b, sq = _sphere_crossing(o[i, 0], o[i, 1], o[i, 2], d[i, 0], d[i, 1], d[i, 2], radius)
        t = b - sq
        if disc > 0.0 and t > 0.0:
            t_out[i] = t
            for j in range(3):
                point_out[i, j] = o[i, j] + t * d[i, j] + centre[j]
        else:
            prim[i] = -1


def _basis(a0, a1, a2):
    """:func:`lunarviz.geometry.sphere_quadrature.orthonormal_basis` for one unit axis: e1, e2 (six
    components) completing it to a right-handed basis, with the same helper-vector choice."""
    if abs(a0) < 0.9:
        h0, h1, h2 = 1.0, 0.0, 0.0
    else:
        h0, h1, h2 = 0.0, 1.0, 0.0
    e10, e11, e12 = a1 * h2 - a2 * h1, a2 * h0 - a0 * h2, a0 * h1 - a1 * h0
    nrm = np.sqrt(e10 * e10 + e11 * e11 + e12 * e12)
    e10, e11, e12 = e10 / nrm, e11 / nrm, e12 / nrm
    return e10, e11, e12, a1 * e12 - a2 * e11, a2 * e10 - a0 * e12, a0 * e11 - a1 * e10


def _on_basis(c, s, cp, sp, a0, a1, a2, e10, e11, e12, e20, e21, e22):
    """The unit vector at polar angle (cos c, sin s) and azimuth (cos cp, sin sp) about axis a
    with basis e1, e2: ``c·a + s·(cp·e1 + sp·e2)``."""
    return (c * a0 + s * (cp * e10 + sp * e20), c * a1 + s * (cp * e11 + sp * e21),
            c * a2 + s * (cp * e12 + sp * e22))


def _sphere_crossing(o0, o1, o2, d0, d1, d2, R):
    """Ray o + t·d (d unit) against the sphere of radius R about the origin: ``(disc, b, sq)``;
    it crosses the sphere where disc > 0, at t = b ∓ sq."""
    b = -(o0 * d0 + o1 * d1 + o2 * d2)
    perp2 = (o0 * o0 + o1 * o1 + o2 * o2) - b * b
    disc = R * R - perp2
    return disc, b, np.sqrt(max(disc, 0.0))

def _cap_row(x, i, c, R, cus, ccs, seg):
    """Row i of the one-cap sphere rule of :func:`lunarviz.geometry.sphere_quadrature.cap_rule`: the
    axis a from the sphere's centre to x, the basis e1, e2 about it, the cap's polar angle t_u and
    azimuth φ_u, and the polar segments ``seg`` (4, 4): t_lo, t_hi and tangent flags, non-empty
    ones first (returned: how many). Same operations in the same order as the numpy rule."""
    two_pi = 2.0 * np.pi
    xc0, xc1, xc2 = x[i, 0] - c[0], x[i, 1] - c[1], x[i, 2] - c[2]
    dxc = np.sqrt(xc0 * xc0 + xc1 * xc1 + xc2 * xc2)
    a0, a1, a2 = xc0 / dxc, xc1 / dxc, xc2 / dxc
    cos_max = R / dxc
    e10, e11, e12, e20, e21, e22 = _basis(a0, a1, a2)
    t_max = np.arccos(min(max(cos_max, -1.0), 1.0))
    cu = cus[i]
    cc = ccs[i]
    ua = cu[0] * a0 + cu[1] * a1 + cu[2] * a2
    u1 = cu[0] * e10 + cu[1] * e11 + cu[2] * e12
    u2 = cu[0] * e20 + cu[1] * e21 + cu[2] * e22
    t_u = np.arctan2(np.hypot(u1, u2), ua)
    phi_u = np.arctan2(u2, u1)
    ac = np.arccos(min(max(cc, -1.0), 1.0))
    real = cc > -1.0 and cc < 1.0
    pts = np.empty(5)
    tan = np.zeros(5, dtype=np.bool_)
    pts[0] = 0.0
    pts[4] = t_max
    cands = (abs(t_u - ac), t_u + ac, two_pi - t_u - ac)
    for j in range(3):
        v = min(max(cands[j], 0.0), t_max) if real else 0.0
        pts[1 + j] = v
        tan[1 + j] = v > 0.0 and v < t_max
    # stable insertion sort (argsort kind="stable")
    for j in range(1, 5):
        pv, tv = pts[j], tan[j]
        m = j - 1
        while m >= 0 and pts[m] > pv:
            pts[m + 1] = pts[m]
            tan[m + 1] = tan[m]
            m -= 1
        pts[m + 1] = pv
        tan[m + 1] = tv
    q = 0  # the non-empty segments, in order (the empty ones carry zero weight)
    for j in range(4):
        if pts[j + 1] > pts[j]:
            seg[q, 0], seg[q, 1] = pts[j], pts[j + 1]
            seg[q, 2], seg[q, 3] = 1.0 if tan[j] else 0.0, 1.0 if tan[j + 1] else 0.0
            q += 1
    return a0, a1, a2, e10, e11, e12, e20, e21, e22, t_u, phi_u, cc, q


def _cap_ring(seg, sgi, u, gw, stu, ctu, cc, phi_u):
    """Polar node u of segment sgi: (sin t, cos t, its weight, φ_lo, φ_hi) (the ring's lit arc)."""
    lo, hi = seg[sgi, 0], seg[sgi, 1]
    s_lo, s_hi = seg[sgi, 2] > 0.5, seg[sgi, 3] > 0.5
    if s_lo and s_hi:
        f, jac = u * u * (3.0 - 2.0 * u), 6.0 * u * (1.0 - u)
    elif s_lo:
        f, jac = u * u, 2.0 * u
    elif s_hi:
        f, jac = 1.0 - (1.0 - u) ** 2, 2.0 * (1.0 - u)
    else:
        f, jac = u, 1.0
    t = lo + (hi - lo) * f
    wt = (hi - lo) * gw * jac * np.sin(t)
    st, ct = np.sin(t), np.cos(t)
    hw = _half_width(ct, st, stu, ctu, cc)
    return st, ct, wt, phi_u - hw, phi_u + hw


def _sphere_cap_count(x, c, R, cus, ccs, gx_t, gw_t, gw_p, counts):
    """Beams with a positive weight per row of :func:`_cap_beams` (no azimuth trig)."""
    seg = np.empty((4, 4))
    for i in range(x.shape[0]):
        a0, a1, a2, e10, e11, e12, e20, e21, e22, t_u, phi_u, cc, ns = _cap_row(x, i, c, R, cus, ccs, seg)
        stu, ctu = np.sin(t_u), np.cos(t_u)
        q = 0
        for sgi in range(ns):
            for it in range(gx_t.shape[0]):
                st, ct, wt, p_lo, p_hi = _cap_ring(seg, sgi, gx_t[it], gw_t[it], stu, ctu, cc, phi_u)
                for ip in range(gw_p.shape[0]):
                    if wt * ((p_hi - p_lo) * gw_p[ip]) > 0.0:
                        q += 1
        counts[i] = q


def _cone_rule(axis, sin_rho, gx, gw, cphi, sphi, d, w):
    """:func:`lunarviz.geometry.sphere_quadrature.cone_rule` one row at a time: Gauss-Legendre in
    u = 1 − cos ψ, the midpoint rule in φ (``cphi``, ``sphi``: its cosines and sines)."""
    n_phi = cphi.shape[0]
    dphi = 2.0 * np.pi / n_phi
    for i in range(axis.shape[0]):
        a0, a1, a2 = axis[i, 0], axis[i, 1], axis[i, 2]
        s = sin_rho[i]
        u_max = s * s / (1.0 + np.sqrt(1.0 - s * s))  # 1 - cos ρ without cancellation
        e10, e11, e12, e20, e21, e22 = _basis(a0, a1, a2)
        col = 0
        for ip in range(gx.shape[0]):
            u = u_max * gx[ip]
            wu = u_max * gw[ip]
            cpsi = 1.0 - u
            spsi = np.sqrt(max(u * (2.0 - u), 0.0))
            for jp in range(n_phi):
                d[i, col, 0], d[i, col, 1], d[i, col, 2] = _on_basis(cpsi, spsi, cphi[jp], sphi[jp], a0, a1, a2,
                                                                     e10, e11, e12, e20, e21, e22)
                w[i, col] = wu * dphi
                col += 1

def _live_beams(x, n, dirs, omega, mu0, bi, ki, xs, ns, ds):
    """Gather the live beams (ω > 0 and μ0 > 0), row-major like ``np.nonzero``."""
    B, K = omega.shape
    q = 0
    for i in range(B):
        for k in range(K):
            if omega[i, k] > 0.0 and mu0[i, k] > 0.0:
                bi[q], ki[q] = i, k
                for j in range(3):
                    xs[q, j] = x[i, j]
                    ns[q, j] = n[i, j]
                    ds[q, j] = dirs[i, k, j]
                q += 1


def _ray_starts(origins, dirs, centre, R, tmax, has_tmax, o_out, t0_out, live):
    """Body-frame origins and the entry distance t0 into the bounding sphere of radius R
    (``EmbreeBody._prepare``); ``live``: the ray meets the sphere ahead (and before tmax)."""
    n = origins.shape[0]
    for i in range(n):
        o0, o1, o2 = origins[i, 0] - centre[0], origins[i, 1] - centre[1], origins[i, 2] - centre[2]
        o_out[i, 0], o_out[i, 1], o_out[i, 2] = o0, o1, o2
        disc, b, sq = _sphere_crossing(o0, o1, o2, dirs[i, 0], dirs[i, 1], dirs[i, 2], R)
        t_exit = b + sq
        t0 = max(b - sq, 0.0)
        t0_out[i] = t0
        ok = disc > 0.0 and t_exit > 0.0
        if has_tmax:
            ok = ok and t0 < tmax[i]
        live[i] = ok


def _ray_batch32(o, d, t0, idx, o32, d32):
    """float32 starts ``o + t0·d`` and directions of rays ``idx`` (Embree's input)."""
    for q in range(idx.shape[0]):
        i = idx[q]
        for j in range(3):
            o32[q, j] = o[i, j] + t0[i] * d[i, j]
            d32[q, j] = d[i, j]


def _earth_lit_dirs(xs, earth, R, us, c_s, n_tab, r1, r2, dirs, weight):
    """One direction per sample toward the Earth's lit, visible part and its weight [sr]:
    the tabulated polar pdf of ``MonteCarloTransport._earth_lit_directions`` (same formulas, same
    uniforms ``r1`` for t and ``r2`` for φ), one sample at a time instead of (N, n_tab) arrays."""
    N = xs.shape[0]
    cell = np.empty(n_tab)
    cdf = np.empty(n_tab)
    g = np.empty(n_tab + 1)
    for i in range(N):
        v0, v1, v2 = xs[i, 0] - earth[0], xs[i, 1] - earth[1], xs[i, 2] - earth[2]
        d = np.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
        a0, a1, a2 = v0 / d, v1 / d, v2 / d
        e10, e11, e12, e20, e21, e22 = _basis(a0, a1, a2)
        ctu = a0 * us[0] + a1 * us[1] + a2 * us[2]
        stu = np.sqrt(max(1.0 - ctu * ctu, 0.0))
        phi_u = np.arctan2(e20 * us[0] + e21 * us[1] + e22 * us[2], e10 * us[0] + e11 * us[1] + e12 * us[2])
        t_max = np.arccos(R / d)
        # cos, sin of t_k = k·t_max/n_tab by rotation (one cos/sin per sample instead of per
        # node; 24 steps keep them within ~1e-15 of numpy's), except at the limb t_max itself,
        # taken as numpy does: there d·cos t − R is zero up to rounding, and for an Earth lit
        # only in its last sliver (θ → 0) that rounding is the whole table
        cdt, sdt = np.cos(t_max / n_tab), np.sin(t_max / n_tab)
        ct, st = 1.0, 0.0
        for k in range(n_tab + 1):
            if k == n_tab:
                ct, st = np.cos(t_max), np.sin(t_max)
            g[k] = _jac_t(ct, st, d, R) * 2.0 * _half_width(ct, st, stu, ctu, c_s)
            ct, st = ct * cdt - st * sdt, st * cdt + ct * sdt
        tot = 0.0
        for k in range(n_tab):
            cell[k] = 0.5 * (g[k + 1] + g[k])
            tot += cell[k]
        floor = 1e-3 * (tot / n_tab) + 1e-300
        dt = t_max / n_tab
        acc = 0.0
        for k in range(n_tab):
            cell[k] = max(cell[k], floor)
            acc += cell[k] * dt
            cdf[k] = acc
        total = cdf[n_tab - 1]
        u = r1[i] * total
        k = 0
        for j in range(n_tab):
            if cdf[j] < u:
                k += 1
        k = min(k, n_tab - 1)
        lo = cdf[k - 1] if k > 0 else 0.0
        frac = (u - lo) / (cell[k] * dt)
        t = (k + min(max(frac, 0.0), 1.0)) * dt
        pdf_t = cell[k] / total
        ct, st = np.cos(t), np.sin(t)
        hw = _half_width(ct, st, stu, ctu, c_s)
        phi = phi_u + (2.0 * r2[i] - 1.0) * hw
        cp, sp = np.cos(phi), np.sin(phi)
        m0, m1, m2 = _on_basis(ct, st, cp, sp, a0, a1, a2, e10, e11, e12, e20, e21, e22)
        w0 = earth[0] + R * m0 - xs[i, 0]
        w1 = earth[1] + R * m1 - xs[i, 1]
        w2 = earth[2] + R * m2 - xs[i, 2]
        r = np.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
        dirs[i, 0], dirs[i, 1], dirs[i, 2] = w0 / r, w1 / r, w2 / r
        weight[i] = _jac_t(ct, st, d, R) * 2.0 * hw / pdf_t if hw > 0 else 0.0


def _half_width(ct, st, stu, ctu, c_s):
    """Half-width of the lit arc of the ring at polar angle t (cos t, sin t) about the sample."""
    den = st * stu
    num = c_s - ct * ctu
    if abs(den) > 1e-300:
        q = num / den
    else:
        q = -np.inf if num < 0 else np.inf
    return np.arccos(min(max(q, -1.0), 1.0))


def _jac_t(ct, st, d, R):
    """dΩ/(dt dφ) seen from distance d of the sphere point at polar angle t (cos t, sin t)."""
    r2 = d * d + R * R - 2.0 * d * R * ct
    return max(d * ct - R, 0.0) * R * R * st / (r2 * np.sqrt(r2))


# ---- one compiled pass per stage between the Embree calls (DeterministicTransport._fused_beam_transport) ----
def _live_beam(i, q, d0, d1, d2, w, n, o, xo0, xo1, xo2, c, Rb, mu0, sh, ch, bi, ki, ds, om_b, idx, o32, d32, m, p):
    """Beam (i, q) of direction d and solid angle w: μ0 and the half phase angle
    (:func:`_beam_angles`); if live (ω > 0, μ0 > 0) it becomes live beam m, and its ray from xo
    (relative to the source's centre c) ray p if it meets the bounding sphere of radius Rb
    (:func:`_ray_starts`, :func:`_ray_batch32`). Returns the new (m, p)."""
    m0 = d0 * n[i, 0] + d1 * n[i, 1] + d2 * n[i, 2]
    mu0[i, q] = m0
    e0, e1, e2 = d0 - o[i, 0], d1 - o[i, 1], d2 - o[i, 2]
    f0, f1, f2 = d0 + o[i, 0], d1 + o[i, 1], d2 + o[i, 2]
    s2 = e0 * e0 + e1 * e1 + e2 * e2
    c2 = f0 * f0 + f1 * f1 + f2 * f2
    inv = 1.0 / np.sqrt(s2 + c2)
    sh[i, q] = np.sqrt(s2) * inv
    ch[i, q] = np.sqrt(c2) * inv
    if not (w > 0.0 and m0 > 0.0):
        return m, p
    bi[m], ki[m] = i, q
    ds[m, 0], ds[m, 1], ds[m, 2] = d0, d1, d2
    om_b[m] = w
    r0, r1, r2 = xo0 - c[0], xo1 - c[1], xo2 - c[2]
    disc, b, sq = _sphere_crossing(r0, r1, r2, d0, d1, d2, Rb)
    if disc > 0.0 and b + sq > 0.0:
        t = max(b - sq, 0.0)
        idx[p] = m
        o32[p, 0], o32[p, 1], o32[p, 2] = r0 + t * d0, r1 + t * d1, r2 + t * d2
        d32[p, 0], d32[p, 1], d32[p, 2] = d0, d1, d2
        p += 1
    return m + 1, p


def _beam_rays(x, n, o, dirs, omega, off, c, Rb, mu0, sh, ch, bi, ki, ds, om_b, idx, o32, d32):
    """Every beam of a (B, K) rule through :func:`_live_beam`, row-major like ``np.nonzero``;
    origins ``x + n·off``. Returns (live beams, rays)."""
    B, K = omega.shape
    m = 0
    p = 0
    for i in range(B):
        xo0, xo1, xo2 = x[i, 0] + n[i, 0] * off, x[i, 1] + n[i, 1] * off, x[i, 2] + n[i, 2] * off
        for k in range(K):
            m, p = _live_beam(i, k, dirs[i, k, 0], dirs[i, k, 1], dirs[i, k, 2], omega[i, k], n, o, xo0, xo1, xo2,
                              c, Rb, mu0, sh, ch, bi, ki, ds, om_b, idx, o32, d32, m, p)
    return m, p


def _cap_beams(x, n, o, c, R, cus, ccs, gx_t, gw_t, gx_p, gw_p, off, Rb, as_rays, om, omega,
               mu0, sh, ch, bi, ki, ds, om_b, idx, o32, d32):
    """The sphere-surface rule of :func:`lunarviz.geometry.sphere_quadrature.cap_rule` for one
    constraint cap per row (``cus`` (B, 3), ``ccs`` (B,)), as beams from x
    (:func:`lunarviz.methods.sources.source_beams`: unit directions and solid angles
    dΩ = cos_y R² dω / r²), the nodes of positive weight first, in the rule's order, then padding
    (ω = 0, toward the centre); one row at a time instead of numpy's (B, ...) arrays
    (the two agree to 1e-12: docs, validation).

    ``as_rays`` False: the beams into ``om`` (B, K, 3) and ``omega`` (B, K). True: each beam
    straight to :func:`_live_beam` (angles, live beams, Embree's rays), without the directions
    in between (:func:`cap_beam_rays`). Returns (live beams, rays) (zeros without rays)."""
    K = mu0.shape[1] if as_rays else omega.shape[1]
    seg = np.empty((4, 4))
    n_p = gx_p.shape[0]
    sx = 2.0 * gx_p - 1.0
    ca, sa = np.empty(n_p), np.empty(n_p)
    m = 0
    p = 0
    xo0, xo1, xo2 = 0.0, 0.0, 0.0
    for i in range(x.shape[0]):
        a0, a1, a2, e10, e11, e12, e20, e21, e22, t_u, phi_u, cc, ns = _cap_row(x, i, c, R, cus, ccs, seg)
        stu, ctu = np.sin(t_u), np.cos(t_u)
        if as_rays:
            xo0, xo1, xo2 = x[i, 0] + n[i, 0] * off, x[i, 1] + n[i, 1] * off, x[i, 2] + n[i, 2] * off
        cpu, spu = np.cos(phi_u), np.sin(phi_u)
        q = 0
        for sgi in range(ns):
            for it in range(gx_t.shape[0]):
                st, ct, wt, p_lo, p_hi = _cap_ring(seg, sgi, gx_t[it], gw_t[it], stu, ctu, cc, phi_u)
                hw = 0.5 * (p_hi - p_lo)
                for ip in range(n_p):
                    w = wt * ((p_hi - p_lo) * gw_p[ip])
                    if not w > 0.0:
                        continue
                    # φ = φ_u + α, α = hw·(2 x_ip − 1): the Gauss nodes are symmetric, so one
                    # sin/cos serves the pair ±α (angle addition; the numpy rule takes sin φ, cos φ)
                    j = ip if ip < n_p - 1 - ip else n_p - 1 - ip
                    if ip == j:
                        ca[j], sa[j] = np.cos(hw * sx[j]), np.sin(hw * sx[j])
                    sal = sa[j] if ip == j else -sa[j]
                    cp = cpu * ca[j] - spu * sal
                    sp = spu * ca[j] + cpu * sal
                    m0, m1, m2 = _on_basis(ct, st, cp, sp, a0, a1, a2, e10, e11, e12, e20, e21, e22)
                    v0 = c[0] + R * m0 - x[i, 0]
                    v1 = c[1] + R * m1 - x[i, 1]
                    v2 = c[2] + R * m2 - x[i, 2]
                    inv_r = 1.0 / np.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
                    d0, d1, d2 = v0 * inv_r, v1 * inv_r, v2 * inv_r
                    wb = max(-(m0 * d0 + m1 * d1 + m2 * d2), 0.0) * R * R * w * (inv_r * inv_r)
                    if as_rays:
                        m, p = _live_beam(i, q, d0, d1, d2, wb, n, o, xo0, xo1, xo2, c, Rb, mu0, sh, ch, bi, ki,
                                          ds, om_b, idx, o32, d32, m, p)
                    else:
                        om[i, q, 0], om[i, q, 1], om[i, q, 2] = d0, d1, d2
                        omega[i, q] = wb
                    q += 1
        for k in range(q, K):  # padding: no light, toward the centre
            if as_rays:
                m, p = _live_beam(i, k, -a0, -a1, -a2, 0.0, n, o, xo0, xo1, xo2, c, Rb, mu0, sh, ch, bi, ki, ds,
                                  om_b, idx, o32, d32, m, p)
            else:
                om[i, k, 0], om[i, k, 1], om[i, k, 2] = -a0, -a1, -a2
                omega[i, k] = 0.0
    return m, p


def _source_hits(x, n, off, bi, ds, idx, prim_in, radius, centre, sun, phi, vis, albedo, has_vis, t_out, L, L_unit,
                 is_earth, L_sun, counts):
    """Embree's facets (``prim_in`` for the rays of live beams ``idx``) refined onto the exact
    sphere (:func:`_sphere_refine`), then the radiance each beam brings: the Sun's surface
    radiance ``L_sun``, or the Lambertian Earth lit by a point Sun
    (:func:`lunarviz.methods.sources.earth_radiance`) times the facet's sunlit fraction ``vis`` and its
    albedo (``albedo`` per facet, or one value); ``counts`` the hits per facet."""
    for q in range(bi.shape[0]):
        t_out[q] = np.inf
        L[q] = 0.0
        L_unit[q] = 0.0
    four_pi = 4.0 * np.pi
    for j in range(idx.shape[0]):
        pr = prim_in[j]
        if pr < 0:
            continue
        q = idx[j]
        i = bi[q]
        o0 = x[i, 0] - centre[0]  # (from x itself: see EmbreeBody.sphere_hits)
        o1 = x[i, 1] - centre[1]
        o2 = x[i, 2] - centre[2]
        d0, d1, d2 = ds[q, 0], ds[q, 1], ds[q, 2]
        disc, b, sq = _sphere_crossing(o0, o1, o2, d0, d1, d2, radius)
        t = b - sq
        if not (disc > 0.0 and t > 0.0):
            continue
        t_out[q] = t
        counts[pr] += 1
        if not is_earth:
            L[q] = L_sun
            continue
        y0 = o0 + t * d0 + centre[0]
        y1 = o1 + t * d1 + centre[1]
        y2 = o2 + t * d2 + centre[2]
        m0, m1, m2 = (y0 - centre[0]) / radius, (y1 - centre[1]) / radius, (y2 - centre[2]) / radius
        v0, v1, v2 = sun[0] - y0, sun[1] - y1, sun[2] - y2
        dsun = np.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
        mu_s = max((m0 * v0 + m1 * v1 + m2 * v2) / dsun, 0.0)
        lu = 1.0 / np.pi * phi / (four_pi * dsun ** 2) * mu_s
        if has_vis:
            lu = lu * vis[pr]
        L_unit[q] = lu
        L[q] = lu * (albedo[pr] if albedo.shape[0] > 1 else albedo[0])


def _occluder_rays(x, n, off, bi, ds, tmax, mask, centre, R, rows, o32, d32, dists):
    """Shadow rays from ``x[bi] + n[bi]·off`` along ``ds`` up to ``tmax`` for the rows of
    ``mask``, against a body's bounding sphere (centre, radius R): :func:`_ray_starts` (culling
    rays that miss it or end before it) and :func:`_ray_batch32`, with Embree's float32
    ``dists`` = tmax − t0. Returns how many rays were written."""
    f32max = 3.4028234663852886e38
    p = 0
    for q in range(bi.shape[0]):
        if not mask[q]:
            continue
        i = bi[q]
        o0 = x[i, 0] + n[i, 0] * off - centre[0]
        o1 = x[i, 1] + n[i, 1] * off - centre[1]
        o2 = x[i, 2] + n[i, 2] * off - centre[2]
        d0, d1, d2 = ds[q, 0], ds[q, 1], ds[q, 2]
        disc, b, sq = _sphere_crossing(o0, o1, o2, d0, d1, d2, R)
        t0 = max(b - sq, 0.0)
        if not (disc > 0.0 and b + sq > 0.0 and t0 < tmax[q]):
            continue
        rows[p] = q
        o32[p, 0], o32[p, 1], o32[p, 2] = o0 + t0 * d0, o1 + t0 * d1, o2 + t0 * d2
        d32[p, 0], d32[p, 1], d32[p, 2] = d0, d1, d2
        dists[p] = min(max(tmax[q] - t0, 0.0), f32max)
        p += 1
    return p


def _scatter_beams(bi, ki, om_b, L, L_free, L_unit, has_unit, e, e_free, e_unit):
    """(B, K) beam irradiances ``value·ω`` at the live beams (bi, ki); zero elsewhere."""
    for q in range(bi.shape[0]):
        i, k = bi[q], ki[q]
        w = om_b[q]
        e[i, k] = L[q] * w
        e_free[i, k] = L_free[q] * w
        if has_unit:
            e_unit[i, k] = L_unit[q] * w



_NUMBA = compiled.available()
if _NUMBA:
    try:
        _beam_angles = compiled.jit(_beam_angles, nogil=True)
        _sphere_refine = compiled.jit(_sphere_refine, nogil=True)
        _basis = compiled.jit(_basis, inline="always")
        _on_basis = compiled.jit(_on_basis, inline="always")
        _sphere_crossing = compiled.jit(_sphere_crossing, inline="always")
        _cap_row = compiled.jit(_cap_row, inline="always")
        _cap_ring = compiled.jit(_cap_ring, inline="always")
        _sphere_cap_count = compiled.jit(_sphere_cap_count, nogil=True)
        _live_beams = compiled.jit(_live_beams, nogil=True)
        _cone_rule = compiled.jit(_cone_rule, nogil=True)
        _ray_starts = compiled.jit(_ray_starts, nogil=True)
        _ray_batch32 = compiled.jit(_ray_batch32, nogil=True)
        _half_width = compiled.jit(_half_width, inline="always")
        _jac_t = compiled.jit(_jac_t, inline="always")
        _earth_lit_dirs = compiled.jit(_earth_lit_dirs, nogil=True)
        _live_beam = compiled.jit(_live_beam, inline="always")
        _beam_rays = compiled.jit(_beam_rays, nogil=True)
        _cap_beams = compiled.jit(_cap_beams, nogil=True)
        _source_hits = compiled.jit(_source_hits, nogil=True)
        _occluder_rays = compiled.jit(_occluder_rays, nogil=True)
        _scatter_beams = compiled.jit(_scatter_beams, nogil=True)
    except Exception:  # noqa: BLE001 (numba unusable here: the numpy path serves)
        _NUMBA = False


def beam_angles(dirs, n, o):
    """``(μ0, sin(g/2), cos(g/2))`` (B, K) of beams ``dirs`` (B, K, 3) at points with normals
    ``n`` (B, 3) seen along ``o`` (B, 3): compiled, or numpy where numba is off."""
    if not _NUMBA:
        sh, ch = half_angle_sin_cos(dirs, o[:, None, :])
        return np.einsum("bkj,bj->bk", dirs, n), sh, ch
    B, K = dirs.shape[:2]
    mu0, sh, ch = np.empty((B, K)), np.empty((B, K)), np.empty((B, K))
    f = np.ascontiguousarray
    _beam_angles(f(dirs, dtype=float), f(n, dtype=float), f(o, dtype=float), mu0, sh, ch)
    return mu0, sh, ch


def sphere_refine(o, d, radius: float, prim, centre):
    """``(hit, t, point)`` on the exact sphere for rays whose facet Embree found (``prim``)."""
    n = len(o)
    prim = np.array(prim, dtype=np.int64)
    if not _NUMBA:
        b = -np.einsum("ij,ij->i", o, d)
        perp2 = np.einsum("ij,ij->i", o, o) - b * b
        disc = radius**2 - perp2
        t = b - np.sqrt(np.clip(disc, 0.0, None))
        hit = (prim >= 0) & (disc > 0) & (t > 0)
        point = np.full((n, 3), np.nan)
        tt = np.full(n, np.inf)
        point[hit] = o[hit] + t[hit, None] * d[hit] + centre
        tt[hit] = t[hit]
        prim[~hit] = -1
        return prim, tt, point
    t = np.full(n, np.inf)
    point = np.full((n, 3), np.nan)
    f = np.ascontiguousarray
    _sphere_refine(f(o, dtype=float), f(d, dtype=float), float(radius), prim, t, point, f(centre, dtype=float))
    return prim, t, point


def sphere_cap_beams(x, c, R: float, cap_u, cap_c, n_t: int, n_phi: int):
    """Beams ``(om, omega)`` (B, K, 3), (B, K) from points x (B, 3) over the part of the sphere
    (centre c, radius R) they see that lies inside the cap ``{m·cap_u > cap_c}`` (one cap, (3,)
    and scalar, or one per row, (B, 3) and (B,)): the same beams as
    ``source_beams(source_sphere_rule(...))`` where that rule has one cap (the Earth's lit face
    seen from points whose horizon does not cut the Earth; the Sun cut by the horizon),
    compiled; ``None`` where numba is off."""
    if not _NUMBA:
        return None
    x, c, rule, counts = _cap_setup(x, c, R, cap_u, cap_c, n_t, n_phi)
    B, kmax = len(x), max(int(counts.max(initial=0)), 1)
    om, omega = np.empty((B, kmax, 3)), np.empty((B, kmax))
    angles, live = _beam_arrays(1, 1, 1)  # (unused without rays)
    _cap_beams(x, x, x, c, float(R), *rule, 0.0, 0.0, False, om, omega, *angles, *live)
    return om, omega


def _cap_setup(x, c, R: float, cap_u, cap_c, n_t: int, n_phi: int):
    """Contiguous inputs of :func:`_cap_beams`: x, c, (cap axes, cap cosines, Gauss rules) and
    the number of beams of each row."""
    f = np.ascontiguousarray
    x, c = f(x, dtype=float), f(c, dtype=float)
    B = len(x)
    gx_t, gw_t = gauss_legendre(n_t)
    gx_p, gw_p = gauss_legendre(n_phi)
    cu = f(np.broadcast_to(cap_u, (B, 3)), dtype=float)
    cc = f(np.broadcast_to(cap_c, (B,)), dtype=float)
    counts = np.empty(B, np.int64)
    _sphere_cap_count(x, c, float(R), cu, cc, gx_t, gw_t, gw_p, counts)
    return x, c, (cu, cc, gx_t, gw_t, gx_p, gw_p), counts


def cone_rule(axis, sin_rho, n_psi: int = 2, n_phi: int = 4):
    """:func:`lunarviz.geometry.sphere_quadrature.cone_rule` (directions (B, n_psi·n_phi, 3) and solid
    angles [sr] filling the cone of half-angle asin(sin_rho) about ``axis``), compiled; the
    numpy rule where numba is off."""
    if not _NUMBA:
        return numpy_rule(axis, sin_rho, n_psi, n_phi)
    f = np.ascontiguousarray
    axis = f(axis, dtype=float)
    B = len(axis)
    gx, gw = gauss_legendre(n_psi)
    phi = (np.arange(n_phi) + 0.5) * (2 * np.pi / n_phi)
    d, w = np.empty((B, n_psi * n_phi, 3)), np.empty((B, n_psi * n_phi))
    _cone_rule(axis, f(np.broadcast_to(sin_rho, (B,)), dtype=float), gx, gw, np.cos(phi), np.sin(phi), d, w)
    return d, w

def live_beams(x, n, dirs, omega, mu0):
    """``(bi, ki, x[bi], n[bi], dirs[bi, ki])`` for the beams with ω > 0 and μ0 > 0."""
    live = (omega > 0) & (mu0 > 0)
    if not _NUMBA:
        bi, ki = np.nonzero(live)
        return bi, ki, x[bi], n[bi], dirs[bi, ki]
    N = int(np.count_nonzero(live))
    bi, ki = np.empty(N, dtype=np.int64), np.empty(N, dtype=np.int64)
    xs, ns, ds = np.empty((N, 3)), np.empty((N, 3)), np.empty((N, 3))
    f = np.ascontiguousarray
    _live_beams(f(x, dtype=float), f(n, dtype=float), f(dirs, dtype=float), f(omega, dtype=float),
                f(mu0, dtype=float), bi, ki, xs, ns, ds)
    return bi, ki, xs, ns, ds


def ray_starts(origins, dirs, centre, R: float, tmax=None):
    """``(o, t0, live)``: body-frame origins, entry distance into the sphere of radius R
    about ``centre``, and whether the ray meets it ahead (and before ``tmax``)."""
    origins = np.asarray(origins, dtype=float)
    dirs = np.asarray(dirs, dtype=float)
    n = len(origins)
    if not _NUMBA:
        o = origins - centre
        b = -np.einsum("ij,ij->i", o, dirs)
        perp2 = np.einsum("ij,ij->i", o, o) - b * b
        disc = R * R - perp2
        t_exit = b + np.sqrt(np.clip(disc, 0.0, None))
        live = (disc > 0.0) & (t_exit > 0.0)
        t0 = np.clip(b - np.sqrt(np.clip(disc, 0.0, None)), 0.0, None)
        if tmax is not None:
            live &= t0 < tmax
        return o, t0, live
    o, t0, live = np.empty((n, 3)), np.empty(n), np.empty(n, dtype=np.bool_)
    tm = np.zeros(1) if tmax is None else np.ascontiguousarray(np.broadcast_to(tmax, (n,)), dtype=float)
    f = np.ascontiguousarray
    _ray_starts(f(origins), f(dirs), f(centre, dtype=float), float(R), tm, tmax is not None, o, t0, live)
    return o, t0, live


def ray_batch32(o, d, t0, idx):
    """``(o[idx] + t0[idx]·d[idx], d[idx])`` as float32 (Embree's input)."""
    if not _NUMBA:
        return (o[idx] + t0[idx, None] * d[idx]).astype(np.float32), d[idx].astype(np.float32)
    o32, d32 = np.empty((len(idx), 3), np.float32), np.empty((len(idx), 3), np.float32)
    f = np.ascontiguousarray
    _ray_batch32(f(o, dtype=float), f(d, dtype=float), f(t0, dtype=float), f(idx, dtype=np.int64), o32, d32)
    return o32, d32


class BeamRays(NamedTuple):
    """The beams of a (B, K) rule at points x with normals n and their rays toward a source
    (:func:`beam_rays`, :func:`cap_beam_rays`)."""
    x: np.ndarray     # (B, 3) lunar points [m]
    n: np.ndarray     # (B, 3) unit normals
    off: float        # ray origins x + n·off [m]
    mu0: np.ndarray   # (B, K) cos incidence of every beam
    sin_hg: np.ndarray  # (B, K) sine of the half phase angle
    cos_hg: np.ndarray  # (B, K)
    bi: np.ndarray    # (M,) row of each live beam (ω > 0, μ0 > 0)
    ki: np.ndarray    # (M,) its column
    dirs: np.ndarray  # (M, 3) its unit direction
    omega: np.ndarray  # (M,) its solid angle [sr]
    idx: np.ndarray   # (P,) live beams whose ray meets the source's bounding sphere
    o32: np.ndarray   # (P, 3) float32 ray starts on that sphere, relative to the source's centre
    d32: np.ndarray   # (P, 3) float32 directions


def _beam_arrays(B: int, K: int, M: int):
    return ((np.empty((B, K)), np.empty((B, K)), np.empty((B, K))),
            (np.empty(M, np.int64), np.empty(M, np.int64), np.empty((M, 3)), np.empty(M), np.empty(M, np.int64),
             np.empty((M, 3), np.float32), np.empty((M, 3), np.float32)))


def _beam_result(x, n, off, angles, live, m: int, p: int) -> BeamRays:
    bi, ki, ds, om_b, idx, o32, d32 = live
    return BeamRays(x, n, off, *angles, bi[:m], ki[:m], ds[:m], om_b[:m], idx[:p], o32[:p], d32[:p])


def beam_rays(x, n, o, dirs, omega, off: float, centre, R: float) -> BeamRays:
    """Beam angles of every beam of ``dirs`` (B, K, 3), ``omega`` (B, K) at points x with normals
    n seen along o, and the live beams (ω > 0, μ0 > 0) as rays from ``x + n·off`` toward a source
    of bounding radius R about ``centre``, ready for Embree: ``beam_angles``, ``live_beams``,
    ``EmbreeBody._prepare`` and ``ray_batch32`` in one compiled pass (numba only)."""
    f = np.ascontiguousarray
    dirs, omega = f(dirs, dtype=float), f(omega, dtype=float)
    x, n = f(x, dtype=float), f(n, dtype=float)
    B, K = omega.shape
    angles, live = _beam_arrays(B, K, B * K)
    m, p = _beam_rays(x, n, f(o, dtype=float), dirs, omega, float(off), f(centre, dtype=float), float(R),
                      *angles, *live)
    return _beam_result(x, n, off, angles, live, m, p)


def cap_beam_rays(x, n, o, c, R: float, cap_u, cap_c, order: int, off: float, Rb: float) -> BeamRays:
    """:func:`sphere_cap_beams` (``order`` × ``order`` nodes) then :func:`beam_rays` toward the
    sphere (c, R) with bounding radius Rb, fused: the beams go straight from the rule to Embree's
    rays (numba only)."""
    x, c, rule, counts = _cap_setup(x, c, R, cap_u, cap_c, order, order)
    n = np.ascontiguousarray(n, dtype=float)
    angles, live = _beam_arrays(len(x), max(int(counts.max(initial=0)), 1), int(counts.sum()))
    m, p = _cap_beams(x, n, np.ascontiguousarray(o, dtype=float), c, float(R), *rule, float(off), float(Rb), True,
                      np.empty((1, 1, 3)), np.empty((1, 1)), *angles, *live)
    return _beam_result(x, n, off, angles, live, m, p)


def source_hits(rays: BeamRays, prim_in, radius: float, centre, n_faces: int, *, sun_radiance: float = 0.0,
                earth=None):
    """``(t, L, L_unit, counts)`` of the live beams: Embree's facets refined onto the exact
    sphere (distance t, inf where missed), the radiance each beam brings (the Sun's
    ``sun_radiance``, or with ``earth = (sun position, Φ, sunlit fraction per facet or None,
    albedo per facet or (1,))`` the Lambertian Earth's, and the same for albedo 1) and the hits
    per facet."""
    M = len(rays.bi)
    t, L, L_unit = np.empty(M), np.empty(M), np.empty(M)
    counts = np.zeros(n_faces, np.int64)
    f = np.ascontiguousarray
    sun, phi, vis, alb = (np.zeros(3), 0.0, None, np.zeros(1)) if earth is None else earth
    _source_hits(rays.x, rays.n, float(rays.off), rays.bi, rays.dirs, rays.idx, f(prim_in, dtype=np.int64),
                 float(radius), f(centre, dtype=float), f(sun, dtype=float), float(phi),
                 np.zeros(1) if vis is None else f(vis, dtype=float), f(alb, dtype=float).reshape(-1),
                 vis is not None, t, L, L_unit, earth is not None, float(sun_radiance), counts)
    return t, L, L_unit, counts


def occluder_rays(rays: BeamRays, tmax, mask, centre, R: float):
    """``(rows, o32, d32, dists)``: the shadow rays ``EmbreeBody.occluded`` would cast for the
    live beams in ``mask`` (from their origins, up to ``tmax``) against a body of bounding radius
    R about ``centre``, gathered and culled in one compiled pass; ``rows`` index the live beams."""
    n = int(np.count_nonzero(mask))
    rows = np.empty(n, np.int64)
    o32, d32, dists = np.empty((n, 3), np.float32), np.empty((n, 3), np.float32), np.empty(n, np.float32)
    P = _occluder_rays(rays.x, rays.n, float(rays.off), rays.bi, rays.dirs, np.ascontiguousarray(tmax, dtype=float),
                       np.ascontiguousarray(mask, dtype=np.bool_), np.ascontiguousarray(centre, dtype=float), float(R),
                       rows, o32, d32, dists)
    return rows[:P], o32[:P], d32[:P], dists[:P]


def scatter_beams(rays: BeamRays, L, L_free, L_unit=None):
    """(B, K) beam irradiances ``L·ω`` (and ``L_free·ω``, ``L_unit·ω``) at the live beams, 0
    elsewhere."""
    shape = rays.mu0.shape
    e, e_free = np.zeros(shape), np.zeros(shape)
    e_unit = np.zeros(shape) if L_unit is not None else np.zeros((1, 1))
    _scatter_beams(rays.bi, rays.ki, rays.omega, L, L_free, L if L_unit is None else L_unit, L_unit is not None,
                   e, e_free, e_unit)
    return e, e_free, (e_unit if L_unit is not None else None)


def earth_lit_directions(xs, earth, R: float, sun_dir, c_s: float, n_tab: int, r1, r2):
    """Compiled ``MonteCarloTransport._earth_lit_directions`` given its two uniforms per sample
    (``r1`` picks the polar angle, ``r2`` the azimuth); ``None`` where numba is off."""
    if not _NUMBA:
        return None
    N = len(xs)
    dirs, weight = np.empty((N, 3)), np.empty(N)
    f = np.ascontiguousarray
    _earth_lit_dirs(f(xs, dtype=float), f(earth, dtype=float), float(R), f(sun_dir, dtype=float), float(c_s),
                    int(n_tab), f(r1, dtype=float), f(r2, dtype=float), dirs, weight)
    return dirs, weight


def warm_up() -> None:
    """Load (or compile) every kernel once on tiny inputs, e.g. before forking workers."""
    if not _NUMBA:
        return
    shading_kernels.warm_up()
    rough_kernels.warm_up()
    one = np.ones((1, 1))
    beam_angles(np.ones((1, 1, 3)), np.ones((1, 3)), np.ones((1, 3)))
    sphere_refine(np.ones((1, 3)), np.ones((1, 3)), 1.0, np.zeros(1, np.int64), np.zeros(3))
    x = np.array([[0.0, 0.0, 10.0]])
    sphere_cap_beams(x, np.zeros(3), 1.0, np.array([1.0, 0.0, 0.0]), 0.0, 2, 2)
    live_beams(x, x, np.ones((1, 1, 3)), one, one)
    cone_rule(np.array([[0.0, 0.0, 1.0]]), np.array([0.01]))
    ray_starts(x, np.array([[0.0, 0.0, -1.0]]), np.zeros(3), 1.0)
    ray_batch32(x, x, np.zeros(1), np.zeros(1, np.int64))
    earth_lit_directions(x, np.zeros(3), 1.0, np.array([1.0, 0.0, 0.0]), 0.01, 4, np.ones(1) * 0.5, np.ones(1) * 0.5)
