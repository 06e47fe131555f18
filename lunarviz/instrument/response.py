"""An instrument's photon-counting response, and the spectral request that images in it.

A pixel collects ``Ṅ = A Ω ∫ L(λ) S(λ) T(λ) Q(λ) λ/(hc) dλ`` photoelectrons per second [e⁻ s⁻¹],
with L the spectral radiance [W m⁻² sr⁻¹ nm⁻¹], S the band's response, T the optics'
transmission, Q the quantum efficiency, A the collecting area [m²] and Ω the pixel's solid angle
[sr]. lunarviz images the scene in two bands at once (one shading pass, the same nodes): the
band S itself (the radiance planes users read, ``∫ L S dλ``) and the *photon band*
``Ŝ(λ) = S T Q λ / λ_ref`` (dimensionless, λ_ref = 1 µm), whose plane P̂ = ∫ L Ŝ dλ turns into
electrons as ``Ṅ = A Ω P̂ λ_ref/(hc)``. Nothing assumes the scene has the Sun's colour: the
earthshine and the moonshine are each weighted by the response at their own wavelengths.
"""

from __future__ import annotations

import numpy as np

from lunarviz.constants import PLANCK_J_S, SPEED_OF_LIGHT_M_S
from lunarviz.instrument.spec import Instrument
from lunarviz.spectral.bands import Band, parse_band
from lunarviz.spectral.request import band_request
from lunarviz.spectral.solar import solar_spectrum

#: the photon band's reference wavelength [m]: Ŝ = S T Q λ/λ_ref
LAMBDA_REF_M = 1e-6
#: photoelectrons per joule of P̂ (λ_ref / hc) [e⁻ J⁻¹]
ELECTRONS_PER_JOULE = LAMBDA_REF_M / (PLANCK_J_S * SPEED_OF_LIGHT_M_S)
#: the photon band's grid step [nm] (the QE and transmission tables are linear between rows)
GRID_STEP_NM = 1.0


def photon_band(inst: Instrument) -> Band:
    """Ŝ = S T Q λ/λ_ref on a 1 nm grid over the band's support (plus the band's own rows)."""
    band = parse_band(inst.band)
    lo, hi = band.support
    lam = np.unique(np.concatenate([np.arange(np.ceil(lo), np.floor(hi) + 1, GRID_STEP_NM),
                                    band.wavelength_nm[(band.wavelength_nm >= lo) & (band.wavelength_nm <= hi)],
                                    [lo, hi]]))
    resp = band.at(lam) * inst.throughput(lam) * lam * 1e-9 / LAMBDA_REF_M
    return Band(photon_label(inst), lam, resp, f"{inst.band} x optics x QE x lambda/1um ({inst.name})")


def photon_label(inst: Instrument) -> str:
    """The photon band's label in image planes: ``BAND:e`` (never a user's band name: it has a colon)."""
    return f"{inst.band}:e"


def instrument_request(inst: Instrument, solar: str):
    """The spectral request of an instrument's images: its band and its photon band."""
    return band_request((parse_band(inst.band), photon_band(inst)), solar_spectrum(solar))


def electron_rate(photon_plane: np.ndarray, pixel_solid_angle: np.ndarray, inst: Instrument) -> np.ndarray:
    """Photoelectrons per second per pixel [e⁻ s⁻¹] from a photon-band plane P̂ [W m⁻² sr⁻¹]."""
    return photon_plane * pixel_solid_angle * inst.collecting_area_m2 * ELECTRONS_PER_JOULE


def write_band_csv(band: Band, path) -> None:
    """A band as a ``wavelength_nm,response`` CSV (what ``--band FILE.csv`` reads)."""
    from pathlib import Path
    rows = "\n".join(f"{lam:.6f},{r:.12e}" for lam, r in zip(band.wavelength_nm, band.response))
    Path(path).write_text(f"# {band.source}\nwavelength_nm,response\n{rows}\n", encoding="utf-8")
