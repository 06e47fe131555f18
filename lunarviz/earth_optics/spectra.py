"""The packaged spectral albedos of the Earth's surface classes (USGS splib07, Kokaly et al. 2017;
``lunarviz/data/spectra/README.md`` names each record): ocean, vegetation, desert and snow."""

from __future__ import annotations

import numpy as np

from lunarviz.caches import memoize
from lunarviz.resources import DATA_DIR, read_table


@memoize(maxsize=8)
def class_spectrum(name: str) -> tuple[np.ndarray, np.ndarray]:
    """(wavelength_nm, albedo) of a packaged surface class."""
    lam, a, _ = read_table(DATA_DIR / "spectra" / f"earth_{name}.csv", f"{name} spectrum")
    return lam, a
