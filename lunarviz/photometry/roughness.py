"""Hapke's macroscopic roughness (1984) and coherent-backscatter opposition effect (2002).

Shadowing function (Hapke 1984, Icarus 59, 41, Eqs. 46-50; the same in Hapke 2012, *Theory
of Reflectance and Emittance Spectroscopy*, 2nd ed., Eqs. 12.45-12.55). With the mean slope
angle θ̄, χ = (1 + π tan²θ̄)^-1/2, E1(x) = exp(-(2/π) cot θ̄ cot x),
E2(x) = exp(-(1/π) cot²θ̄ cot²x), f(ψ) = exp(-2 tan(ψ/2)), ψ the azimuth between the
planes of incidence and emission and η(x) = χ [cos x + sin x tan θ̄ E2(x)/(2 - E1(x))]:

for i ≤ e::

    μ0e = χ [cos i + sin i tan θ̄ (cos ψ E2(e) + sin²(ψ/2) E2(i)) / (2 - E1(e) - (ψ/π) E1(i))]
    μe  = χ [cos e + sin e tan θ̄ (E2(e) - sin²(ψ/2) E2(i)) / (2 - E1(e) - (ψ/π) E1(i))]
    S   = μe/η(e) · μ0/η(i) · χ / [1 - f(ψ) + f(ψ) χ μ0/η(i)]

for e < i the roles of i and e swap in the brackets and the last factor is
χ / [1 - f(ψ) + f(ψ) χ μ/η(e)]. The rough-surface reflectance is the smooth one evaluated at
the effective cosines μ0e, μe, times S (Hapke 1984 Eq. 51)::

    r(i, e, g) = w/(4π) · μ0e/(μ0e + μe) · {[1 + B_SH(g)] p(g) + H(μ0e) H(μe) - 1} · [1 + B_C0 B_C(g)] · S

Coherent backscatter (Hapke 2002, Icarus 157, 523, Eq. 8; 2012 Eq. 9.43), with
y = tan(g/2)/h_C::

    B_C(g) = [1 + (1 - exp(-y))/y] / [2 (1 + y)²]          (B_C(0) = 1)

θ̄ = 0 gives μ0e = μ0, μe = μ, S = 1 exactly, and B_C0 = 0 no coherent term: the smooth
model, bit for bit (:class:`lunarviz.photometry.brdf.Hapke` then evaluates the smooth model).

Neglected: the porosity factor K (Hapke 2008) and the anisotropic multiple scattering of the
2002 H-function (isotropic multiple scattering, as in the paper).
"""

from __future__ import annotations

import numpy as np


def azimuth_from_half_angle(mu0, mu, sin_hg):
    """Azimuth ψ [rad] between incidence and emission planes from cos i, cos e and sin(g/2).

    ``sin²(g/2) = sin²((i-e)/2) + sin i sin e sin²(ψ/2)`` (no cancelling ``cos g - cos i cos e``);
    where sin i sin e = 0 ψ does not matter (S and the effective cosines do not depend on it)
    and 0 is returned.
    """
    mu0, mu, s = (np.asarray(x, dtype=float) for x in (mu0, mu, sin_hg))
    i, e = np.arccos(np.clip(mu0, -1, 1)), np.arccos(np.clip(mu, -1, 1))
    se = np.sin(i) * np.sin(e)
    d = np.sin(0.5 * (i - e))
    ok = se > 1e-300
    q = np.where(ok, (s * s - d * d) / np.where(ok, se, 1.0), 0.0)
    return 2.0 * np.arcsin(np.sqrt(np.clip(q, 0.0, 1.0)))


def shadowing(mu0, mu, psi, theta_bar):
    """Hapke (1984) effective cosines and shadowing function: ``(mu0e, mue, S)``.

    ``mu0 = cos i``, ``mu = cos e`` (both in [0, 1]), ``psi`` the azimuth [rad, 0..π],
    ``theta_bar`` the mean slope angle [rad], 0 ≤ θ̄ < π/2 (θ̄ = 0: smooth, S = 1).
    """
    mu0, mu, psi = np.broadcast_arrays(*(np.asarray(x, dtype=float) for x in (mu0, mu, psi)))
    mu0, mu = np.clip(mu0, 0.0, 1.0), np.clip(mu, 0.0, 1.0)
    if theta_bar <= 0.0:
        return mu0.copy(), mu.copy(), np.ones_like(mu0)
    tb = np.tan(theta_bar)
    cot_tb = 1.0 / tb
    chi = 1.0 / np.sqrt(1.0 + np.pi * tb * tb)
    si, se = np.sqrt(1.0 - mu0 * mu0), np.sqrt(1.0 - mu * mu)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        cot_i = np.where(si > 0, mu0 / np.where(si > 0, si, 1.0), np.inf)
        cot_e = np.where(se > 0, mu / np.where(se > 0, se, 1.0), np.inf)
        e1i = np.exp(-2.0 / np.pi * cot_tb * cot_i)
        e1e = np.exp(-2.0 / np.pi * cot_tb * cot_e)
        e2i = np.exp(-1.0 / np.pi * cot_tb**2 * cot_i**2)
        e2e = np.exp(-1.0 / np.pi * cot_tb**2 * cot_e**2)
        f = np.where(psi < np.pi, np.exp(-2.0 * np.tan(np.minimum(psi, np.pi * (1 - 1e-16)) / 2.0)), 0.0)
    eta_i = chi * (mu0 + si * tb * e2i / (2.0 - e1i))
    eta_e = chi * (mu + se * tb * e2e / (2.0 - e1e))
    cpsi, s2 = np.cos(psi), np.sin(0.5 * psi) ** 2
    ile = mu0 >= mu  # i ≤ e
    # the denominators vanish only at double grazing with ψ = π (where no light goes): there the
    # slope terms are dropped (0/0 otherwise, with numpy's warnings)
    # i ≤ e
    den_a = 2.0 - e1e - (psi / np.pi) * e1i
    da = np.where(den_a > 0, den_a, np.inf)
    mu0e_a = chi * (mu0 + si * tb * (cpsi * e2e + s2 * e2i) / da)
    mue_a = chi * (mu + se * tb * (e2e - s2 * e2i) / da)
    # e < i
    den_b = 2.0 - e1i - (psi / np.pi) * e1e
    db = np.where(den_b > 0, den_b, np.inf)
    mu0e_b = chi * (mu0 + si * tb * (e2i - s2 * e2e) / db)
    mue_b = chi * (mu + se * tb * (cpsi * e2i + s2 * e2e) / db)
    mu0e = np.where(ile, mu0e_a, mu0e_b)
    mue = np.where(ile, mue_a, mue_b)
    with np.errstate(divide="ignore", invalid="ignore"):
        a_i = np.where(eta_i > 0, mu0 / np.where(eta_i > 0, eta_i, 1.0), 0.0)
        a_e = np.where(eta_e > 0, mu / np.where(eta_e > 0, eta_e, 1.0), 0.0)
    last = np.where(ile, a_i, a_e)
    with np.errstate(divide="ignore", invalid="ignore"):
        b_e = np.where(eta_e > 0, mue / np.where(eta_e > 0, eta_e, 1.0), 0.0)  # effective μe over η(e)
    den = 1.0 - f + f * chi * last  # (0 only at double grazing with ψ = 0, where no light goes: S = 0)
    S = np.where(den > 0, b_e * a_i * chi / np.where(den > 0, den, 1.0), 0.0)
    return mu0e, mue, S


def coherent_backscatter(sin_hg, cos_hg, hc):
    """Hapke (2002) Eq. 8 coherent-backscatter shape B_C(g) ∈ [0, 1], B_C(0) = 1, width ``hc``."""
    s, c = np.asarray(sin_hg, dtype=float), np.asarray(cos_hg, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        y = np.where(c > 0, s / np.where(c > 0, c, 1.0), np.inf) / hc
        frac = np.where(y > 1e-8, -np.expm1(-y) / np.where(y > 1e-8, y, 1.0), 1.0 - 0.5 * y)
        out = (1.0 + frac) / (2.0 * (1.0 + y) ** 2)
    return np.where(np.isfinite(y), out, 0.0)
