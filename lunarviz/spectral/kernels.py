"""Compiled spectral shading (numba): one pass over a transport's beams, every wavelength inside.

For P beam arrays ``E_p`` (N samples × K beams; moonshine: the Sun's beams; earthshine: the
Earth's, one array per surface component and one for an Earth of albedo 1), L wavelengths and
the detector weights ``geom``, :func:`spectral_sums` returns

    out[p, l] = Σ_n geom_n Σ_k rf_l(n, k) E_p[n, k]

with ``rf_l`` the radiance factor BRDF·μ0 of paper Eqs. 12-14 (or Lambert's) at wavelength l's
parameters: Hapke ``w/(4π) · μ0e/(μ0e+μe) · {[1+B(g)] p(g) + H(μ0e) H(μe) − 1} · F``. The
effective cosines μ0e, μe and the factor F (roughness shadowing S times the coherent backscatter
1 + B_C0 B_C(g), Hapke 1984 Eq. 51 and 2002 Eq. 8) do not depend on wavelength when θ̄, B_C0 and
h_C are grey: :mod:`lunarviz.spectral.shading` computes them once per transport with
:mod:`lunarviz.photometry.roughness` (for a smooth surface μ0e = μ0, μe = μ, F = 1). The geometry
of each beam is thus read once for every wavelength; per wavelength the work is the phase
function, the surge and the two H-functions. Same formulas as :mod:`lunarviz.photometry.brdf`
(the tests compare the two to 1e-9 through whole sweeps).
"""

from __future__ import annotations

import numpy as np

import lunarviz.compiled as compiled
from lunarviz.photometry.shading_kernels import H1981, LAMBERT
from lunarviz.photometry.shading_kernels import h_value as _h
from lunarviz.photometry.shading_kernels import hg_lobe as _lobe


def _spectral_sums(mu0e, mue, sh, ch, fac, E, geom, alb, has_alb, w, kc, h, B0, p1, p2, pcode, hcode, out,
                   per_sample, keep):
    n, k = mu0e.shape
    P, L = out.shape
    per_beam_mu = mue.shape[1] > 1
    per_beam_f = fac.shape[1] > 1
    four_pi = 4.0 * np.pi
    wi = np.empty(L)
    hm = np.empty(L)
    rfl = np.empty(L)
    acc = np.empty((P, L))
    for i in range(n):
        gi = geom[i]
        if gi == 0.0:
            continue
        for ll in range(L):
            wl = (kc[ll] * alb[i] + (1.0 - kc[ll])) * w[ll] if has_alb else w[ll]
            wi[ll] = min(max(wl, 0.0), 1.0)
        if not per_beam_mu:
            m_s = min(max(mue[i, 0], 0.0), 1.0)
            for ll in range(L):
                hm[ll] = _h(m_s, wi[ll], hcode)
        acc[:, :] = 0.0
        for j in range(k):
            live = False
            for p in range(P):
                if E[p, i, j] != 0.0:
                    live = True
            if not live:
                continue
            m0 = min(max(mu0e[i, j], 0.0), 1.0)
            m = min(max(mue[i, j if per_beam_mu else 0], 0.0), 1.0)
            s = m0 + m
            if pcode != LAMBERT and s <= 0.0:
                continue
            f = fac[i, j if per_beam_f else 0]
            s_ = sh[i, j]
            c_ = ch[i, j]
            for ll in range(L):
                if pcode == LAMBERT:
                    rf = wi[ll] / np.pi * m0
                else:
                    num = h[ll] * c_
                    den = num + s_
                    if den <= 0.0:
                        B = B0[ll] if s_ <= 0.0 else 0.0
                    else:
                        B = B0[ll] * num / den
                    if pcode == 0:  # SHG: p1 = |ξ|, p2 = 1 for a backward lobe
                        Pg = _lobe(p1[ll], s_ if p2[ll] > 0.5 else c_)
                    else:  # DHG: p1 = b, p2 = c
                        fwd = _lobe(p1[ll], c_)
                        bwd = _lobe(p1[ll], s_)
                        wp = 0.5 * (1.0 + p2[ll])
                        wm = 0.5 * (1.0 - p2[ll])
                        Pg = wp * fwd + wm * bwd if pcode == 1 else wp * bwd + wm * fwd
                    hmu = hm[ll] if not per_beam_mu else _h(m, wi[ll], hcode)
                    rf = wi[ll] / four_pi * (m0 / s) * ((1.0 + B) * Pg + _h(m0, wi[ll], hcode) * hmu - 1.0) * f
                rfl[ll] = rf
            for p in range(P):
                e = E[p, i, j]
                if e != 0.0:
                    for ll in range(L):
                        acc[p, ll] += rfl[ll] * e
        for p in range(P):
            for ll in range(L):
                out[p, ll] += gi * acc[p, ll]
                if keep:
                    per_sample[i, p, ll] = acc[p, ll]


def _sums_h1981(mu0e, mue, sh, ch, fac, E, geom, alb, has_alb, w, kc, h, B0, p1, p2, pcode, out, per_sample, keep):
    """:func:`_spectral_sums` for Hapke with the 1981 H-function (the paper's, and every
    preset's), rearranged for speed: what depends on the wavelength only is tabulated once
    (the lobes' (1 − b)², 4b, 1 − b², the DHG weights, w/4π), what depends on the sample only
    once per sample (√(1 − w), H(μ)), and the loop over wavelengths is straight arithmetic.
    The same operations on the same numbers as the generic loop, up to the order of two
    products (rounding). Kept apart from :func:`_spectral_sums` on purpose: folding Lambert and
    the 2002 H-function into this loop (branches inside the wavelength loop) measured 3-3.5x
    slower per beam and wavelength for DHG (12.9 against 3.7 ns)."""
    n, k = mu0e.shape
    P, L = out.shape
    per_beam_mu = mue.shape[1] > 1
    per_beam_f = fac.shape[1] > 1
    four_pi = 4.0 * np.pi
    omb2 = np.empty(L)
    fb = np.empty(L)
    nb = np.empty(L)
    wf = np.empty(L)
    wb = np.empty(L)
    back = np.empty(L)
    for ll in range(L):
        x = p1[ll]
        omb2[ll] = (1.0 - x) ** 2
        fb[ll] = 4.0 * x
        nb[ll] = 1.0 - x * x
        if pcode == 0:  # SHG: one lobe, backward where p2 = 1 (ξ < 0)
            back[ll] = 1.0 if p2[ll] > 0.5 else 0.0
        else:
            wp = 0.5 * (1.0 + p2[ll])
            wm = 0.5 * (1.0 - p2[ll])
            wf[ll], wb[ll] = (wp, wm) if pcode == 1 else (wm, wp)
    wi = np.empty(L)
    cw = np.empty(L)
    gam = np.empty(L)
    hm = np.empty(L)
    rf = np.empty(L)
    acc = np.empty((P, L))
    for i in range(n):
        gi = geom[i]
        if gi == 0.0:
            continue
        for ll in range(L):
            wl = (kc[ll] * alb[i] + (1.0 - kc[ll])) * w[ll] if has_alb else w[ll]
            wl = min(max(wl, 0.0), 1.0)
            wi[ll] = wl
            cw[ll] = wl / four_pi
            gam[ll] = np.sqrt(1.0 - wl)
        if not per_beam_mu:
            m_s = min(max(mue[i, 0], 0.0), 1.0)
            for ll in range(L):
                hm[ll] = (1.0 + 2.0 * m_s) / (1.0 + 2.0 * gam[ll] * m_s)
        acc[:, :] = 0.0
        for j in range(k):
            live = False
            for p in range(P):
                if E[p, i, j] != 0.0:
                    live = True
            if not live:
                continue
            m0 = min(max(mu0e[i, j], 0.0), 1.0)
            m = min(max(mue[i, j if per_beam_mu else 0], 0.0), 1.0)
            s = m0 + m
            if s <= 0.0:
                continue
            q = m0 / s
            f = fac[i, j if per_beam_f else 0]
            s_ = sh[i, j]
            c_ = ch[i, j]
            a0 = 1.0 + 2.0 * m0
            am = 1.0 + 2.0 * m
            tc = c_ * c_
            ts = s_ * s_
            for ll in range(L):
                num = h[ll] * c_
                den = num + s_
                if den <= 0.0:
                    B = B0[ll] if s_ <= 0.0 else 0.0
                else:
                    B = B0[ll] * num / den
                if pcode == 0:
                    qq = omb2[ll] + fb[ll] * (ts if back[ll] > 0.5 else tc)
                    Pg = nb[ll] / (qq * np.sqrt(qq))
                else:
                    q1 = omb2[ll] + fb[ll] * tc
                    q2 = omb2[ll] + fb[ll] * ts
                    Pg = wf[ll] * (nb[ll] / (q1 * np.sqrt(q1))) + wb[ll] * (nb[ll] / (q2 * np.sqrt(q2)))
                hmu = hm[ll] if not per_beam_mu else am / (1.0 + 2.0 * gam[ll] * m)
                h0 = a0 / (1.0 + 2.0 * gam[ll] * m0)
                rf[ll] = cw[ll] * q * ((1.0 + B) * Pg + h0 * hmu - 1.0) * f
            for p in range(P):
                e = E[p, i, j]
                if e != 0.0:
                    for ll in range(L):
                        acc[p, ll] += rf[ll] * e
        for p in range(P):
            for ll in range(L):
                out[p, ll] += gi * acc[p, ll]
                if keep:
                    per_sample[i, p, ll] = acc[p, ll]


_NUMBA = compiled.available()
if _NUMBA:
    try:
        # numpy's error model: no zero-division checks inside the loops (they keep LLVM from
        # vectorising over the wavelengths); every divisor here is positive (s > 0 and den > 0
        # are tested, the lobes' (1 - b)² + 4b t² > 0 for b ≤ 0.95, 1 + 2γμ ≥ 1)
        _spectral_sums = compiled.jit(_spectral_sums, nogil=True, error_model="numpy")
        _sums_h1981 = compiled.jit(_sums_h1981, nogil=True, error_model="numpy")
    except Exception:  # noqa: BLE001 (numba unusable: lunarviz.spectral.shading's numpy path serves)
        _NUMBA = False


def available() -> bool:
    return _NUMBA


def spectral_sums(mu0e, mue, sh, ch, fac, E, geom, alb, w, kc, h, B0, p1, p2, pcode: int, hcode: int,
                  per_sample: bool = False) -> np.ndarray:
    """``out[p, l]`` of the module docstring. ``mue`` and ``fac`` are (N, 1) or (N, K); ``alb``
    (N,) is a lunar map's factor per sample (``None``: none), which w takes with the contrast
    ``kc``: ``w_l · (1 − kc_l + kc_l · alb)`` (kc = 1: the map as it is); the parameter arrays
    are (L,).
    ``per_sample``: instead, each sample's radiance ``Σ_k rf_l E_p`` (N, P, L) (where its geom
    is not zero)."""
    f = np.ascontiguousarray
    L = len(w)
    out = np.zeros((E.shape[0], L))
    keep = np.zeros((len(geom), E.shape[0], L)) if per_sample else np.zeros((1, 1, 1))
    al = f(alb, dtype=float).reshape(-1) if alb is not None else np.zeros(1)
    args = (f(mu0e, dtype=float), f(mue, dtype=float), f(sh, dtype=float), f(ch, dtype=float),
            f(fac, dtype=float), f(E, dtype=float), f(geom, dtype=float), al, alb is not None,
            *(f(np.broadcast_to(np.asarray(v, dtype=float), (L,))) for v in (w, kc, h, B0, p1, p2)))
    if pcode != LAMBERT and hcode == H1981:
        _sums_h1981(*args, int(pcode), out, keep, per_sample)
    else:
        _spectral_sums(*args, int(pcode), int(hcode), out, keep, per_sample)
    return keep if per_sample else out
