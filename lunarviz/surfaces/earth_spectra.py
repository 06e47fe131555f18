"""A spectral Earth: the surface as components, each with a weight per place and an albedo spectrum.

The Earth stays Lambertian here (its anisotropy, glint and Rayleigh scattering are another
module's job: this one only says what albedo each place has at λ). Earthshine is linear in the
Earth's albedo, so a run traces one beam array per component (the component's weight as the
Earth's albedo, :attr:`Transport.e_beam_parts`) and the earthshine at λ is
``Σ_c A_c(λ) · shade_λ(E_c)``.

Components of ``--earth-surface`` and ``--clouds``:

* ``uniform``: one component, weight 1, albedo ``earth_albedo`` (grey at every λ: the paper's
  Earth and every inversion's model Earth);
* ``landocean``: ``ocean`` (1 − c)(1 − f), and the land (1 − c) f split by the packaged 1°
  land-cover map (``lunarviz/data/earth_landcover.npy``: Köppen BW as ``desert``, EF as ``snow``,
  other land ``vegetation``; Beck et al. 2023), with f the land fraction and c the cloud fraction;
* a clear-sky albedo map FILE: ``clear``, weight (1 − c) · map (grey: the map is the albedo);
* clouds: ``cloud``, weight c, albedo ``cloud_albedo`` at every λ (a thick water cloud's albedo
  changes by ~3 % from 450 to 865 nm; King 1997's curve).

``--earth-spectra surface`` (default) gives ocean, vegetation, desert and snow the USGS splib07
spectra in ``lunarviz/data/spectra`` (Kokaly et al. 2017; linear between rows, constant beyond
their ends); ``grey`` gives them the grey ``ocean_albedo`` and ``land_albedo`` at every λ, which
reproduces the grey run. Neglected: seasonal snow and sea ice, the spectral shape of clouds,
vegetation's seasons.
"""

from __future__ import annotations

import numpy as np

from lunarviz.caches import memoize
from lunarviz.earth_optics.spectra import class_spectrum
from lunarviz.parsing import wavelength_label
from lunarviz.resources import DATA_DIR
from lunarviz.surfaces.earth_surface import land_fraction_map
from lunarviz.surfaces.maps import facet_average, facet_sub_count, sample_map

#: land-cover codes of ``earth_landcover.npy`` -> component
LAND_CLASSES = {1: "vegetation", 2: "desert", 3: "snow"}
#: components with a packaged spectrum
TABLED = ("ocean", "vegetation", "desert", "snow")


@memoize(maxsize=1)
def land_cover() -> np.ndarray:
    """The 1° land-cover codes (180, 360): 0 ocean, 1 vegetation, 2 desert, 3 ice."""
    m = np.load(DATA_DIR / "earth_landcover.npy")
    m.setflags(write=False)
    return m


def components(surface) -> tuple[str, ...]:
    """The component names of an :class:`~lunarviz.surfaces.earth_surface.EarthSurface`, in order."""
    if surface.earth_surface == "uniform":
        clear = ("uniform",) if surface.clouds == "none" else ("clear",)
    elif surface.earth_surface == "landocean":
        clear = ("ocean", "vegetation", "desert", "snow")
    else:
        clear = ("clear",)
    return clear + (() if surface.clouds == "none" else ("cloud",))


def weights_at(surface, dirs: np.ndarray) -> np.ndarray:
    """Component weights (n, C) at directions (n, 3) in the Earth's map frame, such that
    ``Σ_c weight_c · grey_albedo_c`` is :meth:`EarthSurface.albedo_at`."""
    c = surface.cloud_fraction_at(dirs)
    clear = 1.0 - c
    cols = []
    if surface.earth_surface == "uniform":
        cols.append(clear)
    elif surface.earth_surface == "landocean":
        f = sample_map(land_fraction_map(), dirs)
        cover = sample_map(land_cover(), dirs)
        cols.append(clear * (1.0 - f))
        for code in LAND_CLASSES:
            mine = (cover == code) | ((cover == 0) & (code == 1))  # land the 1° map calls sea: vegetation
            cols.append(np.where(mine, clear * f, 0.0))
    else:
        cols.append(clear * sample_map(surface.clear_map(), dirs))
    if surface.clouds != "none":
        cols.append(c)
    return np.stack(cols, axis=1)


def grey_albedos(surface) -> dict[str, float]:
    """Each component's grey albedo (what the grey run gives it)."""
    clear = 1.0 if surface.earth_surface not in ("uniform",) else surface.earth_albedo
    return {"uniform": surface.earth_albedo, "clear": clear,
            "ocean": surface.ocean_albedo, "vegetation": surface.land_albedo, "desert": surface.land_albedo,
            "snow": surface.land_albedo, "cloud": surface.cloud_albedo}


def albedo_spectra(surface, names, wavelength_nm, mode: str = "surface") -> np.ndarray:
    """(C, L) albedo of each component at each wavelength: packaged spectra (``surface``) for the
    tabled classes, grey values otherwise (``grey``: every component grey)."""
    lam = np.atleast_1d(np.asarray(wavelength_nm, dtype=float))
    grey = grey_albedos(surface)
    out = np.empty((len(names), len(lam)))
    for i, name in enumerate(names):
        if mode == "surface" and name in TABLED:
            tl, ta = class_spectrum(name)
            out[i] = np.interp(lam, tl, ta)
        else:
            out[i] = grey[name]
    return out


def facet_weights(surface, body, frame: np.ndarray, only=None) -> np.ndarray:
    """(F, C) area-averaged component weights of an Embree body's facets (the same jittered
    points as :meth:`EarthSurface.facet_albedo`, so their grey sum is its albedo); ``only``:
    those facets' alone (sorted indices), as the whole mesh's give them, not kept."""
    memo = body.geometry.setdefault("surface_components", {})
    key = (surface, np.asarray(frame, dtype=float).tobytes())
    if only is not None and key in memo:
        return memo[key][only]
    if only is not None or key not in memo:
        shape = (1800, 3600) if surface.earth_surface == "landocean" else \
            (surface.clear_map().shape if surface.earth_surface != "uniform" else (180, 360))
        k = facet_sub_count(body.vertices, body.faces, shape)
        w = facet_average(lambda d: weights_at(surface, d @ frame), body.vertices, body.faces, k, only=only)
        if only is not None:
            return w
        if len(memo) > 8:
            memo.clear()
        memo[key] = w
    return memo[key]


def weights_toward(surfaces, scene, target: np.ndarray) -> np.ndarray:
    """(C,) component weights as a Lambert Earth lit by a point Sun weights them toward a distant
    ``target`` (:meth:`Surfaces.earth_albedo_toward`'s rule, per component)."""
    return np.atleast_1d(surfaces.earth_albedo_toward(scene, target,
                                                      values=lambda d: weights_at(surfaces.earth, d)))


def spectral_components(surface, nodes, mode: str = "surface") -> tuple[tuple, np.ndarray]:
    """A spectral run's Earth components and their (C, L) albedos at the node wavelengths: the
    surface's classes (:func:`components`, :func:`albedo_spectra`), or for a physical Earth one
    component per node (its reflectance there is the component's weight: albedos the identity)."""
    if surface.physical:
        return tuple(f"{wavelength_label(x)} nm" for x in nodes), np.eye(len(nodes))
    names = components(surface)
    return names, albedo_spectra(surface, names, nodes, mode)
