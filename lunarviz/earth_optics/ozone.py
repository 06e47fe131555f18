"""Absorption by the ozone layer above the scattering air: the Huggins and Chappuis bands.

The ozone column N (``earth.ozone_du`` Dobson units; 1 DU = 2.687e16 molecules cm⁻²) is taken as a
purely absorbing layer above all the scattering (Rayleigh air, clouds, the surface), so that every
path from the Sun to the top of the atmosphere and back crosses it once down and once up and the
top-of-atmosphere reflectance factor is multiplied by (Vermote et al. 1997, *IEEE Trans. Geosci.
Remote Sens.* 35, 675, the gaseous transmittance of 6S)::

    T_O3(λ; μ₀, μ) = exp(−σ(λ) N [m(μ₀) + m(μ)])

with σ the cross section of ``lunarviz/data/spectra/ozone_cross_section.csv`` (Molina & Molina 1986
at 226 K below 350 nm, Serdyuchenko et al. 2014 at 233 K from 360 nm) and m the air mass of a thin
spherical shell at the height h = 22 km of the ozone maximum, as the Dobson network computes it
(Komhyr 1980, *Operations handbook: ozone observations with a Dobson spectrophotometer*, WMO
Global Ozone Research and Monitoring Project Report 6)::

    m(μ) = 1 / √(1 − (R / (R + h))² (1 − μ²))

finite at the horizon (m(0) = (R + h)/√(2Rh + h²) ≈ 12), so a crescent Earth's grazing light is
absorbed along its real slant path, not held at a zenith angle of 89°.

Neglected: the tenth of the column in the troposphere, among the scatterers (and the Rayleigh light
scattered above the ozone peak: ~4 % of the air's mass is above 22 km); the cross section's change
with temperature (a few per cent in the Chappuis band; large in the Huggins band, where the 226 K
column is used); the 10 nm bins' averaging of the Chappuis band's weak structure; the Wulf bands
beyond 835 nm (optical depth < 1e-3).
"""

from __future__ import annotations

import numpy as np

from lunarviz.caches import memoize
from lunarviz.constants import R_EARTH_M
from lunarviz.resources import DATA_DIR, read_table

#: molecules per cm² in one Dobson unit (0.01 mm of ozone at 0 °C and 1013.25 hPa)
DOBSON_CM2 = 2.687e16
#: height of the thin ozone shell [m] (Komhyr 1980)
SHELL_HEIGHT_M = 22.0e3
#: beyond this wavelength [nm] the cross section is taken as zero (the table's last bin ends there)
LAST_NM = 840.0


@memoize(maxsize=1)
def _table() -> tuple[np.ndarray, np.ndarray]:
    lam, sigma, _ = read_table(DATA_DIR / "spectra" / "ozone_cross_section.csv", "ozone cross section")
    return lam, np.log(sigma)


def cross_section(wavelength_nm) -> np.ndarray:
    """σ(λ) [cm²]: linear in log σ between the table's rows (the Huggins band falls by ~3 orders
    of magnitude over 60 nm), held below 290 nm, zero beyond :data:`LAST_NM`."""
    lam, log_sigma = _table()
    x = np.asarray(wavelength_nm, dtype=float)
    return np.where(x < LAST_NM, np.exp(np.interp(x, lam, log_sigma)), 0.0)


def air_mass(mu) -> np.ndarray:
    """m(μ): the slant path through the ozone shell over its vertical path (module docstring); μ
    below 0 is taken as the horizon."""
    s = np.clip(1.0 - np.square(np.clip(np.asarray(mu, float), 0.0, 1.0)), 0.0, 1.0)
    k = R_EARTH_M / (R_EARTH_M + SHELL_HEIGHT_M)
    return 1.0 / np.sqrt(1.0 - k * k * s)


def optical_depth(wavelength_nm, column_du: float) -> np.ndarray:
    """The ozone column's vertical absorption optical depth σ N at λ."""
    return cross_section(wavelength_nm) * float(column_du) * DOBSON_CM2


def transmittance(wavelength_nm: float, column_du: float, mu0, mu) -> np.ndarray:
    """T_O3 = exp(−τ_O3 [m(μ₀) + m(μ)]) of a path down at cos θ = μ₀ and up at μ (broadcast)."""
    tau = float(optical_depth(float(wavelength_nm), column_du))
    if tau == 0.0:
        return np.ones(np.broadcast(np.asarray(mu0), np.asarray(mu)).shape)
    return np.exp(-tau * (air_mass(mu0) + air_mass(mu)))
