#!/usr/bin/env python
"""Independent reference: moonshine and earthshine detector irradiance [W/m^2] for non-spherical
Moons (triaxial ellipsoid, rotated cube) and a sphere check, in the paper's scene (Eq. 3).

Only numpy/scipy; lunarviz is used solely for make_brdf(...).radiance_factor (BRDF*mu0 [1/sr]).

Method (all deterministic product Gauss rules):
* Unit-sphere polar rules cut exactly at circle ("cap") boundaries: the t-range is split at rings
  tangent to a cap boundary and at the crossings of two cap boundaries, each t-segment mapped by
  the smoothstep t = lo + (hi-lo)(3u^2-2u^3) (removes the sqrt singularity at tangent rings);
  on each ring the phi-range is the exact intersection of the caps' arcs.
* Ellipsoid x = c + A p (p on the unit sphere, A = diag(a,b,c)): normal ~ A^-1 p (gradient),
  dA = det(A) |A^-1 p| dOmega_p.  "Lit by the point Sun" and "seen by the detector"
  (n.(P - x) > 0) are exact caps in p: p . A^-1 (P - c) > 1.
* Cube: Gauss-Legendre product rule on each flat face (no kinks on a flat face: the sign of
  n.(P - x) is constant on a face for every point P).
* Earth (extended, Lambertian, albedo 0.3, lit by a point Sun): for every lunar node x, polar
  rule on the Earth's sphere about the sub-x point (where the phase angle g = 0, i.e. the
  opposition cusp, sits: detector = Earth centre), over visible cap ∩ lit cap ∩ x's horizon cap.
* Sun: point source at its centre (exact normal irradiance Phi/(4 pi d^2) of a uniform Lambertian
  sphere); the extended Sun (uniform disc of radiance Phi/(4 pi^2 R_S^2)) is evaluated as a check.
"""
from __future__ import annotations

import json
import os as _os
import sys
import time

import numpy as np

#: where meshes and reference results go (``LUNARVIZ_VALIDATION_DIR``, default validation_out/)
OUT = _os.environ.get("LUNARVIZ_VALIDATION_DIR", "validation_out")
_os.makedirs(OUT, exist_ok=True)

from lunarviz.photometry.brdf import make_brdf

# ---- constants (values as in lunarviz/constants.py; copied, not imported) -------------------
D_SE, D_EM = 1.496e11, 3.800e8
R_MOON, R_EARTH, R_SUN = 1.738e6, 6.378e6, 6.957e8
PHI = 1.626e26
A_EARTH = 0.3

BRDFS = {"lambert": make_brdf("lambert"), "dhg": make_brdf("dhg")}
PHASES = (30, 90, 150)

ELL_AXES = np.array([1.15, 1.00, 0.85]) * R_MOON


def rot_matrix():
    a, b, c = np.radians([25.0, 35.0, 15.0])
    Rz = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    Ry = np.array([[np.cos(b), 0, np.sin(b)], [0, 1, 0], [-np.sin(b), 0, np.cos(b)]])
    Rx = np.array([[1, 0, 0], [0, np.cos(c), -np.sin(c)], [0, np.sin(c), np.cos(c)]])
    return Rz @ Ry @ Rx


ROT = rot_matrix()


def scene(theta_deg):
    t = np.radians(theta_deg)
    sun = np.array([0.0, 0.0, -D_SE])
    moon = np.array([0.0, D_EM * np.sin(t), D_EM * np.cos(t)])
    det = np.zeros(3)
    return sun, moon, det


def unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def half_angle(a, b):
    """sin(g/2), cos(g/2) for unit vectors a, b (..., 3)."""
    s = np.linalg.norm(a - b, axis=-1)
    c = np.linalg.norm(a + b, axis=-1)
    nrm = np.hypot(s, c)
    return s / nrm, c / nrm


def gl01(n):
    x, w = np.polynomial.legendre.leggauss(n)
    return 0.5 * (x + 1), 0.5 * w


# ---- polar rule on the unit sphere over {n.axis >= cos tmax} ∩ caps ----------------------------
def basis(axis):
    helper = np.where(np.abs(axis[:, :1]) < 0.8, [[1.0, 0, 0]], [[0, 0, 1.0]])
    e1 = unit(np.cross(axis, helper))
    return e1, np.cross(axis, e1)


def polar_caps_rule(axis, tmax, caps, n_t, n_phi):
    """axis (B,3) unit, tmax (B,), caps: list (<=2) of (u (B,3) unit, c (B,)) meaning m.u > c.
    Returns nodes (B,M,3), solid-angle weights (B,M)."""
    B = axis.shape[0]
    e1, e2 = basis(axis)
    info = []
    bps = [np.zeros(B), tmax]
    for u, c in caps:
        ua = np.einsum("bj,bj->b", u, axis)
        u1, u2 = np.einsum("bj,bj->b", u, e1), np.einsum("bj,bj->b", u, e2)
        tu = np.arctan2(np.hypot(u1, u2), ua)
        pu = np.arctan2(u2, u1)
        valid = np.abs(c) < 1
        a = np.arccos(np.clip(c, -1, 1))
        for cand in (np.abs(tu - a), tu + a, 2 * np.pi - tu - a):
            bps.append(np.where(valid, np.clip(cand, 0, tmax), 0.0))
        info.append((tu, pu, c))
    if len(caps) == 2:  # crossings of the two cap boundaries
        (uA, cA), (uB, cB) = caps
        G = np.einsum("bj,bj->b", uA, uB)
        den = np.maximum(1 - G * G, 1e-300)
        al = (cA - cB * G) / den
        be = (cB - cA * G) / den
        g2 = (1 - (al * cA + be * cB)) / den
        ok = (g2 > 0) & (np.abs(cA) < 1) & (np.abs(cB) < 1) & (1 - G * G > 1e-14)
        w = np.cross(uA, uB)
        for sgn in (1, -1):
            m = al[:, None] * uA + be[:, None] * uB + sgn * np.sqrt(np.where(ok, g2, 0))[:, None] * w
            tc = np.arccos(np.clip(np.einsum("bj,bj->b", unit(m), axis), -1, 1))
            bps.append(np.where(ok, np.clip(tc, 0, tmax), 0.0))
    bp = np.sort(np.stack(bps, 1), axis=1)
    lo, hi = bp[:, :-1], bp[:, 1:]
    L = hi - lo
    keep = max(int((L > 0).sum(1).max()), 1)
    sel = np.argsort(~(L > 0), axis=1, kind="stable")[:, :keep]
    lo, L = np.take_along_axis(lo, sel, 1), np.take_along_axis(L, sel, 1)
    u, gw = gl01(n_t)
    f, jac = u * u * (3 - 2 * u), 6 * u * (1 - u)
    t = (lo[:, :, None] + L[:, :, None] * f).reshape(B, -1)
    wt = (L[:, :, None] * gw * jac).reshape(B, -1) * np.sin(t)
    st, ct = np.sin(t), np.cos(t)
    # arcs on each ring
    arcs = []
    for tu, pu, c in info:
        den = st * np.sin(tu)[:, None]
        num = c[:, None] - ct * np.cos(tu)[:, None]
        with np.errstate(divide="ignore", invalid="ignore"):
            q = np.where(np.abs(den) > 1e-300, num / den, np.where(num < 0, -np.inf, np.inf))
        h = np.arccos(np.clip(q, -1, 1))
        arcs.append((np.broadcast_to(pu[:, None], h.shape), h))
    R = t.shape[1]
    if len(arcs) == 0:
        starts = np.zeros((B, R, 1)); lens = np.full((B, R, 1), 2 * np.pi)
    elif len(arcs) == 1:
        pu, h = arcs[0]
        starts = (pu - h)[:, :, None]; lens = (2 * h)[:, :, None]
    else:
        (p1, h1), (p2, h2) = arcs
        swap = h1 > h2  # primary = the smaller arc
        pA, hA = np.where(swap, p2, p1), np.minimum(h1, h2)
        pB, hB = np.where(swap, p1, p2), np.maximum(h1, h2)
        s0 = pA - hA
        cc = np.mod(pB - s0, 2 * np.pi)
        fullB = hB >= np.pi
        los, lns = [], []
        for k in (-1, 0, 1):
            a_lo = np.maximum(0.0, cc - hB + 2 * np.pi * k)
            a_hi = np.minimum(2 * hA, cc + hB + 2 * np.pi * k)
            ln = np.maximum(0.0, a_hi - a_lo)
            if k == 0:
                a_lo = np.where(fullB, 0.0, a_lo); ln = np.where(fullB, 2 * hA, ln)
            else:
                ln = np.where(fullB, 0.0, ln)
            los.append(s0 + a_lo); lns.append(ln)
        starts, lens = np.stack(los, 2), np.stack(lns, 2)
    fx, fw = gl01(n_phi)
    phi = starts[..., None] + lens[..., None] * fx  # (B,R,P,n_phi)
    w = wt[:, :, None, None] * lens[..., None] * fw
    sp, cp = np.sin(phi), np.cos(phi)
    stt = st[:, :, None, None, None]
    nodes = (ct[:, :, None, None, None] * axis[:, None, None, None, :]
             + stt * (cp[..., None] * e1[:, None, None, None, :] + sp[..., None] * e2[:, None, None, None, :]))
    nodes, w = nodes.reshape(B, -1, 3), w.reshape(B, -1)
    nz = w > 0
    k = max(int(nz.sum(1).max()), 1)
    sel = np.argsort(~nz, axis=1, kind="stable")[:, :k]
    return np.take_along_axis(nodes, sel[..., None], 1), np.take_along_axis(w, sel, 1)


# ---- radiance of lunar points toward the detector ---------------------------------------------
def moon_radiance_sun(x, n, sun, det, brdf, ext=None):
    """Radiance [W m^-2 sr^-1] toward det. ext=None: point Sun; ext=(n_psi, n_phi): disc."""
    o = unit(det - x)
    mu = np.clip(np.einsum("bj,bj->b", n, o), 0, 1)
    vs = sun - x
    ds = np.linalg.norm(vs, axis=1)
    s = vs / ds[:, None]
    if ext is None:
        mu0 = np.clip(np.einsum("bj,bj->b", n, s), 0, 1)
        sh, ch = half_angle(s, o)
        return brdf.radiance_factor(mu0, mu, sh, ch) * PHI / (4 * np.pi * ds**2)
    n_psi, n_ph = ext
    sinr = R_SUN / ds
    umax = sinr**2 / (1 + np.sqrt(1 - sinr**2))
    gx, gw = gl01(n_psi)
    uu = umax[:, None] * gx
    wu = umax[:, None] * gw
    cpsi, spsi = 1 - uu, np.sqrt(uu * (2 - uu))
    ph = (np.arange(n_ph) + 0.5) * 2 * np.pi / n_ph
    e1, e2 = basis(s)
    d = (cpsi[:, :, None, None] * s[:, None, None, :] + spsi[:, :, None, None]
         * (np.cos(ph)[None, None, :, None] * e1[:, None, None, :] + np.sin(ph)[None, None, :, None] * e2[:, None, None, :]))
    d = d.reshape(len(x), -1, 3)
    dOm = np.repeat(wu * 2 * np.pi / n_ph, n_ph, axis=1)
    mu0 = np.clip(np.einsum("bkj,bj->bk", d, n), 0, 1)
    sh, ch = half_angle(d, o[:, None, :])
    Ls = PHI / (4 * np.pi**2 * R_SUN**2)
    return np.sum(brdf.radiance_factor(mu0, mu[:, None], sh, ch) * Ls * dOm, axis=1)


def moon_radiance_earth(x, n, sun, det, brdfs, order):
    """Radiance toward det for each BRDF in brdfs (dict) from the extended Lambertian Earth."""
    E = np.zeros(3)
    xe = x - E
    dxe = np.linalg.norm(xe, axis=1)
    axis = xe / dxe[:, None]
    tmax = np.arccos(R_EARTH / dxe)
    B = len(x)
    us = np.broadcast_to(unit(sun - E), (B, 3))
    cs = np.full(B, R_EARTH / np.linalg.norm(sun - E))
    ch_ = np.einsum("bj,bj->b", n, xe) / R_EARTH
    m, w = polar_caps_rule(axis, tmax, [(us, cs), (n, ch_)], order, order)
    y = E + R_EARTH * m
    v = y - x[:, None, :]
    r = np.linalg.norm(v, axis=2)
    om = v / r[..., None]
    cos_y = np.clip(-np.einsum("bkj,bkj->bk", m, om), 0, None)
    dOm = cos_y * R_EARTH**2 * w / r**2
    vs = sun - y
    dsy = np.linalg.norm(vs, axis=2)
    LE = A_EARTH / np.pi * PHI / (4 * np.pi * dsy**2) * np.clip(np.einsum("bkj,bkj->bk", m, vs) / dsy, 0, None)
    o = unit(det - x)
    mu = np.clip(np.einsum("bj,bj->b", n, o), 0, 1)
    mu0 = np.clip(np.einsum("bkj,bj->bk", om, n), 0, 1)
    sh, chh = half_angle(om, o[:, None, :])
    eb = LE * dOm
    return {k: np.sum(b.radiance_factor(mu0, mu[:, None], sh, chh) * eb, axis=1) for k, b in brdfs.items()}


def detector_weight(x, n, dA, det, moon):
    v = det - x
    d2 = np.einsum("bj,bj->b", v, v)
    d = np.sqrt(d2)
    mu = np.einsum("bj,bj->b", n, v) / d
    nd = unit(moon - det)
    cosd = -(v @ nd) / d
    return np.clip(mu, 0, None) * np.clip(cosd, 0, None) * dA / d2


# ---- surface rules ---------------------------------------------------------------------------
def ellipsoid_rule(axes, moon, P, cap_point=None, order=32):
    """Nodes x, normals n, areas dA on the ellipsoid part seen from point P (exact cap in p),
    optionally ∩ the part facing cap_point (e.g. lit by the point Sun)."""
    Ainv = 1.0 / axes
    def cap(Q):
        q = Ainv * (Q - moon)
        nq = np.linalg.norm(q)
        return q / nq, 1.0 / nq
    ua, ca = cap(P)
    caps = []
    if cap_point is not None:
        u, c = cap(cap_point)
        caps = [(u[None], np.array([c]))]
    p, w = polar_caps_rule(ua[None], np.array([np.arccos(ca)]), caps, order, order)
    p, w = p[0], w[0]
    g = p * Ainv
    gn = np.linalg.norm(g, axis=1)
    return moon + p * axes, g / gn[:, None], np.prod(axes) * gn * w


def cube_rule(moon, order, R=ROT):
    u, w = np.polynomial.legendre.leggauss(order)
    U, V = np.meshgrid(u * R_MOON, u * R_MOON, indexing="ij")
    W = np.outer(w, w).ravel() * R_MOON**2
    xs, ns, ws = [], [], []
    for k in range(3):
        i, j = [a for a in range(3) if a != k]
        for sgn in (1, -1):
            v = np.zeros((U.size, 3))
            v[:, k] = sgn * R_MOON
            v[:, i], v[:, j] = U.ravel(), V.ravel()
            n0 = np.zeros(3); n0[k] = sgn
            xs.append(moon + v @ R.T); ns.append(np.broadcast_to(R @ n0, v.shape)); ws.append(W)
    return np.concatenate(xs), np.concatenate(ns), np.concatenate(ws)



def sun_surface_nodes(moon, sun, n_t=6, n_phi=12):
    """Nodes y_k (K,3), outward normals (K,3) and areas dA_k (K,) on the part of the Sun's sphere
    facing the Moon's centre (polar Gauss rule about the sub-Moon point; t via smoothstep)."""
    a = unit(moon - sun)
    tmax = np.arccos(R_SUN / np.linalg.norm(moon - sun))
    m, w = polar_caps_rule(a[None], np.array([tmax]), [], n_t, n_phi)
    return sun + R_SUN * m[0], m[0], R_SUN**2 * w[0]


def moonshine_extended(shape, theta, outer, n_t=6, n_phi=12, axes=ELL_AXES):
    """Moonshine with the extended Lambertian Sun (radiance Phi/(4 pi^2 R_S^2)) by superposition
    of Sun-surface point sources y_k; for each y_k the lunar region lit by y_k is an exact cap in
    p-space (ellipsoid) or a constant-sign face (cube), so each term keeps spectral convergence."""
    sun, moon, det = scene(theta)
    Ls = PHI / (4 * np.pi**2 * R_SUN**2)
    ys, ms, dAs = sun_surface_nodes(moon, sun, n_t, n_phi)
    out = {k: 0.0 for k in BRDFS}
    if shape == "cube":
        xc, nc, ac = cube_rule(moon, outer)
    for y, my, dAy in zip(ys, ms, dAs):
        if shape == "cube":
            x, n, a = xc, nc, ac
        else:
            ax = axes if shape == "ellipsoid" else np.full(3, R_MOON)
            x, n, a = ellipsoid_rule(ax, moon, det, cap_point=y, order=outer)
        gw = detector_weight(x, n, a, det, moon)
        v = y - x
        r = np.linalg.norm(v, axis=1)
        om = v / r[:, None]
        cos_y = np.clip(-(om @ my), 0, None)
        dOm = cos_y * dAy / r**2
        o = unit(det - x)
        mu = np.clip(np.einsum("bj,bj->b", n, o), 0, 1)
        mu0 = np.clip(np.einsum("bj,bj->b", n, om), 0, 1)
        sh, ch = half_angle(om, o)
        for k, b in BRDFS.items():
            out[k] += float(np.dot(b.radiance_factor(mu0, mu, sh, ch) * Ls * dOm, gw))
    return out

# ---- drivers ---------------------------------------------------------------------------------
def moonshine(x, n, dA, sun, moon, det, ext=None, chunk=4096):
    gw = detector_weight(x, n, dA, det, moon)
    keep = gw > 0
    x, n, gw = x[keep], n[keep], gw[keep]
    out = {k: 0.0 for k in BRDFS}
    for a in range(0, len(x), chunk):
        sl = slice(a, a + chunk)
        for k, b in BRDFS.items():
            out[k] += float(np.dot(moon_radiance_sun(x[sl], n[sl], sun, det, b, ext), gw[sl]))
    return out


def earthshine(x, n, dA, sun, moon, det, inner=16, chunk=None):
    gw = detector_weight(x, n, dA, det, moon)
    keep = gw > 0
    x, n, gw = x[keep], n[keep], gw[keep]
    if chunk is None:
        chunk = max(8, int(2e5 // (inner * inner * 6)))
    out = {k: 0.0 for k in BRDFS}
    for a in range(0, len(x), chunk):
        sl = slice(a, a + chunk)
        L = moon_radiance_earth(x[sl], n[sl], sun, det, BRDFS, inner)
        for k in BRDFS:
            out[k] += float(np.dot(L[k], gw[sl]))
    return out


def compute(shape, theta, outer, inner, ext=None, axes=ELL_AXES):
    sun, moon, det = scene(theta)
    if shape in ("ellipsoid", "sphere"):
        ax = axes if shape == "ellipsoid" else np.full(3, R_MOON)
        xm, nm, am = ellipsoid_rule(ax, moon, det, cap_point=sun, order=outer)
        xe, ne, ae = ellipsoid_rule(ax, moon, det, cap_point=None, order=outer)
    else:
        xm, nm, am = cube_rule(moon, outer)
        xe, ne, ae = xm, nm, am
    ms = moonshine(xm, nm, am, sun, moon, det, ext)
    es = earthshine(xe, ne, ae, sun, moon, det, inner)
    return {k: {"moonshine_W_m2": ms[k], "earthshine_W_m2": es[k]} for k in BRDFS}


def rel(a, b):
    return abs(a - b) / abs(b)


def maxrel(r1, r2):
    return max(rel(r1[k][q], r2[k][q]) for k in r1 for q in r1[k])


def write_meshes():
    import trimesh
    m = trimesh.creation.icosphere(subdivisions=7, radius=R_MOON)
    m.vertices = m.vertices * (ELL_AXES / R_MOON)
    assert len(m.faces) == 327680
    m.export(OUT + "/ellipsoid_L7.ply")
    b = trimesh.creation.box(extents=[2 * R_MOON] * 3)
    b.vertices = b.vertices @ ROT.T
    b.export(OUT + "/cube_rot.ply")
    return {"ellipsoid_L7.ply": {"faces": len(m.faces), "area_m2": float(m.area)},
            "cube_rot.ply": {"faces": len(b.faces), "area_m2": float(b.area)}}


def geometry_report():
    rep = {}
    for th in PHASES:
        sun, moon, det = scene(th)
        s, o = unit(sun - moon), unit(det - moon)
        alpha = np.degrees(2 * np.arctan2(np.linalg.norm(s - o), np.linalg.norm(s + o)))
        faces = []
        for k in range(3):
            for sgn in (1, -1):
                n0 = np.zeros(3); n0[k] = sgn
                nn = ROT @ n0
                xc = moon + R_MOON * nn
                faces.append({"n": nn.round(4).tolist(),
                              "n.sun": float(nn @ unit(sun - xc)),
                              "n.det": float(nn @ unit(det - xc)),
                              "n.earth_minus_sinrhoE": float(nn @ unit(-xc) - R_EARTH / np.linalg.norm(xc))})
        rep[th] = {"alpha_deg": float(alpha), "cube_faces": faces}
    return rep


if __name__ == "__main__":
    t0 = time.time()
    quick = "--quick" in sys.argv
    print("meshes:", write_meshes())
    geo = geometry_report()
    for th in PHASES:
        print(f"theta={th}: alpha={geo[th]['alpha_deg']:.4f} deg; cube faces (n.sun, n.det, n.e-sin rhoE):",
              [(round(f['n.sun'], 3), round(f['n.det'], 3), round(f['n.earth_minus_sinrhoE'], 3)) for f in geo[th]["cube_faces"]])

    # (outer, inner) ladders, doubling orders; the last is the reported value
    ladders = {"ellipsoid": [(16, 8), (32, 16), (64, 32)], "sphere": [(16, 8), (32, 16), (64, 32)],
               "cube": [(8, 8), (16, 16), (32, 32)]}
    SUN_Q = [(6, 12), (12, 24), (24, 48)]  # Sun-surface (n_t, n_phi) ladder for the extended Sun
    if quick:
        ladders = {k: v[:2] for k, v in ladders.items()}
        SUN_Q = SUN_Q[:2]
    results, conv, point = {}, {}, {}
    for shape in ("ellipsoid", "cube", "sphere"):
        results[shape], conv[shape], point[shape] = {}, {}, {}
        for th in PHASES:
            c = conv[shape][str(th)] = {}
            # earthshine (and point-Sun moonshine) on the (outer, inner) ladder
            runs = []
            for (o, i) in ladders[shape]:
                t1 = time.time()
                r = compute(shape, th, o, i)
                runs.append(((o, i), r))
                print(f"{shape:9s} th={th:3d} outer={o:3d} inner={i:3d} ({time.time()-t1:5.1f}s) "
                      + " ".join(f"{k}:{q[:4]}={r[k][q]:.10e}" for k in r for q in r[k]), flush=True)
            best = runs[-1][1]
            (o, i) = ladders[shape][-1]
            r_o = compute(shape, th, o // 2, i)
            r_i = compute(shape, th, o, i // 2)
            c["earthshine_rel_change"] = {f"{oo}/{ii}": {k: rel(r[k]["earthshine_W_m2"], best[k]["earthshine_W_m2"]) for k in r}
                                          for (oo, ii), r in runs[:-1]}
            c["earthshine_rel_change"][f"{o//2}/{i}"] = {k: rel(r_o[k]["earthshine_W_m2"], best[k]["earthshine_W_m2"]) for k in r_o}
            c["earthshine_rel_change"][f"{o}/{i//2}"] = {k: rel(r_i[k]["earthshine_W_m2"], best[k]["earthshine_W_m2"]) for k in r_i}
            c["moonshine_point_sun_rel_change"] = {f"{oo}": {k: rel(r[k]["moonshine_W_m2"], best[k]["moonshine_W_m2"]) for k in r}
                                                   for (oo, ii), r in runs[:-1]}
            print(f"   earthshine rel change vs {o}/{i}:", {kk: {k: f"{v:.1e}" for k, v in vv.items()} for kk, vv in c["earthshine_rel_change"].items()}, flush=True)
            # moonshine with the extended Sun: outer ladder at top Sun order, Sun ladder at top outer
            t1 = time.time()
            ext = {(oo, sq): moonshine_extended(shape, th, oo, *sq) for sq in SUN_Q[-1:] for (oo, _) in ladders[shape]}
            ext.update({(o, sq): moonshine_extended(shape, th, o, *sq) for sq in SUN_Q[:-1]})
            ebest = ext[(o, SUN_Q[-1])]
            c["moonshine_ext_sun_rel_change"] = {f"outer{oo}/sun{sq[0]}x{sq[1]}": {k: rel(v[k], ebest[k]) for k in v}
                                                 for (oo, sq), v in ext.items() if (oo, sq) != (o, SUN_Q[-1])}
            print(f"   ext-Sun moonshine ({time.time()-t1:.1f}s)", {k: f"{v:.10e}" for k, v in ebest.items()},
                  "rel change:", {kk: {k: f"{v:.1e}" for k, v in vv.items()} for kk, vv in c["moonshine_ext_sun_rel_change"].items()}, flush=True)
            point[shape][str(th)] = {k: {"moonshine_point_sun_W_m2": best[k]["moonshine_W_m2"],
                                         "ext_over_point_minus_1": ebest[k] / best[k]["moonshine_W_m2"] - 1} for k in BRDFS}
            print("   extended/point Sun - 1:", {k: f"{v['ext_over_point_minus_1']:+.2e}" for k, v in point[shape][str(th)].items()})
            results[shape][str(th)] = {k: {"moonshine_W_m2": ebest[k], "earthshine_W_m2": best[k]["earthshine_W_m2"],
                                           "moonshine_point_sun_W_m2": best[k]["moonshine_W_m2"]} for k in BRDFS}

    # sphere cross-check against `lunarviz sweep --method reference`
    sphere_check = {"ours": results["sphere"]}
    try:
        lv = json.load(open(OUT + "/sphere_ref.json"))
        cmp = {}
        for row in lv["rows"]:
            th, b = str(int(round(row["theta_deg"]))), row["brdf"]
            if th in results["sphere"] and b in BRDFS:
                cmp.setdefault(th, {})[b] = {q: {"lunarviz": row[q], "ours": results["sphere"][th][b][q],
                                                 "rel_diff": row[q] / results["sphere"][th][b][q] - 1}
                                             for q in ("moonshine_W_m2", "earthshine_W_m2")}
        sphere_check["vs_lunarviz_reference"] = cmp
        for th, d in cmp.items():
            for b, dd in d.items():
                print(f"sphere: lunarviz/ours-1 th={th} {b}: " + ", ".join(f"{q[:4]} {v['rel_diff']:+.2e}" for q, v in dd.items()))
    except FileNotFoundError:
        print(f"no {OUT}/sphere_ref.json; skipped lunarviz comparison")

    out = {"ellipsoid": results["ellipsoid"], "cube": results["cube"], "sphere_check": sphere_check,
           "convergence": conv, "extended_vs_point_sun": point,
           "geometry": {str(k): v for k, v in geo.items()},
           "notes": {"moonshine_W_m2": "extended Lambertian Sun (uniform radiance Phi/(4 pi^2 R_S^2)), by "
                                       "superposition of Sun-surface nodes; moonshine_point_sun_W_m2: point Sun",
                     "earthshine_W_m2": "extended Lambertian Earth (A=0.3) lit by the point Sun",
                     "detector": "Earth centre, facing the Moon centre; cos(delta) included",
                     "ellipsoid_semi_axes_m": ELL_AXES.tolist(), "cube_rotation_matrix": ROT.tolist(),
                     "ladders_outer_inner": ladders, "sun_quadrature_ladder": SUN_Q}}
    if not quick:
        json.dump(out, open(OUT + "/ref_shapes.json", "w"), indent=1)
    print(f"total {time.time()-t0:.0f}s")
    for shape in ("ellipsoid", "cube", "sphere"):
        for th in PHASES:
            r = results[shape][str(th)]
            print(f"{shape:9s} {th:3d}  " + "  ".join(f"{k}: moon {r[k]['moonshine_W_m2']:.8e} earth {r[k]['earthshine_W_m2']:.8e}" for k in BRDFS))
