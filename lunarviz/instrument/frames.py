"""Frames in counts in FITS: ``EXPECTED_COUNTS`` (noise-free, ADU, 2-D) and ``COUNTS`` (ADU, N frames),
appended to an image file written by :func:`lunarviz.outputs.images.write_fits`.

Both carry the detector's keywords (``GAIN`` [e⁻/ADU], ``RDNOISE`` [e⁻], ``EXPTIME`` [s],
``DARKCUR`` [e⁻ s⁻¹ pixel⁻¹], ``BIASLEV`` [ADU], ``SATURATE`` [ADU]), the frames' provenance
(``INSTRUME``, ``NFRAMES``, ``SEED``, the sky model, the bright-side mask) and, as long strings,
the settings, the instrument and the key that :func:`read_frames` (and ``lunarviz measure``) need
to model the observation again. ``COUNTS`` is streamed: one frame in memory at a time.
"""

from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np

from lunarviz.errors import LunarvizError
from lunarviz.instrument.detector import count_dtype
from lunarviz.instrument.detector import frames as draw_frames
from lunarviz.outputs.images import fits_text, tan_wcs

#: BZERO of unsigned integer counts stored as FITS signed integers
_BZERO = {16: 32768, 32: 2147483648}


def _detector_cards(hdr, obs) -> None:
    inst = obs.instrument
    for k, v, note in (("BUNIT", "adu", "detector counts"),
                       ("INSTRUME", fits_text(inst.name), "lunarviz instrument"),
                       ("GAIN", inst.gain_e_per_adu, "[e-/ADU]"),
                       ("RDNOISE", inst.read_noise_e, "[e-] read noise"),
                       ("EXPTIME", obs.exposure_s, "[s] exposure time"),
                       ("DARKCUR", inst.dark_current_e_per_s, "[e- s-1 pixel-1] dark current"),
                       ("BIASLEV", inst.bias_adu, "[ADU] bias level"),
                       ("SATURATE", inst.saturate_adu, "[ADU] full well or ADC top"),
                       ("FULLWELL", inst.full_well_e, "[e-] full well"),
                       ("BAND", fits_text(inst.band, 40), "spectral response"),
                       ("BRDF", obs.brdf, "lunar BRDF of the scene"),
                       ("SKYMODEL", obs.sky_note[:68], "sky and extinction"),
                       ("EXTINCT", obs.sky.transmission if obs.sky else 1.0, "atmospheric transmission on the Moon"),
                       ("MASKTAU", obs.mask.transmission if obs.mask else 1.0, "bright-side ND transmission"),
                       ("MASKEDGE", obs.mask.edge_along if obs.mask else 0.0, "[radii] mask edge along the Sun")):
        hdr[k] = (v, note)


def _tan_cards(hdr, res) -> None:
    tan_wcs(hdr, res, float(np.degrees(res.camera.scale_rad)))


def append_counts(path, obs, key, settings_json: str, frames: int, seed: int) -> None:
    """Append ``EXPECTED_COUNTS`` and ``frames`` noisy ``COUNTS`` frames to the FITS file ``path``."""
    from astropy.io import fits

    inst = obs.instrument
    exp = fits.ImageHDU(obs.expected_counts.astype(np.float64), name="EXPECTED_COUNTS")
    _detector_cards(exp.header, obs)
    _tan_cards(exp.header, obs.image)
    exp.header["LVKEY"] = (str(key), "phase theta [deg] or UTC time of the scene")
    exp.header["LVSETTNG"] = settings_json
    exp.header["LVINSTR"] = inst.to_json()
    path = str(path)  # astropy names a file by its text (a Path is not always recognised)
    fits.append(path, exp.data, exp.header)
    bits = 16 if count_dtype(inst) == np.uint16 else 32
    hdr = fits.Header()
    hdr["XTENSION"] = "IMAGE"
    hdr["BITPIX"] = bits
    hdr["NAXIS"] = 3
    hdr["NAXIS1"] = inst.width
    hdr["NAXIS2"] = inst.height
    hdr["NAXIS3"] = frames
    hdr["PCOUNT"] = 0
    hdr["GCOUNT"] = 1
    hdr["BSCALE"] = 1
    hdr["BZERO"] = _BZERO[bits]
    hdr["EXTNAME"] = "COUNTS"
    _detector_cards(hdr, obs)
    hdr["NFRAMES"] = (frames, "frames in the cube")
    hdr["SEED"] = (seed, "frame k drawn from numpy default_rng([SEED, k])")
    stream = fits.StreamingHDU(path, hdr)
    signed = np.dtype(f">i{bits // 8}")
    try:
        for f in draw_frames(obs.electrons, inst, frames, seed):
            stream.write((f.astype(np.int64) - _BZERO[bits]).astype(signed))
    finally:
        stream.close()


@dataclass
class Frames:
    """What :func:`read_frames` returns: the counts, their detector and how to model them again."""

    counts: np.ndarray | None  # (N, H, W) ADU, or None (noise-free file read as EXPECTED_COUNTS)
    expected: np.ndarray  # (H, W) ADU
    header: dict
    settings: dict
    instrument: dict
    key: str
    #: the COUNTS extension's header (None when only EXPECTED_COUNTS is read)
    counts_header: dict | None = None


#: the largest image or cube of frames read [bytes]: a file beyond it holds more frames than a
#: measurement averages (write fewer per file)
MAX_FRAMES_BYTES = 2 << 30


def _check_size(path, header) -> None:
    """Refuse an extension whose data (from its header, before reading) exceed MAX_FRAMES_BYTES."""
    try:
        n = abs(int(header.get("BITPIX", 8))) // 8
        for k in range(1, int(header.get("NAXIS", 0)) + 1):
            n *= int(header.get(f"NAXIS{k}", 0))
    except (TypeError, ValueError):
        raise LunarvizError(f"{str(path)!r}: its NAXIS or BITPIX cards are damaged") from None
    if n > MAX_FRAMES_BYTES:
        raise LunarvizError(f"{str(path)!r}: {header.get('EXTNAME', 'an extension')} holds {n / 2**30:.1f} GiB "
                            f"(at most {MAX_FRAMES_BYTES / 2**30:g} GiB are read): write fewer frames per file")


def read_frames(path, use_expected: bool = False) -> Frames:
    """The counts of a ``lunarviz image --instrument`` FITS file (``use_expected``: the noise-free plane)."""
    from pathlib import Path

    from astropy.io import fits
    p = Path(path)
    if not p.is_file():
        raise LunarvizError(f"{str(path)!r} is not a file")
    with open(p, "rb") as f:
        magic = f.read(4)
    if magic[:2] == b"\x1f\x8b" or magic[:3] == b"BZh" or magic[:4] == b"PK\x03\x04":
        raise LunarvizError(f"{str(path)!r} is compressed: decompress it first (its size is then known before "
                            f"it is read)")
    import warnings
    try:
        # (our own file object: astropy leaves its own open when a damaged file makes it raise)
        with warnings.catch_warnings(), open(p, "rb") as fobj, fits.open(fobj, memmap=False, lazy_load_hdus=True) \
                as hdul:
            warnings.simplefilter("ignore")  # a damaged file's warnings: the one-line error below says it
            names = [h.name for h in hdul]
            if "EXPECTED_COUNTS" not in names:
                raise LunarvizError(f"{str(path)!r} has no EXPECTED_COUNTS extension (write it with "
                                    f"lunarviz image --instrument)")
            eh = hdul["EXPECTED_COUNTS"]
            hdr = dict(eh.header)
            _check_size(path, eh.header)
            expected = np.asarray(eh.data, dtype=float)
            counts, counts_hdr = None, None
            if not use_expected:
                if "COUNTS" not in names:
                    raise LunarvizError(f"{str(path)!r} has no COUNTS extension")
                _check_size(path, hdul["COUNTS"].header)
                counts = np.asarray(hdul["COUNTS"].data)
                counts_hdr = dict(hdul["COUNTS"].header)
    except LunarvizError:
        raise
    except Exception as exc:  # astropy raises many types on a damaged file
        raise LunarvizError(f"{str(path)!r} is not a readable FITS file ({type(exc).__name__}: {exc})") from None
    try:
        settings_text, instrument_text, key = hdr["LVSETTNG"], hdr["LVINSTR"], str(hdr["LVKEY"])
    except KeyError:
        raise LunarvizError(f"{str(path)!r}: EXPECTED_COUNTS lacks the LVSETTNG/LVINSTR/LVKEY cards") from None
    try:
        settings, instrument = json.loads(settings_text), json.loads(instrument_text)
    except (TypeError, ValueError, RecursionError):
        raise LunarvizError(f"{str(path)!r}: the LVSETTNG or LVINSTR card is not readable JSON (damaged)") from None
    if not (isinstance(settings, dict) and isinstance(instrument, dict)):
        raise LunarvizError(f"{str(path)!r}: the LVSETTNG or LVINSTR card is not a table")
    if expected.ndim != 2 or expected.size == 0:
        raise LunarvizError(f"{str(path)!r}: EXPECTED_COUNTS of shape {expected.shape} is not an image")
    if counts is not None and counts.ndim == 3 and counts.shape[0] == 0:
        raise LunarvizError(f"{str(path)!r}: COUNTS holds no frames")
    if counts is not None and (counts.ndim != 3 or counts.shape[1:] != expected.shape):
        raise LunarvizError(f"{str(path)!r}: COUNTS of shape {counts.shape} does not match {expected.shape}")
    return Frames(counts, expected, hdr, settings, instrument, key, counts_hdr)
