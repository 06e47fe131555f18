"""The model Earth's own albedos: spherical (Bond) albedo, geometric albedo and phase integral.

For a planet lit by a distant Sun (Russell 1916, ApJ 43, 173; Sobolev 1975, *Light Scattering in
Planetary Atmospheres*, ch. 9), with R(μ₀, μ, φ) each place's reflectance factor (radiance
``E μ₀ R / π``) and ρ_h(μ₀) = (1/π) ∫ R μ dΩ its directional–hemispherical reflectance::

    A_s = ∫_lit ρ_h(μ₀) μ₀ dA / ∫_lit μ₀ dA           (the reflected over the intercepted power)
    p   = (2/3) ∫_disc R(μ₀ = μ, φ = 0) μ² dA / ∫_disc μ² dA   (full phase, over a Lambert disc's)
    q   = A_s / p                                      (the phase integral)

A Lambert sphere of albedo A gives A, 2A/3 and 3/2. These are the model's exact values, over every
direction: Eq. 17 (``bond_albedo`` of a sweep) estimates A_s from the phases a run samples and
reads each p* as a Lambert sphere's, so the two differ wherever the Earth is not Lambert or the
sampled phases miss part of the phase curve.

Quadrature: places on a 1° latitude–longitude grid (midpoints, each weighted by its area); per
class of the physical Earth, ρ_h at the DISORT tables' 47 zenith angles (cubic between them), each
a 12-node Gauss rule in μ times a 32-node midpoint rule in φ over 0-180°
(the plane of the Sun is a mirror); a Lambert class's ρ_h is its albedo. Geometry: the Sun's
direction from each place (the Sun's 0.5° disc and its 1/r² across the Earth are neglected).
"""

from __future__ import annotations

import numpy as np

from lunarviz.caches import memoize
from lunarviz.earth_optics import ozone, rayleigh
from lunarviz.earth_optics.atmosphere import spherical_albedo, transmittance
from lunarviz.earth_optics.classes import Surface, lambert_ground_toa, toa_reflectance
from lunarviz.earth_optics.disort_tables import THETA_DEG, cubic_weights
from lunarviz.geometry.sphere_quadrature import gauss_legendre
from lunarviz.options import earth_params
from lunarviz.surfaces.earth_spectra import albedo_spectra, components, grey_albedos, weights_at
from lunarviz.surfaces.maps import sample_map
from lunarviz.surfaces.physical_earth import class_models, place_grid

#: latitude rows of the place grid (1°); longitudes twice as many
PLACE_ROWS = 180
#: the hemispherical rule of ρ_h: Gauss nodes in μ, midpoints in φ over 0-180°, tabulated at the
#: DISORT tables' zenith angles (cubic between them). A_s of the land-ocean Earth with zonal clouds:
#: within 3e-5 (450 nm) and 2e-4 (650 nm) of a 48 × 128 rule; a black ground's, 3e-5 of the layer's
#: spherical albedo (coarser incidence nodes: 2e-3 there, the path radiance is steep near grazing)
MU_NODES, PHI_NODES = 12, 32
INCIDENCE_DEG = THETA_DEG
#: the physical Earth's parameters of the air over every class (their values key the class tables)
AIR_PARAMETERS = ("cloud_top_hpa", "surface_hpa", "ozone_du")


def _places(scene, frame):
    """Unit place directions in the map frame and the scene frame, the cosine of the Sun's zenith
    angle at each (negative: night) and each place's area weight."""
    la, lo = np.meshgrid(*place_grid(PLACE_ROWS), indexing="ij")
    d = np.stack([np.cos(la) * np.cos(lo), np.cos(la) * np.sin(lo), np.sin(la)], -1).reshape(-1, 3)
    ds = d @ frame.T
    y = scene.earth + scene.radii["earth"] * ds
    vs = scene.sun - y
    vs /= np.linalg.norm(vs, axis=1, keepdims=True)
    return d, np.einsum("ij,ij->i", ds, vs), np.cos(la).ravel()


@memoize(maxsize=16384)
def _class_tables(model: Surface, wavelength_nm: float, air: tuple) -> np.ndarray:
    """(2, nodes): ρ_h and the backscatter R(μ₀, μ₀, φ = 0) of a class at :data:`INCIDENCE_DEG`
    under the air of :data:`AIR_PARAMETERS` ``air`` (the cloud tops' and the ground's pressures
    [hPa], the ozone column [DU]); kept: a run's dates
    share them (each entry is 2 × 47 numbers: room for every class at 2000 wavelengths). The
    backscatter is taken at the nodes, where the cloud table holds exact backscatter (its glory);
    between them the table's own interpolation mixes in neighbouring directions and ripples with
    their 2° period (2 % on a cloudy Earth's p)."""
    params = dict(zip(AIR_PARAMETERS, air))
    mu0 = np.cos(np.radians(INCIDENCE_DEG))
    out = np.stack([hemispherical_reflectance(model, wavelength_nm, mu0, params),
                    toa_reflectance(model, wavelength_nm, mu0, mu0, 0.0, params=params)])
    out.setflags(write=False)
    return out


def hemispherical_reflectance(model: Surface, wavelength_nm: float, mu0, params: dict | None = None) -> np.ndarray:
    """ρ_h(μ₀) = (1/π) ∫ R(μ₀, μ, φ) μ dΩ of a physical class under the air at λ, at ``mu0``."""
    mu, wmu = gauss_legendre(MU_NODES)
    phi = (np.arange(PHI_NODES) + 0.5) * 180.0 / PHI_NODES
    mu0 = np.atleast_1d(np.asarray(mu0, float))
    r = toa_reflectance(model, wavelength_nm, mu0[:, None, None], mu[None, :, None], phi[None, None, :],
                        params=params)
    # (1/π) ∫_0^{2π} ∫_0^1 R μ dμ dφ = (2/π) · π · Σ_μ w μ mean_φ(R) over the mirror half
    return 2.0 * np.einsum("abc,b->a", r, wmu * mu) / PHI_NODES


def _class_values(model, lam, mu0, p, ground) -> tuple[np.ndarray, np.ndarray]:
    """(ρ_h, backscatter R(μ₀, μ₀, 0)), each (n, L), of one class at the places' μ₀ (cubic in the
    zenith angle between the nodes); ``model`` None: a clear-sky map's Lambert ground, per place
    albedo ``ground``."""
    i, wt = cubic_weights(INCIDENCE_DEG, np.degrees(np.arccos(np.clip(mu0, 0.0, 1.0))))
    key = tuple(p[k] for k in AIR_PARAMETERS)  # (the class carries its wind and optical depth)
    if model is not None:
        table = np.stack([_class_tables(model, float(lj), key) for lj in lam], -1)  # (2, nodes, L)
        both = np.einsum("na,knal->knl", wt, table[:, i])
        return both[0], both[1]
    # a clear-sky map's Lambert ground of albedo A under the layer, exactly (atmosphere.lambert_toa
    # times the ozone's T_O3 integrated over the view hemisphere): ρ_h(μ₀; A) = ρ_h(μ₀; 0)
    # + T(μ₀) T̄ A / (1 − S A), with T̄ = 2 ∫ T(μ) T_O3(μ₀, μ) μ dμ the layer's and the ozone's
    # transmittance for isotropic light
    mu, wmu = gauss_legendre(MU_NODES)
    rho_h, back = np.empty((len(mu0), len(lam))), np.empty((len(mu0), len(lam)))
    for j, lj in enumerate(lam):
        black = np.einsum("na,na->n", wt, _class_tables(Surface("lambert", 0.0), float(lj), key)[0][i])
        tau = float(rayleigh.optical_depth(float(lj), p["surface_hpa"]))
        t_o3 = ozone.transmittance(float(lj), p["ozone_du"], mu0[:, None], mu[None, :])
        t_bar = 2.0 * (t_o3 * transmittance(tau, mu)) @ (wmu * mu)
        rho_h[:, j] = black + transmittance(tau, mu0) * t_bar * ground / (1.0 - spherical_albedo(tau) * ground)
        back[:, j] = lambert_ground_toa(ground, float(lj), mu0, mu0, 0.0, p)
    return rho_h, back


def earth_albedos(surface, scene, frame, wavelengths=None, spectra: str = "surface") -> dict[str, np.ndarray]:
    """``{"spherical", "geometric", "phase_integral"}``, each (L,), of the model Earth
    ``surface`` (an :class:`~lunarviz.surfaces.earth_surface.EarthSurface`) lit as in ``scene``
    (its map in ``frame``) at ``wavelengths`` [nm]; ``None``: the grey run's (a physical Earth's
    ``earth.wavelength_nm``, a Lambert Earth's grey albedos); ``spectra``: a spectral Lambert
    Earth's classes (``--earth-spectra``: packaged spectra, or grey)."""
    d, mu0, area = _places(scene, frame)
    lit = mu0 > 0
    d, mu0, area = d[lit], mu0[lit], area[lit]
    names = components(surface)
    weights = weights_at(surface, d)  # (n, C)
    if surface.physical:
        lam = np.atleast_1d(surface.wavelength_nm if wavelengths is None else np.asarray(wavelengths, float))
        p = earth_params(dict(surface.earth_params))
        clear = surface.clear_map() if "clear" in names else None
        ground = None if clear is None else sample_map(clear, d)
        rho_h = np.zeros((len(mu0), len(lam)))
        back = np.zeros((len(mu0), len(lam)))
        cloud = weights[:, -1] if "cloud" in names else np.zeros(len(mu0))
        for c, (name, model) in enumerate(class_models(surface).items()):
            # a clear-sky map's column holds (1 - cloud) · albedo: its places are its clear share,
            # each with its own ground (black ground too: the air above it still reflects)
            share = weights[:, c] if model is not None else 1.0 - cloud
            rows = np.flatnonzero(share > 0)
            if not len(rows):
                continue
            g = None if model is not None else ground[rows]
            mine, mine_back = _class_values(model, lam, mu0[rows], p, g)
            rho_h[rows] += share[rows, None] * mine
            back[rows] += share[rows, None] * mine_back
    else:  # Lambert places: ρ_h = R = each component's albedo
        lam = None if wavelengths is None else np.atleast_1d(np.asarray(wavelengths, float))
        grey = grey_albedos(surface)
        alb = np.array([[grey[n]] for n in names]) if lam is None else \
            albedo_spectra(surface, names, lam, spectra)  # (C, L)
        rho_h = back = weights @ alb
    spherical = (area * mu0) @ rho_h / np.sum(area * mu0)
    geometric = 2.0 / 3.0 * ((area * mu0**2) @ back) / np.sum(area * mu0**2)
    return {"spherical": spherical, "geometric": geometric, "phase_integral": spherical / geometric}
