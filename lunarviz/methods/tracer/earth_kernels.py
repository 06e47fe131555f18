"""The compiled kernel of the mapped Earth (:mod:`lunarviz.methods.tracer.mapped_earth`): the light of
the elements along the Earth's limb, which some lunar points see and others do not, and the light
of every element at lunar points whose horizon cuts the Earth, summed per lunar point and cell of
the Earth's disc in one pass (the numpy paths build (points × elements) temporaries five times
over). The same arithmetic as the numpy paths, so the same sums to rounding (their order differs)."""

from __future__ import annotations

import numpy as np

import lunarviz.compiled as compiled


def available() -> bool:
    """Whether the compiled kernel is in use."""
    return _NUMBA


def _add_element(b, e, x0, x1, x2, xx, n0, n1, n2, nxx, horizon, m, yr, my, yy, w, c, out):
    """Add element e's light at lunar point b to ``out[:, b, c]`` (:func:`_element_sums`)."""
    num = x0 * m[e, 0] + x1 * m[e, 1] + x2 * m[e, 2] - my[e]
    if num <= 0.0:
        return
    if horizon and nxx - (n0 * yr[e, 0] + n1 * yr[e, 1] + n2 * yr[e, 2]) >= 0.0:
        return
    r2 = xx - 2.0 * (x0 * yr[e, 0] + x1 * yr[e, 1] + x2 * yr[e, 2]) + yy[e]
    f = num / (r2 * np.sqrt(r2))
    for p in range(w.shape[0]):
        out[p, b, c] += f * w[p, e]


def _point_terms(xr, nx, b):
    """Lunar point b's coordinates, |x|², its normal and n·x (:func:`_add_element`'s)."""
    x0, x1, x2 = xr[b, 0], xr[b, 1], xr[b, 2]
    n0, n1, n2 = nx[b, 0], nx[b, 1], nx[b, 2]
    return x0, x1, x2, x0 * x0 + x1 * x1 + x2 * x2, n0, n1, n2, n0 * x0 + n1 * x1 + n2 * x2


def _element_sums(xr, nx, horizon, m, yr, my, yy, w, cell, out):
    """``out[p, b, cell[e]] += w[p, e] · max(0, m_e·(x_b - y_e)) / |x_b - y_e|³`` over the
    elements e, for lunar points x_b (xr, relative to the Moon's centre, as yr; ``my`` = m·yr,
    ``yy`` = |yr|²); with ``horizon``, only the elements above x_b's horizon (normal ``nx[b]``:
    n·(x_b - y_e) < 0) count."""
    for b in range(xr.shape[0]):
        x0, x1, x2, xx, n0, n1, n2, nxx = _point_terms(xr, nx, b)
        for e in range(m.shape[0]):
            _add_element(b, e, x0, x1, x2, xx, n0, n1, n2, nxx, horizon, m, yr, my, yy, w, cell[e], out)


def _cell_sums(xr, nx, m, yr, my, yy, w, lo, hi, todo, out):
    """:func:`_element_sums` with horizons over the elements of the cells marked for each point
    alone (``todo[b, c]``; cell c's elements are ``lo[c]:hi[c]``, sorted by cell)."""
    for b in range(xr.shape[0]):
        x0, x1, x2, xx, n0, n1, n2, nxx = _point_terms(xr, nx, b)
        for c in range(todo.shape[1]):
            if todo[b, c]:
                for e in range(lo[c], hi[c]):
                    _add_element(b, e, x0, x1, x2, xx, n0, n1, n2, nxx, True, m, yr, my, yy, w, c, out)


def element_sums(xr, m, yr, my, yy, w, cell, n_cells: int, nx=None) -> np.ndarray:
    """(P, B, n_cells) sums of :func:`_element_sums` (compiled): the limb's band at points whose
    horizon does not cut the Earth (``nx`` None), or every element above the horizons ``nx``."""
    out = np.zeros((w.shape[0], xr.shape[0], n_cells))
    horizon = nx is not None
    _element_sums(np.ascontiguousarray(xr), np.ascontiguousarray(nx if horizon else np.zeros(xr.shape)), horizon,
                  np.ascontiguousarray(m), np.ascontiguousarray(yr), my, yy, np.ascontiguousarray(w),
                  np.ascontiguousarray(cell, dtype=np.int64), out)
    return out


def cell_sums(xr, nx, m, yr, my, yy, w, starts, todo) -> np.ndarray:
    """(P, B, C) sums of every element above the horizons ``nx`` (compiled), in the cells marked
    ``todo`` (B, C) alone (zero elsewhere); the elements sorted by cell, cell c's from
    ``starts[c]``."""
    C = len(starts)
    out = np.zeros((w.shape[0], xr.shape[0], C))
    lo = np.ascontiguousarray(starts, dtype=np.int64)
    hi = np.append(lo[1:], m.shape[0]).astype(np.int64)
    _cell_sums(np.ascontiguousarray(xr), np.ascontiguousarray(nx), np.ascontiguousarray(m), np.ascontiguousarray(yr),
               my, yy, np.ascontiguousarray(w), lo, hi, np.ascontiguousarray(todo), out)
    return out


_NUMBA = compiled.available()
if _NUMBA:
    try:
        _point_terms = compiled.jit(_point_terms, nogil=True, inline="always")
        _add_element = compiled.jit(_add_element, nogil=True, inline="always")
        _element_sums = compiled.jit(_element_sums, nogil=True)
        _cell_sums = compiled.jit(_cell_sums, nogil=True)
    except Exception:  # noqa: BLE001 (numba missing a feature: numpy path)
        _NUMBA = False
