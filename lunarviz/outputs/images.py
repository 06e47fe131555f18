"""Files of synthetic images: FITS (one HDU per plane, TAN WCS), NPY and PNG.

The optics a camera adds (PSF, halo) are :mod:`lunarviz.instrument.optics`.
"""

from __future__ import annotations

import json

import numpy as np

from lunarviz.errors import LunarvizError
from lunarviz.outputs.writers import atomic_path, write_bytes_atomic
from lunarviz.parsing import wavelength_label

BUNIT = "W m-2 sr-1"


def plane_key(brdf: str, label) -> str:
    """``BRDF|LABEL``: a band's name, or a wavelength to 12 significant digits."""
    return f"{brdf}|{wavelength_label(label)}" if isinstance(label, float) else f"{brdf}|{label}"


def fits_text(value, size: int = 68) -> str:
    """``value`` as a FITS card's text: printable ASCII (other characters as ``?``, control
    characters as spaces), at most ``size`` characters (a band file's name may be ``bändé.csv``)."""
    text = "".join(c if " " <= c <= "~" else (" " if ord(c) < 32 or ord(c) == 127 else "?") for c in str(value))
    return text[:size]


def plane_names(planes: dict) -> list[tuple[str, str, str]]:
    """``(EXTNAME, component, key)`` in file order; one BRDF keeps the bare names. A spectral
    plane's key ``BRDF|LABEL`` (a band, or a wavelength in nm) adds the label:
    ``MOONSHINE_DHG_V``, ``EARTHSHINE_550NM``."""
    keys = list(planes["moonshine"])
    brdfs = list(dict.fromkeys(k.split("|")[0] for k in keys))
    out = []
    for k in keys:
        b, _, label = k.partition("|")
        if label and label.replace(".", "").isdigit():
            label += "NM"
        for comp in ("moonshine", "earthshine"):
            parts = [comp.upper()] + ([] if len(brdfs) == 1 else [b.upper()]) + ([label.upper()] if label else [])
            out.append((fits_text("_".join(parts)).replace(" ", "_"), comp, k))
    return out


def write_fits(path, res, planes, extra: dict) -> None:
    from astropy.io import fits

    cam = res.camera
    scale_deg = float(np.degrees(cam.scale_rad))
    prim = fits.PrimaryHDU()
    hdr = prim.header
    hdr["ORIGIN"] = "lunarviz"
    for k, v, note in (("DATE-OBS", res.info.get("time_utc"), "UTC of the scene"),
                       ("OBSERVER", res.info.get("observer"), "observer (geocentre, site, TLE, orbit)"),
                       ("THETA", res.info.get("theta_deg"), "[deg] orbital angle theta (paper Eq. 3)"),
                       ("PHASEANG", res.info.get("alpha_deg"), "[deg] Sun-Moon-observer angle"),
                       ("BETA", res.info.get("beta_deg"), "[deg] Sun-Earth-Moon angle"),
                       ("FOV", cam.fov_deg, "[deg] field of view across the width"),
                       ("SUPERSAM", cam.supersample, "K: K x K rays per pixel"),
                       ("POINTING", cam.pointing, "moon or RA,DEC [deg]"),
                       ("MOON_RA", res.info["moon_ra_deg"], "[deg] Moon centre right ascension"),
                       ("MOON_DEC", res.info["moon_dec_deg"], "[deg] Moon centre declination"),
                       ("LITFRAC", res.lit_fraction, "sunlit fraction of the Moon's disc"),
                       ("PSF", extra.get("psf") or "none", "point-spread function"),
                       ("HALO", extra.get("halo") or "none", "scattered-light wing")):
        if v is not None:
            hdr[k] = (v, note)
    hdr["FRAME"] = res.info["frame"][:68]
    hdr["COMMENT"] = "lunarviz synthetic image: radiance planes per component, pinhole TAN camera at the detector"
    hdr["COMMENT"] = "settings: " + json.dumps(extra.get("settings", {}))[:2000]
    hdus = [prim]
    if res.info.get("spectral") == "wavelength":
        hdus += _cubes(res, planes, scale_deg)
        with atomic_path(path) as tmp:
            fits.HDUList(hdus).writeto(tmp, overwrite=True)
        return
    for ext, comp, key in plane_names(planes):
        b, _, label = key.partition("|")
        h = fits.ImageHDU(np.asarray(planes[comp][key], dtype=np.float64), name=ext)
        hh = h.header
        hh["BUNIT"] = res.info.get("bunit", BUNIT)
        hh["BRDF"] = b
        if label:
            hh["BAND"] = (fits_text(label, 40), "integral of L(lambda) S(lambda) dlambda")
        hh["LIGHT"] = (comp, "moonshine or earthshine")
        tan_wcs(hh, res, scale_deg)
        hh["INTEGRAT"] = (float(np.sum(planes[comp][key] * res.pixel_solid_angle)),
                          f"sum L*Omega [{hh['BUNIT'].replace(' sr-1', '')}]")
        hdus.append(h)
    with atomic_path(path) as tmp:
        fits.HDUList(hdus).writeto(tmp, overwrite=True)


def tan_wcs(hh, res, scale_deg: float, axes: int = 2) -> None:
    """The image axes' TAN WCS (axes 1, 2) in header ``hh``."""
    cam = res.camera
    H, W = cam.height, cam.width
    hh["WCSAXES"] = axes
    hh["CTYPE1"], hh["CTYPE2"] = "RA---TAN", "DEC--TAN"
    hh["CUNIT1"], hh["CUNIT2"] = "deg", "deg"
    hh["CRPIX1"], hh["CRPIX2"] = (W + 1) / 2.0, (H + 1) / 2.0
    hh["CRVAL1"], hh["CRVAL2"] = res.info["boresight_ra_deg"], res.info["boresight_dec_deg"]
    hh["CDELT1"], hh["CDELT2"] = -scale_deg, scale_deg
    hh["RADESYS"] = "ICRS"


def _cubes(res, planes, scale_deg: float) -> list:
    """One cube per component and BRDF (wavelength, row, column), radiance per nm, with a
    linear spectral axis WAVE [nm] (the wavelengths must be evenly spaced: refused before any
    work, :func:`check_cube_wavelengths`)."""
    from astropy.io import fits

    lam = np.asarray(res.info["spectral_labels"], dtype=float)
    keys = list(planes["moonshine"])
    brdfs = list(dict.fromkeys(k.split("|")[0] for k in keys))
    out = []
    for b in brdfs:
        for comp in ("moonshine", "earthshine"):
            cube = np.stack([planes[comp][plane_key(b, float(x))] for x in lam]).astype(np.float64)
            h = fits.ImageHDU(cube, name=comp.upper() if len(brdfs) == 1 else f"{comp.upper()}_{b.upper()}")
            hh = h.header
            hh["BUNIT"] = res.info.get("bunit")
            hh["BRDF"] = b
            hh["LIGHT"] = (comp, "moonshine or earthshine")
            tan_wcs(hh, res, scale_deg, axes=3)
            hh["CTYPE3"], hh["CUNIT3"] = "WAVE", "nm"
            hh["CRPIX3"], hh["CRVAL3"] = 1.0, float(lam[0])
            hh["CDELT3"] = float(lam[1] - lam[0]) if len(lam) > 1 else 1.0
            hh["SPECSYS"] = "TOPOCENT"
            out.append(h)
    return out


def check_cube_wavelengths(wavelengths) -> None:
    """A FITS cube's spectral axis is linear: wavelengths must be evenly spaced and increasing."""
    lam = np.asarray(wavelengths, dtype=float)
    if len(lam) > 1 and (np.any(np.diff(lam) <= 0) or np.ptp(np.diff(lam)) > 1e-9 * lam[-1]):
        raise LunarvizError(f"a FITS image cube needs evenly spaced, increasing wavelengths (START:STOP:STEP); "
                            f"got {', '.join(f'{x:g}' for x in lam[:6])}{' …' if len(lam) > 6 else ''}")


def write_npy(path, planes) -> None:
    import io

    buf = io.BytesIO()
    np.save(buf, np.stack([planes[c][b] for _, c, b in plane_names(planes)]))
    write_bytes_atomic(path, buf.getvalue())


def colour_planes(res, planes) -> tuple[str, list[int]] | None:
    """``(brdf, [indices of the three bands, reddest first])`` when an image holds exactly three
    bands (red, green, blue by their response-weighted mean wavelength, whatever the order on the
    command line), else ``None``."""
    if res.info.get("spectral") != "band" or len(res.info.get("spectral_labels", [])) != 3:
        return None
    b = next(iter(planes["moonshine"])).split("|")[0]
    return b, sorted(range(3), key=lambda i: -res.info["spectral_centres_nm"][i])


def write_colour_png(path, res, planes, title: str = "") -> None:
    """Three bands as red, green, blue: the sunlit Moon (moonshine) and the earthlit Moon
    (earthshine) side by side, each white-balanced to the Sun (a band's radiance over the Sun's
    irradiance in that band: a grey surface lit by the Sun is grey) and scaled to its own
    brightest band, so the colours of the two lights compare while their brightness (10⁻⁴
    apart) does not."""
    import io

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    b, order = colour_planes(res, planes)
    labels = [res.info["spectral_labels"][i] for i in order]
    keys = [f"{b}|{lab}" for lab in labels]
    sun = np.asarray(res.info["spectral_solar_1au"], dtype=float)[order]
    fig, ax = plt.subplots(1, 2, figsize=(10, 5.2))
    for a, comp, name in ((ax[0], "moonshine", "sunlit Moon (moonshine)"),
                          (ax[1], "earthshine", "earthlit Moon (earthshine)")):
        rgb = np.stack([planes[comp][k] / s for k, s in zip(keys, sun)], axis=-1)
        top = 1.15 * float(rgb.max()) if (rgb > 0).any() else 1.0  # headroom: the colour stays visible
        a.imshow(np.clip(rgb / max(top, 1e-300), 0.0, 1.0) ** (1 / 2.2), origin="lower")
        a.set_title(f"{name}, {b}", fontsize=9)
        a.set_xticks([])
        a.set_yticks([])
    fig.suptitle(title or f"R, G, B = {', '.join(labels)}: colours relative to the Sun's (each panel scaled to "
                          f"its brightest band)", fontsize=9)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100)
    plt.close(fig)
    write_bytes_atomic(path, buf.getvalue())


def write_png(path, res, planes, title: str = "", stretch: tuple[float, float] | None = None) -> None:
    """The first BRDF's moonshine + earthshine with an asinh stretch and a colour bar; three
    bands: a colour picture (:func:`write_colour_png`). ``stretch``: (linear width, top) of the
    stretch [radiance], to show several pictures alike (default: this picture's own, the 5th
    percentile of its lit pixels and its maximum)."""
    if colour_planes(res, planes) is not None:
        return write_colour_png(path, res, planes, title)
    import io

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import AsinhNorm

    b = next(iter(planes["moonshine"]))
    tot = planes["moonshine"][b] + planes["earthshine"][b]
    pos = tot[tot > 0]
    lin, top = stretch if stretch is not None else (float(np.percentile(pos, 5)) if pos.size else 1.0,
                                                     float(tot.max()) if pos.size else 1.0)
    lin = max(lin, 1e-30)
    fig, ax = plt.subplots(figsize=(6.4, 5.4))
    im = ax.imshow(tot, origin="lower", cmap="gray", norm=AsinhNorm(linear_width=lin, vmin=0.0, vmax=max(top, lin)))
    cb = fig.colorbar(im, ax=ax, fraction=0.046, pad=0.04)
    # ticks at 0 and the decades from 10× the linear width up (nearer ones would overlap 0's label)
    decades = 10.0 ** np.arange(np.ceil(np.log10(10 * lin)), np.floor(np.log10(max(top, lin))) + 1)
    cb.set_ticks([0.0, *decades])
    cb.ax.minorticks_off()
    cb.set_label(f"radiance [{res.info.get('bunit', BUNIT)}] (asinh stretch)")
    ax.set_xlabel("pixel (east ←)")
    ax.set_ylabel("pixel (north ↑)")
    ax.set_title(title or f"{b}: moonshine + earthshine", fontsize=9)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100)
    plt.close(fig)
    write_bytes_atomic(path, buf.getvalue())
