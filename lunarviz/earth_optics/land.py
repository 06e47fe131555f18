"""Land and snow: the Ross-Thick Li-Sparse-Reciprocal kernel BRDF (the MODIS BRDF/albedo model).

Reflectance factor (Lucht, Schaaf & Strahler 2000, *IEEE TGRS* 38, 977, Eqs. 37–46; Wanner, Li
& Strahler 1995)::

    ρ(θ₀, θ, φ) = f_iso + f_vol K_vol + f_geo K_geo

with φ = 0 the viewer on the Sun's side (the hot spot at θ = θ₀), K_vol the Ross-Thick kernel,
K_geo the Li-Sparse-Reciprocal kernel with crown shape h/b = 2, b/r = 1. The shape is one case
of the RAMI4ATM benchmark (Joint Research Centre; the weights f_iso = 0.209741, f_vol =
0.081384, f_geo = 0.004140 at 865 nm, the defaults of Eradiate's ``rtls`` plugin), scaled for each
class so that its white-sky (bi-hemispherical) albedo equals the class's packaged spectral albedo
at λ. The kernels grow without bound toward the horizon (sec θ terms; the model is fitted to
zenith angles up to ~70°), so zenith angles beyond :data:`MAX_ZENITH_DEG` are held at it, and the
white-sky integrals are those of the kernels so held (computed here; unheld they are Lucht et al.
2000's Table 1, 0.189184 and −1.377622, the values the tests check). A bright class
(snow) whose albedo leaves no room under 1 for the shape's anisotropy has the anisotropy scaled
down until its directional albedo is at most 1 at every angle (energy conservation); where the
kernels would give a negative reflectance the shape is held at 0 (before its white-sky albedo is
taken, so that the class's albedo is kept exactly). Neglected: each class's own shape (one shape
serves vegetation, desert and snow; snow's forward scattering is not in it).
"""

from __future__ import annotations

import numpy as np

from lunarviz.caches import memoize
from lunarviz.earth_optics.disort_tables import THETA_DEG, cubic_weights, theta_of

#: RAMI4ATM kernel weights (f_iso, f_vol, f_geo), whose ratios give the shape
RAMI4ATM_WEIGHTS = (0.209741, 0.081384, 0.004140)
#: white-sky integrals of the kernels unheld (Lucht et al. 2000, Table 1)
WHITE_SKY = (1.0, 0.189184, -1.377622)
HB, BR = 2.0, 1.0
#: zenith angles beyond this are held at it [deg]
MAX_ZENITH_DEG = 70.0


def kernels(mu0, mu, phi_deg, max_zenith_deg: float = MAX_ZENITH_DEG) -> tuple[np.ndarray, np.ndarray]:
    """(K_vol, K_geo) at cos θ₀, cos θ and relative azimuth φ [deg] (0: backscatter side), the
    zenith angles held at ``max_zenith_deg``."""
    mu0, mu, phi = np.broadcast_arrays(np.asarray(mu0, float), np.asarray(mu, float), np.asarray(phi_deg, float))
    low = np.cos(np.radians(min(max_zenith_deg, 89.9999)))
    mu0, mu = np.clip(mu0, low, 1.0), np.clip(mu, low, 1.0)
    ph = np.radians(phi)
    s0, s1 = np.sqrt(1 - mu0 * mu0), np.sqrt(1 - mu * mu)
    cxi = np.clip(mu0 * mu + s0 * s1 * np.cos(ph), -1.0, 1.0)
    xi = np.arccos(cxi)
    k_vol = ((np.pi / 2 - xi) * cxi + np.sin(xi)) / (mu0 + mu) - np.pi / 4
    t0, t1 = BR * s0 / mu0, BR * s1 / mu  # tan θ' (b/r = 1: θ' = θ)
    c0, c1 = 1.0 / np.sqrt(1 + t0 * t0), 1.0 / np.sqrt(1 + t1 * t1)
    sec = 1.0 / c0 + 1.0 / c1
    d2 = np.clip(t0 * t0 + t1 * t1 - 2 * t0 * t1 * np.cos(ph), 0.0, None)
    cost = np.clip(HB * np.sqrt(d2 + (t0 * t1 * np.sin(ph)) ** 2) / sec, -1.0, 1.0)
    t = np.arccos(cost)
    overlap = (t - np.sin(t) * cost) * sec / np.pi
    cxi_p = c0 * c1 + (t0 * c0) * (t1 * c1) * np.cos(ph)
    k_geo = overlap - sec + 0.5 * (1 + cxi_p) / (c0 * c1)
    return k_vol, k_geo


@memoize(maxsize=1)
def _shape_albedos() -> tuple[float, np.ndarray]:
    """The RAMI4ATM shape's white-sky albedo and its directional albedo on the tables' zenith nodes
    (Gauss–Legendre in μ', midpoint in φ), with the kernels held as :func:`kernels` holds them."""
    x, w = np.polynomial.legendre.leggauss(64)
    mu, wm = 0.5 * (x + 1), 0.5 * w
    phi = (np.arange(90) + 0.5) * 2.0  # 0 … 180: the kernels are even in φ
    nodes = np.cos(np.radians(THETA_DEG))
    dhr = 2.0 * np.einsum("ijk,i->j", land_shape(mu[:, None, None], nodes[None, :, None], phi[None, None, :]),
                          wm * mu) / len(phi)  # (1/π)∫∫ ρ μ' dμ' dφ at each node
    i, wt = cubic_weights(THETA_DEG, theta_of(mu))
    white = float(2.0 * np.sum(np.einsum("na,na->n", wt, dhr[i]) * wm * mu))
    dhr.setflags(write=False)
    return white, dhr


def land_shape(mu0, mu, phi_deg) -> np.ndarray:
    """The RAMI4ATM shape f_iso + f_vol K_vol + f_geo K_geo, held ≥ 0 (the geometry of a class)."""
    f = np.asarray(RAMI4ATM_WEIGHTS)
    kv, kg = kernels(mu0, mu, phi_deg)
    return np.clip(f[0] + f[1] * kv + f[2] * kg, 0.0, None)


def _anisotropy(albedo):
    """(white-sky albedo of the shape, the fraction of its anisotropy kept at ``albedo``)."""
    a = np.asarray(albedo, float)
    white, dhr = _shape_albedos()
    peak = float(dhr.max()) / white  # the largest directional albedo per unit white-sky albedo
    return white, np.clip((1.0 - a) / np.maximum(a * (peak - 1.0), 1e-300), 0.0, 1.0)


def land_parts(albedo) -> tuple[np.ndarray, np.ndarray]:
    """(constant, scale): the class of white-sky albedo ``albedo`` reflects ρ = constant + scale ×
    :func:`land_shape` (the module's equation: the shape scaled to the albedo, its anisotropy
    reduced where the directional albedo would pass 1)."""
    a = np.asarray(albedo, float)
    white, keep = _anisotropy(a)
    return a * (1.0 - keep), keep * a / white


def land_directional(albedo) -> tuple[np.ndarray, float]:
    """(directional albedo on the tables' zenith nodes, white-sky albedo) of a class: linear in
    the shape's, so in closed form from :func:`_shape_albedos`."""
    constant, scale = land_parts(float(albedo))
    return constant + scale * _shape_albedos()[1], float(albedo)
