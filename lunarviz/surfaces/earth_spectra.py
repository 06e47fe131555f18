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

from lunarviz.caches import BoundedCache, memoize, mesh_digest
from lunarviz.earth_optics.spectra import class_spectrum
from lunarviz.parsing import wavelength_label
from lunarviz.resources import DATA_DIR
from lunarviz.surfaces.earth_surface import land_fraction_map, zonal_cloud_table
from lunarviz.surfaces import earth_field_kernels as K
from lunarviz.surfaces.maps import facet_average, facet_linear_fit, facet_sub_count, lat_lon_deg, sample_map_at

#: land-cover codes of ``earth_landcover.npy`` -> component
LAND_CLASSES = {1: "vegetation", 2: "desert", 3: "snow"}
#: components with a packaged spectrum
TABLED = ("ocean", "vegetation", "desert", "snow")
#: samples per facet side of the component fields (:func:`facet_weight_fields`): 2.2 a map cell's
#: side, 24-32 (a facet's sampling noise falls as its points grow, and a finer mesh sums more
#: facets: at a fixed density per cell, level 7's 144 points a facet left more noise than level 6's
#: 576), and at most this many points over the whole mesh (a date reads its visible facets' alone)
FIELD_SAMPLES = 200_000_000


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
    lat_lon = lat_lon_deg(dirs)  # (once for every map read)
    c = surface.cloud_fraction_at(dirs, lat_lon)
    clear = 1.0 - c
    out = np.zeros((len(c), len(components(surface))))
    if surface.earth_surface == "uniform":
        out[:, 0] = clear
    elif surface.earth_surface == "landocean":
        f = sample_map_at(land_fraction_map(), *lat_lon)
        cover = sample_map_at(land_cover(), *lat_lon)
        out[:, 0] = clear * (1.0 - f)
        land = clear * f
        for i, code in enumerate(LAND_CLASSES, start=1):
            mine = (cover == code) | ((cover == 0) & (code == 1))  # land the 1° map calls sea: vegetation
            out[mine, i] = land[mine]
    else:
        out[:, 0] = clear * sample_map_at(surface.clear_map(), *lat_lon)
    if surface.clouds != "none":
        out[:, -1] = c
    return out


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
    key = (surface, surface.map_keys(), np.asarray(frame, dtype=float).tobytes())
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


def _map_shape(surface) -> tuple[int, int]:
    """The shape of the finest map ``surface`` reads (its facets' samples are finer than its cells)."""
    if surface.earth_surface == "landocean":
        return (1800, 3600)
    return surface.clear_map().shape if surface.earth_surface != "uniform" else (180, 360)


def _compiled_fits(surface, frame: np.ndarray):
    """The compiled fit of ``surface``'s component weights (:func:`weights_at`'s maps and reads:
    :func:`lunarviz.surfaces.earth_field_kernels.component_fits`), or ``None``."""
    C = len(components(surface))
    if surface.earth_surface == "uniform":
        clear = {"clear_kind": K.CLEAR_ONE}
    elif surface.earth_surface == "landocean":
        clear = {"clear_kind": K.CLEAR_LANDOCEAN, "clear_map": land_fraction_map(), "cover": land_cover()}
    else:
        clear = {"clear_kind": K.CLEAR_MAP, "clear_map": surface.clear_map()}
    if surface.clouds == "none":
        cloud = {"cloud_kind": K.CLOUD_NONE}
    elif surface.clouds == "zonal":
        cloud = {"cloud_kind": K.CLOUD_ZONAL, "zonal": zonal_cloud_table()}
    else:
        cloud = {"cloud_kind": K.CLOUD_MAP, "cloud_map": surface.cloud_map()}
    return K.component_fits(frame, C, **clear, **cloud)


#: the component fields of a turned body's facets (:func:`facet_weight_fields`), per surface and
#: mesh, kept for the process: ~13 MB a level-6 Earth, 52 MB at level 7 (five components)
TURNED_FIELDS = BoundedCache(4)


def facet_weight_fields(surface, body, frame: np.ndarray, only) -> tuple[np.ndarray, np.ndarray]:
    """The component weights of an Embree body's facets ``only`` (sorted indices) as linear fields
    over each facet (:func:`lunarviz.surfaces.maps.facet_linear_fit`: (n, C) values at the
    centroids, (n, C, 3) gradients in scene axes), k² jittered points a facet (:data:`FIELD_SAMPLES`),
    each facet's values its own points' (whatever else is computed). A body turned into the map's
    frame (``frame`` its rotation: a mapped Earth on dates) covers the same part of the map at every
    date: its fields are fitted in its own frame and kept per surface and mesh for the process
    (:data:`TURNED_FIELDS`), each date computing only the facets no earlier date did, and turned
    into scene axes. Otherwise kept with the body per frame (a θ sweep's Earth keeps one frame)."""
    turned = body.rotation is not None and np.array_equal(frame, body.rotation)
    if turned:
        geo = body.geometry
        key = (surface, surface.map_keys(), mesh_digest(geo["mesh"]), float(body.radius))
        if key not in TURNED_FIELDS:
            TURNED_FIELDS[key] = _fields_memo(surface, geo["body_vertices"], body.faces)
        value, grad = _fields_of(surface, TURNED_FIELDS.get(key), geo["body_vertices"], body.faces, np.eye(3),
                                 only)
        return value, grad @ body.rotation.T
    memo = body.geometry.setdefault("surface_fields", {})
    key = (surface, surface.map_keys(), np.asarray(frame, dtype=float).tobytes())
    if key not in memo:
        if len(memo) > 2:
            memo.clear()
        memo[key] = _fields_memo(surface, body.vertices, body.faces)
    return _fields_of(surface, memo[key], body.vertices, body.faces, frame, only)


def _fields_memo(surface, vertices, faces) -> dict:
    """An empty store of a mesh's facet fields (:func:`_fields_of`)."""
    return {"k": facet_sub_count(vertices, faces, _map_shape(surface), FIELD_SAMPLES, 2.2, most=32, least=24),
            "done": np.zeros(len(faces), bool), "value": None, "grad": None}


def _fields_of(surface, m: dict, vertices, faces, frame, only) -> tuple[np.ndarray, np.ndarray]:
    """The fields of facets ``only`` from the store ``m``, fitting those not yet there (mesh axes)."""
    only = np.asarray(only, dtype=np.int64)
    todo = only[~m["done"][only]]
    if todo.size:
        v, g = facet_linear_fit(lambda d: weights_at(surface, d @ frame), vertices, faces, m["k"], only=todo,
                                fit=_compiled_fits(surface, frame))
        if m["value"] is None:
            m["value"] = np.zeros((len(faces), v.shape[1]))
            m["grad"] = np.zeros((len(faces), v.shape[1], 3))
        m["value"][todo], m["grad"][todo] = v, g
        m["done"][todo] = True
    if m["value"] is None:  # (nothing asked yet: no facet lit and seen, as at full Moon)
        C = len(components(surface))
        return np.zeros((len(only), C)), np.zeros((len(only), C, 3))
    return m["value"][only], m["grad"][only]


def weights_toward(surfaces, scene, target: np.ndarray, rows: int | None = None) -> np.ndarray:
    """(C,) component weights as a Lambert Earth lit by a point Sun weights them toward a distant
    ``target`` (:meth:`Surfaces.earth_albedo_toward`'s rule, per component; ``rows``: its grid's)."""
    return np.atleast_1d(surfaces.earth_albedo_toward(scene, target, rows=rows,
                                                      values=lambda d: weights_at(surfaces.earth, d)))


def spectral_components(surface, nodes, mode: str = "surface") -> tuple[tuple, np.ndarray]:
    """A spectral run's Earth components and their (C, L) albedos at the node wavelengths: the
    surface's classes (:func:`components`, :func:`albedo_spectra`), or for a physical Earth one
    component per node (its reflectance there is the component's weight: albedos the identity)."""
    if surface.physical:
        return tuple(f"{wavelength_label(x)} nm" for x in nodes), np.eye(len(nodes))
    names = components(surface)
    return names, albedo_spectra(surface, names, nodes, mode)
