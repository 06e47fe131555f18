"""The physical Earth as a planet (``--earth-brdf physical``): each place's reflectance toward a
direction, per facet of a traced Earth and integrated over the disc for the point-Earth methods.

Each place is a mix of the classes of :mod:`lunarviz.surfaces.earth_spectra` (``--earth-surface`` and
``--clouds``), each class reflecting as its model under the Rayleigh atmosphere and the ozone
(:func:`lunarviz.earth_optics.classes.toa_reflectance`): the uniform Earth and a clear-sky map
FILE as Lambert surfaces of their albedo, ``ocean`` as Cox–Munk glint with whitecaps and water,
``vegetation``/``desert``/``snow`` with the Ross–Li shape and their USGS spectra, ``cloud`` as
the DISORT cloud under the air above its top. The options ``--ocean-albedo``, ``--land-albedo``
and ``--cloud-albedo`` are the Lambert Earth's: the physical classes carry their own.

A place's radiance toward a distant point (the Moon) is ``E μ_s R(μ_s, μ_t, φ) / π``: a Lambert
place of albedo R. So a traced Earth takes, per surface element (three a facet), R toward the
Moon's centre at the element's point with its facet's area-averaged class weights as its albedo
(:meth:`~lunarviz.methods.tracer.facet_surfaces.FacetSurfaces.earth_element_values`; per-facet
arrays take R at the facet's centre, :func:`facet_reflectance`), and the point-Earth methods
take ``∫ R μ_s μ_t dA / ∫ μ_s μ_t dA`` as the Earth's albedo. Neglected: R's change across an
element (second order; measured with the tracer's error model, docs: accuracy, "A physical
Earth") and across the Moon as seen from the Earth (0.26°), the Earth's curvature in the
scattering atmosphere (plane-parallel: beyond 89° zenith angles are held there; the ozone above
it takes the slant path of a spherical shell).
"""

from __future__ import annotations

import numpy as np

from lunarviz.earth_optics.classes import Surface, lambert_ground_toa, surface_from_name, toa_reflectance
from lunarviz.options import earth_params
from lunarviz.photometry.earth_phase import lambert_phase_function
from lunarviz.surfaces.earth_spectra import components, facet_weights, weights_at
from lunarviz.surfaces.maps import map_frame, sample_map


def _geometry(normals, to_sun, to_target):
    """μ_s, μ_t and the azimuth [deg] (0: target on the Sun's side) at unit normals (n, 3) for
    unit directions to the Sun and the target ((n, 3) or (3,))."""
    ms = np.einsum("ij,ij->i", normals, np.broadcast_to(to_sun, normals.shape))
    mt = np.einsum("ij,ij->i", normals, np.broadcast_to(to_target, normals.shape))
    a = to_sun - ms[:, None] * normals
    b = to_target - mt[:, None] * normals
    den = np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1)
    cphi = np.where(den > 1e-12, np.einsum("ij,ij->i", a, b) / np.maximum(den, 1e-300), 1.0)
    return ms, mt, np.degrees(np.arccos(np.clip(cphi, -1.0, 1.0)))


def class_models(surface) -> dict[str, Surface]:
    """Each component of ``surface`` (an :class:`~lunarviz.surfaces.earth_surface.EarthSurface`) as its
    physical class (``clear`` of a map FILE is Lambert per place: ``None`` here)."""
    p = earth_params(dict(surface.earth_params))
    out = {}
    for name in components(surface):
        if name == "uniform":
            out[name] = Surface("lambert", float(p["ground_albedo"]))
        elif name == "clear":
            out[name] = None if surface.earth_surface != "uniform" else Surface("lambert", float(p["ground_albedo"]))
        else:
            out[name] = surface_from_name(name, wind_speed=p["wind_speed"],
                                          cloud_optical_depth=p["cloud_optical_depth"],
                                          chlorophyll=p["chlorophyll"])
    return out


def reflectance(surface, weights, map_dirs, normals, to_sun, to_target, wavelengths) -> np.ndarray:
    """(n, L) top-of-atmosphere reflectance factor toward the target of places with component
    ``weights`` (n, C) (:func:`lunarviz.surfaces.earth_spectra.weights_at` or facet averages) at unit
    ``normals`` (n, 3) (``map_dirs``: the same in the map frame, for a clear-sky map's albedo)."""
    p = earth_params(dict(surface.earth_params))
    ms, mt, phi = _geometry(normals, to_sun, to_target)
    lit = np.flatnonzero((ms > 0) & (mt > 0))
    lam = np.atleast_1d(np.asarray(wavelengths, float))
    out = np.zeros((len(normals), len(lam)))
    if not len(lit):
        return out
    models = class_models(surface)
    for c, (name, model) in enumerate(models.items()):
        w = weights[lit, c]
        rows = lit[w > 0]
        if not len(rows):
            continue
        if model is None:  # a clear-sky map: Lambert at the map's albedo, per place
            albedo = sample_map(surface.clear_map(), map_dirs[rows])
            frac = weights[rows, c] / np.maximum(albedo, 1e-300)  # weights_at folds the map into its weight
            for j, lj in enumerate(lam):
                out[rows, j] += np.where(albedo > 0, frac, 0.0) * lambert_ground_toa(albedo, lj, ms[rows], mt[rows],
                                                                                   phi[rows], p)
            continue
        geometry: dict = {}  # the class's wavelength-free parts at these places, computed once
        for j, lj in enumerate(lam):
            out[rows, j] += weights[rows, c] * toa_reflectance(model, lj, ms[rows], mt[rows], phi[rows], params=p,
                                                               geometry=geometry)
    return out


def facet_reflectance(surface, body, frame, sun, target, wavelengths, only=None) -> np.ndarray:
    """(F, L) reflectance factor of a traced Earth's facets toward ``target`` (scene points [m]),
    each at its centre with its classes' area-averaged weights; ``only``: those facets' alone
    (sorted indices), as the whole mesh's give them."""
    w = facet_weights(surface, body, frame, only)
    tri = body.vertices[body.faces if only is None else body.faces[only]]
    centre = tri.mean(axis=1)
    n = centre / np.linalg.norm(centre, axis=1, keepdims=True)  # mesh frame = scene frame about the centre
    y = body.centre + n * body.radius
    to_sun = (sun - y) / np.linalg.norm(sun - y, axis=1, keepdims=True)
    to_t = (target - y) / np.linalg.norm(target - y, axis=1, keepdims=True)
    return reflectance(surface, w, n @ frame, n, to_sun, to_t, wavelengths)


def place_grid(rows: int) -> tuple[np.ndarray, np.ndarray]:
    """Latitudes (rows,) and longitudes (2 rows,) [rad] of the places on which the Earth's disc
    and sphere integrals are taken: cell midpoints, north to south and from −180° east."""
    lat = np.radians(90.0 - (np.arange(rows) + 0.5) * 180.0 / rows)
    lon = np.radians(-180.0 + (np.arange(2 * rows) + 0.5) * 180.0 / rows)
    return lat, lon


def albedo_toward(surface, scene, frame, target, wavelengths, rows: int = 180) -> np.ndarray:
    """(L,) the point Earth's albedo toward a distant ``target``: ``∫ R μ_s μ_t dA / ∫ μ_s μ_t dA``
    on a grid of ``rows`` latitudes × 2 ``rows`` longitudes (:func:`place_grid`), μ_s, μ_t and R
    from each place's own directions to the Sun and the target."""
    radius = scene.radii["earth"]
    lat, lon = place_grid(rows)
    lam = np.atleast_1d(np.asarray(wavelengths, float))
    num, den = np.zeros(len(lam)), 0.0
    for a in range(0, rows, 45):
        la = lat[a:a + 45, None]
        d = np.stack([np.cos(la) * np.cos(lon), np.cos(la) * np.sin(lon),
                      np.broadcast_to(np.sin(la), (len(la), len(lon)))], -1).reshape(-1, 3)
        ds = d @ frame.T
        # directions to the Sun and the target from each place (from the centre they are off by up
        # to R_E/D ≈ 1° at the Moon, which R's steepness near the limb and terminator does not allow)
        y = scene.earth + radius * ds
        vs = scene.sun - y
        vt = target - y
        vs /= np.linalg.norm(vs, axis=1, keepdims=True)
        vt /= np.linalg.norm(vt, axis=1, keepdims=True)
        w = np.clip(np.einsum("ij,ij->i", ds, vs), 0, None) * np.clip(np.einsum("ij,ij->i", ds, vt), 0, None) \
            * np.repeat(np.cos(la[:, 0]), len(lon))
        keep = np.flatnonzero(w > 0)
        if not len(keep):
            continue
        r = reflectance(surface, weights_at(surface, d[keep]), d[keep], ds[keep], vs[keep], vt[keep], lam)
        num += w[keep] @ r
        den += float(w[keep].sum())
    return num / den if den > 0 else np.full(len(lam), np.nan)


def albedo_toward_moon(surfaces, scene, wavelengths) -> np.ndarray:
    """(L,) :func:`albedo_toward` the Moon's centre for a scene's
    :class:`~lunarviz.surfaces.point_values.Surfaces` (its Earth's rotation gives the map frame)."""
    frame = map_frame(scene, "earth", surfaces.earth_rotation_deg)
    return albedo_toward(surfaces.earth, scene, frame, scene.moon, wavelengths)


def _direction(scene, beta_deg, psi_deg) -> np.ndarray:
    """Unit vector at angle β from the Sun seen from the Earth's centre, turned by ψ about the Sun
    line from the half-plane that holds the Moon (ψ = 0; the Earth's pole where the Moon is on the line)."""
    us = (scene.sun - scene.earth) / np.linalg.norm(scene.sun - scene.earth)
    ref = scene.moon - scene.earth
    ref = ref - (ref @ us) * us
    if np.linalg.norm(ref) < 1e-9 * np.linalg.norm(scene.moon - scene.earth):
        ref = np.array([0.0, 0.0, 1.0]) - us[2] * us
    e1 = ref / np.linalg.norm(ref)
    e2 = np.cross(us, e1)
    b, p = np.radians(beta_deg), np.radians(psi_deg)
    return np.cos(b) * us + np.sin(b) * (np.cos(p) * e1 + np.sin(p) * e2)


def apparent_albedo(surface, scene, frame, beta_deg, psi_deg, wavelength_nm: float, rows: int = 90) -> float:
    """The Earth's apparent albedo a(β, ψ) toward a distant viewer at phase angle β (turned ψ about
    the Sun line): its intensity over a Lambert sphere's of albedo 1, ``I = a (2/3) R² E f_L(β)``."""
    far = scene.earth + 1e3 * np.linalg.norm(scene.moon - scene.earth) * _direction(scene, beta_deg, psi_deg)
    return float(albedo_toward(surface, scene, frame, far, [wavelength_nm], rows=rows)[0])


def bond_albedo(surface, scene, frame, wavelength_nm: float, order: int = 16, azimuths: int = 8,
                rows: int = 90) -> tuple[float, float]:
    """(Bond albedo, geometric albedo) of the model Earth lit as in ``scene``: the reflected power
    over all directions, ``A_B = (2 / 3π) ∫∫ a(β, ψ) f_L(β) sin β dβ dψ`` (Gauss–Legendre in β,
    midpoints in ψ; a Lambert sphere of albedo A gives A), and ``p = (2/3) a(β → 0)`` (β = 0.5°)."""
    x, w = np.polynomial.legendre.leggauss(order)
    beta = 0.5 * np.pi * (x + 1.0)
    psi = (np.arange(azimuths) + 0.5) * 360.0 / azimuths
    total = 0.0
    for b, wb in zip(beta, 0.5 * np.pi * w):
        a = np.mean([apparent_albedo(surface, scene, frame, np.degrees(b), p, wavelength_nm, rows) for p in psi])
        total += wb * a * float(lambert_phase_function(b)) * np.sin(b)
    geometric = 2.0 / 3.0 * apparent_albedo(surface, scene, frame, 0.5, 0.0, wavelength_nm, rows)
    return 2.0 / (3.0 * np.pi) * 2.0 * np.pi * total, geometric
