"""An earthshine instrument: optics, band, detector and (for a ground telescope) its sky, read from
a small TOML file.

``--instrument salex|bbso|FILE.toml``. Keys (units in the names; every one documented here):

==============================  ===================================================================
``name``, ``description``,      text; ``source`` says where the values come from (or that they are
``source``                      assumptions)
``aperture_m``                  entrance pupil diameter [m]
``central_obstruction_m``       diameter of a central obstruction [m] (0 for a refractor)
``focal_length_m``              effective focal length [m]; or ``pixel_scale_arcsec`` instead
``pixel_size_um``               detector pixel pitch [µm]
``width``, ``height``           detector format [pixels]
``band``                        the spectral response: any ``--band`` (``V``, ``S2A-B4``, ``LO-HI``,
                                a CSV file)
``optics_transmission``         the optics' throughput: a number, or ``[[nm, T], ...]``
``quantum_efficiency``          the detector's QE: a number, or ``[[nm, QE], ...]``
``gain_e_per_adu``              [e⁻ ADU⁻¹]
``read_noise_e``                [e⁻ rms per read]
``dark_current_e_per_s``        [e⁻ s⁻¹ pixel⁻¹]
``bias_adu``                    [ADU]
``full_well_e``                 [e⁻]: a pixel holds no more charge
``bit_depth``                   ADC bits: counts lie in 0 … 2^bits − 1
``psf``, ``halo``               as ``lunarviz image --psf``/``--halo`` (arcsec)
``exposure_s``                  default exposure [s]
``supersample``                 rays per pixel side of the synthetic image (default 2)
``bright_side_nd``              transmission of a focal-plane neutral-density half-plane over the
                                sunlit side (1: none); placed each pointing just short of the
                                terminator (:mod:`lunarviz.instrument.disc`)
``bright_side_nd_sigma``        its calibration's relative standard uncertainty
``band_centre_sigma_nm``        standard uncertainty of the band's centre [nm] (default 1)
``[atmosphere]``                a ground telescope's site, used when the observer is a ground site:
                                ``extinction_mag_per_airmass``, ``dark_sky_mag_arcsec2`` (band's)
==============================  ===================================================================

Tables are linear between their rows and zero outside; a band reaching outside a table's range is
refused. Unknown keys are refused (a typo would otherwise be a silent default).
"""

from __future__ import annotations

import json
import re
import tomllib
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from lunarviz.errors import LunarvizError, any_case, did_you_mean, short_repr
from lunarviz.resources import DATA_DIR
from lunarviz.spectral.bands import parse_band

INSTRUMENT_DIR = DATA_DIR / "instruments"
#: arcseconds per radian
ARCSEC_PER_RAD = 180.0 / np.pi * 3600.0
#: the largest accepted instrument file [bytes]
MAX_FILE_BYTES = 1_000_000


@dataclass(frozen=True)
class Atmosphere:
    """A ground site's atmosphere in the instrument's band."""

    extinction_mag_per_airmass: float = 0.2
    dark_sky_mag_arcsec2: float = 21.0


@dataclass(frozen=True)
class Instrument:
    """An imager; see the module docstring for every field's meaning and unit."""

    name: str
    aperture_m: float
    pixel_size_um: float
    width: int
    height: int
    band: str
    gain_e_per_adu: float
    read_noise_e: float
    dark_current_e_per_s: float
    bias_adu: float
    full_well_e: float
    bit_depth: int
    exposure_s: float
    focal_length_m: float = 0.0
    pixel_scale_arcsec: float = 0.0
    central_obstruction_m: float = 0.0
    optics_transmission: object = 1.0
    quantum_efficiency: object = 1.0
    psf: str = "none"
    halo: str = "none"
    supersample: int = 2
    bright_side_nd: float = 1.0
    bright_side_nd_sigma: float = 0.0
    band_centre_sigma_nm: float = 1.0
    description: str = ""
    source: str = ""
    atmosphere: Atmosphere | None = field(default=None)

    @property
    def collecting_area_m2(self) -> float:
        """π/4 (D² − d²) [m²]."""
        return float(np.pi / 4 * (self.aperture_m**2 - self.central_obstruction_m**2))

    @property
    def scale_arcsec(self) -> float:
        """Pixel scale [arcsec per pixel]."""
        if self.pixel_scale_arcsec > 0:
            return float(self.pixel_scale_arcsec)
        return float(self.pixel_size_um * 1e-6 / self.focal_length_m * ARCSEC_PER_RAD)

    @property
    def fov_deg(self) -> float:
        """Field of view across the detector's width [deg] (a pinhole camera: 2 atan(W s / 2))."""
        half = self.width * self.scale_arcsec / ARCSEC_PER_RAD / 2
        return float(np.degrees(2 * np.arctan(half)))

    @property
    def adc_max(self) -> int:
        return int(2**self.bit_depth - 1)

    @property
    def saturate_adu(self) -> float:
        """The highest meaningful count [ADU]: the full well or the ADC's top, whichever is lower."""
        return float(min(self.bias_adu + self.full_well_e / self.gain_e_per_adu, self.adc_max))

    def margin_px(self) -> float:
        """Pixels kept clear of the limb, the terminator and the mask's edge: three PSF widths
        (FWHM of a ``gaussian:`` PSF, or the kernel's half-size) plus three pixels."""
        psf = self.psf.strip().lower()
        if psf.startswith("gaussian:"):
            return 3.0 * float(psf.split(":", 1)[1]) / self.scale_arcsec + 3.0
        if psf in ("", "none"):
            return 3.0
        return float(np.load(self.psf).shape[0] // 2) + 3.0

    def throughput(self, wavelength_nm) -> np.ndarray:
        """Optics transmission × QE at ``wavelength_nm``."""
        return _curve(self.optics_transmission, wavelength_nm) * _curve(self.quantum_efficiency, wavelength_nm)

    def to_dict(self) -> dict:
        """The TOML table of this instrument (:func:`instrument_from_dict` reads it back)."""
        d = asdict(self)
        if d["atmosphere"] is None:
            del d["atmosphere"]
        return d

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), separators=(",", ":"))


def _curve(spec, wavelength_nm) -> np.ndarray:
    lam = np.asarray(wavelength_nm, dtype=float)
    if np.isscalar(spec) or np.ndim(spec) == 0:
        return np.full_like(lam, float(spec))
    t = np.asarray(spec, dtype=float)
    return np.interp(lam, t[:, 0], t[:, 1], left=0.0, right=0.0)


_POSITIVE = ("aperture_m", "pixel_size_um", "gain_e_per_adu", "full_well_e", "exposure_s")
_NON_NEGATIVE = ("read_noise_e", "dark_current_e_per_s", "bias_adu", "central_obstruction_m", "focal_length_m",
                 "pixel_scale_arcsec", "bright_side_nd", "bright_side_nd_sigma", "band_centre_sigma_nm")
_INTEGER = {"width": (8, 4096), "height": (8, 4096), "bit_depth": (8, 32), "supersample": (1, 16)}
_TEXT = ("name", "band", "psf", "halo", "description", "source")
#: an instrument's name: ASCII letters, digits, spaces and ._+-, not a path (no "/", "\\" or "..")
_NAME = re.compile(r"(?!.*\.\.)[A-Za-z0-9][A-Za-z0-9 ._+-]{0,39}")
_CURVES = ("optics_transmission", "quantum_efficiency")


def _check_curve(where: str, key: str, v):
    if isinstance(v, bool):
        raise LunarvizError(f"{where}: {key} = {v!r} is not a number or a [[nm, value], ...] table")
    if isinstance(v, (int, float)):
        if not (0 < v <= 1):
            raise LunarvizError(f"{where}: {key} = {short_repr(v)} must be in (0, 1]")
        return float(v)
    try:
        t = np.asarray(v, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise LunarvizError(f"{where}: {key} is not a number or a [[nm, value], ...] table") from None
    if t.ndim != 2 or t.shape[1] != 2 or len(t) < 2:
        raise LunarvizError(f"{where}: {key} table must be [[nm, value], ...] with at least two rows")
    if not np.all(np.isfinite(t)) or np.any(np.diff(t[:, 0]) <= 0) or np.any(t[:, 1] < 0) or np.any(t[:, 1] > 1):
        raise LunarvizError(f"{where}: {key} table needs increasing wavelengths and values in [0, 1]")
    if not np.any(t[:, 1] > 0):
        raise LunarvizError(f"{where}: {key} table is zero everywhere")
    return [[float(a), float(b)] for a, b in t]


#: the largest accepted value of each number (beyond them no instrument, and float trouble)
_UPPER = {"aperture_m": 50.0, "central_obstruction_m": 50.0, "focal_length_m": 1000.0, "pixel_size_um": 1000.0,
          "pixel_scale_arcsec": 3600.0, "gain_e_per_adu": 1e6, "read_noise_e": 1e4, "dark_current_e_per_s": 1e6,
          "bias_adu": 2.0**32, "full_well_e": 1e9, "exposure_s": 1e5, "bright_side_nd": 1.0,
          "bright_side_nd_sigma": 1.0, "band_centre_sigma_nm": 100.0}


#: the smallest accepted value of the positive numbers (below them, rounding rather than physics)
_LOWER = {"aperture_m": 1e-3, "pixel_size_um": 0.1, "gain_e_per_adu": 1e-3, "full_well_e": 1.0, "exposure_s": 1e-6}


#: the exposures [s] an instrument file, ``image`` and ``measure`` accept
MIN_EXPOSURE_S, MAX_EXPOSURE_S = _LOWER["exposure_s"], _UPPER["exposure_s"]


def _check_number(where: str, key: str, v, positive: bool) -> float:
    hi, lo = _UPPER.get(key, np.inf), _LOWER.get(key, 0.0)
    try:
        x = float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else np.nan
    except OverflowError:  # (an integer of 400 digits)
        x = np.inf
    if not np.isfinite(x) or x < 0 or (positive and x == 0) or x > hi or x < lo:
        raise LunarvizError(f"{where}: {key} = {short_repr(v)} must be a {'positive' if positive else 'non-negative'} "
                            f"number from {lo:g} to {hi:g}")
    return x


def instrument_from_dict(d: dict, where: str = "instrument") -> Instrument:
    """An :class:`Instrument` from a TOML table, every value checked (one-line errors naming it)."""
    known = set(Instrument.__dataclass_fields__)
    unknown = sorted(set(d) - known)
    if unknown:
        raise LunarvizError(f"{where}: unknown key {unknown[0]!r} (see lunarviz.instrument.spec)")
    missing = [k for k in ("name",) + _POSITIVE + ("width", "height", "band", "read_noise_e", "dark_current_e_per_s",
                                                 "bias_adu", "bit_depth") if k not in d]
    if missing:
        raise LunarvizError(f"{where}: missing key {missing[0]!r}")
    kw: dict = {}
    for k, v in d.items():
        if k in _POSITIVE or k in _NON_NEGATIVE:
            kw[k] = _check_number(where, k, v, k in _POSITIVE)
        elif k in _INTEGER:
            lo, hi = _INTEGER[k]
            if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
                raise LunarvizError(f"{where}: {k} = {v!r} must be an integer from {lo} to {hi}")
            kw[k] = v
        elif k in _TEXT:
            if not isinstance(v, str):
                raise LunarvizError(f"{where}: {k} = {v!r} must be text")
            if k == "name" and not _NAME.fullmatch(v):
                raise LunarvizError(f"{where}: name = {v!r} must be 1-40 ASCII letters, digits, spaces or ._+- "
                                    f"(it names files and FITS cards)")
            kw[k] = v
        elif k in _CURVES:
            kw[k] = _check_curve(where, k, v)
        elif k == "atmosphere":
            kw[k] = _atmosphere(where, v)
    if not (kw.get("focal_length_m", 0) > 0) ^ (kw.get("pixel_scale_arcsec", 0) > 0):
        raise LunarvizError(f"{where}: give focal_length_m or pixel_scale_arcsec (one of them, positive)")
    if kw.get("central_obstruction_m", 0.0) >= kw["aperture_m"]:
        raise LunarvizError(f"{where}: central_obstruction_m = {kw['central_obstruction_m']!r} must be smaller than "
                            f"the aperture")
    if not (0 < kw.get("bright_side_nd", 1.0) and kw.get("bright_side_nd_sigma", 0.0) < 1):
        raise LunarvizError(f"{where}: need 0 < bright_side_nd ≤ 1 and bright_side_nd_sigma < 1 (got "
                            f"{kw.get('bright_side_nd', 1.0)!r}, {kw.get('bright_side_nd_sigma', 0.0)!r})")
    inst = Instrument(**kw)
    if inst.fov_deg >= 20:
        raise LunarvizError(f"{where}: a field of {inst.fov_deg:.3g} deg is not an earthshine imager's (< 20 deg)")
    if inst.bias_adu + 6 * inst.read_noise_e / inst.gain_e_per_adu > inst.adc_max:
        raise LunarvizError(f"{where}: bias_adu = {inst.bias_adu!r} leaves no room below the ADC's {inst.adc_max}")
    from lunarviz.instrument.optics import parse_halo, parse_psf
    try:
        band = parse_band(inst.band)
    except LunarvizError as exc:
        raise LunarvizError(f"{where}: band: {exc}") from None
    try:
        parse_psf(inst.psf, inst.scale_arcsec, (inst.height, inst.width))
        halo = parse_halo(inst.halo, inst.scale_arcsec, (inst.height, inst.width))
    except LunarvizError as exc:
        raise LunarvizError(f"{where}: {str(exc).replace('--psf', 'psf').replace('--halo', 'halo')}") from None
    if halo is not None and halo[0] >= 0.5:
        raise LunarvizError(f"{where}: halo {inst.halo!r} puts {halo[0]:g} of the light in the wing (< 0.5 expected)")
    lo, hi = band.support
    for k in _CURVES:
        v = getattr(inst, k)
        if isinstance(v, list) and (v[0][0] > lo or v[-1][0] < hi):
            raise LunarvizError(f"{where}: the {k} table ({v[0][0]:g}-{v[-1][0]:g} nm) does not cover the band "
                                f"{inst.band!r} ({lo:g}-{hi:g} nm)")
    lam = np.linspace(lo, hi, 512)
    if not np.any(band.at(lam) * inst.throughput(lam) > 0):
        raise LunarvizError(f"{where}: the optics and the quantum efficiency pass no light in the band {inst.band!r}")
    return inst


def _atmosphere(where: str, v) -> Atmosphere:
    if not isinstance(v, dict):
        raise LunarvizError(f"{where}: [atmosphere] must be a table")
    unknown = sorted(set(v) - set(Atmosphere.__dataclass_fields__))
    if unknown:
        raise LunarvizError(f"{where}: unknown key atmosphere.{unknown[0]}")
    k = _check_number(where, "atmosphere.extinction_mag_per_airmass", v.get("extinction_mag_per_airmass", 0.2), False)
    m = _check_number(where, "atmosphere.dark_sky_mag_arcsec2", v.get("dark_sky_mag_arcsec2", 21.0), True)
    if k > 5 or not 10 <= m <= 30:
        raise LunarvizError(f"{where}: atmosphere values out of range (extinction ≤ 5 mag/airmass, dark sky "
                            f"10-30 mag/arcsec²): {k!r}, {m!r}")
    return Atmosphere(k, m)


def packaged_instruments() -> dict[str, Path]:
    """``{name: file}`` of the presets in ``lunarviz/data/instruments``."""
    return {p.stem: p for p in sorted(INSTRUMENT_DIR.glob("*.toml"))}


def instrument_spec_text(spec) -> str | None:
    """What :func:`load_instrument` takes again for ``spec``: a preset's name, a file's absolute
    path (None for an :class:`Instrument` built in Python)."""
    if isinstance(spec, Instrument):
        return None
    text = str(spec).strip()
    return any_case(text, packaged_instruments()) or str(Path(text).resolve())


def load_instrument(spec) -> Instrument:
    """``salex``, ``bbso``, a ``.toml`` file, or an :class:`Instrument` (returned as is)."""
    if isinstance(spec, Instrument):
        return spec
    text = str(spec).strip()
    presets = packaged_instruments()
    preset = any_case(text, presets)
    path = presets[preset] if preset is not None else Path(text)
    if preset is None and path.suffix.lower() != ".toml":
        raise LunarvizError(f"instrument {text!r}{did_you_mean(text, presets)} is not {', '.join(presets)} or a "
                            ".toml file")
    if not path.is_file():
        raise LunarvizError(f"instrument {text!r}: no such file")
    if path.stat().st_size > MAX_FILE_BYTES:
        raise LunarvizError(f"instrument {text!r}: larger than {MAX_FILE_BYTES} bytes")
    try:
        d = tomllib.loads(path.read_text(encoding="utf-8"))
    except RecursionError:
        raise LunarvizError(f"instrument {text!r}: nested too deep to be an instrument file") from None
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise LunarvizError(f"instrument {text!r}: not readable TOML ({exc})") from None
    return instrument_from_dict(d, f"instrument {text!r}")
