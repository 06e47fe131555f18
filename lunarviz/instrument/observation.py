"""What an instrument records from a scene: the synthetic image in its band, through its optics
(at a ground site) the atmosphere and a bright-side neutral-density mask, as a photoelectron
rate per pixel.

The camera (:func:`lunarviz.methods.camera.synthesize`, the caller's) images the scene in the
instrument's band and in its photon band (:mod:`lunarviz.instrument.response`); the PSF and the halo act on
both (:func:`lunarviz.instrument.optics.apply_optics`); at a ground site the Moon's light is dimmed
and a uniform sky is added (:mod:`lunarviz.instrument.sky_background`). The radiance planes stay those above
the atmosphere (as every lunarviz image); the electron rates carry everything.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lunarviz.errors import LunarvizError
from lunarviz.geometry.scene_geometry import SceneGeometry
from lunarviz.instrument.detector import expected_counts, expected_electrons
from lunarviz.instrument.disc import BrightSideMask, DiscGeometry, masked_pixels
from lunarviz.instrument.optics import apply_optics, parse_halo, parse_psf
from lunarviz.instrument.response import electron_rate, photon_band, photon_label
from lunarviz.instrument.sky_background import SiteSky, site_sky
from lunarviz.instrument.spec import MAX_EXPOSURE_S, MIN_EXPOSURE_S, Instrument
from lunarviz.methods.camera import Camera, ImageResult


@dataclass
class Observation:
    """One pointing of an instrument at the Moon, noise-free."""

    instrument: Instrument
    exposure_s: float
    brdf: str
    image: object  # ImageResult: radiance planes in the band (after the optics), keys BRDF|BAND
    raw_rates: dict  # {"moonshine", "earthshine"}: photoelectron rates [e⁻ s⁻¹] before the optics
    rates: dict  # {"moonshine", "earthshine", "sky"}: [e⁻ s⁻¹] per pixel after optics and atmosphere
    sky: SiteSky | None
    sky_note: str
    geometry: DiscGeometry
    mask: BrightSideMask | None
    masked: np.ndarray  # (H, W) bool: pixels behind the bright-side mask

    @property
    def rate_e_s(self) -> np.ndarray:
        """Total photoelectron rate per pixel [e⁻ s⁻¹] (dark current excluded)."""
        return self.rates["moonshine"] + self.rates["earthshine"] + self.rates["sky"]

    @property
    def electrons(self) -> np.ndarray:
        """Expected charge per pixel and exposure [e⁻] (dark current included, before the full well)."""
        return expected_electrons(self.rate_e_s, self.instrument, self.exposure_s)

    @property
    def expected_counts(self) -> np.ndarray:
        return expected_counts(self.electrons, self.instrument)


def instrument_camera(inst: Instrument) -> Camera:
    """The pinhole camera of the instrument's detector, pointed at the Moon."""
    return Camera(fov_deg=inst.fov_deg, width=inst.width, height=inst.height, supersample=inst.supersample,
                  pointing="moon")


def optics_kernels(inst: Instrument, camera):
    pix_arcsec = float(np.degrees(camera.scale_rad)) * 3600.0
    shape = (camera.height, camera.width)
    return parse_psf(inst.psf, pix_arcsec, shape), parse_halo(inst.halo, pix_arcsec, shape)


def check_exposure(inst: Instrument, exposure_s: float | None) -> float:
    """The exposure [s]: ``exposure_s``, or the instrument's own; a one-line error outside
    [MIN_EXPOSURE_S, MAX_EXPOSURE_S] (the bounds of an instrument file's own exposure)."""
    try:
        if isinstance(exposure_s, (str, bool)):
            raise TypeError
        t = inst.exposure_s if exposure_s is None else float(exposure_s)
    except (TypeError, ValueError, OverflowError):
        raise LunarvizError(f"--exposure {str(exposure_s)[:40]!r} must be a number of seconds in "
                            f"[{MIN_EXPOSURE_S:g}, {MAX_EXPOSURE_S:g}]") from None
    if not (np.isfinite(t) and MIN_EXPOSURE_S <= t <= MAX_EXPOSURE_S):
        raise LunarvizError(f"--exposure {exposure_s!r} must be in [{MIN_EXPOSURE_S:g}, {MAX_EXPOSURE_S:g}] seconds")
    return t


def observe(res: ImageResult, geometry: SceneGeometry, brdf: str, inst: Instrument,
            exposure_s: float | None = None) -> Observation:
    """The noise-free observation by ``inst`` of the scene that ``res`` images.

    Parameters
    ----------
    res : ImageResult
        The image by :func:`instrument_camera` in the instrument's band and photon band
        (:func:`lunarviz.instrument.response.instrument_request`), above the atmosphere; its planes
        are passed through the optics here, in place.
    geometry : SceneGeometry
        The task's bodies and detector (the disc's geometry and the bright-side mask).
    brdf : str
        The lunar BRDF imaged (the planes' ``BRDF|BAND`` keys).
    inst : Instrument
        The instrument.
    exposure_s : float, optional
        Exposure [s] (default: the instrument's).

    Returns
    -------
    Observation
        Photoelectron rates per pixel [e⁻ s⁻¹] (raw and after optics, atmosphere and mask), the sky.
    """
    t = check_exposure(inst, exposure_s)
    camera = res.camera
    e_key = f"{brdf}|{photon_label(inst)}"
    omega = res.pixel_solid_angle
    raw = {c: electron_rate(res.planes[c][e_key], omega, inst) for c in ("moonshine", "earthshine")}
    psf, halo = optics_kernels(inst, camera)
    for comp in res.planes:
        for b in res.planes[comp]:
            res.planes[comp][b] = apply_optics(res.planes[comp][b], psf, halo)
    rates = {c: electron_rate(res.planes[c][e_key], omega, inst) for c in ("moonshine", "earthshine")}
    sky, note = None, "none (observer above the atmosphere)"
    altitude = res.info.get("moon_altitude_deg")
    if altitude is not None and inst.atmosphere is None:
        note = "none (the instrument file has no [atmosphere])"
    elif altitude is not None:
        atm = inst.atmosphere
        sky = site_sky(altitude, atm.extinction_mag_per_airmass, atm.dark_sky_mag_arcsec2)
        note = sky.model
    sky_rate = np.zeros_like(omega)
    if sky is not None:
        e_moon = sum(float(np.sum(raw[c])) for c in raw)  # [e⁻ s⁻¹] of the whole Moon above the atmosphere
        band = photon_band(inst)
        band_width = float(np.trapezoid(band.response, band.wavelength_nm))
        dark = electron_rate(np.full_like(omega, sky.dark_sky_radiance_w_m2_sr_nm * band_width), omega, inst)
        # scattered moonlight: L_sky = E_moon × ratio, in electrons: the Moon's electrons per unit
        # collecting area and solid angle → per pixel: e_moon × ratio × Ω_pixel
        sky_rate = dark + e_moon * sky.scattered_per_irradiance_sr * omega
        rates = {c: r * sky.transmission for c, r in rates.items()}
    rates["sky"] = sky_rate
    geom, mask, masked = masked_pixels(geometry, camera, inst.bright_side_nd, inst.margin_px())
    if mask is not None:  # a focal-plane filter: after the optics' halo, on every light alike
        rates = {c: np.where(masked, r * mask.transmission, r) for c, r in rates.items()}
    # the photon band is an internal plane: the image keeps the band's radiance planes only
    for comp in res.planes:
        res.planes[comp] = {b: v for b, v in res.planes[comp].items() if b != e_key}
    return Observation(inst, t, brdf, res, raw, rates, sky, note, geom, mask, masked)
