"""Per-facet surface properties from maps: a lunar albedo map and a land, ocean and cloud Earth.

Maps are equirectangular in the body frame (docs: conventions, "Maps"): row 0 is latitude +90° (north
up), column 0 starts at longitude −180°, east-positive, cells pixel-centred, ``width = 2·height``.
``.npy`` arrays hold values directly; ``.png``/``.tif`` images are read as linear values scaled
to [0, 1] (8- and 16-bit integers by their full range, float images as they are; colour images by
the mean of their colour channels).

The body frame is MOON_ME for the Moon and ITRS for the Earth on dates (the mesh frame there);
in the paper's θ scene the north poles are +x, the Moon's map (0°, 0°) faces the Earth (tidal
lock) and the Earth's sub-solar longitude is ``earth_rotation_deg`` (:func:`map_frame`).

Facet values are *area* averages: each facet is split into k² equal sub-triangles and the map is
read (nearest cell) at every sub-triangle's centroid, k chosen so the samples are finer than the
map's cells (:func:`facet_average`). Quadrature methods without facets (``analytic``,
``reference``) read the map at their nodes (:func:`sample_map`).

Earth surfaces (Lambert per facet; ocean glint and anisotropic cloud reflection are neglected):
``uniform`` (the scalar albedo), ``landocean`` (the global-land-mask package's 30″ land mask,
averaged to a 0.1° land fraction) or a clear-sky albedo map, combined per sample with a cloud
fraction c as ``(1 - c)·A_clear + c·A_cloud`` and then averaged by area.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lunarviz.caches import file_key, memoize
from lunarviz.errors import LunarvizError
from lunarviz.geometry.subdivision import sub_barycentric
from lunarviz.resources import DATA_DIR

MAP_SUFFIXES = (".npy", ".png", ".tif", ".tiff")
DATA = DATA_DIR
#: the synthetic lunar albedo map shipped for tests and demos (scripts/make_synthetic_moon_map.py)
SYNTHETIC_MOON_MAP = DATA / "synthetic_moon_albedo.npy"
EARTH_SURFACES = ("uniform", "landocean")
CLOUDS = ("none", "zonal")
#: Default Lambert albedos of the ``landocean`` Earth (broadband, visible):
#: ocean 0.06, the diffuse sea-surface albedo (Payne 1972, J. Atmos. Sci. 29, 959);
#: land 0.25, a mid value of land surfaces (0.1 forest to 0.4 desert; Hartmann 2016, Global
#: Physical Climatology, 2nd ed., Table 4.2); cloud 0.4, chosen so that with ``zonal`` clouds
#: the global mean is 0.30 (the paper's Earth; CERES Bond albedo 0.29, Stephens et al. 2015,
#: Rev. Geophys. 53, 141). They are parameters (``--land-albedo`` ...), not measurements.
LAND_ALBEDO, OCEAN_ALBEDO, CLOUD_ALBEDO = 0.25, 0.06, 0.40
#: samples per facet side are capped so one facet average reads at most this many cells in all
MAX_SAMPLES = 8_000_000
_LAND_BLOCK = 12  # 30″ mask cells per 0.1° land-fraction cell


# --------------------------------------------------------------------------------------------
# reading and checking maps
# --------------------------------------------------------------------------------------------
#: the most cells a map may have (a 0.01° global grid is 6.5e8): 5e7 cells are 0.4 GB as float64
MAX_MAP_CELLS = 50_000_000


def read_grid(path, what: str = "map", error=LunarvizError) -> np.ndarray:
    """A 2-D grid of real, finite numbers from ``.npy`` (values) or ``.png``/``.tif`` (linear,
    scaled to [0, 1]: 8- and 16-bit integers by their full range, float images as they are,
    palette and colour images by the mean of their RGB channels); ``error`` (one line) otherwise.
    Shared by the surface maps and the DEM meshes (:func:`lunarviz.bodies.shapes.read_map`)."""
    import stat
    p = Path(path)
    suffix = p.suffix.lower()
    try:
        regular = stat.S_ISREG(p.stat().st_mode)
    except OSError:
        regular = False
    if not regular:  # a FIFO or device would block the reader
        raise error(f"{what} {str(path)!r}: file not found (or not a regular file)")
    if suffix not in MAP_SUFFIXES:
        raise error(f"{what} {str(path)!r}: unknown format {suffix or '(none)'}; use {', '.join(MAP_SUFFIXES)}")
    try:
        if suffix == ".npy":
            a = np.load(p, allow_pickle=False, mmap_mode="r")
            if a.size > MAX_MAP_CELLS:
                raise error(f"{what} {str(path)!r}: {a.size:,} cells is more than the {MAX_MAP_CELLS:,} a map may "
                            f"have ({8 * a.size / 2**30:.1f} GiB as float64)")
            a = np.array(a)
        else:
            import warnings

            from PIL import Image
            with warnings.catch_warnings():  # Pillow's bomb warning: our own cap below speaks instead
                warnings.simplefilter("ignore", Image.DecompressionBombWarning)
                im = Image.open(p)
            with im:  # the header only: nothing is decoded before the size is checked
                if im.width * im.height > MAX_MAP_CELLS:
                    raise error(f"{what} {str(path)!r}: {im.width}×{im.height} pixels is more than the "
                                f"{MAX_MAP_CELLS:,} a map may have")
                if im.mode in ("P", "PA", "LA", "RGBA", "CMYK", "YCbCr", "LAB", "HSV"):
                    im = im.convert("RGB")
                if im.mode == "I":  # 32-bit integers: no full range to scale by
                    raise error(f"{what} {str(path)!r}: 32-bit integer images are ambiguous; save 8- or 16-bit "
                                f"integers, floats, or a .npy array")
                bits16 = im.mode.startswith("I;16")
                a = np.asarray(im)
            if bits16:
                a = a.astype(float) / 65535.0
            elif a.dtype == bool:
                a = a.astype(float)
            elif a.dtype.kind in "ui":
                a = a.astype(float) / float(np.iinfo(a.dtype).max)
            if a.ndim == 3:
                a = a[..., :3].mean(axis=2)
    except LunarvizError:
        raise
    except Exception as exc:  # noqa: BLE001 (any reader failure is a bad file)
        raise error(f"{what} {str(path)!r}: unreadable ({type(exc).__name__}: {exc})") from None
    if a.dtype.kind not in "fiub":
        raise error(f"{what} {str(path)!r}: values of type {a.dtype} are not real numbers")
    a = np.asarray(a, dtype=float)
    if a.ndim != 2 or min(a.shape) < 2:
        raise error(f"{what} {str(path)!r}: shape {a.shape} is not a 2-D grid (rows = latitude, columns = longitude)")
    if not np.all(np.isfinite(a)):
        raise error(f"{what} {str(path)!r}: holds {int((~np.isfinite(a)).sum())} NaN or infinite values")
    return a


def read_map(path, what: str = "map") -> np.ndarray:
    """An equirectangular map as float64 (H, 2H) (:func:`read_grid`); one-line error otherwise."""
    a = read_grid(path, what)
    if a.shape[1] != 2 * a.shape[0]:
        raise LunarvizError(f"{what} {str(path)!r} has shape {a.shape}: an equirectangular map has width = 2 × "
                            f"height (e.g. (180, 360))")
    return a


def map_scale(absolute: bool, brdf) -> float:
    """Factor from a lunar map's values to ``brdf``'s albedo parameter: 1 for a ``FILE:MEAN``
    map (its values are the parameter), the BRDF's own parameter for a pattern (``FILE``)."""
    return 1.0 if absolute else brdf.albedo_parameter


def check_range(values: np.ndarray, what: str, lo: float = 0.0, hi: float = 1.0) -> None:
    vmin, vmax = float(np.min(values)), float(np.max(values))
    if vmin < lo or vmax > hi:
        bad = vmax if vmax > hi else vmin
        raise LunarvizError(f"{what} holds {bad:g}, outside [{lo:g}, {hi:g}]")


def cell_areas(shape) -> np.ndarray:
    """Relative areas (H, 1) of the rows of an equirectangular map on the sphere (exact)."""
    h = shape[0]
    edges = np.radians(90.0 - 180.0 * np.arange(h + 1) / h)
    return (np.sin(edges[:-1]) - np.sin(edges[1:]))[:, None]


def map_mean(m: np.ndarray) -> float:
    """Area-weighted mean of an equirectangular map over the sphere."""
    w = cell_areas(m.shape)
    return float((m * w).sum() / (w.sum() * m.shape[1]))


# --------------------------------------------------------------------------------------------
# frames and sampling
# --------------------------------------------------------------------------------------------
def lat_lon_deg(dirs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Planetocentric latitude and east longitude [deg] of directions (n, 3) in a body frame."""
    d = np.asarray(dirs, dtype=float)
    r = np.linalg.norm(d, axis=-1)
    lat = np.degrees(np.arcsin(np.clip(d[..., 2] / r, -1.0, 1.0)))
    lon = np.degrees(np.arctan2(d[..., 1], d[..., 0]))
    return lat, lon


def sample_map(m: np.ndarray, dirs: np.ndarray) -> np.ndarray:
    """The map's cell value (nearest cell) at directions (..., 3) in the map's frame."""
    lat, lon = lat_lon_deg(dirs)
    h, w = m.shape
    row = np.clip(((90.0 - lat) / 180.0 * h).astype(np.int64), 0, h - 1)
    col = np.clip(((lon + 180.0) / 360.0 * w).astype(np.int64), 0, w - 1)
    return m[row, col]


def _rot_x(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def _rot_z(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def map_frame(scene, body: str, earth_rotation_deg: float = 0.0) -> np.ndarray:
    """Rotation ``x_scene = R @ x_map`` of ``body``'s map frame.

    Dated scenes: the body's own frame (MOON_ME, ITRS), which is also its mesh's frame. The θ
    scene (docs: conventions): north poles along +x; the Moon's map (0°, 0°) toward the Earth (tidally
    locked, no libration); the Earth's sub-solar point at longitude ``earth_rotation_deg`` on
    its equator (the Sun lies in the equatorial plane: an equinox).
    """
    if scene.general:
        r = scene.rotation(body)
        return np.eye(3) if r is None else r
    z = np.array([1.0, 0.0, 0.0])  # north pole
    if body == "moon":
        x = -scene.moon / np.linalg.norm(scene.moon)  # sub-Earth point
        lon0 = 0.0
    else:
        x = (scene.sun - scene.earth) / np.linalg.norm(scene.sun - scene.earth)  # sub-solar point
        lon0 = np.radians(earth_rotation_deg)
    y = np.cross(z, x)
    base = np.stack([x, y, z], axis=1)  # body (lon 0, lat 0) → x, east → y, pole → z
    return base @ _rot_z(-lon0)


def facet_sub_count(vertices, faces, m_shape, max_samples: int = MAX_SAMPLES) -> int:
    """k such that k² samples per facet are finer than the map's cells (capped)."""
    tri = vertices[faces]
    r = np.linalg.norm(vertices, axis=1).mean()
    edge = float(np.sqrt(np.mean(np.sum((tri[:, 1] - tri[:, 0]) ** 2, axis=1)))) / r  # rad
    cell = np.pi / m_shape[0]
    k = int(np.ceil(2.0 * edge / cell))
    cap = int(np.sqrt(max_samples / max(len(faces), 1)))
    return int(max(min(8, cap), min(k, 16, max(cap, 1))))


def facet_points(vertices, faces, k: int, rng: np.random.Generator | None = None) -> np.ndarray:
    """(F, k², 3) points, one uniform in each of the k² equal sub-triangles of each facet
    (body-centred): stratified and jittered, so a map's pattern cannot line up with the mesh's
    (the sub-triangles' centroids of an icosphere sit on its symmetry circles and bias a banded
    map by up to 1e-3). ``rng`` ``None``: the centroids."""
    cen, corners = sub_barycentric(k)
    if rng is None:
        return np.einsum("sk,fkj->fsj", cen, vertices[faces])
    F, S = len(faces), len(cen)
    r1, r2 = rng.random((F, S)), rng.random((F, S))
    s1 = np.sqrt(r1)
    # uniform in a triangle: (1 - √r1) A + √r1 (1 - r2) B + √r1 r2 C, in barycentric coordinates
    bary = ((1 - s1)[..., None] * corners[None, :, 0] + (s1 * (1 - r2))[..., None] * corners[None, :, 1]
            + (s1 * r2)[..., None] * corners[None, :, 2])  # (F, S, 3)
    return np.einsum("fsk,fkj->fsj", bary, vertices[faces])


#: the fixed seed of the jittered facet samples: results are deterministic
SAMPLE_SEED = 20261124


def facet_average(values_at, vertices, faces, k: int, chunk: int = 65536, spread: bool = False):
    """Area average over each facet of ``values_at(dirs)`` (dirs (n, 3) in the mesh frame; values
    (n,) or (n, C): then (F, C) averages), from k² stratified, jittered points per facet
    (deterministic: a fixed seed); with ``spread`` also the values' standard deviation over the
    facet (``(mean, std)``)."""
    out = None
    sd = np.zeros(len(faces))
    rng = np.random.default_rng(SAMPLE_SEED)
    for a in range(0, len(faces), chunk):
        p = facet_points(vertices, faces[a:a + chunk], k, rng)
        v = values_at(p.reshape(-1, 3))
        v = v.reshape(p.shape[:2] + v.shape[1:])
        if out is None:
            out = np.empty((len(faces),) + v.shape[2:])
        out[a:a + chunk] = v.mean(axis=1)
        if spread:
            sd[a:a + chunk] = v.std(axis=1)
    if out is None:
        out = np.empty(len(faces))
    return (out, sd) if spread else out


# --------------------------------------------------------------------------------------------
# the Moon
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class MoonAlbedoMap:
    """``--moon-albedo-map FILE[:MEAN]`` (``FILE`` may be ``synthetic``, the shipped demo map).

    ``FILE``: a pattern. Each BRDF's albedo parameter (Lambert albedo, Hapke w) is multiplied per
    facet by ``map / ⟨map⟩`` (⟨⟩ the area-weighted mean over the sphere): every BRDF keeps its
    own mean, and a uniform map changes nothing. ``FILE:MEAN``: the map is normalised to the
    area-weighted mean MEAN and its values *are* the albedo parameter of every BRDF.
    """

    path: str
    mean: float | None = None

    @classmethod
    def parse(cls, text: str) -> "MoonAlbedoMap":
        text = str(text).strip()
        if not text:
            raise LunarvizError("--moon-albedo-map is empty: give FILE[:MEAN] or synthetic[:MEAN]")
        path, mean = text, None
        head, sep, tail = text.rpartition(":")
        if sep and head and not tail.startswith(("\\", "/")) and not Path(text).is_file():
            try:
                mean = float(tail)
            except ValueError:
                raise LunarvizError(f"--moon-albedo-map {text!r}: the mean after ':' must be a number, "
                                    f"not {tail!r}") from None
            path = head
            if not (np.isfinite(mean) and 0.0 < mean <= 1.0):
                raise LunarvizError(f"--moon-albedo-map mean {tail!r} must be in (0, 1]")
        out = cls(path, mean)
        out.values()  # read and check now, before any work
        return out

    @property
    def absolute(self) -> bool:
        return self.mean is not None

    def source(self) -> Path:
        return SYNTHETIC_MOON_MAP if self.path == "synthetic" else Path(self.path)

    def values(self) -> np.ndarray:
        """The map, normalised: mean 1 (a pattern) or mean MEAN (albedo values)."""
        return _moon_map_values(file_key(self.source()), self.mean)

    def check_brdfs(self, brdfs: dict) -> None:
        """Every BRDF's per-facet albedo parameter stays within [0, 1]."""
        v = self.values()
        for name, b in brdfs.items():
            top = float(v.max()) * map_scale(self.absolute, b)
            if top > 1.0:
                pname = "albedo" if name == "lambert" else "w"
                raise LunarvizError(f"--moon-albedo-map {self.path!r} gives {name} {pname} up to {top:.3g} > 1: "
                                    f"give a smaller :MEAN or a smaller {pname}")


@memoize(maxsize=8)
def _moon_map_values(key: tuple, mean: float | None) -> np.ndarray:
    """The lunar map at ``key`` (:func:`lunarviz.caches.file_key`), scaled to ``mean``."""
    path = key[0]
    m = read_map(path, "Moon albedo map")
    mu = map_mean(m)
    if mu <= 0.0:
        raise LunarvizError(f"Moon albedo map {path!r} has mean {mu:g}: it must be positive")
    check_range(m, f"Moon albedo map {path!r}", 0.0, np.inf)
    out = m / mu * (1.0 if mean is None else mean)
    if mean is not None:
        check_range(out, f"Moon albedo map {path!r} normalised to mean {mean:g}")
    out.setflags(write=False)
    return out


def moon_facet_values(amap: MoonAlbedoMap, body, frame: np.ndarray, faces=None):
    """Per-facet map values on an Embree body (vertices in scene axes, body-centred), for a map
    frame ``frame`` (:func:`map_frame`): ``(mean, std)`` over each facet (or over each triangle
    of ``faces`` into ``body.vertices``-like ``(vertices, faces)``)."""
    m = amap.values()
    verts, tris = (body.vertices, body.faces) if faces is None else faces
    k = facet_sub_count(verts, tris, m.shape)
    return facet_average(lambda d: sample_map(m, d @ frame), verts, tris, k, spread=True)


# --------------------------------------------------------------------------------------------
# the Earth
# --------------------------------------------------------------------------------------------
def land_fraction_map() -> np.ndarray:
    """Land fraction on a 0.1° grid (1800, 3600) from the global-land-mask package's 30″ mask
    (block means of 12×12 cells; lakes count as land, as in the package). Derived once and
    cached on disk (``$LUNARVIZ_CACHE`` or ``~/.cache/lunarviz``)."""
    return _land_fraction()


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
    rows = [ln.split(",") for ln in (DATA / "zonal_clouds.csv").read_text().splitlines()
            if ln.strip() and not ln.startswith("#")]
    a = np.array([[float(x) for x in r] for r in rows[1:]])
    return a[:, 0], a[:, 1]


@dataclass(frozen=True)
class EarthSurface:
    """``--earth-surface uniform|landocean|FILE`` and ``--clouds none|zonal|FILE``."""

    surface: str = "uniform"
    clouds: str = "none"
    albedo: float = 0.3  # the uniform surface's (clear-sky) albedo
    land_albedo: float = LAND_ALBEDO
    ocean_albedo: float = OCEAN_ALBEDO
    cloud_albedo: float = CLOUD_ALBEDO
    #: ``lambert`` or ``physical`` (:mod:`lunarviz.bodies.physical_earth`), and the physical Earth's
    #: parameters as sorted (name, value) pairs
    brdf: str = "lambert"
    earth_params: tuple = ()

    def __post_init__(self):
        if self.brdf not in ("lambert", "physical"):
            raise LunarvizError(f"Earth BRDF {self.brdf!r} is not one of lambert, physical")
        if self.earth_params:
            from lunarviz.earth_optics.surfaces import earth_params
            earth_params(dict(self.earth_params))
        if self.brdf == "physical":  # the classes carry their own albedos
            for name, default in (("land_albedo", LAND_ALBEDO), ("ocean_albedo", OCEAN_ALBEDO),
                                  ("cloud_albedo", CLOUD_ALBEDO)):
                if getattr(self, name) != default:
                    raise LunarvizError(f"--{name.replace('_', '-')} is the Lambert Earth's: --earth-brdf physical "
                                        f"takes its classes' own (docs: the Earth as it reflects)")
        for name in ("albedo", "land_albedo", "ocean_albedo", "cloud_albedo"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float, np.number)) and np.isfinite(v) and 0.0 <= v <= 1.0):
                raise LunarvizError(f"{name.replace('_', ' ')} {v!r} must be a number in [0, 1]")
        if self.surface not in EARTH_SURFACES:
            self.clear_map()  # a file: read and check now
        if self.clouds not in CLOUDS:
            self.cloud_map()

    @classmethod
    def from_options(cls, o) -> "EarthSurface":
        """The Earth surface that settings ``o`` (any object with the ``surfaces`` options of
        :mod:`lunarviz.options` and ``earth_albedo``) describe."""
        params = getattr(o, "params", None)
        earth = (params or {}).get("earth", {}) if params is not None else dict(getattr(o, "earth_params", ()))
        return cls(o.earth_surface, o.clouds, o.earth_albedo, o.land_albedo, o.ocean_albedo, o.cloud_albedo,
                   getattr(o, "earth_brdf", "lambert"), tuple(sorted(earth.items())))

    @property
    def uniform(self) -> bool:
        """One Lambert albedo everywhere (the physical Earth never is: it reflects by geometry)."""
        return self.surface == "uniform" and self.clouds == "none" and self.brdf == "lambert"

    @property
    def physical(self) -> bool:
        return self.brdf == "physical"

    @property
    def wavelength_nm(self) -> float:
        """The wavelength [nm] of a grey run's physical Earth (``earth.wavelength_nm``)."""
        return float(dict(self.earth_params).get("wavelength_nm", 550.0))

    def clear_map(self):
        if self.surface == "uniform":
            return None
        if self.surface == "landocean":
            f = land_fraction_map()
            return self.land_albedo * f + self.ocean_albedo * (1.0 - f)
        return _earth_map(file_key(self.surface), "Earth surface map")

    def cloud_map(self):
        if self.clouds in CLOUDS:
            return None
        return _earth_map(file_key(self.clouds), "cloud-fraction map")

    def albedo_at(self, dirs: np.ndarray) -> np.ndarray:
        """Lambert albedo at directions (n, 3) in the Earth's map frame: clear sky and cloud
        combined as ``(1 - c) A_clear + c A_cloud``."""
        clear = self.clear_map()
        a = np.full(len(dirs), float(self.albedo)) if clear is None else sample_map(clear, dirs)
        if self.clouds == "none":
            return a
        c = self.cloud_fraction_at(dirs)
        return (1.0 - c) * a + c * self.cloud_albedo

    def cloud_fraction_at(self, dirs: np.ndarray) -> np.ndarray:
        """Cloud fraction at directions (n, 3) in the Earth's map frame (0 without clouds)."""
        if self.clouds == "none":
            return np.zeros(len(dirs))
        if self.clouds == "zonal":
            lat, _ = lat_lon_deg(dirs)
            la, cf = zonal_cloud_table()
            return np.interp(lat, la, cf)
        return sample_map(self.cloud_map(), dirs)

    def facet_albedo(self, body, frame: np.ndarray) -> np.ndarray:
        """Per-facet (area-averaged) albedo of an Embree body for map frame ``frame``; kept with
        the body's cached geometry (a θ sweep's Earth keeps one frame: computed once)."""
        if self.uniform:
            return np.full(body.n_faces, float(self.albedo))
        memo = body.geometry.setdefault("surface_albedo", {})
        key = (self, np.asarray(frame, dtype=float).tobytes())
        if key not in memo:
            if len(memo) > 8:
                memo.clear()
            memo[key] = self._facet_albedo(body, frame)
        return memo[key]

    def _facet_albedo(self, body, frame: np.ndarray) -> np.ndarray:
        shape = (1800, 3600) if self.surface == "landocean" else \
            (self.clear_map().shape if self.surface != "uniform" else (180, 360))
        k = facet_sub_count(body.vertices, body.faces, shape)
        return facet_average(lambda d: self.albedo_at(d @ frame), body.vertices, body.faces, k)


@memoize(maxsize=8)
def _earth_map(key: tuple, what: str) -> np.ndarray:
    """The Earth map at ``key`` (:func:`lunarviz.caches.file_key`), checked."""
    path = key[0]
    m = read_map(path, what)
    check_range(m, f"{what} {path!r}")
    m.setflags(write=False)
    return m


# --------------------------------------------------------------------------------------------
# point values for the quadrature methods (analytic, reference)
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Surfaces:
    """The surfaces of a scene for methods without facets: the lunar map and the Earth's
    surface read at points (nearest cell; see the module docstring)."""

    moon_map: MoonAlbedoMap | None = None
    earth: EarthSurface = EarthSurface()
    earth_rotation_deg: float = 0.0

    def moon_values_at(self, scene, points: np.ndarray):
        """Lunar map values at lunar surface points (n, 3) [m] (scene frame), or ``None``."""
        if self.moon_map is None:
            return None
        d = (np.asarray(points) - scene.moon) @ map_frame(scene, "moon")
        return sample_map(self.moon_map.values(), d)

    def earth_albedo_at(self, scene, points: np.ndarray) -> np.ndarray | float:
        """Earth albedo at Earth surface points (..., 3) [m] (scene frame); the scalar if uniform."""
        if self.earth.uniform:
            return float(self.earth.albedo)
        p = np.asarray(points) - scene.earth
        d = p.reshape(-1, 3) @ map_frame(scene, "earth", self.earth_rotation_deg)
        return self.earth.albedo_at(d).reshape(p.shape[:-1])

    def earth_albedo_toward(self, scene, target: np.ndarray, rows: int | None = None, values=None):
        """The Earth's albedo as a Lambert Earth lit by a point Sun weights it toward a distant
        ``target`` (the Moon's centre): ``∫A μ_s μ_t dA / ∫μ_s μ_t dA`` over the sphere, on a
        grid of cells at least as fine as the surface's maps (the map's value per cell).
        ``values``: a function of map-frame directions (n, 3) giving (n,) or (n, C) values to
        weight instead of the albedo (:mod:`lunarviz.spectral.earth`'s components)."""
        if self.earth.uniform and values is None:
            return float(self.earth.albedo)
        if self.earth.physical:
            raise AssertionError("a physical Earth: use lunarviz.bodies.physical_earth.albedo_toward")  # a caller bug
        values = values or self.earth.albedo_at
        clear = self.earth.clear_map()
        n = max(360, min(1800, 0 if clear is None else clear.shape[0]))
        lat = np.radians(90.0 - (np.arange(n) + 0.5) * 180.0 / n)
        lon = np.radians(-180.0 + (np.arange(2 * n) + 0.5) * 180.0 / n)
        frame = map_frame(scene, "earth", self.earth_rotation_deg)
        us = (scene.sun - scene.earth) / np.linalg.norm(scene.sun - scene.earth)
        ut = (target - scene.earth) / np.linalg.norm(target - scene.earth)
        num = den = 0.0
        cl = np.cos(lon)
        sl = np.sin(lon)
        for a in range(0, n, 90):
            la = lat[a:a + 90, None]
            d = np.stack([np.cos(la) * cl, np.cos(la) * sl, np.broadcast_to(np.sin(la), (len(la), 2 * n))], -1)
            ds = d @ frame.T  # scene frame
            w = np.clip(ds @ us, 0, None) * np.clip(ds @ ut, 0, None) * np.cos(la)
            if not w.any():
                continue
            A = values(d.reshape(-1, 3))
            A = A.reshape(w.shape + A.shape[1:])
            if A.ndim == 2:
                num += float((A * w).sum())
            else:
                num = num + (A * w[..., None]).sum(axis=(0, 1))
            den += float(w.sum())
        if np.ndim(num) == 0:
            return float(num) / den if den > 0 else float("nan")
        return num / den if den > 0 else np.full(np.shape(num), np.nan)
