"""The ocean's surface: Cox–Munk sun glint with Fresnel reflection, whitecaps and the light that
leaves the water.

Glint (Cox & Munk 1954, *J. Opt. Soc. Am.* 44, 838): facets tilted by β with isotropic Gaussian
slopes of mean square slope σ² = 0.003 + 0.00512 U (U the wind speed at 12.5 m [m s⁻¹], the clean
surface), reflecting specularly with the Fresnel reflectance r(ω) of water (n = 1.34,
unpolarised). As a reflectance factor (Eq. 2 of Cox & Munk; Zhang & Wang 2010)::

    ρ_g(μ₀, μ, φ) = π r(ω) p(β) G / (4 μ₀ μ cos⁴β),    p(β) = exp(−tan²β / σ²) / (π σ²)

with cos 2ω = the cosine between the directions to the Sun and to the viewer, and G the shadowing
of Smith's function for Gaussian slopes, G = 1 / (1 + Λ(μ₀) + Λ(μ)) (Mishchenko & Travis 1997,
*J. Geophys. Res.* 102, 16989, Eq. 13)::

    Λ(μ) = ½ [σ tanθ e^{−cot²θ/σ²} / √π − erfc(cot θ / σ)]

Whitecaps (Lambertian): fraction W = 2.95e-6 U^3.52 (Monahan & O'Muircheartaigh 1980, *J. Phys.
Oceanogr.* 10, 2094) of reflectance 0.22 (Koepke 1984, *Appl. Opt.* 23, 1816). Light leaving the
water (Lambertian): the packaged open-ocean spectrum (USGS splib07 sea water, a directional-
hemispherical reflectance that includes the surface's Fresnel reflection) less its Fresnel level,
the spectrum's mean beyond 800 nm where water absorbs nearly all that enters: 0.026 at 450 nm,
0.008 at 550 nm, 0.002 at 865 nm (Morel & Maritorena 2001's clear ocean gives ~0.024 and ~0.006
at chlorophyll 0.1 mg m⁻³). The total is W ρ_wc + (1 − W)(ρ_g + ρ_w). Neglected: the slopes' anisotropy with
wind direction (Cox & Munk's σ_u², σ_c²), polarisation, whitecaps' spectral fall in the near
infrared (Frouin et al. 1996), the interface's effect on the angular shape of the water's light.
"""

from __future__ import annotations

import numpy as np
from scipy.special import erfc

from lunarviz.earth_optics.spectra import class_spectrum

#: refractive index of sea water in the visible (Hale & Querry 1973 ~1.33, salt +0.006)
WATER_INDEX = 1.34
#: whitecap reflectance (Koepke 1984)
WHITECAP_REFLECTANCE = 0.22
#: cos θ below which a direction is taken as the horizon (no glint: 90° to 1e-6 rad)
GRAZING_MU = 1e-6
#: wavelengths [nm] beyond which the packaged ocean spectrum is all Fresnel reflection
FRESNEL_LEVEL_FROM_NM = 800.0


def slope_variance(wind_speed: float) -> float:
    """σ² of Cox & Munk's clean sea (isotropic: σ_u² + σ_c²)."""
    return 0.003 + 0.00512 * float(wind_speed)


def whitecap_fraction(wind_speed: float) -> float:
    """W of Monahan & O'Muircheartaigh (1980)."""
    return 2.95e-6 * float(wind_speed) ** 3.52


def fresnel(cos_incidence, n: float = WATER_INDEX) -> np.ndarray:
    """Unpolarised Fresnel reflectance of a planar interface air → medium of index n."""
    ci = np.clip(np.asarray(cos_incidence, dtype=float), 0.0, 1.0)
    st2 = (1.0 - ci * ci) / (n * n)
    ct = np.sqrt(np.clip(1.0 - st2, 0.0, 1.0))
    rs = (ci - n * ct) / (ci + n * ct)
    rp = (n * ci - ct) / (n * ci + ct)
    return 0.5 * (rs * rs + rp * rp)


def _smith_lambda(mu, sigma):
    mu = np.clip(mu, 1e-9, 1.0)
    s = np.sqrt(np.clip(1.0 - mu * mu, 0.0, None))
    cot = np.minimum(mu / np.maximum(s, 1e-300), 1e6)  # beyond: Λ = 0 to double precision
    return 0.5 * (sigma * np.exp(-(cot / sigma) ** 2) / (np.sqrt(np.pi) * np.maximum(cot, 1e-300)) - erfc(cot / sigma))


def glint(mu0, mu, phi_deg, wind_speed: float, shadowing: bool = True) -> np.ndarray:
    """ρ_g: Cox–Munk glint reflectance factor (azimuth 0 = viewer on the Sun's side: the
    specular direction is at φ = 180°)."""
    mu0, mu, phi = np.broadcast_arrays(np.asarray(mu0, float), np.asarray(mu, float), np.asarray(phi_deg, float))
    sig2 = slope_variance(wind_speed)
    s0, s1 = np.sqrt(np.clip(1 - mu0 * mu0, 0, None)), np.sqrt(np.clip(1 - mu * mu, 0, None))
    ph = np.radians(phi)
    cos2w = mu0 * mu + s0 * s1 * np.cos(ph)  # Sun · viewer
    cosw = np.sqrt(np.clip(0.5 * (1.0 + cos2w), 0.0, 1.0))
    cosb = (mu0 + mu) / np.maximum(2.0 * cosw, 1e-300)
    cosb = np.clip(cosb, 1e-12, 1.0)
    tan2 = (1.0 - cosb * cosb) / (cosb * cosb)
    p = np.exp(-tan2 / sig2) / (np.pi * sig2)
    out = np.pi * fresnel(cosw) * p / (4.0 * np.maximum(mu0 * mu, 1e-300) * cosb**4)
    if shadowing:
        sig = np.sqrt(sig2)
        out = out / (1.0 + _smith_lambda(mu0, sig) + _smith_lambda(mu, sig))
    return np.where((mu0 > GRAZING_MU) & (mu > GRAZING_MU), out, 0.0)


def water_leaving(wavelength_nm) -> np.ndarray:
    """ρ_w(λ): the Lambertian reflectance of the light leaving the water (module docstring)."""
    lam, a = class_spectrum("ocean")
    level = float(np.mean(a[lam >= FRESNEL_LEVEL_FROM_NM]))
    return np.clip(np.interp(np.asarray(wavelength_nm, float), lam, a) - level, 0.0, None)


def ocean_reflectance(wavelength_nm, mu0, mu, phi_deg, wind_speed: float) -> np.ndarray:
    """The ocean's reflectance factor W ρ_wc + (1 − W)(ρ_g + ρ_w)."""
    return ocean_from_glint(glint(mu0, mu, phi_deg, wind_speed), wavelength_nm, wind_speed)


def ocean_from_glint(glint_rf, wavelength_nm, wind_speed: float) -> np.ndarray:
    """W ρ_wc + (1 − W)(ρ_g + ρ_w) from the glint ρ_g already at hand."""
    w = whitecap_fraction(wind_speed)
    return w * WHITECAP_REFLECTANCE + (1.0 - w) * (glint_rf + water_leaving(wavelength_nm))
