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
Oceanogr.* 10, 2094) of reflectance 0.22 (Koepke 1984, *Appl. Opt.* 23, 1816).

Light leaving the water (Lambertian), from the water's inherent optical properties for open-ocean
(case 1) water of chlorophyll concentration Chl (``earth.chlorophyll``, mg m⁻³): the irradiance
reflectance just below the surface R = f b_b / a with f = 0.33 (Morel & Prieur 1977, *Limnol.
Oceanogr.* 22, 709), carried through the surface as ρ_w = ℜ R with ℜ = 0.529 (Morel & Gentili
1996, *Appl. Opt.* 35, 4850; the upwelling radiance below the surface taken isotropic, Q = π)::

    a   = a_w(λ) + A_p(λ) Chl^E_p(λ) + a_y(440) e^{−0.014 (λ − 440)}
    b_b = b_w(λ)/2 + b_p(λ) [0.002 + 0.01 (0.5 − 0.25 log₁₀ Chl) (λ/550)^ν]

with a_w the pure water's absorption (``lunarviz/data/spectra/water_absorption.csv``: IOCCG 2018's
spectrum, Pope & Fry 1997 in the visible, Kou et al. 1993 in the near infrared), A_p and E_p the
particles' absorption (Bricaud et al. 1998, ``ocean_particle_absorption.csv``; held below 400 nm,
zero beyond 700 nm), the yellow substance a_y(440) = 0.2 A_p(440) Chl^E_p(440) covarying with the
particles (Prieur & Sathyendranath 1981, *Limnol. Oceanogr.* 26, 671; slope: Bricaud, Morel & Prieur
1981, *Limnol. Oceanogr.* 26, 43), sea water's scattering b_w = 0.00288 (λ/500)^−4.32 m⁻¹ (Morel
1974), and the particles' scattering b_p = 0.416 Chl^0.766 (λ/550)^ν with ν = 0.5 (log₁₀ Chl − 0.3)
below 2 mg m⁻³ and 0 above (Morel & Maritorena 2001, *J. Geophys. Res.* 106, 7163). Clear water
(Chl 0.1) gives 0.024 at 450 nm, 0.005 at 550 nm, and 2e-5 at 865 nm, where the water absorbs
4.6 m⁻¹: the ocean is black in the near infrared but for its glint and whitecaps.

The total is W ρ_wc + (1 − W)(ρ_g + ρ_w). Neglected: the slopes' anisotropy with wind direction
(Cox & Munk's σ_u², σ_c²), the polarisation of the whitecaps and the water's light (the glint's is
:func:`glint_stokes`), whitecaps' spectral fall in the near infrared (Frouin et
al. 1996), the angular shape of the water's light (Q is 3-5 sr, not π: the nadir radiance is
~20-35 % lower and the grazing one higher; Morel & Gentili 1996), coastal (case 2) water,
Raman scattering and fluorescence.
"""

from __future__ import annotations

import numpy as np
from scipy.special import erfc

from lunarviz.caches import memoize
from lunarviz.earth_optics.stokes import frame_angle, rotate
from lunarviz.options import EARTH_PARAMETER_DEFAULTS
from lunarviz.resources import DATA_DIR, read_table

#: refractive index of sea water in the visible (Hale & Querry 1973 ~1.33, salt +0.006)
WATER_INDEX = 1.34
#: whitecap reflectance (Koepke 1984)
WHITECAP_REFLECTANCE = 0.22
#: cos θ below which a direction is taken as the horizon (no glint: 90° to 1e-6 rad)
GRAZING_MU = 1e-6
#: R = f b_b / a just below the surface (Morel & Prieur 1977)
F_FACTOR = 0.33
#: ℜ: the surface's transmission of the upwelling light with its n² law (Morel & Gentili 1996)
SURFACE_TRANSMISSION = 0.529
#: the yellow substance's absorption at 440 nm over the particles' (Prieur & Sathyendranath 1981)
CDOM_FRACTION = 0.2
#: the yellow substance's spectral slope [nm⁻¹] (Bricaud, Morel & Prieur 1981)
CDOM_SLOPE_PER_NM = 0.014


def slope_variance(wind_speed: float) -> float:
    """σ² of Cox & Munk's clean sea (isotropic: σ_u² + σ_c²)."""
    return 0.003 + 0.00512 * float(wind_speed)


def whitecap_fraction(wind_speed: float) -> float:
    """W of Monahan & O'Muircheartaigh (1980)."""
    return 2.95e-6 * float(wind_speed) ** 3.52


def fresnel_parts(cos_incidence, n: float = WATER_INDEX) -> tuple[np.ndarray, np.ndarray]:
    """(|r_s|², |r_p|²): Fresnel reflectances of a planar interface air → medium of index n for
    light polarised across (s) and in (p) the plane of incidence."""
    ci = np.clip(np.asarray(cos_incidence, dtype=float), 0.0, 1.0)
    st2 = (1.0 - ci * ci) / (n * n)
    ct = np.sqrt(np.clip(1.0 - st2, 0.0, 1.0))
    rs = (ci - n * ct) / (ci + n * ct)
    rp = (n * ci - ct) / (n * ci + ct)
    return rs * rs, rp * rp


def fresnel(cos_incidence, n: float = WATER_INDEX) -> np.ndarray:
    """Unpolarised Fresnel reflectance of a planar interface air → medium of index n."""
    rs2, rp2 = fresnel_parts(cos_incidence, n)
    return 0.5 * (rs2 + rp2)


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


def glint_stokes(mu0, mu, phi_deg, wind_speed: float) -> np.ndarray:
    """(..., 3): the glint's reflectance factors (I, Q, U) for unpolarised sunlight, in the meridian
    plane of the view (the conventions of :mod:`lunarviz.earth_optics.stokes`). Each facet reflects
    specularly, so the plane of incidence is the plane of scattering (Sun, facet, viewer) and the
    light is polarised across it by Fresnel's law: Q/I = (|r_p|² − |r_s|²)/(|r_p|² + |r_s|²) there
    at the facets' incidence ω (cos 2ω = the Sun's direction · the viewer's), turned into the
    meridian plane. I is :func:`glint`."""
    mu0, mu, phi = np.broadcast_arrays(np.asarray(mu0, float), np.asarray(mu, float), np.asarray(phi_deg, float))
    s0, s1, ph = np.sqrt(np.clip(1 - mu0 * mu0, 0, None)), np.sqrt(np.clip(1 - mu * mu, 0, None)), np.radians(phi)
    k0 = np.stack([-s0, np.zeros_like(s0), -mu0], -1)  # sunlight (the Sun at azimuth 0)
    k = np.stack([s1 * np.cos(ph), s1 * np.sin(ph), mu], -1)  # toward the viewer
    cosw = np.sqrt(np.clip(0.5 * (1.0 - np.einsum("...i,...i->...", k0, k)), 0.0, 1.0))
    rs2, rp2 = fresnel_parts(cosw)
    i = glint(mu0, mu, phi, wind_speed)
    e_perp = np.cross(k0, k)
    norm = np.linalg.norm(e_perp, axis=-1, keepdims=True)
    e_perp = np.where(norm > 1e-12, e_perp / np.maximum(norm, 1e-300), [0.0, 1.0, 0.0])  # (backscatter: any)
    e_par = np.cross(e_perp, k)
    m_perp = np.stack([-np.sin(ph), np.cos(ph), np.zeros_like(ph)], -1)  # z × k/|z × k| (at nadir its limit)
    m_par = np.cross(m_perp, k)
    q = i * np.divide(rp2 - rs2, rp2 + rs2, out=np.zeros_like(i), where=rp2 + rs2 > 0)
    return rotate(np.stack([i, q, np.zeros_like(i)], -1), frame_angle(e_par, e_perp, m_par))


@memoize(maxsize=1)
def _water_tables() -> tuple[np.ndarray, ...]:
    lam_w, a_w, _ = read_table(DATA_DIR / "spectra" / "water_absorption.csv", "water absorption")
    rows = [line for line in (DATA_DIR / "spectra" / "ocean_particle_absorption.csv").read_text().splitlines()
            if line.strip() and not line.startswith("#")]
    lam_p, amp, expo = np.loadtxt(rows[1:], delimiter=",", unpack=True)  # after its header line
    return lam_w, a_w, lam_p, amp, expo


def inherent_optics(wavelength_nm, chlorophyll: float) -> tuple[np.ndarray, np.ndarray]:
    """(a, b_b) [m⁻¹]: case-1 water's absorption and backscattering coefficients at λ for
    chlorophyll ``chlorophyll`` [mg m⁻³] (module docstring)."""
    lam = np.asarray(wavelength_nm, dtype=float)
    chl = float(chlorophyll)
    lam_w, a_w, lam_p, amp, expo = _water_tables()
    def particles(x):  # A_p Chl^E_p
        return np.interp(x, lam_p, amp, right=0.0) * chl ** np.interp(x, lam_p, expo)
    a_y = CDOM_FRACTION * particles(440.0) * np.exp(-CDOM_SLOPE_PER_NM * (lam - 440.0))
    nu = 0.5 * (np.log10(chl) - 0.3) if chl < 2.0 else 0.0
    b_p = 0.416 * chl**0.766 * (lam / 550.0) ** nu
    b_bp = b_p * (0.002 + 0.01 * (0.5 - 0.25 * np.log10(chl)) * (lam / 550.0) ** nu)
    b_w = 0.00288 * (lam / 500.0) ** -4.32
    return np.interp(lam, lam_w, a_w) + particles(lam) + a_y, 0.5 * b_w + b_bp


def water_leaving(wavelength_nm, chlorophyll: float = EARTH_PARAMETER_DEFAULTS["chlorophyll"]) -> np.ndarray:
    """ρ_w(λ) = ℜ f b_b / a: the Lambertian reflectance of the light leaving the water (module
    docstring)."""
    a, b_b = inherent_optics(wavelength_nm, chlorophyll)
    return SURFACE_TRANSMISSION * F_FACTOR * b_b / a


def ocean_reflectance(wavelength_nm, mu0, mu, phi_deg, wind_speed: float,
                      chlorophyll: float = EARTH_PARAMETER_DEFAULTS["chlorophyll"]) -> np.ndarray:
    """The ocean's reflectance factor W ρ_wc + (1 − W)(ρ_g + ρ_w)."""
    return ocean_from_glint(glint(mu0, mu, phi_deg, wind_speed), wavelength_nm, wind_speed, chlorophyll)


def ocean_parts(wavelength_nm, wind_speed: float,
                chlorophyll: float = EARTH_PARAMETER_DEFAULTS["chlorophyll"]) -> tuple[np.ndarray, float]:
    """(constant, scale): the ocean reflects W ρ_wc + (1 − W)(ρ_g + ρ_w) = constant + scale × ρ_g,
    the glint ρ_g being the only part with a shape and the only part free of λ."""
    w = whitecap_fraction(wind_speed)
    return w * WHITECAP_REFLECTANCE + (1.0 - w) * water_leaving(wavelength_nm, chlorophyll), 1.0 - w


def ocean_from_glint(glint_rf, wavelength_nm, wind_speed: float,
                     chlorophyll: float = EARTH_PARAMETER_DEFAULTS["chlorophyll"]) -> np.ndarray:
    """W ρ_wc + (1 − W)(ρ_g + ρ_w) from the glint ρ_g already at hand."""
    constant, scale = ocean_parts(wavelength_nm, wind_speed, chlorophyll)
    return constant + scale * glint_rf
