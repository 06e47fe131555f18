"""Compiled shading kernels (numba): the Hapke radiance of paper Eq. 10 summed over beams.

The ray tracer's shading evaluates, for N lunar samples and K beams each,
``L_n = Σ_k BRDF(μ0_nk, μ_n, g_nk)·μ0_nk·E_nk`` for every BRDF (paper Eqs. 10, 12-14). In numpy
that is a dozen (N, K) temporaries per BRDF; here it is one pass over the beams per sample,
without temporaries, and the unit-albedo earthshine (``e_beam_unit``) rides along for free.

Same formulas as :mod:`lunarviz.brdf` (the reference implementation, kept and tested against
these to 1e-13 relative in tests/test_kernels.py): the smooth Hapke model with SHG or DHG (both
conventions) and the Hapke 1981 or 2002 H-functions. Everything else (roughness, coherent
backscatter, the exact H-function, Lambert) stays on the numpy path.

numba is a dependency, but the kernels are optional at run time: ``LUNARVIZ_NUMBA=0`` or a
failed import falls back to numpy, with the same numbers to rounding. Compiled code is cached
on disk (``cache=True``), so worker processes load it instead of compiling.
"""

from __future__ import annotations

import os

import numpy as np

try:  # pragma: no cover - exercised through available()
    if os.environ.get("LUNARVIZ_NUMBA", "1") == "0":
        raise ImportError("disabled by LUNARVIZ_NUMBA=0")
    import numba
    _NUMBA = True
except ImportError:  # pragma: no cover
    numba = None
    _NUMBA = False

#: phase-function codes
SHG, DHG_PAPER, DHG_HAPKE2012 = 0, 1, 2
#: H-function codes
H1981, H2002 = 0, 1


def available() -> bool:
    """Whether the compiled kernels are in use."""
    return _NUMBA


def _lobe(x, t):
    return (1.0 - x * x) / ((1.0 - x) ** 2 + 4.0 * x * t * t) ** 1.5


def _h(x, w, hcode):
    g = np.sqrt(1.0 - w)
    if hcode == 0:
        return (1.0 + 2.0 * x) / (1.0 + 2.0 * g * x)
    r0 = (1.0 - g) / (1.0 + g)
    xlog = x * (np.log1p(x) - np.log(x)) if x > 0.0 else 0.0
    return 1.0 / (1.0 - w * (r0 * x + 0.5 * (1.0 - 2.0 * r0 * x) * xlog))


def _hapke_sum(mu0, mu, sh, ch, e, e_unit, albedo, w0, h, B0, pcode, p1, p2, hcode, has_unit, has_albedo,
               out, out_unit):
    n, k = mu0.shape
    four_pi = 4.0 * np.pi
    for i in range(n):
        w = albedo[i] if has_albedo else w0
        m = min(max(mu[i], 0.0), 1.0)
        hm = _h(m, w, hcode)
        acc = 0.0
        acc_u = 0.0
        for j in range(k):
            ej = e[i, j]
            eu = e_unit[i, j] if has_unit else 0.0
            if ej == 0.0 and eu == 0.0:
                continue
            m0 = min(max(mu0[i, j], 0.0), 1.0)
            s = m0 + m
            if s <= 0.0:
                continue
            s_ = sh[i, j]
            c_ = ch[i, j]
            num = h * c_
            den = num + s_
            if den <= 0.0:
                B = B0 if s_ <= 0.0 else 0.0
            else:
                B = B0 * num / den
            if pcode == 0:  # SHG: p1 = |ξ|, p2 = 1 for a backward lobe (ξ < 0)
                P = _lobe(p1, s_ if p2 > 0.5 else c_)
            else:  # DHG: p1 = b, p2 = c
                fwd = _lobe(p1, c_)
                bwd = _lobe(p1, s_)
                wp = 0.5 * (1.0 + p2)
                wm = 0.5 * (1.0 - p2)
                P = wp * fwd + wm * bwd if pcode == 1 else wp * bwd + wm * fwd
            rf = w / four_pi * (m0 / s) * ((1.0 + B) * P + _h(m0, w, hcode) * hm - 1.0)
            acc += rf * ej
            acc_u += rf * eu
        out[i] = acc
        out_unit[i] = acc_u


def _beam_angles(dirs, n, o, mu0_out, sh_out, ch_out):
    """μ0 = dirs·n and the half-angle sine and cosine between dirs and o, per beam
    (:func:`lunarviz.geometry.half_angle_sin_cos`: |a − b| = 2 sin(g/2), |a + b| = 2 cos(g/2))."""
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
        b = -(o[i, 0] * d[i, 0] + o[i, 1] * d[i, 1] + o[i, 2] * d[i, 2])
        perp2 = o[i, 0] * o[i, 0] + o[i, 1] * o[i, 1] + o[i, 2] * o[i, 2] - b * b
        disc = radius * radius - perp2
        t = b - np.sqrt(max(disc, 0.0))
        if disc > 0.0 and t > 0.0:
            t_out[i] = t
            for j in range(3):
                point_out[i, j] = o[i, j] + t * d[i, j] + centre[j]
        else:
            prim[i] = -1


def _jit(fn, **kw):
    """``numba.njit`` with an on-disk cache where one can be written (the package folder or
    numba's user cache), else without: a read-only install must not stop lunarviz."""
    try:
        return numba.njit(cache=True, **kw)(fn)
    except Exception:  # noqa: BLE001 (numba raises RuntimeError "no locator available")
        return numba.njit(cache=False, **kw)(fn)


if _NUMBA:
    try:
        _lobe = _jit(_lobe, inline="always")
        _h = _jit(_h, inline="always")
        _beam_angles = _jit(_beam_angles, nogil=True)
        _sphere_refine = _jit(_sphere_refine, nogil=True)
        _hapke_sum = _jit(_hapke_sum, nogil=True)
    except Exception:  # noqa: BLE001 (numba unusable here: the numpy path serves)
        _NUMBA = False


def hapke_codes(model) -> tuple[int, float, float, int] | None:
    """(phase code, p1, p2, H code) for a smooth Hapke model the kernel handles, else ``None``."""
    from .brdf import DoubleHG, Hapke, SingleHG
    if not isinstance(model, Hapke) or model.rough or model.h_function not in ("hapke1981", "hapke2002"):
        return None
    hcode = H1981 if model.h_function == "hapke1981" else H2002
    ph = model.phase
    if isinstance(ph, SingleHG):
        return SHG, abs(ph.xi), 1.0 if ph.xi < 0 else 0.0, hcode
    if isinstance(ph, DoubleHG):
        return (DHG_PAPER if ph.convention == "paper" else DHG_HAPKE2012), ph.b, ph.c, hcode
    return None


def hapke_radiances(model, mu0, mu, sin_hg, cos_hg, e_beam, e_unit=None, albedo=None):
    """``(Σ_k rf·e_beam, Σ_k rf·e_unit or None)`` per sample for a smooth Hapke ``model``
    (``hapke_codes`` not ``None``); ``albedo`` (N,) replaces w per sample."""
    pcode, p1, p2, hcode = hapke_codes(model)
    n = mu0.shape[0]
    out = np.empty(n)
    out_u = np.empty(n)
    f = np.ascontiguousarray
    eu = f(e_unit, dtype=float) if e_unit is not None else np.zeros((1, 1))
    al = f(albedo, dtype=float).reshape(-1) if albedo is not None else np.zeros(1)
    _hapke_sum(f(mu0, dtype=float), f(np.broadcast_to(mu, (n,)), dtype=float), f(sin_hg, dtype=float),
               f(cos_hg, dtype=float), f(e_beam, dtype=float), eu, al, float(model.w), float(model.h),
               float(model.B0), pcode, float(p1), float(p2), hcode, e_unit is not None, albedo is not None,
               out, out_u)
    return out, (out_u if e_unit is not None else None)


def beam_angles(dirs, n, o):
    """``(μ0, sin(g/2), cos(g/2))`` (B, K) of beams ``dirs`` (B, K, 3) at points with normals
    ``n`` (B, 3) seen along ``o`` (B, 3): compiled, or numpy where numba is off."""
    if not _NUMBA:
        from .geometry import half_angle_sin_cos
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
