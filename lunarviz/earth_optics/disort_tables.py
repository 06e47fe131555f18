"""The packaged DISORT tables of the physical Earth: their grids, their loading and interpolation.

How they are made: the documentation's *Earth as it reflects* page. Interpolation is cubic in the
zenith angles (2° nodes) and, for the Rayleigh layer, cubic in log τ of the quantities divided by
τ (smooth, finite as τ → 0); beyond 89° a zenith angle is held at 89° (the plane-parallel
atmosphere is not valid there anyway, and such light carries the weight cos θ ≤ 0.017).
"""

from __future__ import annotations

import numpy as np

from lunarviz.caches import memoize
from lunarviz.resources import DATA_DIR

TABLE_DIR = DATA_DIR / "earth_optics"
#: zenith-angle nodes of every table [deg]: every 2° to 86°, then every 1° (R grows like 1/μ there)
THETA_DEG = np.r_[np.arange(0.0, 86.5, 2.0), 87.0, 88.0, 89.0]
#: Rayleigh optical depths tabulated: from 1e-4 (beyond 2.5 µm) to 2 (below 300 nm at 1100 hPa)
RAYLEIGH_TAU = np.geomspace(1e-4, 2.0, 44)
#: azimuth nodes of the cloud table [deg]; 0 = viewer on the Sun's side
CLOUD_PHI_DEG = np.arange(0.0, 181.0, 5.0)
#: the plane-parallel liquid water cloud tabulated: droplets of Hansen & Travis (1974)'s gamma size
#: distribution (effective radius and variance), water's refractive index at 550 nm (Hale & Querry
#: 1973), Legendre moments of its Mie phase function kept, over a dark surface (a sea's albedo)
CLOUD = {"r_eff_um": 10.0, "v_eff": 0.1, "wavelength_um": 0.55, "n_real": 1.333, "n_imag": 1.96e-9,
         "moments": 1000, "surface_albedo": 0.06}
#: the cloud's optical depths tabulated (at 550 nm), from thin cirrus-like to deep convective cloud
#: (ISCCP's classes span 0.3-379); cubic in log τ between them, closer where the reflectance
#: bends most (thin clouds: 0.7 % off fresh solutions at τ = 1.4 with nodes a factor 2 apart)
CLOUD_TAU = np.array([0.5, 0.7, 1.0, 1.4, 2.0, 2.8, 3.6, 4.8, 6.0, 8.0, 10.0, 15.0, 23.0, 40.0, 60.0, 100.0, 150.0])
MAX_THETA_DEG = float(THETA_DEG[-1])
#: Gauss–Legendre nodes in cos θ' on (0, 1) of the tabulated sky (the coupling's quadrature)
SKY_ORDER = 48


@memoize(maxsize=1)
def sky_nodes() -> tuple[np.ndarray, np.ndarray]:
    """(μ', weight) of the Gauss–Legendre rule on (0, 1) on which the sky is tabulated (read-only)."""
    x, w = np.polynomial.legendre.leggauss(SKY_ORDER)
    mu, wt = 0.5 * (x + 1.0), 0.5 * w
    mu.setflags(write=False)
    wt.setflags(write=False)
    return mu, wt


@memoize(maxsize=3)
def load(name: str) -> dict:
    """The arrays of ``name``.npz (``rayleigh``, ``cloud`` or ``rayleigh_stokes``), read-only."""
    with np.load(TABLE_DIR / f"{name}.npz") as z:
        out = {k: z[k] for k in z.files}
    for v in out.values():
        v.setflags(write=False)
    return out


def theta_of(mu) -> np.ndarray:
    """Zenith angle [deg] of cos θ, held within the tables' 0 … 89°."""
    return np.clip(np.degrees(np.arccos(np.clip(mu, -1.0, 1.0))), 0.0, MAX_THETA_DEG)


def cubic_weights(nodes: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Indices (n, 4) and weights (n, 4) of Lagrange cubic interpolation on ``nodes`` (held at
    the ends): the four nodes around x, shifted inward at the edges."""
    x = np.clip(np.asarray(x, dtype=float), nodes[0], nodes[-1])
    j = np.clip(np.searchsorted(nodes, x) - 2, 0, len(nodes) - 4)
    idx = j[..., None] + np.arange(4)
    xs = nodes[idx]
    w = np.ones(idx.shape)
    for a in range(4):
        for b in range(4):
            if a != b:
                w[..., a] *= (x - xs[..., b]) / (xs[..., a] - xs[..., b])
    return idx, w
