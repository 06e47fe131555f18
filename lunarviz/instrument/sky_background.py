"""A ground site's atmosphere in the frame: extinction of the Moon's light, the moonless sky, and
moonlight scattered by the atmosphere (Krisciunas & Schaefer 1991, PASP 103, 1033; "K&S").

* Extinction: the Moon's light is dimmed by ``10^(-0.4 k X(Z_m))`` (K&S Eq. 21's first factor),
  with k [mag per airmass] the instrument's ``atmosphere.extinction_mag_per_airmass`` and
  ``X(Z) = (1 - 0.96 sin² Z)^(-1/2)`` (K&S Eq. 3). The earthlit and the sunlit Moon are dimmed
  alike, which is why the earthshine/moonshine ratio needs no extinction correction.
* The moonless sky: ``B = B_zen 10^(-0.4 k (X-1)) X`` (K&S Eq. 2) with B_zen the instrument's
  ``atmosphere.dark_sky_mag_arcsec2``; magnitudes become radiance with the V zero point
  3.631e-11 W m⁻² nm⁻¹ (Bessell et al. 1998, A&A 333, 231), flat in f_λ across the band.
* Scattered moonlight: K&S Eqs. 15-21, ``B_moon = f(ρ) I* 10^(-0.4 k X(Z_m)) [1 - 10^(-0.4 k X(Z))]``
  with ``f(ρ) = 10^5.36 (1.06 + cos² ρ) + 10^(6.15 - ρ/40)`` [nL per foot-candle]; instead of K&S's
  Moon magnitude I* the Moon's own irradiance in the band (moonshine + earthshine, outside the
  atmosphere) is used, so the sky has the Moon's colour: ``L_sky = E_moon f(ρ) … × (3.183e-6 cd m⁻²
  per nL) / (10.764 lx per fc)`` [sr⁻¹ × E_moon]. f is taken at ρ = 10°, the inner edge of K&S's
  validity: the aureole closer to the Moon is the instrument's halo (its ``halo`` includes the
  atmosphere's). The sky is uniform over the frame (the frame spans < 1°, where K&S's f and the
  airmass change by < 3 %).

Neglected: the sky's own colour (Rayleigh blue), airglow lines, differential extinction across
the frame (< 1e-3 at Z < 70°), seeing beyond the PSF.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lunarviz.errors import LunarvizError

#: V = 0 spectral flux density [W m⁻² nm⁻¹] (Bessell, Castelli & Plez 1998, Table A2)
V_ZERO_POINT_W_M2_NM = 3.631e-11
#: one square arcsecond [sr]
ARCSEC2_SR = (np.pi / 180.0 / 3600.0) ** 2
#: luminance of one nanoLambert [cd m⁻²]: 1e-9 × 1e4/π
NANOLAMBERT_CD_M2 = 1e-9 * 1e4 / np.pi
#: illuminance of one foot-candle [lx]
FOOTCANDLE_LX = 10.7639
#: K&S's scattering function is valid from this separation from the Moon [deg]
KS_MIN_SEPARATION_DEG = 10.0
#: below this altitude [deg] the plane-parallel airmass and K&S's model fail
MIN_ALTITUDE_DEG = 5.0


def airmass(zenith_deg) -> np.ndarray:
    """K&S Eq. 3: X(Z) = (1 - 0.96 sin² Z)^(-1/2)."""
    z = np.radians(np.asarray(zenith_deg, dtype=float))
    return (1.0 - 0.96 * np.sin(z) ** 2) ** -0.5


def ks_scattering_function(rho_deg) -> np.ndarray:
    """K&S Eq. 21's f(ρ) [nL per foot-candle]: Rayleigh plus Mie scattering at separation ρ [deg]."""
    r = np.asarray(rho_deg, dtype=float)
    return 10**5.36 * (1.06 + np.cos(np.radians(r)) ** 2) + 10 ** (6.15 - r / 40.0)


@dataclass(frozen=True)
class SiteSky:
    """The atmosphere's effect on one frame."""

    transmission: float  # 10^(-0.4 k X(Z_m)) on the Moon's light
    scattered_per_irradiance_sr: float  # L_sky / E_moon [sr⁻¹] (E_moon outside the atmosphere)
    dark_sky_radiance_w_m2_sr_nm: float  # the moonless sky's spectral radiance (flat over the band)
    moon_zenith_deg: float
    model: str


def site_sky(moon_altitude_deg: float, extinction_mag_per_airmass: float, dark_sky_mag_arcsec2: float) -> SiteSky:
    """The sky of a frame centred on the Moon at ``moon_altitude_deg``."""
    if not np.isfinite(moon_altitude_deg) or moon_altitude_deg < MIN_ALTITUDE_DEG:
        raise LunarvizError(f"the Moon is {moon_altitude_deg:.3g} deg above the site's horizon: a ground frame needs "
                            f"at least {MIN_ALTITUDE_DEG:g} deg")
    zm = 90.0 - float(moon_altitude_deg)
    k = float(extinction_mag_per_airmass)
    X = float(airmass(zm))
    t = 10 ** (-0.4 * k * X)
    f = float(ks_scattering_function(KS_MIN_SEPARATION_DEG))
    scattered = f * t * (1.0 - t) * NANOLAMBERT_CD_M2 / FOOTCANDLE_LX
    mag = dark_sky_mag_arcsec2 - 2.5 * np.log10(10 ** (-0.4 * k * (X - 1.0)) * X)
    dark = V_ZERO_POINT_W_M2_NM * 10 ** (-0.4 * mag) / ARCSEC2_SR
    return SiteSky(t, scattered, float(dark), zm,
                   f"K&S1991 k={k:g}mag/X X={X:.3f} sky={dark_sky_mag_arcsec2:g}mag/as2 rho=10")
