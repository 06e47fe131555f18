"""Compiled shading kernels (numba): the Hapke radiance of paper Eq. 10 summed over beams.

The ray tracer's shading evaluates, for N lunar samples and K beams each,
``L_n = Σ_k BRDF(μ0_nk, μ_n, g_nk)·μ0_nk·E_nk`` for every BRDF (paper Eqs. 10, 12-14). In numpy
that is a dozen (N, K) temporaries per BRDF; here it is one pass over the beams per sample,
without temporaries, and the unit-albedo earthshine (``e_beam_unit``) rides along for free.

Same formulas as :mod:`lunarviz.photometry.brdf` (the reference implementation, kept and tested
against these to 1e-13 relative in the test suite): the smooth Hapke model with SHG or DHG
(both conventions) and the Hapke 1981 or 2002 H-functions. Everything else (roughness, coherent
backscatter, the exact H-function) stays on the numpy path. Lambert shading runs through the
same loop (the ``LAMBERT`` code).
"""

from __future__ import annotations

import numpy as np

import lunarviz.compiled as compiled
from lunarviz.photometry.brdf import DoubleHG, Hapke, SingleHG, make_brdf


def available() -> bool:
    """Whether the compiled shading kernels are in use."""
    return _NUMBA


#: phase-function codes (LAMBERT: no phase function, the Lambert radiance factor)
SHG, DHG_PAPER, DHG_HAPKE2012, LAMBERT = 0, 1, 2, -1
#: H-function codes
H1981, H2002 = 0, 1



def _lobe(x, t):
    q = (1.0 - x) ** 2 + 4.0 * x * t * t
    return (1.0 - x * x) / (q * np.sqrt(q))  # q**1.5 (a pow call costs ~3x a sqrt)


def _h(x, w, hcode):
    g = np.sqrt(1.0 - w)
    if hcode == 0:
        return (1.0 + 2.0 * x) / (1.0 + 2.0 * g * x)
    r0 = (1.0 - g) / (1.0 + g)
    xlog = x * (np.log1p(x) - np.log(x)) if x > 0.0 else 0.0
    return 1.0 / (1.0 - w * (r0 * x + 0.5 * (1.0 - 2.0 * r0 * x) * xlog))


def _surge_phase(s_, c_, h, B0, pcode, p1, p2):
    """``[1 + B(g)] p(g)`` from sin(g/2), cos(g/2): the surge ``B0 h/(h + tan(g/2))`` and the
    SHG (p1 = |ξ|, p2 = 1 for a backward lobe) or DHG (p1 = b, p2 = c; pcode 1 the paper's
    convention, 2 Hapke 2012's) phase function."""
    num = h * c_
    den = num + s_
    if den <= 0.0:
        B = B0 if s_ <= 0.0 else 0.0
    else:
        B = B0 * num / den
    if pcode == 0:
        P = _lobe(p1, s_ if p2 > 0.5 else c_)
    else:
        fwd = _lobe(p1, c_)
        bwd = _lobe(p1, s_)
        wp = 0.5 * (1.0 + p2)
        wm = 0.5 * (1.0 - p2)
        P = wp * fwd + wm * bwd if pcode == 1 else wp * bwd + wm * fwd
    return (1.0 + B) * P


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
            if pcode == LAMBERT:  # radiance factor (w/π)·μ0 (Lambert.radiance_factor)
                rf = w / np.pi * m0
                acc += rf * ej
                acc_u += rf * eu
                continue
            rf = w / four_pi * (m0 / s) * (_surge_phase(sh[i, j], ch[i, j], h, B0, pcode, p1, p2)
                                           + _h(m0, w, hcode) * hm - 1.0)
            acc += rf * ej
            acc_u += rf * eu
        out[i] = acc
        out_unit[i] = acc_u




_NUMBA = compiled.available()
if _NUMBA:
    try:
        _lobe = compiled.jit(_lobe, inline="always")
        _h = compiled.jit(_h, inline="always")
        _surge_phase = compiled.jit(_surge_phase, inline="always")
        _hapke_sum = compiled.jit(_hapke_sum, nogil=True)
    except Exception:  # noqa: BLE001 (numba unusable here: the numpy path serves)
        _NUMBA = False


#: the Henyey-Greenstein lobe, Hapke's H-functions and the surge times the phase function for
#: other compiled kernels (:mod:`lunarviz.spectral.kernels`, :mod:`lunarviz.photometry.rough_kernels`),
#: inlined there as here
hg_lobe, h_value, surge_phase = _lobe, _h, _surge_phase


def hapke_codes(model) -> tuple[int, float, float, int] | None:
    """(phase code, p1, p2, H code) for a smooth Hapke model the kernel handles, else ``None``."""
    return None if getattr(model, "rough", False) else phase_codes(model)


def phase_codes(model) -> tuple[int, float, float, int] | None:
    """(phase code, p1, p2, H code) of a Hapke model, smooth or rough, with an SHG or DHG phase
    function and the Hapke 1981 or 2002 H-function, else ``None``."""
    if not isinstance(model, Hapke) or model.h_function not in ("hapke1981", "hapke2002"):
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


def lambert_radiances(model, mu0, e_beam, e_unit=None, albedo=None):
    """``(Σ_k rf·e_beam, Σ_k rf·e_unit or None)`` per sample for a :class:`lunarviz.photometry.brdf.Lambert`
    ``model`` (compiled only; :func:`_hapke_sum` with the LAMBERT code); ``albedo`` (N,)
    replaces its albedo per sample."""
    f = np.ascontiguousarray
    n = mu0.shape[0]
    out, out_u = np.empty(n), np.empty(n)
    eu = f(e_unit, dtype=float) if e_unit is not None else np.zeros((1, 1))
    al = f(albedo, dtype=float).reshape(-1) if albedo is not None else np.zeros(1)
    mu0 = f(mu0, dtype=float)
    _hapke_sum(mu0, np.zeros(n), mu0, mu0, f(e_beam, dtype=float), eu, al, float(model.albedo), 0.0, 0.0, LAMBERT,
               0.0, 0.0, H1981, e_unit is not None, albedo is not None, out, out_u)
    return out, (out_u if e_unit is not None else None)



def warm_up() -> None:
    """Load (or compile) the shading kernels once on tiny inputs, e.g. before forking workers."""
    if not _NUMBA:
        return
    one = np.ones((1, 1))
    hapke_radiances(make_brdf("dhg"), one, np.ones(1), one, one, one, one, np.ones(1))
    lambert_radiances(make_brdf("lambert"), one, one, one, np.ones(1))
