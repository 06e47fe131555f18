"""The Sun's spectrum: a packaged solar spectral irradiance at 1 au, and how the grey Sun relates to it.

lunarviz's grey Sun is the paper's: a Lambertian sphere emitting Φ = 1.626e26 W over 400-750 nm
(:data:`lunarviz.constants.PHI_SUN_W`), i.e. ``Φ / (4π au²) = 578 W m⁻²`` at 1 au. A spectral run
replaces that number by the spectral irradiance ``E_sun(λ)`` of a packaged table (or a user's)
[W m⁻² nm⁻¹ at 1 au]: every transport is linear in the Sun's power, so the spectral irradiance at
the detector is the grey transport shaded at λ times ``4π au² E_sun(λ) / Φ`` [nm⁻¹]
(:func:`solar_scale`). The default table, ``tsis1-hsrs`` (TSIS-1 Hybrid Solar Reference Spectrum
v2, Coddington et al. 2023), holds 602.9 W m⁻² in 400-750 nm at 1 au: 4.3 % more than the paper's
Φ gives (578.2), and ~1 % more than Wehrli (1985), the spectrum ROLO was calibrated with (595-598,
depending on how its table is read).

``grey`` is the paper's Sun spread flat over 400-750 nm (``Φ / (4π au² · 350 nm)``, zero outside):
a spectral run with it and grey surfaces reproduces the grey run exactly (the conservation
check of the documentation's light-in-colour page). Tables are ``wavelength_nm,irradiance_W_m2_nm`` CSV files
(``#`` lines are comments), wavelengths increasing; between rows the spectrum is linear.

Neglected: the Sun's variability (≈0.1 % over a solar cycle in the visible), limb darkening's
colour (the Sun is a uniform disc in the transport), and the Doppler shifts of its lines.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lunarviz.caches import file_key, memoize
from lunarviz.constants import PHI_SUN_W
from lunarviz.errors import LunarvizError, unknown_choice
from lunarviz.options import SOLAR_SPECTRA
from lunarviz.resources import DATA_DIR, read_table

#: the astronomical unit [m] (IAU 2012 Resolution B2)
AU_M = 1.495978707e11
#: the paper's band [nm], over which the grey Sun's Φ is given
GREY_BAND_NM = (400.0, 750.0)
#: packaged solar spectra (:data:`lunarviz.options.SOLAR_SPECTRA`): name -> file in ``lunarviz/data/spectra``
#: (each file's header cites its source)
PACKAGED = {"tsis1-hsrs": "solar_tsis1_hsrs_v2.csv"}
#: the named spectra: the packaged tables and the paper's flat grey Sun
DEFAULT = "tsis1-hsrs"


@dataclass(frozen=True)
class SolarSpectrum:
    """A solar spectral irradiance at 1 au: ``wavelength_nm`` (increasing) and
    ``irradiance_W_m2_nm``, linear between rows, zero outside them."""

    name: str
    wavelength_nm: np.ndarray
    irradiance_W_m2_nm: np.ndarray
    source: str = ""

    def at(self, wavelength_nm) -> np.ndarray:
        """Spectral irradiance at 1 au [W m⁻² nm⁻¹] at ``wavelength_nm`` (linear between rows)."""
        lam = np.asarray(wavelength_nm, dtype=float)
        self.check_covers(lam)
        return np.interp(lam, self.wavelength_nm, self.irradiance_W_m2_nm, left=0.0, right=0.0)

    def check_covers(self, lam) -> None:
        """A one-line error for wavelengths outside the table."""
        lam = np.atleast_1d(lam)
        lo, hi = self.wavelength_nm[0], self.wavelength_nm[-1]
        bad = lam[(lam < lo) | (lam > hi)]
        if bad.size:
            raise LunarvizError(f"wavelength {bad[0]:g} nm is outside the solar spectrum {self.name!r} "
                                f"({lo:g}-{hi:g} nm)")

    def integral(self, lo: float, hi: float) -> float:
        """``∫ E_sun dλ`` over [lo, hi] nm at 1 au [W m⁻²] (exact for the piecewise-linear table)."""
        x = np.unique(np.concatenate([[lo, hi], self.wavelength_nm[(self.wavelength_nm > lo) &
                                                                    (self.wavelength_nm < hi)]]))
        return trapezoid(np.interp(x, self.wavelength_nm, self.irradiance_W_m2_nm, 0.0, 0.0), x)


def trapezoid(y, x) -> float:
    """The trapezoid rule (numpy's ``trapezoid`` is numpy ≥ 2 only)."""
    y, x = np.asarray(y, dtype=float), np.asarray(x, dtype=float)
    return float(np.sum(0.5 * (y[1:] + y[:-1]) * np.diff(x)))


def solar_scale(spectrum: SolarSpectrum, wavelength_nm, phi_w: float = PHI_SUN_W) -> np.ndarray:
    """``4π au² E_sun(λ) / Φ`` [nm⁻¹]: what turns a transport lit by the grey Sun of power ``phi_w``
    into one lit by the spectrum at λ (the Sun's spectral power over its grey power)."""
    return 4.0 * np.pi * AU_M**2 * spectrum.at(wavelength_nm) / phi_w


def grey_sun() -> SolarSpectrum:
    """The paper's Sun, flat over 400-750 nm: ``Φ/(4π au² · 350 nm)`` [W m⁻² nm⁻¹] at 1 au, zero
    outside (the table's edges are 1e-9 nm wide ramps)."""
    lo, hi = GREY_BAND_NM
    level = PHI_SUN_W / (4.0 * np.pi * AU_M**2 * (hi - lo))
    eps = 1e-9
    lam = np.array([lo - eps, lo, hi, hi + eps])
    return SolarSpectrum("grey", lam, np.array([0.0, level, level, 0.0]),
                         "the paper's Φ = 1.626e26 W spread flat over 400-750 nm")


@memoize(maxsize=8)
def _load(key: tuple, name: str) -> SolarSpectrum:
    lam, e, notes = read_table(key[0])
    return SolarSpectrum(name, lam, e, notes)


def solar_spectrum(name: str = DEFAULT) -> SolarSpectrum:
    """A named spectrum (:data:`SOLAR_SPECTRA`) or a CSV file of ``wavelength_nm,irradiance_W_m2_nm``."""
    key = str(name).strip()
    if key == "grey":
        return grey_sun()
    if key in PACKAGED:
        return _load(file_key(DATA_DIR / "spectra" / PACKAGED[key]), key)
    if key.lower().endswith((".csv", ".txt")):
        return _load(file_key(key), key)
    raise LunarvizError(f"{unknown_choice('solar spectrum', name, SOLAR_SPECTRA)} or give a .csv file")
