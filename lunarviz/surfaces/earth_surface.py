"""The Earth's surface as Lambert facets: ``--earth-surface uniform|landocean|FILE`` and
``--clouds none|zonal|FILE``.

``uniform`` (the scalar albedo), ``landocean`` (the global-land-mask package's 30″ land mask,
averaged to a 0.1° land fraction) or a clear-sky albedo map, combined per sample with a cloud
fraction c as ``(1 - c)·A_clear + c·A_cloud`` and then averaged by area (ocean glint and
anisotropic cloud reflection are neglected here: :mod:`lunarviz.surfaces.physical_earth` has them).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lunarviz.caches import file_key, memoize
from lunarviz.errors import LunarvizError
from lunarviz.options import BY_NAME, EARTH_PARAMETER_DEFAULTS, compose, earth_params, group, validate
from lunarviz.resources import DATA_DIR
from lunarviz.surfaces.maps import (
    check_range,
    facet_average,
    facet_sub_count,
    lat_lon_deg,
    read_map,
    sample_map,
    sample_map_at,
)

EARTH_SURFACES = ("uniform", "landocean")
CLOUDS = ("none", "zonal")
_LAND_BLOCK = 12  # 30″ mask cells per 0.1° land-fraction cell


def land_fraction_map() -> np.ndarray:
    """Land fraction on a 0.1° grid (1800, 3600) from the global-land-mask package's 30″ mask
    (block means of 12×12 cells; lakes count as land, as in the package). Derived once and
    cached on disk (``$LUNARVIZ_CACHE`` or ``~/.cache/lunarviz``)."""
    return _land_fraction()


@memoize(maxsize=4)
def _landocean_map(land_albedo: float, ocean_albedo: float) -> np.ndarray:
    """The land-ocean clear-sky albedo map (read-only, built once per pair of albedos: a map read
    chunk by chunk asked for it again each time, 0.03 s each)."""
    f = land_fraction_map()
    out = land_albedo * f + ocean_albedo * (1.0 - f)
    out.setflags(write=False)
    return out


@memoize(maxsize=1)
def _land_fraction() -> np.ndarray:
    cache = Path(os.environ.get("LUNARVIZ_CACHE", Path.home() / ".cache" / "lunarviz"))
    f = cache / "land_fraction_0.1deg_v1.npy"
    if f.is_file():
        try:
            counts = np.load(f)
            if counts.shape == (1800, 3600):
                return counts.astype(float) / _LAND_BLOCK**2
        except (OSError, ValueError):
            pass
    import importlib.util
    spec = importlib.util.find_spec("global_land_mask")
    if spec is None or not spec.submodule_search_locations:
        raise LunarvizError("--earth-surface landocean needs the global-land-mask package: "
                            "pip install global-land-mask")
    # the package's own file, read here (importing its ``globe`` module keeps ~1 GB alive)
    npz = Path(list(spec.submodule_search_locations)[0]) / "globe_combined_mask_compressed.npz"
    with np.load(npz) as z:
        ocean = z["mask"]  # (21600, 43200) bool, True = ocean; rows from +90° down, columns from -180°
    counts = np.empty((1800, 3600), dtype=np.uint8)
    step = 100  # blocks of rows at a time: bounded temporaries
    for r in range(0, 1800, step):
        blk = ocean[r * _LAND_BLOCK:(r + step) * _LAND_BLOCK].reshape(-1, _LAND_BLOCK, 3600, _LAND_BLOCK)
        counts[r:r + step] = _LAND_BLOCK**2 - blk.sum(axis=(1, 3), dtype=np.int32)
    del ocean
    try:
        cache.mkdir(parents=True, exist_ok=True)
        tmp = f.with_suffix(f".{os.getpid()}.tmp.npy")
        np.save(tmp, counts)
        os.replace(tmp, f)
    except OSError:
        pass  # a read-only home: recompute next time
    return counts.astype(float) / _LAND_BLOCK**2


@memoize(maxsize=1)
def zonal_cloud_table() -> tuple[np.ndarray, np.ndarray]:
    """Zonal-mean total cloud fraction: latitudes [deg] and fractions (lunarviz/data/zonal_clouds.csv)."""
    rows = [ln.split(",") for ln in (DATA_DIR / "zonal_clouds.csv").read_text().splitlines()
            if ln.strip() and not ln.startswith("#")]
    a = np.array([[float(x) for x in r] for r in rows[1:]])
    return a[:, 0], a[:, 1]


@dataclass(frozen=True)
@compose("earth")
class EarthSurface:
    """The Earth's surface: the options of the schema's ``earth`` group (:mod:`lunarviz.options`:
    ``earth_surface``, ``clouds``, ``earth_brdf``, the albedos), and the physical Earth's
    parameters as sorted (name, value) pairs (``--param earth.NAME=VALUE``,
    :data:`lunarviz.options.EARTH_PARAMETERS`)."""

    earth_params: tuple = ()

    def __post_init__(self):
        validate(self, group("earth"))
        if self.earth_params:
            earth_params(dict(self.earth_params))
        if self.earth_brdf == "physical":  # the classes carry their own albedos
            for name in ("land_albedo", "ocean_albedo", "cloud_albedo"):
                if getattr(self, name) != BY_NAME[name].default:
                    raise LunarvizError(f"--{name.replace('_', '-')} is the Lambert Earth's: --earth-brdf physical "
                                        f"takes its classes' own (docs: the Earth as it reflects)")
        if self.earth_surface not in EARTH_SURFACES:
            self.clear_map()  # a file: read and check now
        if self.clouds not in CLOUDS:
            self.cloud_map()

    @classmethod
    def from_options(cls, o) -> "EarthSurface":
        """The Earth surface that ``o`` (a resolved scene, the tracer's settings: anything with the
        ``earth`` options of :mod:`lunarviz.options`, and ``params`` or ``earth_params``) describes."""
        params = getattr(o, "params", None)
        earth = (params or {}).get("earth", {}) if params is not None else dict(getattr(o, "earth_params", ()))
        return cls(**{x.name: getattr(o, x.name) for x in group("earth")}, earth_params=tuple(sorted(earth.items())))

    @property
    def uniform(self) -> bool:
        """One Lambert albedo everywhere (the physical Earth never is: it reflects by geometry)."""
        return self.earth_surface == "uniform" and self.clouds == "none" and self.earth_brdf == "lambert"

    @property
    def physical(self) -> bool:
        return self.earth_brdf == "physical"

    @property
    def wavelength_nm(self) -> float:
        """The wavelength [nm] of a grey run's physical Earth (``earth.wavelength_nm``)."""
        return float(dict(self.earth_params).get("wavelength_nm", EARTH_PARAMETER_DEFAULTS["wavelength_nm"]))

    def map_keys(self) -> tuple:
        """The content keys (:func:`lunarviz.caches.file_key`) of the map files this surface reads:
        with it in a cache's key, a map rewritten in the same process is read again."""
        return tuple(file_key(p) for p, names in ((self.earth_surface, EARTH_SURFACES), (self.clouds, CLOUDS))
                     if p not in names)

    def clear_map(self):
        if self.earth_surface == "uniform":
            return None
        if self.earth_surface == "landocean":
            return _landocean_map(float(self.land_albedo), float(self.ocean_albedo))
        return _earth_map(file_key(self.earth_surface), "Earth surface map")

    def cloud_map(self):
        if self.clouds in CLOUDS:
            return None
        return _earth_map(file_key(self.clouds), "cloud-fraction map")

    def albedo_at(self, dirs: np.ndarray) -> np.ndarray:
        """Lambert albedo at directions (n, 3) in the Earth's map frame: clear sky and cloud
        combined as ``(1 - c) A_clear + c A_cloud``."""
        clear = self.clear_map()
        a = np.full(len(dirs), float(self.earth_albedo)) if clear is None else sample_map(clear, dirs)
        if self.clouds == "none":
            return a
        c = self.cloud_fraction_at(dirs)
        return (1.0 - c) * a + c * self.cloud_albedo

    def cloud_fraction_at(self, dirs: np.ndarray, lat_lon=None) -> np.ndarray:
        """Cloud fraction at directions (n, 3) in the Earth's map frame (0 without clouds);
        ``lat_lon``: their latitudes and longitudes [deg] (:func:`lat_lon_deg`), where known."""
        if self.clouds == "none":
            return np.zeros(len(dirs))
        lat, lon = lat_lon_deg(dirs) if lat_lon is None else lat_lon
        if self.clouds == "zonal":
            la, cf = zonal_cloud_table()
            return np.interp(lat, la, cf)
        return sample_map_at(self.cloud_map(), lat, lon)

    def varies(self, in_colour: bool) -> bool:
        """Whether the Earth's reflectance varies over its surface (so the ray tracer sums it per
        facet): not uniform, and its albedo not one value (:meth:`albedo_constant`; the physical
        Earth never is), or ``in_colour`` (a spectral run's components differ in their spectra even
        where their grey albedos agree)."""
        return not self.uniform and (in_colour or not self.albedo_constant())

    def albedo_constant(self) -> bool:
        """Whether the albedo is one value over the whole sphere, from the maps themselves: a
        constant clear-sky map (or none) under no clouds, a constant cloud fraction, or clouds of
        the clear sky's own albedo (the Lambert Earth; the physical Earth never is)."""
        if self.uniform:
            return True
        if self.physical:
            return False
        clear = self.clear_map()
        a = None if clear is None else (float(clear.flat[0]) if np.all(clear == clear.flat[0]) else None)
        if clear is None:
            a = float(self.earth_albedo)
        if a is None:
            return False
        if self.clouds == "none":
            return True
        if self.clouds == "zonal":
            c = zonal_cloud_table()[1]
        else:
            c = self.cloud_map()
        return bool(np.all(c == c.flat[0])) or a == float(self.cloud_albedo)

    def facet_albedo(self, body, frame: np.ndarray, only=None) -> np.ndarray:
        """Per-facet (area-averaged) albedo of an Embree body for map frame ``frame``; kept with
        the body's cached geometry (a θ sweep's Earth keeps one frame: computed once). ``only``:
        those facets' alone (sorted indices), as the whole mesh's give them, not kept."""
        if self.uniform:
            return np.full(body.n_faces if only is None else len(only), float(self.earth_albedo))
        memo = body.geometry.setdefault("surface_albedo", {})
        key = (self, self.map_keys(), np.asarray(frame, dtype=float).tobytes())
        if only is not None:
            return memo[key][only] if key in memo else self._facet_albedo(body, frame, only)
        if key not in memo:
            if len(memo) > 8:
                memo.clear()
            memo[key] = self._facet_albedo(body, frame)
        return memo[key]

    def _facet_albedo(self, body, frame: np.ndarray, only=None) -> np.ndarray:
        shape = (1800, 3600) if self.earth_surface == "landocean" else \
            (self.clear_map().shape if self.earth_surface != "uniform" else (180, 360))
        k = facet_sub_count(body.vertices, body.faces, shape)
        return facet_average(lambda d: self.albedo_at(d @ frame), body.vertices, body.faces, k, only=only)


@memoize(maxsize=8)
def _earth_map(key: tuple, what: str) -> np.ndarray:
    """The Earth map at ``key`` (:func:`lunarviz.caches.file_key`), checked."""
    path = key[0]
    m = read_map(path, what)
    check_range(m, f"{what} {path!r}")
    m.setflags(write=False)
    return m
