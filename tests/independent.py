"""Independent references for non-spherical Moons, written apart from the tracer.

Shares no code with lunarviz beyond the BRDF formulas (``model.brdf``, checked against a
textbook implementation in tests/test_brdf.py) and the paper's constants. Everything else is
numpy: analytic surfaces (a triaxial ellipsoid by parametric Gauss quadrature, a cube by
Gauss quadrature over each face), a point Sun at the Sun's centre (exact for a flat face that
sees the whole solar disc; the extended Sun changes a curved body's moonshine by O(ρ²) ≈ 2e-5
with ρ = 0.27°, plus penumbra terms of the same order), and an *extended* Lambertian Earth
integrated over its visible cap from every lunar point (polar Gauss rule about the sub-point;
the Earth's terminator and the lunar horizon are kinks the rule resolves at second order).

Scene (paper Eq. 3): Earth at the origin, Sun at (0, 0, −D_SE), Moon at
(0, D_EM sin θ, D_EM cos θ); detector at the Earth's centre, facing the Moon's centre; no
occlusion at the phases used (30°–150°). Detector irradiance = Σ L·μ·cosδ·dA/d² (paper Eq. 11).
"""

from __future__ import annotations

import numpy as np

from lunarviz import constants as C

EARTH_ALBEDO = 0.3


def scene(theta_deg: float):
    t = np.radians(theta_deg)
    sun = np.array([0.0, 0.0, -C.D_SE_M])
    moon = np.array([0.0, C.D_EM_M * np.sin(t), C.D_EM_M * np.cos(t)])
    return sun, np.zeros(3), moon


def ellipsoid_surface(a, b, c, n=160):
    """Points, outward unit normals and area weights [m²] on the ellipsoid x²/a²+y²/b²+z²/c²=1
    (body frame): Gauss–Legendre in the polar angle u (n nodes), uniform in the longitude v
    (2n nodes, spectrally exact for periodic integrands)."""
    xu, wu = np.polynomial.legendre.leggauss(n)
    u = 0.5 * np.pi * (xu + 1)
    wu = 0.5 * np.pi * wu
    v = (np.arange(2 * n) + 0.5) * np.pi / n
    U, V = np.meshgrid(u, v, indexing="ij")
    su, cu, sv, cv = np.sin(U), np.cos(U), np.sin(V), np.cos(V)
    X = np.stack([a * su * cv, b * su * sv, c * cu], -1)
    Xu = np.stack([a * cu * cv, b * cu * sv, -c * su], -1)
    Xv = np.stack([-a * su * sv, b * su * cv, np.zeros_like(U)], -1)
    cr = np.cross(Xu, Xv)
    dA = np.linalg.norm(cr, axis=-1) * wu[:, None] * (np.pi / n)
    g = X / np.array([a * a, b * b, c * c])
    nrm = g / np.linalg.norm(g, axis=-1, keepdims=True)
    return X.reshape(-1, 3), nrm.reshape(-1, 3), dA.reshape(-1)


def box_surface(half: float, rotation: np.ndarray, n=24):
    """Points, normals and weights on the cube [−half, half]³ rotated by ``rotation``
    (v' = R v): an n×n Gauss product rule on each face."""
    x, w = np.polynomial.legendre.leggauss(n)
    P, Q = np.meshgrid(x * half, x * half, indexing="ij")
    W = np.outer(w, w) * half * half
    pts, nrms, wts = [], [], []
    for axis in range(3):
        for sgn in (-1.0, 1.0):
            p = np.zeros(P.shape + (3,))
            others = [k for k in range(3) if k != axis]
            p[..., axis] = sgn * half
            p[..., others[0]] = P
            p[..., others[1]] = Q
            nn = np.zeros(3)
            nn[axis] = sgn
            pts.append(p.reshape(-1, 3))
            nrms.append(np.broadcast_to(nn, (P.size, 3)))
            wts.append(W.reshape(-1))
    pts, nrms = np.concatenate(pts) @ rotation.T, np.concatenate(nrms) @ rotation.T
    return pts, nrms, np.concatenate(wts)


def _half_angle(a, b):
    d, p = a - b, a + b
    s, c = np.linalg.norm(d, axis=-1), np.linalg.norm(p, axis=-1)
    nn = np.sqrt(s * s + c * c)
    return s / nn, c / nn


def detector_irradiance(theta_deg, surface, models, earth_order=12, chunk=2048, earthshine=True, lit=None,
                        positions=None):
    """``{brdf: (moonshine, earthshine)}`` [W m⁻²] for a Moon surface (x, n, dA) given in the
    body frame (centred on the Moon's centre, paper axes). ``lit(x_body, s, o)``, if given,
    returns a mask of points that the Sun (direction s) lights and the detector (direction o)
    sees past the body's own relief (an analytic shadow condition). ``positions`` = (Sun,
    Moon, detector) [m] relative to the Earth's centre replaces the θ scene (real-sky tests)."""
    if positions is None:
        sun, earth, moon = scene(theta_deg)
        det = earth
    else:
        sun, moon, det = (np.asarray(v, dtype=float) for v in positions)
        earth = np.zeros(3)
    x_b, n_all, dA_all = surface
    x_all = x_b + moon
    det_n = (moon - det) / np.linalg.norm(moon - det)
    out = {k: [0.0, 0.0] for k in models}
    for a in range(0, len(x_all), chunk):
        x, n, dA = x_all[a:a + chunk], n_all[a:a + chunk], dA_all[a:a + chunk]
        v = det - x
        d = np.linalg.norm(v, axis=1)
        o = v / d[:, None]
        mu = np.clip(np.einsum("ij,ij->i", n, o), 0, None)
        geom = mu * np.clip(-np.einsum("ij,j->i", v, det_n) / d, 0, None) * dA / d**2
        live = geom > 0
        x, n, o, mu, geom = x[live], n[live], o[live], mu[live], geom[live]
        seen_lit = np.ones(len(x), dtype=bool)
        if lit is not None:
            s_dir = (sun - x) / np.linalg.norm(sun - x, axis=1, keepdims=True)
            seen_lit = lit(x - moon, s_dir, o)
        if len(x) == 0:
            continue
        # moonshine: point Sun
        vs = sun - x
        ds = np.linalg.norm(vs, axis=1)
        s = vs / ds[:, None]
        E_sun = C.PHI_SUN_W / (4 * np.pi * ds**2)
        mu0 = np.clip(np.einsum("ij,ij->i", n, s), 0, None) * seen_lit
        sh, ch = _half_angle(s, o)
        if not earthshine:
            for k, model in models.items():
                f_s = np.where(mu0 > 0, model.brdf(mu0, mu, sh, ch), 0.0)
                out[k][0] += float(np.sum(f_s * mu0 * E_sun * geom))
            continue
        # earthshine: extended Lambert Earth over its lit, visible part from each point, in
        # polar coordinates (t, φ) about the sub-point: each ring's lit arc φu ± hw(t) gets
        # its own Gauss rule (the terminator is then an integration limit, not a kink), and
        # t is split where the arc closes or becomes a full ring.
        om, dOmega, L_e = _earth_beams(x, sun, earth, earth_order)
        mu0e = np.clip(np.einsum("btj,bj->bt", om, n), 0, None)
        she, che = _half_angle(om, o[:, None, :])
        for k, model in models.items():
            f_s = np.where(mu0 > 0, model.brdf(mu0, mu, sh, ch), 0.0)
            out[k][0] += float(np.sum(f_s * mu0 * E_sun * geom))
            mu_b = np.broadcast_to(mu[:, None], mu0e.shape)
            f_e = np.where(mu0e > 0, model.brdf(mu0e, mu_b, she, che), 0.0)
            L = np.sum(f_e * mu0e * L_e * dOmega, axis=1)
            out[k][1] += float(np.sum(L * geom))
    return {k: tuple(v) for k, v in out.items()}


def _earth_beams(x, sun, earth, order):
    """Directions (B, K, 3) from lunar points x to Earth nodes, their solid angles dΩ (B, K)
    and the Earth's radiance there (B, K) [W m⁻² sr⁻¹]; point Sun lights the Earth."""
    R = C.R_EARTH_M
    xg, wg = np.polynomial.legendre.leggauss(order)
    ve = x - earth
    de = np.linalg.norm(ve, axis=1)
    ax = ve / de[:, None]
    helper = np.where(np.abs(ax[:, :1]) < 0.9, np.array([[1.0, 0, 0]]), np.array([[0, 1.0, 0]]))
    e1 = np.cross(ax, helper)
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    e2 = np.cross(ax, e1)
    us = (sun - earth) / np.linalg.norm(sun - earth)
    c_s = R / np.linalg.norm(sun - earth)  # lit: m·us > c_s (point Sun at finite distance)
    ctu = ax @ us
    tau = np.arccos(np.clip(ctu, -1, 1))
    stu = np.sin(tau)
    phi_u = np.arctan2(e2 @ us, e1 @ us)
    tmax = np.arccos(R / de)
    a_s = np.arccos(c_s)
    # t-breakpoints where the lit arc closes (hw = 0) or fills the ring (hw = π)
    cuts = np.stack([np.abs(tau - a_s), tau + a_s, 2 * np.pi - tau - a_s], 1)
    edges = np.sort(np.concatenate([np.zeros((len(x), 1)), np.minimum(cuts, tmax[:, None]), tmax[:, None]], 1), 1)
    ts, wts = [], []
    for k in range(edges.shape[1] - 1):
        lo, hi = edges[:, k:k + 1], edges[:, k + 1:k + 2]
        ts.append(lo + 0.5 * (hi - lo) * (xg + 1))
        wts.append(0.5 * (hi - lo) * wg)
    t, wt = np.concatenate(ts, 1), np.concatenate(wts, 1)  # (B, T)
    with np.errstate(divide="ignore", invalid="ignore"):
        q = (c_s - np.cos(t) * ctu[:, None]) / (np.sin(t) * stu[:, None])
    q = np.where(np.isfinite(q), q, np.where(np.cos(t) * ctu[:, None] > c_s, -1.0, 1.0))
    hw = np.arccos(np.clip(q, -1, 1))  # (B, T)
    phi = phi_u[:, None, None] + hw[..., None] * xg[None, None, :]  # (B, T, P)
    wphi = hw[..., None] * wg[None, None, :]
    m = (np.cos(t)[..., None, None] * ax[:, None, None, :]
         + np.sin(t)[..., None, None] * (np.cos(phi)[..., None] * e1[:, None, None, :]
                                        + np.sin(phi)[..., None] * e2[:, None, None, :]))
    y = earth + R * m
    vy = x[:, None, None, :] - y
    r = np.linalg.norm(vy, axis=-1)
    cos_y = np.clip(np.einsum("btpj,btpj->btp", m, vy) / r, 0, None)
    dA_y = R * R * np.sin(t)[..., None] * wt[..., None] * wphi
    vsy = sun - y
    dsy = np.linalg.norm(vsy, axis=-1)
    mu_s = np.clip(np.einsum("btpj,btpj->btp", m, vsy) / dsy, 0, None)
    L_e = EARTH_ALBEDO / np.pi * C.PHI_SUN_W / (4 * np.pi * dsy**2) * mu_s
    B = len(x)
    return ((-vy / r[..., None]).reshape(B, -1, 3), (cos_y * dA_y / r**2).reshape(B, -1), L_e.reshape(B, -1))


def rotation_zyx(z_deg, y_deg, x_deg) -> np.ndarray:
    """R = Rz(z)·Ry(y)·Rx(x)."""
    a, b, c = np.radians([z_deg, y_deg, x_deg])
    Rz = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    Ry = np.array([[np.cos(b), 0, np.sin(b)], [0, 1, 0], [-np.sin(b), 0, np.cos(b)]])
    Rx = np.array([[1, 0, 0], [0, np.cos(c), -np.sin(c)], [0, np.sin(c), np.cos(c)]])
    return Rz @ Ry @ Rx


def cap_intersection_area(t1, t2, t12):
    """Area of the intersection of two caps of angular radii t1, t2 whose centres are t12 apart
    on the unit sphere (Tovchigrechko & Vakser 2001, Protein Sci. 10, 1572, Eq. A1)."""
    if t12 >= t1 + t2:
        return 0.0
    if t12 <= abs(t1 - t2):
        return 2 * np.pi * (1 - np.cos(min(t1, t2)))
    c1, c2, c12 = np.cos(t1), np.cos(t2), np.cos(t12)
    s1, s2, s12 = np.sin(t1), np.sin(t2), np.sin(t12)
    a0 = np.arccos(np.clip((c12 - c1 * c2) / (s1 * s2), -1, 1))
    a1 = np.arccos(np.clip((c2 - c1 * c12) / (s1 * s12), -1, 1))
    a2 = np.arccos(np.clip((c1 - c2 * c12) / (s2 * s12), -1, 1))
    return 2 * (np.pi - a0 - a1 * c1 - a2 * c2)


def bowl_shadow_fraction(depth_over_radius: float, elevation_deg: float) -> float:
    """Shadowed fraction of a spherical bowl crater's surface, Sun at ``elevation_deg`` above
    the rim plane (Buhl, Welch & Rea 1968 geometry; derivation in tests/test_meshes.py)."""
    # bowl: sphere of radius S whose centre is c above the rim plane, rim radius r0 = 1
    h = depth_over_radius
    S = (1 + h * h) / (2 * h)
    a = np.arccos((S - h) / S)  # the bowl is the cap of angular radius a about −ẑ
    e = np.radians(elevation_deg)
    return cap_intersection_area(a, a, 2 * e) / (2 * np.pi * (1 - np.cos(a)))


def eclipse_moonshine(surface, model, sun, moon, det=None):
    """Moonshine [W m⁻²] with the Earth (sphere R_Earth at the origin) in front of the Sun, and
    without: ``(eclipsed, free)``. Each lunar point x receives Φ/(4π d²) times the visible
    fraction of the solar disc, 1 − A(ρ_S, ρ_E, γ)/A(ρ_S), with A the exact area of two
    overlapping caps (:func:`cap_intersection_area`; a uniform-radiance Lambertian Sun), ρ the
    angular radii and γ the Sun-Earth separation seen from x. The incidence is the disc
    centre's (the shift of the visible part's centroid is O(ρ_S) ≈ 0.005 rad, so μ0 errs by
    ≲ 0.5 % at grazing incidence and far less over the disc)."""
    det = np.zeros(3) if det is None else np.asarray(det, float)
    x_b, n, dA = surface
    x = x_b + moon
    v = det - x
    d = np.linalg.norm(v, axis=1)
    o = v / d[:, None]
    det_n = (moon - det) / np.linalg.norm(moon - det)
    mu = np.clip(np.einsum("ij,ij->i", n, o), 0, None)
    geom = mu * np.clip(-np.einsum("ij,j->i", v, det_n) / d, 0, None) * dA / d**2
    vs = sun - x
    ds = np.linalg.norm(vs, axis=1)
    s = vs / ds[:, None]
    mu0 = np.clip(np.einsum("ij,ij->i", n, s), 0, None)
    live = (geom > 0) & (mu0 > 0)
    ve = -x
    de = np.linalg.norm(ve, axis=1)
    rho_s = np.arcsin(C.R_SUN_M / ds)
    rho_e = np.arcsin(C.R_EARTH_M / de)
    gamma = np.arccos(np.clip(np.einsum("ij,ij->i", s, ve / de[:, None]), -1, 1))
    frac = np.ones(len(x))
    for i in np.flatnonzero(live):
        frac[i] = 1 - cap_intersection_area(rho_s[i], rho_e[i], gamma[i]) / (2 * np.pi * (1 - np.cos(rho_s[i])))
    sh, ch = _half_angle(s, o)
    f = np.where(live, model.brdf(np.where(live, mu0, 1.0), np.where(live, mu, 1.0), sh, ch), 0.0)
    e = C.PHI_SUN_W / (4 * np.pi * ds**2)
    free = float(np.sum(f * mu0 * e * geom))
    return float(np.sum(f * mu0 * e * geom * frac)), free


# ----------------------------------------------------------------------------------------------
# maps: a Moon and an Earth whose albedo varies with longitude, integrated in each
# body's own latitude/longitude so that the albedo's edges (meridians) are integration limits
# ----------------------------------------------------------------------------------------------
def gauss_legendre(lo, hi, n):
    x, w = np.polynomial.legendre.leggauss(n)
    return lo + 0.5 * (hi - lo) * (x + 1), 0.5 * (hi - lo) * w


def _lonlat_rule(lon_edges_deg, n_lon, n_lat, lat_edges_deg=(-90.0, 90.0)):
    """Nodes (lat, lon) [rad] and weights cos(lat) dlat dlon over the sphere between the
    longitude edges and the latitude edges (each segment its own Gauss rule)."""
    las, wlas = [], []
    for a, b in zip(lat_edges_deg[:-1], lat_edges_deg[1:]):
        x, w = gauss_legendre(np.radians(a), np.radians(b), n_lat)
        las.append(x)
        wlas.append(w)
    la, wla = np.concatenate(las), np.concatenate(wlas)
    lons, wlos = [], []
    for a, b in zip(lon_edges_deg[:-1], lon_edges_deg[1:]):
        if b > a:
            lo, wl = gauss_legendre(np.radians(a), np.radians(b), n_lon)
            lons.append(lo)
            wlos.append(wl)
    lo, wlo = np.concatenate(lons), np.concatenate(wlos)
    LA, LO = np.meshgrid(la, lo, indexing="ij")
    W = np.outer(wla * np.cos(la), wlo)
    return LA.ravel(), LO.ravel(), W.ravel()


def _edges(*cuts):
    """Sorted longitudes [deg] in [-180, 180] including ±180 and each cut (wrapped)."""
    c = [((x + 180.0) % 360.0) - 180.0 for x in cuts]
    return np.unique(np.concatenate([[-180.0, 180.0], c]))


def mapped_irradiance(theta_deg, models, moon_albedo=None, earth_albedo=None, earth_lon_sub_solar_deg=0.0,
                      moon_cuts=(), earth_cuts=(), n_moon=(48, 24), n_earth=(32, 24), moon_lat_cuts=(),
                      earth_lat_cuts=(), earth_reflectance=None):
    """``{brdf: (moonshine, earthshine)}`` [W m⁻²] in the θ scene, detector at the Earth's centre.

    Frames (DESIGN.md): both north poles along +x; the Moon's (0°, 0°) faces the Earth; the
    Earth's sub-solar point is at longitude ``earth_lon_sub_solar_deg``. ``moon_albedo(lat, lon)``
    [deg] returns each BRDF's albedo parameter (Lambert albedo, Hapke w) per node as a dict
    ``{brdf: array}`` (``None``: the models' own); ``earth_albedo(lat, lon)`` the Earth's Lambert
    albedo (``None``: 0.3). ``*_cuts``: longitudes [deg] where the albedo jumps; the rules are
    split there and at the Earth's terminator and limb meridians. Point Sun; the Earth is an
    extended Lambert body lit by a point Sun; no occlusion. ``earth_reflectance(m, s, t)``: an
    anisotropic Earth instead, its reflectance factor R at unit normals ``m``, directions to the
    Sun ``s`` and to each lunar point ``t`` (arrays (B, K, 3)), evaluated per pair of lunar point and
    Earth node (radiance ``E μ_s R / π``).
    """
    sun, earth, moon = scene(theta_deg)
    pole = np.array([1.0, 0.0, 0.0])
    # the Moon: lon/lat rule over the near side split at the map's edges and the terminator
    e0 = -moon / np.linalg.norm(moon)
    e1 = np.cross(pole, e0)
    s_m = (sun - moon) / np.linalg.norm(sun - moon)
    lon_s_moon = np.degrees(np.arctan2(s_m @ e1, s_m @ e0))
    cuts_m = [-90.0, 90.0, lon_s_moon - 90.0, lon_s_moon + 90.0, *moon_cuts]
    edges_m = _edges(*cuts_m)
    edges_m = edges_m[(edges_m >= -90.0) & (edges_m <= 90.0)]
    LA, LO, W = _lonlat_rule(edges_m, *n_moon, np.unique(np.r_[-90.0, 90.0, moon_lat_cuts]))
    nrm = (np.cos(LA) * np.cos(LO))[:, None] * e0 + (np.cos(LA) * np.sin(LO))[:, None] * e1 + np.sin(LA)[:, None] * pole
    x = moon + C.R_MOON_M * nrm
    dA = W * C.R_MOON_M**2
    lat_m, lon_m = np.degrees(LA), np.degrees(LO)
    # the Earth: frame of the sub-solar point
    s_hat = (sun - earth) / np.linalg.norm(sun - earth)
    east = np.cross(pole, s_hat)
    lam_s = np.radians(earth_lon_sub_solar_deg)
    m_hat = moon / np.linalg.norm(moon)
    lon_moon_e = earth_lon_sub_solar_deg + np.degrees(np.arctan2(m_hat @ east, m_hat @ s_hat))
    edges_e = _edges(earth_lon_sub_solar_deg - 90, earth_lon_sub_solar_deg + 90, lon_moon_e - 90, lon_moon_e + 90,
                     *earth_cuts)
    ELA, ELO, EW = _lonlat_rule(edges_e, *n_earth, np.unique(np.r_[-90.0, 90.0, earth_lat_cuts]))
    dl = ELO - lam_s
    m = (np.cos(ELA) * np.cos(dl))[:, None] * s_hat + (np.cos(ELA) * np.sin(dl))[:, None] * east \
        + np.sin(ELA)[:, None] * pole
    y = earth + C.R_EARTH_M * m
    vsy = sun - y
    dsy = np.linalg.norm(vsy, axis=1)
    mu_s = np.clip(np.einsum("ij,ij->i", m, vsy) / dsy, 0, None)
    A_e = np.full(len(y), EARTH_ALBEDO) if earth_albedo is None else earth_albedo(np.degrees(ELA), np.degrees(ELO))
    L_e = A_e / np.pi * C.PHI_SUN_W / (4 * np.pi * dsy**2) * mu_s  # (Y,)
    keep = L_e > 0
    y, m, L_e, dA_y = y[keep], m[keep], L_e[keep], EW[keep] * C.R_EARTH_M**2
    s_y = vsy[keep] / dsy[keep][:, None]
    # detector geometry at the Earth's centre
    det = earth
    v = det - x
    d = np.linalg.norm(v, axis=1)
    o = v / d[:, None]
    mu = np.clip(np.einsum("ij,ij->i", nrm, o), 0, None)
    det_n = (moon - det) / np.linalg.norm(moon - det)
    geom = mu * np.clip(-np.einsum("ij,j->i", v, det_n) / d, 0, None) * dA / d**2
    vs = sun - x
    ds = np.linalg.norm(vs, axis=1)
    s = vs / ds[:, None]
    mu0 = np.clip(np.einsum("ij,ij->i", nrm, s), 0, None)
    E_sun = C.PHI_SUN_W / (4 * np.pi * ds**2)
    sh, ch = _half_angle(s, o)
    alb = None if moon_albedo is None else moon_albedo(lat_m, lon_m)
    out = {}
    for k, model in models.items():
        a = None if alb is None else alb[k]
        f_s = np.where(mu0 > 0, model.brdf(mu0, mu, sh, ch, albedo=a), 0.0)
        ms = float(np.sum(f_s * mu0 * E_sun * geom))
        es = 0.0
        for c0 in range(0, len(x), 256):
            sl = slice(c0, c0 + 256)
            vy = y[None, :, :] - x[sl, None, :]  # lunar point → Earth node
            r = np.linalg.norm(vy, axis=2)
            om = vy / r[..., None]
            cos_y = np.clip(-np.einsum("bkj,kj->bk", om, m), 0, None)
            mu0e = np.clip(np.einsum("bkj,bj->bk", om, nrm[sl]), 0, None)
            she, che = _half_angle(om, o[sl][:, None, :])
            ab = None if a is None else a[sl][:, None]
            f_e = np.where(mu0e > 0, model.brdf(mu0e, np.broadcast_to(mu[sl][:, None], mu0e.shape), she, che,
                                                albedo=ab), 0.0)
            L_y = L_e[None, :]
            if earth_reflectance is not None:  # L_e holds the albedo 0.3 (no map): rescale to R per pair
                R = earth_reflectance(np.broadcast_to(m, om.shape), np.broadcast_to(s_y, om.shape), -om)
                L_y = L_e[None, :] / EARTH_ALBEDO * R
            L = np.sum(f_e * mu0e * L_y * cos_y * dA_y[None, :] / r**2, axis=1)
            es += float(np.sum(L * geom[sl]))
        out[k] = (ms, es)
    return out


def _smooth_gauss(lo, hi, n):
    """Gauss nodes on [lo, hi] through φ = lo + (hi - lo)(3t² - 2t³): a length that closes like
    √(hi - φ) or √(φ - lo) at an end (a ring tangent to a cap) becomes analytic in t."""
    x, w = np.polynomial.legendre.leggauss(n)
    t = 0.5 * (x + 1.0)
    return lo + (hi - lo) * t * t * (3 - 2 * t), (hi - lo) * 6 * t * (1 - t) * 0.5 * w


def _lune_nodes(u_src, u_det, c_lo, c_hi, a_det, n_lat, n_lon):
    """Unit normals and weights dΩ over {n·u_det > a_det} ∩ {n·u_src > c_lo} of the unit sphere,
    cut where n·u_src = c_hi (the edge of the source's penumbra band). Latitude φ and longitude λ
    about the pole u_src × u_det (both directions on the equator, so the region is symmetric in φ):
    every boundary is λ = ±acos(c / cos φ) about its direction, an analytic function of φ between
    the latitudes where it closes, and the rule splits φ there."""
    p = np.cross(u_src, u_det)
    if np.linalg.norm(p) < 1e-12:  # source and detector in one direction (earthshine from the geocentre)
        p = np.cross(u_det, [1.0, 0, 0] if abs(u_det[0]) < 0.9 else [0, 1.0, 0])
    p /= np.linalg.norm(p)
    e0 = u_det
    e1 = np.cross(p, e0)
    lam_s = np.arctan2(u_src @ e1, u_src @ e0)
    top = np.arccos(max(a_det, c_lo, 0.0))
    closing = sorted({0.0, top, *[np.arccos(c) for c in (a_det, c_lo, c_hi) if 0 < c < 1 and np.arccos(c) < top]})
    normals, weights = [], []
    for f0, f1 in zip(closing[:-1], closing[1:]):
        for phi, wphi in zip(*_smooth_gauss(f0, f1, n_lat)):
            cp = np.cos(phi)
            half = {c: np.arccos(np.clip(c / cp, -1, 1)) for c in (a_det, c_lo, c_hi)}
            lo = max(-half[a_det], lam_s - half[c_lo])
            hi = min(half[a_det], lam_s + half[c_lo])
            if hi <= lo:
                continue
            cuts = sorted({lo, hi, *[v for v in (lam_s - half[c_hi], lam_s + half[c_hi]) if lo < v < hi]})
            for l0, l1 in zip(cuts[:-1], cuts[1:]):
                lam, wl = gauss_legendre(l0, l1, n_lon)
                for sgn in (1.0, -1.0):  # both hemispheres
                    n = (cp * np.cos(lam))[:, None] * e0 + (cp * np.sin(lam))[:, None] * e1 \
                        + (sgn * np.sin(phi)) * p
                    normals.append(n)
                    weights.append(wl * wphi * cp)
    return np.concatenate(normals), np.concatenate(weights)


def extended_irradiance(theta_deg, models, n_lat=40, n_lon=24, sun_nodes=(8, 16), earth_order=12, chunk=512):
    """``{brdf: (moonshine, earthshine)}`` [W m⁻²] with an *extended* Sun (a sphere of uniform
    radiance Φ/(4π² R_S²), its disc integrated from every lunar point and cut at the point's
    horizon) and an extended Lambert Earth lit by a point Sun (:func:`_earth_beams`), on the exact
    lunar sphere; θ scene, detector at the Earth's centre, no occlusion. The lunar surface is
    integrated by :func:`_lune_nodes` over the part lit by some of the source and seen by the
    detector (not the library's cap rule: latitude and longitude about the Sun-detector pole)."""
    sun, earth, moon = scene(theta_deg)
    det = earth
    R_M = C.R_MOON_M
    out = {k: [0.0, 0.0] for k in models}
    det_n = (moon - det) / np.linalg.norm(moon - det)
    d_det = np.linalg.norm(det - moon)
    u_det = (det - moon) / d_det
    L_sun = C.PHI_SUN_W / (4 * np.pi**2 * C.R_SUN_M**2)
    xr, wr = np.polynomial.legendre.leggauss(sun_nodes[0])
    psi = (np.arange(sun_nodes[1]) + 0.5) * 2 * np.pi / sun_nodes[1]
    for path, (src, R_src) in enumerate(((sun, C.R_SUN_M), (earth, C.R_EARTH_M))):
        d_src = np.linalg.norm(src - moon)
        nrm, w = _lune_nodes((src - moon) / d_src, u_det, (R_M - R_src) / d_src, (R_M + R_src) / d_src,
                             R_M / d_det, n_lat, n_lon)
        for a in range(0, len(nrm), chunk):
            n = nrm[a:a + chunk]
            x = moon + R_M * n
            v = det - x
            d = np.linalg.norm(v, axis=1)
            o = v / d[:, None]
            mu = np.clip(np.einsum("ij,ij->i", n, o), 0, None)
            geom = mu * np.clip(-v @ det_n / d, 0, None) * w[a:a + chunk] * R_M**2 / d**2
            if path == 0:  # the Sun's disc from x: polar Gauss in r (dΩ = sin r dr dψ), uniform in ψ
                vs = sun - x
                ds = np.linalg.norm(vs, axis=1)
                ax = vs / ds[:, None]
                rho = np.arcsin(C.R_SUN_M / ds)
                helper = np.where(np.abs(ax[:, :1]) < 0.9, np.array([[1.0, 0, 0]]), np.array([[0, 1.0, 0]]))
                e1 = np.cross(ax, helper)
                e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
                e2 = np.cross(ax, e1)
                r = 0.5 * rho[:, None] * (xr + 1)  # (B, R)
                wr_b = 0.5 * rho[:, None] * wr * np.sin(r)
                om = (np.cos(r)[..., None, None] * ax[:, None, None, :]
                      + np.sin(r)[..., None, None] * (np.cos(psi)[None, None, :, None] * e1[:, None, None, :]
                                                     + np.sin(psi)[None, None, :, None] * e2[:, None, None, :]))
                om = om.reshape(len(x), -1, 3)
                dOm = np.repeat(wr_b, len(psi), axis=1) * (2 * np.pi / len(psi))
                L_b = np.full(dOm.shape, L_sun)
            else:
                om, dOm, L_b = _earth_beams(x, sun, earth, earth_order)
            mu0 = np.clip(np.einsum("bkj,bj->bk", om, n), 0, None)
            sh, ch = _half_angle(om, o[:, None, :])
            mu_b = np.broadcast_to(mu[:, None], mu0.shape)
            for k, model in models.items():
                f = np.where(mu0 > 0, model.brdf(mu0, mu_b, sh, ch), 0.0)
                out[k][path] += float(np.sum(np.sum(f * mu0 * L_b * dOm, axis=1) * geom))
    return {k: tuple(v) for k, v in out.items()}
