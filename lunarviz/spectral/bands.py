"""Spectral bands: spectral response functions (SRFs) by name, as a top-hat, or from a file.

``--band NAME|LO-HI|FILE.csv[,...]``:

* ``NAME``: a packaged instrument band (``lunarviz/data/bands/*.csv``, each file's header cites
  its source: Sentinel-2A MSI ``S2A-B1`` … ``S2A-B12``, MODIS ``MODIS-TERRA-B1`` … ``-B9``), the
  Johnson-Cousins ``U``, ``B``, ``V``, ``R``, ``I`` of Bessell (1990, PASP 102, 1181; the tables of
  the ``speclite`` package, ``bessell-B`` …), or any other ``speclite`` filter by its name
  (``sdss2010-r``, ``decam2014-g``, …);
* ``LO-HI``: a top-hat, response 1 from LO to HI nm (``400-750`` is the paper's band);
* ``FILE.csv``: ``wavelength_nm,response`` rows (linear between rows, zero outside).

A band's value is ``∫ E(λ) S(λ) dλ`` with S the response as tabulated (applied to energy; a
photon-counting SRF is the user's to convert). The integral is computed without shading every
nanometre: E(λ) = s(λ) T(λ) where s is the Sun's spectrum (lines and all, integrated on its own
1 nm grid) and T the transport shaded with the surfaces' parameters at λ, which vary smoothly;
T is shaded at nodes every :data:`NODE_STEP_NM` across the band and taken linear between them
(:func:`band_weights`: hat functions integrated against s·S exactly on the fine grid). Where T is
constant the band value is exact; the error of the linear T is second order in the node step.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lunarviz.caches import file_key, memoize
from lunarviz.errors import LunarvizError, any_case, did_you_mean
from lunarviz.resources import DATA_DIR, read_table

#: node step of band integrals [nm]: surface spectra (the vegetation's red edge is ~30 nm wide)
#: and the lunar parameters are linear to ~1e-3 over it
NODE_STEP_NM = 10.0
#: Johnson-Cousins names -> speclite's Bessell (1990) tables
JOHNSON = {"U": "bessell-U", "B": "bessell-B", "V": "bessell-V", "R": "bessell-R", "I": "bessell-I"}
BAND_DIR = DATA_DIR / "bands"
#: at most this many bands in one run
MAX_BANDS = 64


@dataclass(frozen=True)
class Band:
    """A spectral response: its name, wavelengths [nm] (increasing) and response (≥ 0)."""

    name: str
    wavelength_nm: np.ndarray
    response: np.ndarray
    source: str = ""

    @property
    def support(self) -> tuple[float, float]:
        """The smallest interval [nm] outside which the response is zero."""
        nz = np.flatnonzero(self.response > 0)
        i0, i1 = max(nz[0] - 1, 0), min(nz[-1] + 1, len(self.response) - 1)
        return float(self.wavelength_nm[i0]), float(self.wavelength_nm[i1])

    def at(self, wavelength_nm) -> np.ndarray:
        return np.interp(wavelength_nm, self.wavelength_nm, self.response, left=0.0, right=0.0)

    @property
    def centre_nm(self) -> float:
        """The response-weighted mean wavelength ∫λS dλ / ∫S dλ [nm] (S linear between rows)."""
        lam, s = self.wavelength_nm, self.response
        x = np.linspace(lam[0], lam[-1], 20 * len(lam))
        sx = np.interp(x, lam, s)
        return float(np.sum(x * sx) / np.sum(sx))


def packaged_bands() -> dict[str, Path]:
    """``{NAME: file}`` of the instrument bands shipped in ``lunarviz/data/bands``."""
    return {p.stem: p for p in sorted(BAND_DIR.glob("*.csv"))}


@memoize(maxsize=32)
def _file_band(key: tuple, name: str) -> Band:
    lam, s, notes = read_table(key[0], "spectral response")
    if not np.any(s > 0):
        raise LunarvizError(f"spectral response {key[0]!r} is zero everywhere")
    return Band(name, lam, s, notes)


def _speclite_band(name: str) -> Band | None:
    try:
        import speclite.filters
    except ImportError:  # pragma: no cover (a dependency; kept optional for the numbers)
        return None
    try:
        f = speclite.filters.load_filter(name)
    except (ValueError, OSError, KeyError):
        return None
    lam = np.asarray(f.wavelength, dtype=float) / 10.0  # Å -> nm
    return Band(name, lam, np.asarray(f.response, dtype=float),
                f"speclite filter {name!r}: {f.meta.get('description', '')}".strip())


def parse_band(text: str) -> Band:
    """One ``NAME|LO-HI|FILE.csv`` (see the module docstring)."""
    t = str(text).strip()
    if not t:
        raise LunarvizError("empty band name")
    if t.lower().endswith((".csv", ".txt")):
        return _file_band(file_key(t), Path(t).stem)
    if "-" in t and t.replace("-", "", 1).replace(".", "").replace("e", "").isdigit():
        lo_s, hi_s = t.split("-", 1)
        try:
            lo, hi = float(lo_s), float(hi_s)
        except ValueError:
            raise LunarvizError(f"malformed band {t!r}: use LO-HI in nm, e.g. 400-750") from None
        if not (np.isfinite(lo) and np.isfinite(hi) and 0 < lo < hi):
            raise LunarvizError(f"band {t!r}: need 0 < LO < HI [nm]")
        return Band(t, np.array([lo, hi]), np.array([1.0, 1.0]), f"top-hat {lo:g}-{hi:g} nm")
    packaged = packaged_bands()
    t = any_case(t, packaged) or t  # (s2a-b4: S2A-B4)
    if t in packaged:
        return _file_band(file_key(packaged[t]), t)
    b = _speclite_band(JOHNSON.get(t, t))
    if b is not None:
        return Band(t, b.wavelength_nm, b.response, b.source)
    raise LunarvizError(f"unknown band {t!r}{did_you_mean(t, [*JOHNSON, *packaged])}: use {', '.join(JOHNSON)}, a "
                        f"packaged band ({', '.join(packaged)}), a speclite filter name (e.g. sdss2010-r), LO-HI [nm] "
                        f"or a .csv file")


def parse_bands(text) -> tuple[Band, ...]:
    """A comma-separated list of bands (names must be distinct)."""
    parts = [p for p in (str(text).split(",") if isinstance(text, str) else list(text))]
    bands = tuple(parse_band(p) for p in parts)
    if len(bands) > MAX_BANDS:
        raise LunarvizError(f"{len(bands)} bands: at most {MAX_BANDS} in one run")
    names = [b.name for b in bands]
    dup = next((n for n in names if names.count(n) > 1), None)
    if dup is not None:
        raise LunarvizError(f"band {dup!r} is listed twice")
    return bands


def band_nodes(band: Band, step: float = NODE_STEP_NM) -> np.ndarray:
    """Nodes [nm] where a band's transport is shaded: its support's ends and the multiples of
    ``step`` between them."""
    lo, hi = band.support
    inner = np.arange(np.floor(lo / step) + 1, np.ceil(hi / step)) * step
    return np.unique(np.concatenate([[lo], inner[(inner > lo) & (inner < hi)], [hi]]))


def band_weights(band: Band, nodes: np.ndarray, solar) -> np.ndarray:
    """Weights W_j [W m⁻² at 1 au per unit T] with ``∫ E_sun(λ) S(λ) T(λ) dλ = Σ_j W_j T(λ_j)`` for
    T linear between ``nodes`` (sorted; every node of the band's support among them): the hat
    function of each node integrated against E_sun·S on the union of the solar table's, the
    response's and the nodes' wavelengths (trapezoid rule). ``Σ_j W_j`` is the band's solar
    irradiance at 1 au, :func:`band_solar_irradiance`, exactly."""
    lo, hi = band.support
    sl = solar.wavelength_nm
    grid = np.unique(np.concatenate([sl[(sl > lo) & (sl < hi)], band.wavelength_nm[(band.wavelength_nm >= lo) &
                                                                                    (band.wavelength_nm <= hi)],
                                     nodes[(nodes >= lo) & (nodes <= hi)], [lo, hi]]))
    solar.check_covers(np.array([lo, hi]))
    f = solar.at(grid) * band.at(grid)
    dx = np.diff(grid)
    cell = 0.5 * dx  # trapezoid: each grid point's share of its two cells
    wgrid = np.zeros_like(grid)
    wgrid[:-1] += cell
    wgrid[1:] += cell
    wgrid *= f
    # hat functions of the nodes at the grid points (linear interpolation is a partition of unity)
    W = np.zeros(len(nodes))
    j = np.clip(np.searchsorted(nodes, grid, side="right") - 1, 0, len(nodes) - 2)
    t = (grid - nodes[j]) / (nodes[j + 1] - nodes[j])
    t = np.clip(t, 0.0, 1.0)
    np.add.at(W, j, wgrid * (1.0 - t))
    np.add.at(W, j + 1, wgrid * t)
    return W


def band_solar_irradiance(band: Band, solar) -> float:
    """``∫ E_sun(λ) S(λ) dλ`` at 1 au [W m⁻²], the same rule as :func:`band_weights`."""
    nodes = band_nodes(band)
    return float(band_weights(band, nodes, solar).sum())
