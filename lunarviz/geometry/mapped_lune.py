"""The lune rule on a Moon with an albedo map: the map's cells moved into the weights.

The detector's irradiance from the lit, visible lune is ``I = ∫ r(m(x); g(x)) dA``, where
``g(x)`` is the geometry and light at x (smooth inside the lune rule's blocks: cut at the
terminator, at the source's penumbra band and, for a rough BRDF, where i = e) and ``m(x)`` the
map, constant on cells of ~1° (its edges are everywhere inside the lune). Two interpolations
separate them:

* in the map value: ``r(m; g) ≈ Σ_q r(m_q; g) ℓ_q(m)``, Lagrange polynomials ``ℓ_q`` on Q
  Chebyshev nodes ``m_q`` spanning the values met (Hapke's reflectance is analytic in w, with
  its nearest singularity at w = 1; Lambert is linear: exact);
* in the position: within each block of the coarse rule (a tensor grid of Gauss nodes in the
  block's coordinates u_t, u_φ ∈ [0, 1]), ``r(m_q; g(x))`` is smooth and its polynomial
  interpolant through the coarse nodes converges spectrally.

So ``I ≈ Σ_ij Σ_q r(m_q; g(x_ij)) W_ij^q`` with ``W_ij^q = ∫ ℓ_i(u_t) ℓ_j(u_φ) ℓ_q(m(x)) dA``:
the coarse nodes are traced once and shaded at the Q map values; the map enters only the
weights. They are summed over the map's own cells (Gauss points in sin(lat) and lon, where the
area element is exact and the map constant: no aliasing of the cells' edges), each point placed
in its block by :func:`~lunarviz.geometry.sphere_quadrature.rule_coordinates`; cells that a
block's edge crosses take a finer grid of points, those outside the lune dropping out.

Known limit: that point sampling of the edge cells errs as (point spacing / lune width)²: with a
constant map, against the plain lune rule, 2.5e-7 at θ = 10°, 1.9e-6 at 60°, 4.6e-5 at 150° and
4.2e-4 at 170° (tests/test_mapped_lune.py). Tolerances (``--rtol``) therefore do not choose this
rule yet; it runs where ``TraceSettings.lune_order`` is given on a mapped Moon. The fix is a rule
in the block's own coordinates over each cut cell. Cost: ~0.1-0.3 s per path and date (locating
~10⁵ cell points), more than tracing its nodes.
"""

from __future__ import annotations

from dataclasses import dataclass

import functools

import numpy as np

from lunarviz.errors import LunarvizError
from lunarviz.geometry.sphere_quadrature import cap_rule, gauss_legendre, rule_coordinates

#: Chebyshev nodes in the map's value (rough Hapke, rolo-fit-map at θ = 60°: 4 nodes err by 3e-4,
#: 6 by 3e-6, 8 by 5e-8 against 10; the error falls ~100x per 2 nodes)
ALBEDO_NODES = 8
#: Gauss points per map-cell side (2: exact for cubics in sin(lat) and lon over a cell), and in
#: the cells that a block's edge (terminator, limb, penumbra band, i = e) crosses
CELL_NODES = 2
EDGE_NODES = 8


@dataclass
class AlbedoNodes:
    """The map's part of a mapped lune rule: sample k is shaded at every map value
    ``values[q]`` and weighted by ``factors[k, q]`` (its area times the factor is ``W_k^q``)."""

    values: np.ndarray  # (Q,) map values
    factors: np.ndarray  # (N, Q)


def lagrange_matrix(nodes: np.ndarray, points: np.ndarray) -> np.ndarray:
    """``L[p, i] = ℓ_i(points[p])``: the Lagrange basis of ``nodes`` at ``points`` (barycentric
    form; exact 1 where a point is a node)."""
    nodes, points = np.asarray(nodes, float), np.asarray(points, float)
    diff = nodes[:, None] - nodes[None, :]
    np.fill_diagonal(diff, 1.0)
    bw = 1.0 / diff.prod(axis=1)
    d = points[:, None] - nodes[None, :]
    hit = d == 0.0
    d = np.where(hit, 1.0, d)
    L = bw / d
    L /= L.sum(axis=1, keepdims=True)
    rows = hit.any(axis=1)
    L[rows] = hit[rows].astype(float)
    return L


def chebyshev_nodes(lo: float, hi: float, q: int) -> np.ndarray:
    """Q Chebyshev points of the first kind on [lo, hi] (one point, the middle, where lo = hi)."""
    if not hi > lo:
        return np.array([0.5 * (lo + hi)])
    k = np.arange(q)
    return 0.5 * (lo + hi) + 0.5 * (hi - lo) * np.cos((2 * k + 1) * np.pi / (2 * q))


def lune_caps(scene, source: np.ndarray, source_radius: float, bisector: bool):
    """The lune rule's geometry: pole (toward the detector), its cosine, the caps (lit: kept;
    the penumbra band's far edge and, with ``bisector``, the circle i = e: cuts only) and φ = 0
    opposite the source's azimuth."""
    M, R = scene.moon, scene.radii["moon"]
    to_det, to_src = scene.det - M, source - M
    d_det, d_src = np.linalg.norm(to_det), np.linalg.norm(to_src)
    if d_det <= R:
        raise LunarvizError("the detector is inside the Moon")
    o, s = to_det / d_det, to_src / d_src
    u = [s, s]
    c = [(R - source_radius) / d_src, (R + source_radius) / d_src]
    split = [False, True]
    if bisector and np.linalg.norm(s - o) > 1e-9:
        # i = e: n·(S - x)/|S - x| = n·(D - x)/|D - x|, with |S - x| ≈ d_src and |D - x| ≈ d_det
        # (the rest is second order in R/d): the plane n·(s - o) = R/d_src - R/d_det
        b = s - o
        u.append(b / np.linalg.norm(b))
        c.append((R / d_src - R / d_det) / np.linalg.norm(b))
        split.append(True)
    return o, R / d_det, np.array([u]), np.array([c]), np.array([split]), -s


@functools.lru_cache(maxsize=4)
def map_cell_nodes(shape: tuple[int, int], k: int):
    """Gauss nodes of every cell of a lat/lon map of ``shape`` (rows from +90°, columns from
    -180°): k×k per cell in (sin lat, lon), where the area element is exactly dμ dλ. Returns
    unit vectors (cells, k², 3) in the map's frame and weights (cells, k²) [sr]."""
    h, w = shape
    g, gw = gauss_legendre(k)
    mu_edges = np.sin(np.radians(90.0 - 180.0 * np.arange(h + 1) / h))  # decreasing
    lon_edges = np.radians(-180.0 + 360.0 * np.arange(w + 1) / w)
    dmu = mu_edges[:-1] - mu_edges[1:]  # (h,)
    mu = mu_edges[1:, None] + dmu[:, None] * g  # (h, k)
    dl = lon_edges[1] - lon_edges[0]
    lon = lon_edges[:-1, None] + dl * g  # (w, k)
    cl = np.sqrt(np.clip(1.0 - mu * mu, 0.0, None))
    M, L = mu[:, None, :, None], lon[None, :, None, :]  # (h, 1, k, 1), (1, w, 1, k)
    C = cl[:, None, :, None]
    d = np.stack(np.broadcast_arrays(C * np.cos(L), C * np.sin(L), M), axis=-1)  # (h, w, k, k, 3)
    wts = (dmu[:, None] * gw)[:, None, :, None] * (dl * gw)[None, None, None, :]
    wts = np.broadcast_to(wts, (h, w, k, k))
    out = (d.reshape(h * w, k * k, 3), np.ascontiguousarray(wts).reshape(h * w, k * k))
    for a in out:
        a.setflags(write=False)
    return out


def mapped_lune_rule(scene, source: np.ndarray, source_radius: float, order: int, values: np.ndarray,
                     frame: np.ndarray, bisector: bool = False, cell_nodes: int = CELL_NODES,
                     edge_nodes: int = EDGE_NODES, albedo_nodes: int = ALBEDO_NODES):
    """Coarse nodes of the lune rule and the map's weights (module docstring).

    Parameters
    ----------
    scene : SceneGeometry; source, source_radius : the source's centre [m] and radius [m].
    order : Gauss points per block side of the coarse rule (the one that is traced).
    values : the map (h, w), constant on its lat/lon cells; frame : ``x_scene = frame @ x_map``.
    bisector : cut the blocks where i = e (a rough BRDF's kink).
    cell_nodes, edge_nodes : Gauss points per cell side (cells that a block's edge crosses:
        ``edge_nodes``, of which those outside the region drop out).

    Returns
    -------
    x (N, 3) [m], n (N, 3), dA (N,) [m²] (the coarse rule's areas) and :class:`AlbedoNodes`;
    ``None`` where the blocks are not smooth patches (a ring's arc wraps; callers fall back).
    """
    geo = lune_caps(scene, source, source_radius, bisector)
    axis, cmax, cu, cc, split, zero = geo
    nc, wc = cap_rule(axis[None, :], [cmax], cu, cc, split, order, order, phi_zero=zero[None, :],
                      crossings=True, structured=True)
    S, n_iv = wc.shape[1] // order, wc.shape[2]
    wc = wc[0].reshape(S, order, n_iv, order)
    if not np.array_equal((wc > 0).any(axis=(1, 3)), (wc > 0).all(axis=(1, 3))):
        return None  # a block is empty on some rings only: not one smooth patch

    def locate(d):  # map-frame unit vectors → block coordinates
        return rule_coordinates(d @ frame.T, axis, cmax, cu[0], cc[0], split[0], zero, crossings=True)

    h, w = values.shape
    pts, wts = map_cell_nodes((h, w), cell_nodes)
    # cells the region may touch: centre within a cell's half-diagonal of the lit, visible caps
    centre = pts.mean(axis=1) @ frame.T
    reach = np.sin(np.radians(0.75 * max(180.0 / h, 360.0 / w)))
    near = (centre @ axis > cmax - reach) & (centre @ cu[0, 0] > cc[0, 0] - reach)
    cells = np.flatnonzero(near)
    seg, itv, ut, up, ins = (a.reshape(len(cells), -1) for a in locate(pts[cells].reshape(-1, 3)))
    block = np.where(ins, seg * n_iv + itv, -1)
    # a cell whose nodes or corners lie in different blocks (or partly outside) holds an edge
    corner_ids = _cell_corner_ids((h, w))[cells]  # (C, 4) into the (h + 1)·(w + 1) grid vertices
    used = np.unique(corner_ids)
    cs, ci, *_, cins = locate(_grid_vertices((h, w))[used])
    vblock = np.full((h + 1) * (w + 1), -1)
    vblock[used] = np.where(cins, cs * n_iv + ci, -1)
    allb = np.concatenate([block, vblock[corner_ids]], axis=1)
    edge = (allb != allb[:, :1]).any(axis=1)
    whole = ~edge & (allb[:, 0] >= 0)
    m_cell = values.reshape(-1)[cells]
    parts = [(block[whole].ravel(), ut[whole].ravel(), up[whole].ravel(), wts[cells[whole]].ravel(),
              np.repeat(m_cell[whole], wts.shape[1]))]
    if edge.any():
        ep, ew = _sub_cell_nodes((h, w), cells[edge], edge_nodes)
        s2, i2, ut2, up2, in2 = locate(ep.reshape(-1, 3))
        mm = np.repeat(m_cell[edge], ew.shape[1])
        parts.append(((s2 * n_iv + i2)[in2], ut2[in2], up2[in2], ew.ravel()[in2], mm[in2]))
    blk, u_t, u_p, wp, mp = (np.concatenate(c) for c in zip(*parts))
    vals = chebyshev_nodes(float(mp.min()), float(mp.max()), albedo_nodes) if len(mp) else np.array([1.0])
    ell = lagrange_matrix(vals, mp) * wp[:, None]  # (P, Q)
    g = gauss_legendre(order)[0]
    W = np.zeros((S, order, n_iv, order, len(vals)))
    for b in np.unique(blk):
        sel = blk == b
        Lt, Lp = lagrange_matrix(g, u_t[sel]), lagrange_matrix(g, u_p[sel])
        A = (Lt[:, :, None] * ell[sel][:, None, :]).reshape(len(Lt), -1)  # (P, order·Q)
        W[b // n_iv, :, b % n_iv] = (A.T @ Lp).reshape(order, len(vals), order).transpose(0, 2, 1)  # one GEMM
    keep = wc > 0
    nc = nc[0].reshape(S, order, n_iv, order, 3)[keep]
    R = scene.radii["moon"]
    return scene.moon + R * nc, nc, wc[keep] * R * R, AlbedoNodes(values=vals, factors=W[keep] / wc[keep][:, None])


@functools.lru_cache(maxsize=4)
def _grid_vertices(shape):
    """The (h + 1)·(w + 1) cell corners of a lat/lon map (unit vectors in its frame)."""
    h, w = shape
    lat = np.radians(90.0 - 180.0 * np.arange(h + 1) / h)
    lon = np.radians(-180.0 + 360.0 * np.arange(w + 1) / w)
    La, Lo = np.meshgrid(lat, lon, indexing="ij")
    v = np.stack([np.cos(La) * np.cos(Lo), np.cos(La) * np.sin(Lo), np.sin(La)], axis=-1).reshape(-1, 3)
    v.setflags(write=False)
    return v


@functools.lru_cache(maxsize=4)
def _cell_corner_ids(shape):
    """Indices (cells, 4) of every cell's corners in :func:`_grid_vertices`."""
    h, w = shape
    ids = np.arange((h + 1) * (w + 1)).reshape(h + 1, w + 1)
    out = np.stack([ids[:-1, :-1], ids[:-1, 1:], ids[1:, :-1], ids[1:, 1:]], axis=2).reshape(h * w, 4)
    out.setflags(write=False)
    return out


def _sub_cell_nodes(shape, cells, k):
    """k×k Gauss nodes (C, k², 3) and weights of the given cells (as :func:`map_cell_nodes`)."""
    pts, wts = map_cell_nodes(shape, k)
    return pts[cells], wts[cells]
