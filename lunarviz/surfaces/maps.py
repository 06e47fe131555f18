"""Equirectangular maps on a body: reading and checking them, their frames, and reading them on a
mesh's facets.

Maps are equirectangular in the body frame (docs: conventions, "Maps"): row 0 is latitude +90° (north
up), column 0 starts at longitude −180°, east-positive, cells pixel-centred, ``width = 2·height``.
``.npy`` arrays hold values directly; ``.png``/``.tif`` images are read as linear values scaled
to [0, 1] (8- and 16-bit integers by their full range, float images as they are; colour images by
the mean of their colour channels).

The body frame is MOON_ME for the Moon and ITRS for the Earth on dates (the mesh frame there);
in the paper's θ scene the north poles are +x, the Moon's map (0°, 0°) faces the Earth (tidal
lock) and the Earth's sub-solar longitude is ``earth_rotation_deg`` (:func:`map_frame`).

Facet values are *area* averages: each facet is split into k² equal sub-triangles and the map is
read (nearest cell) at a jittered point of every sub-triangle, k chosen so the samples are finer than
the map's cells (:func:`facet_average`); or, where a facet's light varies across it (the mapped
Earth's), the map's least-squares linear fit over the same points (:func:`facet_linear_fit`), which
keeps its first moments too. Quadrature methods without facets (``analytic``,
``reference``) read the map at their nodes (:func:`sample_map`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

import lunarviz.compiled as compiled
from lunarviz.errors import LunarvizError
from lunarviz.geometry.subdivision import sub_barycentric

MAP_SUFFIXES = (".npy", ".png", ".tif", ".tiff")
#: samples per facet side are capped so one facet average reads at most this many cells in all
MAX_SAMPLES = 8_000_000
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


def lat_lon_deg(dirs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Planetocentric latitude and east longitude [deg] of directions (n, 3) in a body frame."""
    d = np.asarray(dirs, dtype=float)
    r = np.linalg.norm(d, axis=-1)
    lat = np.degrees(np.arcsin(np.clip(d[..., 2] / r, -1.0, 1.0)))
    lon = np.degrees(np.arctan2(d[..., 1], d[..., 0]))
    return lat, lon


def sample_map(m: np.ndarray, dirs: np.ndarray) -> np.ndarray:
    """The map's cell value (nearest cell) at directions (..., 3) in the map's frame."""
    return sample_map_at(m, *lat_lon_deg(dirs))


def sample_map_at(m: np.ndarray, lat: np.ndarray, lon: np.ndarray) -> np.ndarray:
    """The map's cell value (the cell holding it) at latitudes and east longitudes [deg]."""
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


def facet_sub_count(vertices, faces, m_shape, max_samples: int = MAX_SAMPLES, per_cell: float = 2.0,
                    most: int = 16, least: int = 8) -> int:
    """k such that k² samples per facet are finer than the map's cells (``per_cell`` a cell's side),
    at least ``least`` and at most ``most``, and at most ``max_samples`` over the whole mesh."""
    tri = vertices[faces]
    r = np.linalg.norm(vertices, axis=1).mean()
    edge = float(np.sqrt(np.mean(np.sum((tri[:, 1] - tri[:, 0]) ** 2, axis=1)))) / r  # rad
    cell = np.pi / m_shape[0]
    k = int(np.ceil(per_cell * edge / cell))
    cap = int(np.sqrt(max_samples / max(len(faces), 1)))
    return int(max(min(least, cap), min(k, most, max(cap, 1))))


def _random_rows(rng: np.random.Generator, F: int, S: int, rows: np.ndarray) -> np.ndarray:
    """``rng.random((F, S))[rows]``, leaving ``rng`` where that draw leaves it, drawing only the rows'
    values where the bit generator can skip ahead (PCG64, one 64-bit step a float64: ``advance``
    passes the others; no 32-bit value buffered, which ``advance`` would drop) and ``rows`` are
    increasing indices in [0, F); else the whole draw. The same numbers either way."""
    bg = rng.bit_generator
    skip = isinstance(bg, (np.random.PCG64, np.random.PCG64DXSM)) and not bg.state["has_uint32"] \
        and rows.dtype.kind in "iu" and rows.ndim == 1 and (len(rows) == 0 or rows[0] >= 0 and rows[-1] < F) \
        and bool(np.all(np.diff(rows) > 0))
    if not skip:
        return rng.random((F, S))[rows]
    if len(rows) == 0:  # (a block of facets none of which is asked for: passed, not drawn)
        bg.advance(F * S)
        return np.empty((0, S))
    out = np.empty((len(rows), S))
    first = np.flatnonzero(np.r_[True, np.diff(rows) != 1])  # runs of consecutive rows
    pos = 0
    for a, b in zip(first.tolist(), first[1:].tolist() + [len(rows)]):
        bg.advance(int(rows[a]) * S - pos)
        out[a:b] = rng.random((b - a, S))
        pos = (int(rows[a]) + b - a) * S
    bg.advance(F * S - pos)
    return out


def _jittered_points(corners, r1, r2, tri, out):
    """``out[f, s] = Σ_k b_k tri[f, k]`` with b the barycentric point (1 - √r1) A + √r1 (1 - r2) B
    + √r1 r2 C of sub-triangle s (corners A, B, C: ``corners[s]``) of facet f (compiled)."""
    F, S = r1.shape
    for f in range(F):
        for s in range(S):
            s1 = np.sqrt(r1[f, s])
            w0, w1, w2 = 1.0 - s1, s1 * (1.0 - r2[f, s]), s1 * r2[f, s]
            b0 = w0 * corners[s, 0, 0] + w1 * corners[s, 1, 0] + w2 * corners[s, 2, 0]
            b1 = w0 * corners[s, 0, 1] + w1 * corners[s, 1, 1] + w2 * corners[s, 2, 1]
            b2 = w0 * corners[s, 0, 2] + w1 * corners[s, 1, 2] + w2 * corners[s, 2, 2]
            for j in range(3):
                out[f, s, j] = b0 * tri[f, 0, j] + b1 * tri[f, 1, j] + b2 * tri[f, 2, j]


def facet_points(vertices, faces, k: int, rng: np.random.Generator | None = None, rows=None) -> np.ndarray:
    """(F, k², 3) points, one uniform in each of the k² equal sub-triangles of each facet
    (body-centred): stratified and jittered, so a map's pattern cannot line up with the mesh's
    (the sub-triangles' centroids of an icosphere sit on its symmetry circles and bias a banded
    map by up to 1e-3). ``rng`` ``None``: the centroids. ``rows``: only those of ``faces`` (indices
    into it), with the points they take among all of ``faces`` (the same draws)."""
    cen, corners = sub_barycentric(k)
    if rng is None:
        return np.einsum("sk,fkj->fsj", cen, vertices[faces if rows is None else faces[rows]])
    F, S = len(faces), len(cen)
    if rows is None:
        r1, r2 = rng.random((F, S)), rng.random((F, S))
    else:
        r1, r2 = (_random_rows(rng, F, S, np.asarray(rows)) for _ in range(2))
        faces = faces[rows]
    if _NUMBA:  # one compiled pass (numpy builds five (F, S, 3) temporaries)
        out = np.empty((len(faces), S, 3))
        _jittered_points(np.ascontiguousarray(corners, dtype=float), r1, r2,
                         np.ascontiguousarray(vertices[faces], dtype=float), out)
        return out
    s1 = np.sqrt(r1)
    # uniform in a triangle: (1 - √r1) A + √r1 (1 - r2) B + √r1 r2 C, in barycentric coordinates
    bary = ((1 - s1)[..., None] * corners[None, :, 0] + (s1 * (1 - r2))[..., None] * corners[None, :, 1]
            + (s1 * r2)[..., None] * corners[None, :, 2])  # (F, S, 3)
    return np.einsum("fsk,fkj->fsj", bary, vertices[faces])


#: the fixed seed of the jittered facet samples: results are deterministic
SAMPLE_SEED = 20261124


def facet_average(values_at, vertices, faces, k: int, chunk: int = 65536, spread: bool = False, only=None):
    """Area average over each facet of ``values_at(dirs)`` (dirs (n, 3) in the mesh frame; values
    (n,) or (n, C): then (F, C) averages), from k² stratified, jittered points per facet
    (deterministic: a fixed seed); with ``spread`` also the values' standard deviation over the
    facet (``(mean, std)``). ``only``: the averages of those facets alone (sorted indices into
    ``faces``), bit for bit those of the whole mesh's (each facet its own points)."""
    out = None
    n_out = len(faces) if only is None else len(only)
    sd = np.zeros(n_out)
    rng = np.random.default_rng(SAMPLE_SEED)
    only = None if only is None else np.asarray(only, dtype=np.int64)
    for a in range(0, len(faces), chunk):
        if only is None:
            rows, dest = None, slice(a, a + chunk)
        else:
            lo, hi = np.searchsorted(only, [a, a + chunk])
            rows, dest = only[lo:hi] - a, slice(lo, hi)
        p = facet_points(vertices, faces[a:a + chunk], k, rng, rows)
        if p.shape[0] == 0:
            continue
        v = values_at(p.reshape(-1, 3))
        v = v.reshape(p.shape[:2] + v.shape[1:])
        if out is None:
            out = np.empty((n_out,) + v.shape[2:])
        out[dest] = v.mean(axis=1)
        if spread:
            sd[dest] = v.std(axis=1)
    if out is None:
        out = np.empty(n_out)
    return (out, sd) if spread else out


def facet_linear_fit(values_at, vertices, faces, k: int, only=None, chunk_samples: int = 1 << 22, fit=None):
    """Each facet's least-squares linear fit of ``values_at(dirs)`` (values (n,) or (n, C)) over the
    k² jittered points of :func:`facet_points` (the same seed as :func:`facet_average`): the fit's
    value at the facet's centroid (F, C) and its gradient in the facet's plane (F, C, 3) [per
    mesh unit]. The fit keeps the map's zeroth and first moments over the facet, so a rule exact
    for linear functions integrates the map against any linear weight (a Lambert Earth's light
    across a facet) as the samples do; the facet's mean alone puts a coastline's light at the
    facet's centre (first order in the facet's size). Its value at the centroid is the samples'
    mean corrected by their offset from it (a control variate: the points' exact mean is the
    centroid). ``only``: those facets alone (sorted indices into ``faces``), bit for bit as the
    whole mesh's (each facet its own points). ``fit(p, c, e1, e2)``: a compiled fit of the same
    values (points (f, S, 3), centroids (f, 3), the plane's axes (f, 3) each), else
    :func:`linear_fits` of ``values_at``. Fewer than three points a facet: no gradient."""
    F_all = len(faces)
    only = np.arange(F_all) if only is None else np.asarray(only, dtype=np.int64)
    fit = fit or (lambda p, c, e1, e2: linear_fits(values_at, p, c, e1, e2))
    S = k * k
    chunk = max(1, chunk_samples // S)
    rng = np.random.default_rng(SAMPLE_SEED)
    value = grad = None
    for a in range(0, F_all, chunk):
        lo, hi = np.searchsorted(only, [a, a + chunk])
        p = facet_points(vertices, faces[a:a + chunk], k, rng, only[lo:hi] - a)  # (f, S, 3)
        if p.shape[0] == 0:
            continue
        tri = vertices[faces[only[lo:hi]]]
        e1 = tri[:, 1] - tri[:, 0]
        e1 /= np.linalg.norm(e1, axis=1)[:, None]
        nrm = np.cross(e1, tri[:, 2] - tri[:, 0])
        e2 = np.cross(nrm / np.linalg.norm(nrm, axis=1)[:, None], e1)
        v, g = fit(p, tri.mean(axis=1), e1, e2)
        if value is None:
            value, grad = np.empty((len(only), v.shape[1])), np.empty((len(only), v.shape[1], 3))
        value[lo:hi], grad[lo:hi] = v, g
    if value is None:
        value, grad = np.zeros((0, 1)), np.zeros((0, 1, 3))
    return value, grad


def linear_fits(values_at, p, c, e1, e2):
    """Least-squares linear fits of ``values_at`` over each facet's points p (f, S, 3): values at
    the centroids c (f, C) and gradients along the plane's axes e1, e2 (f, C, 3)
    (:func:`facet_linear_fit`)."""
    d = p - c[:, None, :]
    q0, q1 = np.einsum("fsj,fj->fs", d, e1), np.einsum("fsj,fj->fs", d, e2)  # (f, S): in the facet's plane
    v = values_at(p.reshape(-1, 3))
    v = v.reshape(p.shape[:2] + (-1,))  # (f, S, C)
    vm = v.mean(axis=1)
    q0 -= (m0 := q0.mean(axis=1))[:, None]
    q1 -= (m1 := q1.mean(axis=1))[:, None]
    s00, s01, s11 = (q0 * q0).sum(1), (q0 * q1).sum(1), (q1 * q1).sum(1)
    x0, x1 = (q0[:, :, None] * v).sum(1), (q1[:, :, None] * v).sum(1)  # (f, C): Σ q (v - v̄)
    det = s00 * s11 - s01**2
    ok = det > 1e-12 * (s00 + s11) ** 2
    det = np.where(ok, det, np.inf)[:, None]  # (no gradient where the points are too few)
    g0, g1 = (s11[:, None] * x0 - s01[:, None] * x1) / det, (s00[:, None] * x1 - s01[:, None] * x0) / det
    return (vm - m0[:, None] * g0 - m1[:, None] * g1,
            g0[:, :, None] * e1[:, None, :] + g1[:, :, None] * e2[:, None, :])


def facet_field_at(value, grad, vertices, faces, points, radial: bool = False) -> np.ndarray:
    """The linear fields of :func:`facet_linear_fit` (``value`` (n, C), ``grad`` (n, C, 3), each
    row's facet ``faces`` (n, 3) of ``vertices``) at ``points`` (n, 3) (mesh frame, body-centred):
    on the facets, or with ``radial`` on the body's exact sphere, each then projected radially
    onto its facet's plane (a sphere's facets face away from its centre)."""
    tri = vertices[faces]
    c = tri.mean(axis=1)
    if radial:
        nrm = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        points = points * (np.einsum("ij,ij->i", nrm, c) / np.einsum("ij,ij->i", nrm, points))[:, None]
    return value + np.einsum("icj,ij->ic", grad, points - c)


_NUMBA = compiled.available()
if _NUMBA:
    try:
        _jittered_points = compiled.jit(_jittered_points, nogil=True)
    except Exception:  # noqa: BLE001 (numba unusable here: the numpy path serves)
        _NUMBA = False
