"""The Earth map's component fields over facets in one compiled pass (numba).

:func:`lunarviz.surfaces.maps.facet_linear_fit` fits each facet's component weights
(:func:`lunarviz.surfaces.earth_spectra.weights_at`) linearly over its jittered points. Read in
numpy, each point's weights are a row of an (n, C) array, reduced afterwards; here each facet's
points are read and summed in one loop, so a level-6 Earth's 576 points a facet cost what its 81
did. The same maps, the same nearest-cell reads and the same zonal interpolation as ``weights_at``:
the fits equal the numpy path's to rounding (``tests/test_surfaces.py``).
"""

from __future__ import annotations

import numpy as np

import lunarviz.compiled as compiled

#: clear-sky kinds: one component (the clear sky: 1, or a clear-sky map's value) or the land-ocean
#: classes (ocean, vegetation, desert, snow)
CLEAR_ONE, CLEAR_MAP, CLEAR_LANDOCEAN = 0, 1, 2
#: cloud kinds: none, the zonal table, a cloud map
CLOUD_NONE, CLOUD_ZONAL, CLOUD_MAP = 0, 1, 2


def _cell(m_h, m_w, lat, lon):
    """The row and column of the cell holding (lat, lon) [deg] in an (h, w) map (maps.sample_map_at)."""
    row = min(max(int((90.0 - lat) / 180.0 * m_h), 0), m_h - 1)
    col = min(max(int((lon + 180.0) / 360.0 * m_w), 0), m_w - 1)
    return row, col


def _interp(x, xp, fp):
    """np.interp(x, xp, fp) of a scalar x (xp increasing; the end values beyond the ends)."""
    n = len(xp)
    if x <= xp[0]:
        return fp[0]
    if x >= xp[n - 1]:
        return fp[n - 1]
    i = np.searchsorted(xp, x, side="right") - 1
    t = (x - xp[i]) / (xp[i + 1] - xp[i])
    return fp[i] + t * (fp[i + 1] - fp[i])


def _fits(p, c, e1, e2, frame, clear_kind, clear_map, cover, cloud_kind, la, cf, cloud_map, value, grad):
    """value (f, C), grad (f, C, 3): each facet's linear fit of the component weights over its
    points p (f, S, 3) (maps.linear_fits, with weights_at's reads)."""
    F, S = p.shape[0], p.shape[1]
    C = value.shape[1]
    w = np.zeros(C)
    for f in range(F):
        sv = np.zeros(C)
        s0v = np.zeros(C)
        s1v = np.zeros(C)
        sq0 = sq1 = s00 = s01 = s11 = 0.0
        for s in range(S):
            x, y, z = p[f, s, 0], p[f, s, 1], p[f, s, 2]
            d0, d1, d2 = x - c[f, 0], y - c[f, 1], z - c[f, 2]
            q0 = d0 * e1[f, 0] + d1 * e1[f, 1] + d2 * e1[f, 2]
            q1 = d0 * e2[f, 0] + d1 * e2[f, 1] + d2 * e2[f, 2]
            # the point in the map's frame (dirs @ frame), its latitude and longitude [deg]
            mx = x * frame[0, 0] + y * frame[1, 0] + z * frame[2, 0]
            my = x * frame[0, 1] + y * frame[1, 1] + z * frame[2, 1]
            mz = x * frame[0, 2] + y * frame[1, 2] + z * frame[2, 2]
            r = np.sqrt(mx * mx + my * my + mz * mz)
            lat = np.degrees(np.arcsin(min(max(mz / r, -1.0), 1.0)))
            lon = np.degrees(np.arctan2(my, mx))
            cloud = 0.0
            if cloud_kind == CLOUD_ZONAL:
                cloud = _interp(lat, la, cf)
            elif cloud_kind == CLOUD_MAP:
                i, j = _cell(cloud_map.shape[0], cloud_map.shape[1], lat, lon)
                cloud = cloud_map[i, j]
            clear = 1.0 - cloud
            for k in range(C):
                w[k] = 0.0
            if clear_kind == CLEAR_ONE:
                w[0] = clear
            elif clear_kind == CLEAR_MAP:
                i, j = _cell(clear_map.shape[0], clear_map.shape[1], lat, lon)
                w[0] = clear * clear_map[i, j]
            else:
                i, j = _cell(clear_map.shape[0], clear_map.shape[1], lat, lon)
                frac = clear_map[i, j]
                w[0] = clear * (1.0 - frac)
                i, j = _cell(cover.shape[0], cover.shape[1], lat, lon)
                code = 1 if cover[i, j] == 0 else cover[i, j]  # (land the 1° map calls sea: vegetation)
                if code <= 3:  # (a code of no class carries no land, as in weights_at)
                    w[code] = clear * frac
            if cloud_kind != CLOUD_NONE:
                w[C - 1] = cloud
            for k in range(C):
                sv[k] += w[k]
                s0v[k] += q0 * w[k]
                s1v[k] += q1 * w[k]
            sq0 += q0
            sq1 += q1
            s00 += q0 * q0
            s01 += q0 * q1
            s11 += q1 * q1
        m0, m1 = sq0 / S, sq1 / S
        s00 -= S * m0 * m0
        s01 -= S * m0 * m1
        s11 -= S * m1 * m1
        det = s00 * s11 - s01 * s01
        ok = det > 1e-12 * (s00 + s11) ** 2
        for k in range(C):
            vm = sv[k] / S
            x0, x1 = s0v[k] - m0 * sv[k], s1v[k] - m1 * sv[k]  # Σ (q - q̄) v
            g0 = (s11 * x0 - s01 * x1) / det if ok else 0.0
            g1 = (s00 * x1 - s01 * x0) / det if ok else 0.0
            value[f, k] = vm - m0 * g0 - m1 * g1
            for j in range(3):
                grad[f, k, j] = g0 * e1[f, j] + g1 * e2[f, j]


_NUMBA = compiled.available()
if _NUMBA:
    try:
        _cell = compiled.jit(_cell, inline="always")
        _interp = compiled.jit(_interp, inline="always")
        _fits = compiled.jit(_fits, nogil=True)
    except Exception:  # noqa: BLE001 (numba unusable here: the numpy path serves)
        _NUMBA = False


def available() -> bool:
    """Whether the compiled fits can be used in this process."""
    return _NUMBA


def component_fits(frame: np.ndarray, n_components: int, clear_kind: int, clear_map=None, cover=None,
                   cloud_kind: int = CLOUD_NONE, zonal=None, cloud_map=None):
    """A ``fit(p, c, e1, e2)`` for :func:`lunarviz.surfaces.maps.facet_linear_fit` of an Earth
    map's ``n_components`` component weights (:func:`lunarviz.surfaces.earth_spectra.weights_at`)
    in map frame ``frame``, compiled; ``None`` where numba is not available. ``clear_kind``:
    :data:`CLEAR_ONE`, :data:`CLEAR_MAP` (``clear_map``: the clear-sky map) or
    :data:`CLEAR_LANDOCEAN` (``clear_map``: the land fraction, ``cover``: the land-cover codes);
    ``cloud_kind``: :data:`CLOUD_NONE`, :data:`CLOUD_ZONAL` (``zonal``: latitudes [deg] and
    fractions) or :data:`CLOUD_MAP` (``cloud_map``)."""
    if not _NUMBA:
        return None
    none = np.zeros((1, 1))
    clear_map = none if clear_map is None else np.ascontiguousarray(clear_map, dtype=float)
    cover = np.zeros((1, 1), np.int64) if cover is None else np.ascontiguousarray(cover, dtype=np.int64)
    la, cf = (np.zeros(1), np.zeros(1)) if zonal is None else (np.ascontiguousarray(t, dtype=float) for t in zonal)
    cloud_map = none if cloud_map is None else np.ascontiguousarray(cloud_map, dtype=float)
    frame = np.ascontiguousarray(frame, dtype=float)

    def fit(p, c, e1, e2):
        value, grad = np.empty((len(p), n_components)), np.empty((len(p), n_components, 3))
        _fits(np.ascontiguousarray(p), np.ascontiguousarray(c), np.ascontiguousarray(e1), np.ascontiguousarray(e2),
              frame, clear_kind, clear_map, cover, cloud_kind, la, cf, cloud_map, value, grad)
        return value, grad
    return fit
