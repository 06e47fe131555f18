"""Body shapes you can ask for: triaxial ellipsoids, DEM topography, seeded cratered Moons and
locally refined ("patch") spheres, as closed triangle meshes in metres in the body frame.

Every shape starts from a trimesh icosphere at a chosen subdivision level, optionally warped
by a conformal zoom that moves resolution toward one point (:func:`zoom_toward`), then has
its vertices displaced radially (DEM, craters) or scaled per axis (ellipsoid). So every mesh
is watertight with outward normals by construction, and ``lunarviz mesh make`` writes them
for reuse with ``--moon-mesh`` and friends. None of these meshes is tagged as an analytic
shape: the tracer shades them on their facets (or crease-limited interpolated normals).

Crater morphology (simple, fresh, bowl-shaped craters):

* depth/diameter d/D = 0.196 (Pike 1977, "Size-dependence in the shape of fresh impact
  craters on the Moon", Proc. Lunar Sci. Conf. 8, 3427: d = 0.196 D^1.010 for simple craters);
* rim height h_r = 0.036 D (Pike 1977: h_r = 0.036 D^1.014);
* interior: a paraboloid from the floor (h_r − d at the centre) to the rim crest (h_r at
  ρ = D/2);
* exterior: the ejecta blanket thins as h_r (ρ/r)^−3 (McGetchin, Settle & Head 1973, EPSL 20,
  226), cut to zero beyond 3 r;
* sizes: a cumulative power law N(>D) ∝ D^−2 between ``d_min`` and ``d_max`` (the slope of
  the lunar production function for D of a few km to ~100 km, Neukum, Ivanov & Hartmann 2001,
  Space Sci. Rev. 96, 55), drawn by inverse transform; centres uniform on the sphere or inside
  a cap. Overlapping craters add their height profiles (no degradation modelled).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

from lunarviz.bodies.meshes import MeshError, unit_icosphere
from lunarviz.outputs.writers import atomic_path
from lunarviz.surfaces.maps import read_grid

SHAPES = ("sphere", "ellipsoid", "dem", "craters", "patch")
#: Pike (1977) simple-crater ratios (module docstring).
DEPTH_RATIO = 0.196
RIM_RATIO = 0.036
#: Ejecta profile cut-off [crater radii].
EJECTA_EXTENT = 3.0
#: Cumulative size-frequency slope: N(>D) ∝ D^SFD_SLOPE.
SFD_SLOPE = -2.0


def _lonlat_to_unit(lon_deg, lat_deg) -> np.ndarray:
    lon, lat = np.radians(lon_deg), np.radians(lat_deg)
    return np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)], axis=-1)


def unit_to_lonlat(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """East-positive longitude in [−180, 180) and latitude [deg] of unit vectors (body frame:
    +z north, +x at longitude 0)."""
    lat = np.degrees(np.arctan2(u[..., 2], np.hypot(u[..., 0], u[..., 1])))
    lon = np.degrees(np.arctan2(u[..., 1], u[..., 0]))
    return lon, lat


def zoom_toward(unit_vertices: np.ndarray, centre: np.ndarray, k: float) -> np.ndarray:
    """Conformal zoom of points on the unit sphere toward ``centre``: stereographic projection
    from the antipode, scaling by 1/k, and back. Facet sizes shrink by k near ``centre`` and
    grow by k at the antipode; angles (facet shapes) are preserved, and a closed mesh stays
    closed (a local high-resolution patch without T-junctions)."""
    if not (np.isfinite(k) and k >= 1):
        raise MeshError(f"patch zoom {k!r} must be a number ≥ 1")
    c = centre / np.linalg.norm(centre)
    # rotation taking c to +z
    a = np.cross(c, [0.0, 0.0, 1.0])
    s, cz = np.linalg.norm(a), c[2]
    if s < 1e-15:
        Rm = np.eye(3) if cz > 0 else np.diag([1.0, -1.0, -1.0])
    else:
        a = a / s
        K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
        Rm = np.eye(3) + s * K + (1 - cz) * K @ K
    v = unit_vertices @ Rm.T
    # polar angle ψ from the patch centre: tan(ψ'/2) = tan(ψ/2)/k (stereographic scaling),
    # azimuth kept; written with atan2 so the antipode (ψ = π) stays put
    rho = np.hypot(v[:, 0], v[:, 1])
    psi = np.arctan2(rho, v[:, 2])
    psi2 = 2.0 * np.arctan2(np.sin(psi / 2), k * np.cos(psi / 2))
    with np.errstate(invalid="ignore", divide="ignore"):
        cx = np.where(rho > 0, v[:, 0] / rho, 1.0)
        cy = np.where(rho > 0, v[:, 1] / rho, 0.0)
    v2 = np.stack([np.sin(psi2) * cx, np.sin(psi2) * cy, np.cos(psi2)], axis=1)
    return v2 @ Rm


def base_sphere(level: int, patch: tuple[float, float, float] | None = None) -> trimesh.Trimesh:
    """Unit icosphere at ``level``, optionally zoomed toward ``patch = (lat, lon, k)``."""
    m = unit_icosphere(level)
    v = np.asarray(m.vertices, dtype=float)
    if patch is not None:
        lat, lon, k = patch
        v = zoom_toward(v, _lonlat_to_unit(lon, lat), k)
    return trimesh.Trimesh(v, m.faces, process=False)


def ellipsoid(a: float, b: float, c: float, level: int, patch=None) -> trimesh.Trimesh:
    """Triaxial ellipsoid with semi-axes a, b, c [m] along x, y, z."""
    for name, v in (("a", a), ("b", b), ("c", c)):
        if not (np.isfinite(v) and v > 0):
            raise MeshError(f"ellipsoid semi-axis {name}={v!r} must be positive")
    m = base_sphere(level, patch)
    return trimesh.Trimesh(np.asarray(m.vertices) * [a, b, c], m.faces, process=False)


def read_map(path) -> np.ndarray:
    """An equirectangular map (.npy values, or .png/.tif image scaled to [0, 1]) as float64
    (rows from +90° to −90°, columns from −180° eastward, pixel-centred):
    :func:`lunarviz.surfaces.maps.read_grid`, errors as :class:`MeshError`."""
    return read_grid(path, "map", MeshError)


def sample_map(grid: np.ndarray, lon_deg, lat_deg) -> np.ndarray:
    """Bilinear value of an equirectangular ``grid`` at (lon, lat) [deg], periodic in longitude."""
    from scipy.interpolate import RegularGridInterpolator
    ny, nx = grid.shape
    lat_c = 90.0 - (np.arange(ny) + 0.5) * 180.0 / ny
    lon_c = -180.0 + (np.arange(nx) + 0.5) * 360.0 / nx
    # wrap one column each side; clamp latitude to the outer pixel centres
    lon_w = np.concatenate([[lon_c[-1] - 360.0], lon_c, [lon_c[0] + 360.0]])
    g = np.concatenate([grid[:, -1:], grid, grid[:, :1]], axis=1)
    f = RegularGridInterpolator((lat_c[::-1], lon_w), g[::-1], bounds_error=False, fill_value=None)
    lat = np.clip(lat_deg, lat_c[-1], lat_c[0])
    lon = (np.asarray(lon_deg) + 180.0) % 360.0 - 180.0
    return f(np.stack([lat, lon], axis=-1))


def dem(path, radius: float, height_scale: float, level: int, patch=None) -> trimesh.Trimesh:
    """Topography: heights ``height_scale × map`` [m] draped radially on a sphere of ``radius``."""
    if not (np.isfinite(height_scale)):
        raise MeshError(f"DEM height scale {height_scale!r} must be finite")
    grid = read_map(path)
    m = base_sphere(level, patch)
    u = np.asarray(m.vertices)
    lon, lat = unit_to_lonlat(u)
    h = height_scale * sample_map(grid, lon, lat)
    r = radius + h
    if np.any(r <= 0.05 * radius):
        raise MeshError(f"DEM {path}: heights × {height_scale:g} reach the body's centre")
    return trimesh.Trimesh(u * r[:, None], m.faces, process=False)


def crater_population(n: int, d_min: float, d_max: float, seed: int,
                      region: tuple[float, float, float] | None = None):
    """``n`` crater centres (unit vectors) and diameters [m]: N(>D) ∝ D^SFD_SLOPE on
    [d_min, d_max], centres uniform on the sphere or in the cap ``region = (lat, lon, radius_deg)``."""
    if not (isinstance(n, (int, np.integer)) and n >= 0):
        raise MeshError(f"crater count {n!r} must be a non-negative integer")
    if not (0 < d_min <= d_max):
        raise MeshError(f"crater diameters {d_min!r}..{d_max!r} must satisfy 0 < min ≤ max")
    rng = np.random.default_rng(seed)
    u = rng.random(n)
    k = -SFD_SLOPE  # inverse transform of the truncated Pareto on [d_min, d_max]
    D = d_min * (1 - u * (1 - (d_min / d_max) ** k)) ** (-1 / k)
    if region is None:
        z = rng.uniform(-1, 1, n)
        phi = rng.uniform(0, 2 * np.pi, n)
        c = np.stack([np.sqrt(1 - z * z) * np.cos(phi), np.sqrt(1 - z * z) * np.sin(phi), z], axis=1)
    else:
        lat, lon, rad = region
        ax = _lonlat_to_unit(lon, lat)
        cz = rng.uniform(np.cos(np.radians(rad)), 1, n)
        phi = rng.uniform(0, 2 * np.pi, n)
        e1 = np.cross(ax, [0, 0, 1.0]) if abs(ax[2]) < 0.9 else np.cross(ax, [1.0, 0, 0])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(ax, e1)
        sz = np.sqrt(1 - cz * cz)
        c = cz[:, None] * ax + sz[:, None] * (np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2)
    return c, D


def crater_heights(u: np.ndarray, centres: np.ndarray, diameters: np.ndarray, radius: float) -> np.ndarray:
    """Height [m] at unit directions ``u`` of the summed crater profiles (module docstring)."""
    h = np.zeros(len(u))
    for c, D in zip(centres, diameters):
        r = 0.5 * D
        rho = radius * 2 * np.arcsin(np.clip(0.5 * np.linalg.norm(u - c, axis=1), 0, 1))  # surface distance
        inside = rho < r
        d = DEPTH_RATIO * D
        hr = RIM_RATIO * D
        h[inside] += hr - d * (1 - (rho[inside] / r) ** 2)
        out = (rho >= r) & (rho < EJECTA_EXTENT * r)
        h[out] += hr * ((r / rho[out]) ** 3 - EJECTA_EXTENT**-3) / (1 - EJECTA_EXTENT**-3)
    return h


def craters(radius: float, level: int, n: int, d_min: float, d_max: float, seed: int = 0,
            region=None, patch=None) -> trimesh.Trimesh:
    """A seeded synthetic cratered sphere of ``radius`` [m] (module docstring)."""
    m = base_sphere(level, patch)
    u = np.asarray(m.vertices)
    cen, D = crater_population(n, d_min, d_max, seed, region)
    h = crater_heights(u, cen, D, radius)
    return trimesh.Trimesh(u * (radius + h)[:, None], m.faces, process=False)


def patch(radius: float, level: int, lat: float, lon: float, k: float) -> trimesh.Trimesh:
    """A sphere of ``radius`` [m] whose resolution is ``k`` times finer around (lat, lon)."""
    m = base_sphere(level, (lat, lon, k))
    return trimesh.Trimesh(np.asarray(m.vertices) * radius, m.faces, process=False)


def write_mesh(mesh: trimesh.Trimesh, path) -> Path:
    """Write ``mesh`` in the format its suffix names (.ply .obj .stl .off .glb), atomically."""
    p = Path(path)
    fmt = p.suffix.lower().lstrip(".")
    if fmt not in ("ply", "obj", "stl", "off", "glb"):
        raise MeshError(f"mesh output {path!r}: use .ply, .obj, .stl, .off or .glb")
    if fmt == "ply":  # float64 vertices: metre precision at the Sun's radius
        data = _ply_float64(mesh)
    else:
        data = mesh.export(file_type=fmt)
    if isinstance(data, str):
        data = data.encode()
    with atomic_path(p) as tmp:
        Path(tmp).write_bytes(data)
    return p


def _ply_float64(mesh: trimesh.Trimesh) -> bytes:
    """Binary little-endian PLY with float64 vertices (trimesh writes float32 by default)."""
    v = np.asarray(mesh.vertices, dtype="<f8")
    f = np.asarray(mesh.faces, dtype="<i4")
    head = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(v)}\nproperty double x\n"
            f"property double y\nproperty double z\nelement face {len(f)}\n"
            "property list uchar int vertex_indices\nend_header\n").encode()
    faces = np.empty(len(f), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    faces["n"] = 3
    faces["i"] = f
    return head + v.tobytes() + faces.tobytes()
