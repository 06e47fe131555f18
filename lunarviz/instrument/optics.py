"""The optics of a camera: PSF and scattered-light halo, applied to radiance planes.

PSF (``--psf``): ``none``; ``gaussian:FWHM_ARCSEC``; or a ``.npy`` kernel (2-D, odd sides, finite,
non-negative, at most the image's size; normalised to unit sum). The scattered-light wing
(``--halo FRACTION,INDEX[,CORE_ARCSEC]``) is a power law ``(1 + (r/r_c)²)^(-INDEX/2)`` (r the
angular distance, r_c the core radius, default one pixel) carrying FRACTION of the light; it is
tabulated out to the frame's diagonal and normalised there, so light it would throw farther is
not modelled. The total PSF is ``(1 - FRACTION)·core + FRACTION·(core ∗ halo)``. Convolutions
are FFT-based (scipy); light scattered off the frame leaves it (flux is conserved to the
extent the frame holds it).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from lunarviz.errors import LunarvizError


#: the largest image [pixels] a halo is convolved with: its kernel is (2H−1)×(2W−1), and its FFT
#: convolution takes ~450 bytes a pixel (1.8 GB at 2048², measured)
MAX_HALO_PIXELS = 2048 * 2048


def parse_psf(text: str | None, pixel_arcsec: float, shape) -> np.ndarray | None:
    """The PSF kernel (unit sum) for ``--psf``, or None."""
    if text is None or str(text).strip().lower() in ("", "none"):
        return None
    t = str(text).strip()
    if t.lower().startswith("gaussian:"):
        try:
            fwhm = float(t.split(":", 1)[1])
        except ValueError:
            raise LunarvizError(f"--psf {text!r}: use gaussian:FWHM_ARCSEC") from None
        if not (np.isfinite(fwhm) and fwhm > 0):
            raise LunarvizError(f"--psf {text!r}: the FWHM must be a positive number of arcseconds")
        sig = fwhm / pixel_arcsec / (2 * np.sqrt(2 * np.log(2)))
        half = int(np.ceil(5 * sig))
        if 2 * half + 1 > 2 * max(shape):
            raise LunarvizError(f"--psf {text!r}: wider than the image")
        y, x = np.ogrid[-half:half + 1, -half:half + 1]
        # (x/σ clipped, not /σ²: a tiny σ² underflows to 0/0; exp(-0.5·1e6) is 0 already)
        k = np.exp(-0.5 * (np.clip(x / sig, -1e3, 1e3) ** 2 + np.clip(y / sig, -1e3, 1e3) ** 2))
        return k / k.sum()
    p = Path(t)
    if not p.is_file():
        raise LunarvizError(f"--psf {text!r} is not none, gaussian:FWHM_ARCSEC or a .npy file")
    try:
        k = np.load(p, allow_pickle=False)
    except Exception as exc:
        raise LunarvizError(f"--psf {text!r}: unreadable ({type(exc).__name__})") from None
    if k.dtype.kind not in "fiu":
        raise LunarvizError(f"--psf {text!r}: kernel values of type {k.dtype} are not real numbers")
    if k.ndim != 2 or k.shape[0] % 2 == 0 or k.shape[1] % 2 == 0:
        raise LunarvizError(f"--psf {text!r}: kernel shape {k.shape} must be 2-D with odd sides")
    if k.shape[0] > shape[0] or k.shape[1] > shape[1]:
        raise LunarvizError(f"--psf {text!r}: kernel shape {k.shape} is larger than the image {tuple(shape)}")
    k = np.asarray(k, dtype=float)
    if not np.all(np.isfinite(k)) or np.any(k < 0) or k.max() <= 0:
        raise LunarvizError(f"--psf {text!r}: kernel values must be finite, non-negative, not all zero")
    k = k / k.max()  # (first: a kernel of 1e308s would sum to inf, one of 1e-320s lose its digits)
    return k / k.sum()


def parse_halo(text: str | None, pixel_arcsec: float, shape):
    """``(fraction, kernel)`` for ``--halo FRACTION,INDEX[,CORE_ARCSEC]``, or None."""
    if text is None or str(text).strip().lower() in ("", "none"):
        return None
    try:
        vals = [float(v) for v in str(text).split(",")]
    except ValueError:
        raise LunarvizError(f"--halo {text!r}: use FRACTION,INDEX[,CORE_ARCSEC]") from None
    if len(vals) not in (2, 3):
        raise LunarvizError(f"--halo {text!r}: use FRACTION,INDEX[,CORE_ARCSEC]")
    frac, index = vals[0], vals[1]
    core = vals[2] if len(vals) == 3 else pixel_arcsec
    if not (0 <= frac <= 1 and np.isfinite(index) and index > 0 and np.isfinite(core) and core > 0):
        raise LunarvizError(f"--halo {text!r}: need 0 ≤ FRACTION ≤ 1, INDEX > 0, CORE_ARCSEC > 0")
    H, W = shape
    if H * W > MAX_HALO_PIXELS:
        raise LunarvizError(f"--halo on {W}x{H} pixels: its kernel spans the image twice over (about "
                            f"{H * W * 450 / 2**30:.0f} GiB to convolve); at most {MAX_HALO_PIXELS} pixels")
    y, x = np.ogrid[-(H - 1):H, -(W - 1):W]
    r = np.hypot(x, y) * pixel_arcsec
    k = (1.0 + (r / core) ** 2) ** (-index / 2)
    return frac, k / k.sum()


def apply_optics(plane: np.ndarray, psf, halo) -> np.ndarray:
    """``plane`` through the PSF and the halo (FFT convolutions; unchanged without either)."""
    from scipy.signal import fftconvolve  # (scipy.signal: loaded where an image is convolved)
    out = plane
    if psf is not None:
        out = fftconvolve(out, psf, mode="same")
    if halo is not None:
        frac, k = halo
        out = (1 - frac) * out + frac * fftconvolve(out, k, mode="same")
    return np.clip(out, 0.0, None) if (psf is not None or halo is not None) else out
