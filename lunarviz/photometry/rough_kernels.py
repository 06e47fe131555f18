"""Compiled rough Hapke shading at albedo nodes (numba): the mapped lune rule's radiances, and
the facets' (each sample its own w, or the two of its map spread).

The mapped lune rule (:mod:`lunarviz.geometry.mapped_lune`) shades each lunar sample at Q values
of the map and weights them: ``L_n = Σ_q F_nq Σ_k r(w_q; μ0_nk, μ_n, g_nk) E_nk``. On a rough Moon
(``rolo-fit-map``) the numpy path builds a dozen (N, Q, K) temporaries per BRDF; here each beam's
geometry (the azimuth ψ, Hapke's 1984 effective cosines and shadowing S, the surge, the phase
function and the coherent backscatter) is computed once and only the H-functions, which alone
depend on w, once per value. The spectral shading (:mod:`lunarviz.spectral.shading`) takes the
same per-beam geometry (:func:`rough_geometry`: μ0e, μe and S with the coherent backscatter) for
its wavelengths' kernels.

Same formulas as :mod:`lunarviz.photometry.roughness` and
:meth:`lunarviz.photometry.brdf.Hapke._rough_r` (the reference implementation, compared with this
to 1e-12: docs, validation): Hapke (1984) Eqs. 46-51, Hapke (2002) Eq. 8, SHG or DHG
(both conventions), the Hapke 1981 or 2002 H-functions.
"""

from __future__ import annotations

import numpy as np

import lunarviz.compiled as compiled
from lunarviz.photometry import shading_kernels
from lunarviz.photometry.brdf import make_brdf
from lunarviz.photometry.shading_kernels import h_value, surge_phase


def _emergent(m, tb, cot_tb, chi):
    """The emergence side of Hapke (1984)'s shadowing for cos e = ``m`` (Eqs. 46-50,
    :func:`lunarviz.photometry.roughness.shadowing`): sin e, e, E1(e), E2(e), η(e) and μ/η(e)."""
    se = np.sqrt(1.0 - m * m)
    cot_e = m / se if se > 0.0 else np.inf
    e1e = np.exp(-2.0 / np.pi * cot_tb * cot_e)
    e2e = np.exp(-1.0 / np.pi * cot_tb * cot_tb * cot_e * cot_e)
    eta_e = chi * (m + se * tb * e2e / (2.0 - e1e))
    a_e = m / eta_e if eta_e > 0.0 else 0.0
    return se, np.arccos(m), e1e, e2e, eta_e, a_e


def _beam_rough(m0, m, s_, se, ang_e, e1e, e2e, eta_e, a_e, tb, cot_tb, chi):
    """Hapke (1984)'s effective cosines and shadowing (μ0e, μe, S) of one beam: cos i = ``m0``,
    cos e = ``m`` (its :func:`_emergent` terms), sin(g/2) = ``s_``. The formulas of
    :func:`lunarviz.photometry.roughness.shadowing`, with its guards: the slope terms dropped where
    their denominator vanishes (double grazing with ψ = π) and S = 0 where its own does."""
    # ψ from sin²(g/2) = sin²((i - e)/2) + sin i sin e sin²(ψ/2) (roughness.azimuth_from_half_angle)
    si = np.sqrt(1.0 - m0 * m0)
    sisi = si * se
    d = np.sin(0.5 * (np.arccos(m0) - ang_e))
    s2 = min(max((s_ * s_ - d * d) / sisi, 0.0), 1.0) if sisi > 1e-300 else 0.0  # sin²(ψ/2)
    psi = 2.0 * np.arcsin(np.sqrt(s2))
    cpsi = 1.0 - 2.0 * s2
    # Hapke (1984) Eqs. 46-50; f(ψ) = exp(-2 tan(ψ/2))
    cot_i = m0 / si if si > 0.0 else np.inf
    e1i = np.exp(-2.0 / np.pi * cot_tb * cot_i)
    e2i = np.exp(-1.0 / np.pi * cot_tb * cot_tb * cot_i * cot_i)
    f = np.exp(-2.0 * np.sqrt(s2 / (1.0 - s2))) if s2 < 1.0 else 0.0
    eta_i = chi * (m0 + si * tb * e2i / (2.0 - e1i))
    mu0e, mue = chi * m0, chi * m
    if m0 >= m:  # i ≤ e
        den = 2.0 - e1e - (psi / np.pi) * e1i
        if den > 0.0:
            mu0e = chi * (m0 + si * tb * (cpsi * e2e + s2 * e2i) / den)
            mue = chi * (m + se * tb * (e2e - s2 * e2i) / den)
    else:
        den = 2.0 - e1i - (psi / np.pi) * e1e
        if den > 0.0:
            mu0e = chi * (m0 + si * tb * (e2i - s2 * e2e) / den)
            mue = chi * (m + se * tb * (cpsi * e2i + s2 * e2e) / den)
    a_i = m0 / eta_i if eta_i > 0.0 else 0.0
    last = a_i if m0 >= m else a_e
    b_e = mue / eta_e if eta_e > 0.0 else 0.0
    den_s = 1.0 - f + f * chi * last
    return mu0e, mue, (b_e * a_i * chi / den_s if den_s > 0.0 else 0.0)


def _coherent(s_, c_, Bc0, hc):
    """1 + B_C0 B_C(g) of Hapke (2002) Eq. 8 (:func:`lunarviz.photometry.roughness.coherent_backscatter`)
    for sin(g/2) = ``s_``, cos(g/2) = ``c_``."""
    if Bc0 <= 0.0:
        return 1.0
    y = (s_ / c_) / hc if c_ > 0.0 else np.inf
    if not np.isfinite(y):
        return 1.0
    frac = -np.expm1(-y) / y if y > 1e-8 else 1.0 - 0.5 * y
    return 1.0 + Bc0 * (1.0 + frac) / (2.0 * (1.0 + y) ** 2)


def _rough_geometry(mu0, mu, sh, ch, theta_bar, Bc0, hc, mu0e_out, mue_out, s_out):
    """μ0e, μe and S (1 + B_C0 B_C) per beam (N, K) of samples with cos e = ``mu`` (N,)."""
    n, k = mu0.shape
    tb = np.tan(theta_bar)
    cot_tb = 1.0 / tb
    chi = 1.0 / np.sqrt(1.0 + np.pi * tb * tb)
    for i in range(n):
        m = min(max(mu[i], 0.0), 1.0)
        se, ang_e, e1e, e2e, eta_e, a_e = _emergent(m, tb, cot_tb, chi)
        for j in range(k):
            m0 = min(max(mu0[i, j], 0.0), 1.0)
            mu0e, mue, S = _beam_rough(m0, m, sh[i, j], se, ang_e, e1e, e2e, eta_e, a_e, tb, cot_tb, chi)
            mu0e_out[i, j] = mu0e
            mue_out[i, j] = mue
            s_out[i, j] = S * _coherent(sh[i, j], ch[i, j], Bc0, hc)


def _rough_nodes_sum(mu0, mu, sh, ch, e, e_unit, w_nodes, factors, h, B0, pcode, p1, p2, hcode, theta_bar,
                     Bc0, hc, has_unit, out, out_unit):
    n, k = mu0.shape
    nq = w_nodes.shape[1]  # (rows: one per sample, or one for all)
    per_sample = w_nodes.shape[0] > 1
    four_pi = 4.0 * np.pi
    gam = np.sqrt(1.0 - w_nodes)  # Hapke 1981: H(x) = (1 + 2x)/(1 + 2γx), γ = √(1 - w)
    tb = np.tan(theta_bar)
    cot_tb = 1.0 / tb
    chi = 1.0 / np.sqrt(1.0 + np.pi * tb * tb)
    for i in range(n):
        row = i if per_sample else 0
        m = min(max(mu[i], 0.0), 1.0)
        se, ang_e, e1e, e2e, eta_e, a_e = _emergent(m, tb, cot_tb, chi)
        acc = 0.0
        acc_u = 0.0
        for j in range(k):
            ej = e[i, j]
            eu = e_unit[i, j] if has_unit else 0.0
            if ej == 0.0 and eu == 0.0:
                continue
            m0 = min(max(mu0[i, j], 0.0), 1.0)
            s_ = sh[i, j]
            c_ = ch[i, j]
            mu0e, mue, S = _beam_rough(m0, m, s_, se, ang_e, e1e, e2e, eta_e, a_e, tb, cot_tb, chi)
            sb = surge_phase(s_, c_, h, B0, pcode, p1, p2) - 1.0  # (brdf.Hapke)
            cb = _coherent(s_, c_, Bc0, hc)
            tot = mu0e + mue
            frac_e = mu0e / tot if tot > 0.0 else 0.0
            geo = frac_e * S * cb / four_pi
            r = 0.0
            if hcode == 0:
                top = (1.0 + 2.0 * mu0e) * (1.0 + 2.0 * mue)
                for qq in range(nq):
                    hh = top / ((1.0 + 2.0 * gam[row, qq] * mu0e) * (1.0 + 2.0 * gam[row, qq] * mue))
                    r += factors[i, qq] * w_nodes[row, qq] * (sb + hh)
            else:
                for qq in range(nq):
                    w = w_nodes[row, qq]
                    r += factors[i, qq] * w * (sb + h_value(mu0e, w, hcode) * h_value(mue, w, hcode))
            r *= geo
            acc += r * ej
            acc_u += r * eu
        out[i] = acc
        out_unit[i] = acc_u


def available() -> bool:
    """Whether the compiled kernels are in use."""
    return _NUMBA


def handles(model) -> bool:
    """Whether the kernel shades ``model``: a rough Hapke (θ̄ > 0) with an SHG or DHG phase
    function and the Hapke 1981 or 2002 H-function."""
    return _NUMBA and getattr(model, "rough", False) and shading_kernels.phase_codes(model) is not None \
        and model.theta_bar > 0.0


def rough_node_radiances(model, mu0, mu, sin_hg, cos_hg, e_beam, e_unit, w_nodes, factors):
    """``(Σ_q F_nq Σ_k r(w_q)·e_beam, the same with e_unit or None)`` per sample (N,) for a rough
    Hapke ``model`` (:func:`handles`), the map's values ``w_nodes`` (Q,) [w], or each sample's own
    (N, Q), and weights ``factors`` (N, Q)."""
    pcode, p1, p2, hcode = shading_kernels.phase_codes(model)
    n = mu0.shape[0]
    out, out_u = np.empty(n), np.empty(n)
    f = np.ascontiguousarray
    eu = f(e_unit, dtype=float) if e_unit is not None else np.zeros((1, 1))
    _rough_nodes_sum(f(mu0, dtype=float), f(np.broadcast_to(mu, (n,)), dtype=float), f(sin_hg, dtype=float),
                     f(cos_hg, dtype=float), f(e_beam, dtype=float), eu, f(np.atleast_2d(w_nodes), dtype=float),
                     f(factors, dtype=float), float(model.h), float(model.B0), pcode, float(p1), float(p2), hcode,
                     float(np.radians(model.theta_bar)), float(model.Bc0), float(model.hc), e_unit is not None,
                     out, out_u)
    return out, (out_u if e_unit is not None else None)


def rough_geometry(mu0, mu, sin_hg, cos_hg, theta_bar_rad: float, Bc0: float, hc: float):
    """``(μ0e, μe, S·(1 + B_C0 B_C))`` per beam (N, K) for cos i ``mu0`` (N, K) and cos e ``mu``
    (N,) (compiled; :func:`handles`' models): what :func:`lunarviz.photometry.roughness.shadowing`
    and :func:`~lunarviz.photometry.roughness.coherent_backscatter` give, to rounding."""
    f = np.ascontiguousarray
    mu0 = f(mu0, dtype=float)
    out = [np.empty(mu0.shape) for _ in range(3)]
    sh, ch = (f(np.broadcast_to(a, mu0.shape), dtype=float) for a in (sin_hg, cos_hg))
    _rough_geometry(mu0, f(np.broadcast_to(mu, (mu0.shape[0],)), dtype=float), sh, ch, float(theta_bar_rad),
                    float(Bc0), float(hc), *out)
    return tuple(out)


def warm_up() -> None:
    """Load (or compile) the kernel once on tiny inputs, e.g. before forking workers."""
    if not _NUMBA:
        return
    one = np.ones((1, 1))
    rough_node_radiances(make_brdf("dhg", params={"theta_bar": 20.0}), one, np.ones(1), one, one, one, one,
                         np.full(1, 0.5), one)


_NUMBA = shading_kernels.available()
if _NUMBA:
    try:
        _emergent = compiled.jit(_emergent, nogil=True)
        _beam_rough = compiled.jit(_beam_rough, nogil=True)
        _coherent = compiled.jit(_coherent, nogil=True)
        _rough_nodes_sum = compiled.jit(_rough_nodes_sum, nogil=True)
        _rough_geometry = compiled.jit(_rough_geometry, nogil=True)
    except Exception:  # noqa: BLE001 (numba unusable here: the numpy path serves)
        _NUMBA = False
