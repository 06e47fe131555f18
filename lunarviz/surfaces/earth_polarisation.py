"""The whole Earth's polarised light toward a distant observer: its disc-integrated Stokes vector
against the phase angle.

The Earth of a uniform Lambert ground of albedo A under the Rayleigh layer above ``surface_hpa``
and the ozone (:func:`lunarviz.earth_optics.classes.toa_stokes`), lit by a distant Sun and seen by
a distant observer at phase angle α. Each place's Stokes vector, in the meridian plane of its view
(:mod:`lunarviz.earth_optics.stokes`), is turned into the plane of scattering of the whole planet
(Sun, Earth and observer: e_⊥ = k₀ × k/|k₀ × k| with k₀ the sunlight's direction and k the light's
toward the observer, e_∥ = e_⊥ × k) and summed with the weight of its radiance and its projected
area, as the geometric albedo is (:mod:`lunarviz.surfaces.earth_albedos`)::

    (I, Q, U)(α) = (2/3) ∫_lit,seen R(μ₀, μ, φ) μ₀ μ dA / ∫_disc μ² dA

so that I(0) is the geometric albedo and I(α) = p Φ(α) with Φ the phase function; −Q/I is the
degree of polarisation counted positive across the plane of scattering (as Rayleigh light is), and
U vanishes by the mirror symmetry of the lit disc. Quadrature: the places of
:func:`~lunarviz.surfaces.physical_earth.place_grid` (1° cells, midpoints, each weighted by its area).
Neglected: the Earth's oblateness, the Sun's disc, and the polarisation of the sea's glint, land and
clouds (the ground is Lambert: it reflects unpolarised light).
"""

from __future__ import annotations

import numpy as np

from lunarviz.earth_optics.classes import Surface, toa_stokes
from lunarviz.earth_optics.stokes import frame_angle, rotate
from lunarviz.geometry.scene_geometry import unit
from lunarviz.surfaces.physical_earth import place_grid

#: latitude rows of the place grid (1°); longitudes twice as many
PLACE_ROWS = 180


def disc_places(phase_deg: float, rows: int = PLACE_ROWS) -> dict:
    """The lit places seen by a distant observer at phase angle ``phase_deg``: their normals ``n``,
    ``mu0``, ``mu``, azimuths ``phi_deg`` (the viewer's less the Sun's, counterclockwise about each
    place's zenith) and ``weight`` (2/3 μ₀ μ dA / ∫_disc μ² dA: Σ weight × R is the disc's I(α)),
    with the unit vectors ``view`` (the light's direction toward the observer) and ``sun``."""
    alpha = np.radians(float(phase_deg))
    lat, lon = place_grid(rows)
    la, lo = np.meshgrid(lat, lon, indexing="ij")
    n = np.stack([np.cos(la) * np.cos(lo), np.cos(la) * np.sin(lo), np.sin(la)], -1).reshape(-1, 3)
    area = np.repeat(np.cos(lat), len(lon))
    view = np.array([1.0, 0.0, 0.0])
    sun = np.array([np.cos(alpha), np.sin(alpha), 0.0])
    mu, mu0 = n @ view, n @ sun
    den = np.sum(area[mu > 0] * mu[mu > 0] ** 2)
    keep = (mu > 1e-9) & (mu0 > 1e-9)  # (places on the limb or the terminator carry no light)
    n, area, mu, mu0 = n[keep], area[keep], mu[keep], mu0[keep]
    s_t, v_t = sun - mu0[:, None] * n, view - mu[:, None] * n
    phi = np.degrees(np.arctan2(np.einsum("ij,ij->i", n, np.cross(s_t, v_t)), np.einsum("ij,ij->i", s_t, v_t)))
    return {"n": n, "mu0": mu0, "mu": mu, "phi_deg": phi, "weight": 2.0 / 3.0 * area * mu0 * mu / den,
            "view": view, "sun": sun}


def disc_stokes(phase_deg: float, wavelength_nm: float, ground_albedo: float, params: dict | None = None,
                rows: int = PLACE_ROWS) -> np.ndarray:
    """(3,) the Earth's (I, Q, U)(α) at phase angle ``phase_deg`` (module docstring: the plane of
    scattering as reference, normalised to the geometric albedo) over a Lambert ground of
    ``ground_albedo`` at λ; ``params``: the Earth's (``surface_hpa``, ``ozone_du``)."""
    d = disc_places(phase_deg, rows)
    n, view, sun = d["n"], d["view"], d["sun"]
    st = toa_stokes(Surface("lambert", float(ground_albedo)), wavelength_nm, d["mu0"], d["mu"], d["phi_deg"],
                    params=params)
    # from each place's meridian frame (e_⊥ = n × k) into the plane of scattering's
    e_perp_m = unit(np.cross(n, view))
    e_par_m = np.cross(e_perp_m, view)
    e_perp = np.cross(-sun, view)
    e_perp = e_perp / np.linalg.norm(e_perp) if np.linalg.norm(e_perp) > 1e-12 else np.array([0.0, 0.0, 1.0])
    e_par = np.cross(e_perp, view)
    turned = rotate(st, frame_angle(e_par_m, e_perp_m, e_par))
    return np.einsum("i,ij->j", d["weight"], turned)
