"""The lune rule on a Moon with an albedo map: the map's cells moved into the weights.

The detector's irradiance from the lit, visible lune is ``I = ∫ r(m(x); g(x)) dA``, where
``g(x)`` is the geometry and light at x (smooth inside the lune rule's blocks: cut at the
terminator, at the source's penumbra band and, for a rough BRDF, where i = e) and ``m(x)`` the
map, constant on cells of ~1° (its edges are everywhere inside the lune). Two interpolations
separate them:

* in the map value: ``r(m; g) ≈ Σ_q r(m_q; g) ℓ_q(γ(m))``, Lagrange polynomials ``ℓ_q`` on Q
  Chebyshev nodes spanning the map's values in γ = √(1 - w), w the BRDF's single-scattering
  albedo at m (Hapke's reflectance is analytic in w but for a branch point at w = 1, which γ
  removes: 6 nodes in γ err as 8 in m, and the rule takes 5, :data:`GAMMA_NODES`; Lambert is a
  polynomial in γ of degree 2: exact);
* in the position: within each block of the coarse rule (a tensor grid of Gauss nodes in the
  block's coordinates u_t, u_φ ∈ [0, 1]), ``r(m_q; g(x))`` is smooth and its polynomial
  interpolant through the coarse nodes converges spectrally.

So ``I ≈ Σ_ij Σ_q r(m_q; g(x_ij)) W_ij^q`` with ``W_ij^q = ∫ ℓ_i(u_t) ℓ_j(u_φ) ℓ_q(m(x)) dA``:
the coarse nodes are traced once and shaded at the Q map values; the map enters only the
weights. They are summed over the map's own cells in (sin lat, lon), where the area element is
exact and the map constant (no aliasing of the cells' edges), each point placed in its block by
:func:`~lunarviz.geometry.sphere_quadrature.rule_coordinates`: whole panels of cells that no
block edge comes near by a body-fixed rule whose weights against the cells are summed once per
map (:func:`_panel_rule`); other whole cells by their centre and corners (exact for cubics;
corners shared); cells that a block edge crosses or passes near
(terminator, limb, penumbra band, t-rings, the kink) along lines cut at every edge (closed form
for circles, bisection for the kink) with Gauss points per piece. Checks: a constant map against
the plain lune rule ≤ 7e-7 from θ = 10° to 179.5°; a brute-force cell sum; the facets
(docs: accuracy, "A lunar map in the lune rule"). Cost: 0.04-0.2 s per path and date (locating 2-8·10⁴ points, most
of them in the cut cells, and one GEMM per block), more than tracing the nodes. The model
behind ``--rtol`` was measured on ``rolo-fit-map`` (w·m in 0.29-0.57); for maps spanning much
wider albedos the 8 albedo nodes err more (a map of w·m in 0.05-0.9: 1.5e-5; rows on other maps
carry no bound anyway).
"""

from __future__ import annotations

import functools
import hashlib
from dataclasses import dataclass

import numpy as np

from lunarviz.caches import BoundedCache
from lunarviz.errors import LunarvizError
from lunarviz.geometry import quadrature_kernels
from lunarviz.geometry.sphere_quadrature import (
    cap_rule,
    gauss_legendre,
    kink_threshold,
    rule_coordinates,
    rule_segments,
)

#: Chebyshev nodes in the map's value m (rough Hapke, rolo-fit-map's DHG, w·m up to 0.57, 400
#: geometries with μ₀, μ down to 0.02: 4 nodes err by 4e-4, 6 by 4e-6, 8 by 4e-8; the error falls
#: ~100x per 2 nodes: the reflectance's nearest singularity, a branch point at w = 1, is near)
ALBEDO_NODES = 8
#: ... in γ = √(1 - w) (:func:`albedo_coordinate`), where that branch point is gone (Hapke's
#: H-functions are rational in γ, their poles at γ ≤ -1/2; the factor w = 1 - γ² is a
#: polynomial): the same geometries err by 3e-5 (4 nodes), 1e-6 (5), 3e-8 (6), 3e-11 (8); 5,
#: whose 1e-6 is at grazing geometries and 1/50 of the rule's own error at --rtol 1e-4 (the
#: models are measured with them, against 8), where 6 match the 8 in m; used where the shaded
#: BRDFs' scale from m to w is known (``albedo_scale``)
GAMMA_NODES = 5
#: in the cells that a block's edge (terminator, limb, penumbra band, t-segment ring) crosses:
#: Gauss lines, and points per piece of each line (:func:`_edge_cell_nodes`): 3 against 8 differ
#: by ≤ 4e-8 for θ ≤ 120° and up to 1e-6 at θ = 175° (4: 4.4e-7 there), far under the rule's
#: own error at the orders ``--rtol`` takes (docs: accuracy)
EDGE_NODES = 3
#: ... but 2 in lunes at least this wide [rad] (the Sun's path at θ ≤ 135°, the Earth's from
#: near the Earth at every θ), where the cut cells are a small share of the region: 2 against 8
#: differ there by ≤ 1.8e-7 on rolo-fit-map's traced paths (θ = 5-135°; 1.6e-6 at 165° and
#: 1.3e-5 at 175°, where 3 stay), for ~45 % fewer points in the cut cells (most of the rule's
#: located points) and a quarter less time in the rule
WIDE_LUNE = np.radians(45.0)
EDGE_NODES_WIDE = 2
#: blocks thinner than this [rad of arc] one way (t-segments between nearby tangent rings, the
#: penumbra band's own segments, slivers) and the penumbra band's blocks across it take a
#: quarter of the rule's order that way, at least THIN_ORDER (cap_rule's ``thin``): across 3° a
#: smooth integrand needs no more, and the band holds ~ρ² ≈ 2e-5 of the Sun's path. At full order
#: such blocks hold half the nodes of an order-24 moonshine rule and most of its beams (the band's nodes take
#: 72-512 beams each: the Sun partly below their horizon). Measured (docs: accuracy):
#: ≤ 1e-7 against full orders for θ = 5-176° (orders 16-32)
THIN_WIDTH = np.radians(3.0)
THIN_ORDER = 6
#: ... where such a block (or t-segment) holds under this share of the region's solid angle
#: (a crescent near new Moon is thin as a whole and keeps its orders; at 5 % the band's blocks
#: of θ = 172-175° crescents would be thinned and err by up to 1.9e-6, not converging)
THIN_SHARE = 0.01
#: whole panels: squares of PANEL_CELLS × PANEL_CELLS map cells that no block edge comes near take
#: a body-fixed rule, PANEL_NODES² points at Gauss nodes in (sin lat, lon) whose weights against
#: the map's cells are summed once per map (:func:`_panel_rule`), in place of each cell's centre
#: and corners (~2 located points a cell): the interpolant of the coarse rule is a smooth
#: function across a panel, its polynomial of degree PANEL_NODES - 1 errs by ~(panel/2)^PANEL_NODES
#: times its derivatives (docs: accuracy; panels against cells)
PANEL_CELLS = 4
PANEL_NODES = 3
#: ... in latitudes up to this [deg] (nearer the map's poles (sin lat, lon) squeeze a panel)
PANEL_MAX_LAT = 66.0


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
    bw = quadrature_kernels.barycentric_weights(nodes)
    d = points[:, None] - nodes[None, :]
    hit = d == 0.0
    d = np.where(hit, 1.0, d)
    L = bw / d
    L /= L.sum(axis=1, keepdims=True)
    rows = hit.any(axis=1)
    L[rows] = hit[rows].astype(float)
    return L


def chebyshev_nodes(lo: float, hi: float, q: int) -> np.ndarray:
    """Q Chebyshev points of the first kind on [lo, hi] (one point, the middle, where the range
    is under 1e-9 of its values: Q points would round onto each other there, and the map's
    contrast changes the reflectance by less)."""
    if not hi - lo > 1e-9 * max(abs(lo), abs(hi)):
        return np.array([0.5 * (lo + hi)])
    k = np.arange(q)
    return 0.5 * (lo + hi) + 0.5 * (hi - lo) * np.cos((2 * k + 1) * np.pi / (2 * q))


def albedo_coordinate(values: np.ndarray, albedo_scale: float) -> np.ndarray:
    """The variable the albedo nodes interpolate in: γ = √(1 - w) for w = ``albedo_scale`` · m
    (``albedo_scale`` > 0), else the map's value m itself."""
    values = np.asarray(values, dtype=float)
    return np.sqrt(np.clip(1.0 - albedo_scale * values, 0.0, None)) if albedo_scale > 0 else values


def lune_caps(scene, source: np.ndarray, source_radius: float, kink: bool = False):
    """The lune rule's geometry (as :func:`lunarviz.methods.analytic.lunar_surface_rule`): pole
    (toward the detector), its cosine, the caps (lit: kept; the penumbra band's far edge: a cut),
    φ = 0 opposite the source's azimuth (so no ring's arc wraps through φ = 0) and, with ``kink``,
    the cut where i = e (:func:`~lunarviz.geometry.sphere_quadrature.kink_threshold`: ``(R/d_src,
    R/d_det)``; else None)."""
    M, R = scene.moon, scene.radii["moon"]
    to_det, to_src = scene.det - M, source - M
    d_det, d_src = np.linalg.norm(to_det), np.linalg.norm(to_src)
    if d_det <= R:
        raise LunarvizError("the detector is inside the Moon")
    o, s = to_det / d_det, to_src / d_src
    if np.linalg.norm(s - o) < 1e-6:  # the source on the pole (to rounding): concentric caps, whole rings
        s = o  # (else the caps' boundaries leave t-segments ~1e-8 rad wide with their own intervals)
    caps_c = np.array([[(R - source_radius) / d_src, (R + source_radius) / d_src]])
    return o, R / d_det, np.array([[s, s]]), caps_c, np.array([[False, True]]), -s, \
        (R / d_src, R / d_det) if kink and np.linalg.norm(s - o) > 0 else None


def mapped_lune_rule(scene, source: np.ndarray, source_radius: float, order: int, values: np.ndarray,
                     frame: np.ndarray, kink: bool = False, edge_nodes: int | None = None,
                     albedo_nodes: int | None = None, thin: bool = True, panels: bool = True,
                     albedo_scale: float = 0.0, cut_rings: bool = False):
    """Coarse nodes of the lune rule and the map's weights (module docstring).

    Parameters
    ----------
    scene : SceneGeometry; source, source_radius : the source's centre [m] and radius [m].
    order : Gauss points per block side of the coarse rule (the one that is traced).
    values : the map (h, w), constant on its lat/lon cells; frame : ``x_scene = frame @ x_map``.
    kink : cut the blocks where i = e (Hapke's roughness changes form there: a rough BRDF's kink;
        exact for a point source, whose beams' own kinks a small disc like the Sun's smooths).
    edge_nodes : in cells that a block's edge crosses, Gauss lines (of constant longitude or
        sin(lat)), each cut where it crosses a block's edge and given this many points per piece
        (:func:`_edge_cell_nodes`); ``None``: :data:`EDGE_NODES_WIDE` in lunes at least
        :data:`WIDE_LUNE` wide, else :data:`EDGE_NODES`.
    thin : thin blocks take fewer nodes (:data:`THIN_WIDTH`; False: ``order`` everywhere).
    panels : whole panels of cells take their body-fixed rule (:data:`PANEL_CELLS`; False: every
        cell its centre and corners).
    albedo_scale : the factor from the map's values to the shaded BRDFs' single-scattering albedo
        w (the largest, where several non-linear BRDFs are shaded): the albedo nodes are then
        Chebyshev points in γ = √(1 - w) (:func:`albedo_coordinate`); 0: in the map's value.
    albedo_nodes : how many (``None``: :data:`GAMMA_NODES` in γ, :data:`ALBEDO_NODES` in m).
    cut_rings : cut cells at the t-segments' rings too, as at the integrand's own edges (the error
        model's reference; False: a cell or panel astride a ring takes each point's own block).

    Returns
    -------
    x (N, 3) [m], n (N, 3), dA (N,) [m²] (the coarse rule's areas) and :class:`AlbedoNodes`;
    ``None`` where the blocks are not smooth patches (a ring's arc wraps; callers fall back).
    """
    axis, cmax, cu, cc, split, zero, kink = lune_caps(scene, source, source_radius, kink)
    if edge_nodes is None:  # the lune's width: π less the source's angle from the pole
        edge_nodes = EDGE_NODES_WIDE if np.pi - np.arccos(np.clip(axis @ cu[0, 0], -1, 1)) >= WIDE_LUNE else EDGE_NODES
    nc, wc, (t_ord, p_ord) = cap_rule(axis[None, :], [cmax], cu, cc, split, order, order, phi_zero=zero[None, :],
                                      crossings=True, structured=True, kink=kink,
                                      thin=(THIN_WIDTH, max(THIN_ORDER, -(-order // 4)), THIN_SHARE) if thin
                                      else (0.0, order, 0.0))
    S, n_iv = wc.shape[1] // order, wc.shape[2]
    t_ord, p_ord = t_ord[0], p_ord[0]  # (S,), (S, n_iv): Gauss points per block in t and in φ
    wc = wc[0].reshape(S, order, n_iv, order)
    slots = (np.arange(order)[None, :, None, None] < t_ord[:, None, None, None]) & \
        (np.arange(order)[None, None, None, :] < p_ord[:, None, :, None])  # each block's own Gauss points
    if not np.array_equal((wc > 0).any(axis=(1, 3)), ((wc > 0) | ~slots).all(axis=(1, 3))):
        return None  # a block is empty on some rings only: not one smooth patch

    def locate(d):  # map-frame unit vectors → block coordinates
        return rule_coordinates(d @ frame.T, axis, cmax, cu[0], cc[0], split[0], zero, crossings=True, kink=kink)

    h, w = values.shape
    if not albedo_scale * float(values.max()) < 1.0:  # (w ≥ 1 somewhere: no γ; the BRDF refuses it anyway)
        albedo_scale = 0.0
    if albedo_nodes is None:
        albedo_nodes = GAMMA_NODES if albedo_scale > 0 else ALBEDO_NODES
    coords = albedo_coordinate(values, albedo_scale)
    circles, curve = _block_edges(axis, cmax, cu[0], cc[0], split[0], kink, frame)
    # the integrand's own edges (the caps' circles: terminator, the penumbra band's far edge, the
    # limb; the kink) cut cells and keep panels away; the t-rings only part the coarse rule's
    # blocks, across which the integrand is smooth: a cell or panel astride one takes each point
    # in its own block (that block's interpolant, as accurate there as the other's)
    hard = circles if cut_rings else circles[:3]
    sides = _side_codes(hard, curve)
    # one set of albedo nodes for the whole map (the panels' weights are summed once per map): the
    # nodes span values the lune may not hold, which moves the result within the interpolation's
    # error (GAMMA_NODES, ALBEDO_NODES); ``vals`` in the coordinate
    vals = chebyshev_nodes(float(coords.min()), float(coords.max()), albedo_nodes)
    centres, area = _cell_centres((h, w))
    # cells the region may touch: centre within a cell's half-diagonal of the lit, visible caps
    cs = centres @ frame.T
    reach = np.sin(np.radians(0.75 * max(180.0 / h, 360.0 / w)))
    cells = np.flatnonzero((cs @ axis > cmax - reach) & (cs @ cu[0, 0] > cc[0, 0] - reach))
    parts = []
    if panels:  # whole panels: their body-fixed rule, and their cells out of the cell sums below
        found = _whole_panels(coords, vals, frame, axis, cmax, cu[0, 0], cc[0, 0], hard, curve, sides, locate, n_iv)
        if found is not None:
            parts.append(found[0])
            cells = np.setdiff1d(cells, found[1], assume_unique=True)
    parts += _cell_parts(cells, coords, vals, circles, hard, curve, sides, locate, n_iv, edge_nodes)
    blk, u_t, u_p, ell = (np.concatenate(c) for c in zip(*parts))
    if blk.size and (blk.max() >= S * n_iv or (wc[:, 0, :, 0].ravel()[blk] == 0).any()):
        return None  # a point in a block the coarse rule does not have: the facets
    W = _block_weights(blk, u_t, u_p, ell, (S, order, n_iv), t_ord, p_ord)
    keep = wc > 0
    nc = nc[0].reshape(S, order, n_iv, order, 3)[keep]
    R = scene.radii["moon"]
    m_nodes = (1.0 - vals * vals) / albedo_scale if albedo_scale > 0 else vals  # the nodes as map values
    return scene.moon + R * nc, nc, wc[keep] * R * R, AlbedoNodes(values=m_nodes, factors=W[keep] / wc[keep][:, None])


def _cell_parts(cells, coords, vals, circles, hard, curve, sides, locate, n_iv, edge_nodes) -> list:
    """The map cells ``cells`` outside panels as parts ``(block, u_t, u_φ, ell)`` of the block
    weights: whole cells by the centre-and-corners rule, cells that an edge (``hard``, the kink
    ``curve``) crosses or passes near by lines cut at the edges (:func:`_edge_cell_nodes`).
    ``coords``: the map in the albedo nodes' coordinate; ``circles[0]``, ``circles[2]``: the lit
    and visible caps (the region)."""
    h, w = coords.shape
    centres, area = _cell_centres((h, w))
    corner_ids = _cell_corner_ids((h, w))[cells]  # (C, 4) into the (h + 1)·(w + 1) grid vertices
    nv = (h + 1) * (w + 1)
    (lit_u, lit_c), (vis_u, vis_c) = circles[0], circles[2]  # the region: lit (any of the disc) and seen

    def inside(p):
        return (p @ lit_u > lit_c) & (p @ vis_u > vis_c)
    # a cell whose centre and corners lie on different sides of an edge, or that an edge passes
    # within (a lune thinner than a cell slips between those five points), holds an edge; the
    # others lie wholly inside or wholly outside, and only the whole cells inside are located
    near, north, east = _edges_near((h, w), cells, hard, curve)
    centre_sides = sides(centres[cells])
    corner_sides = sides(_grid_vertices((h, w))[corner_ids.ravel()]).reshape(-1, 4)
    edge = near | (corner_sides != centre_sides[:, None]).any(axis=1)
    whole = np.flatnonzero(~edge & inside(centres[cells]))
    seg, itv, ut, up, ins = locate(centres[cells[whole]])
    vblock, v_ut, v_up = _located_vertices((h, w), corner_ids[whole], locate, n_iv)
    found = ins & (vblock[corner_ids[whole]] >= 0).all(axis=1)  # (else its edge, to rounding: cut it)
    edge[whole[~found]] = True
    whole, block, ut, up = whole[found], (seg * n_iv + itv)[found], ut[found], up[found]
    m_cell = coords.reshape(-1)[cells]
    # whole cells: the rectangle rule in (sin lat, lon) with the centre (2/3 of the area) and the
    # corners (1/12 each), exact for cubics like 2×2 Gauss points, with the corners shared by the
    # cells around them (their weights summed per vertex): ~2 located points a cell, not 5
    ell_cell = lagrange_matrix(vals, m_cell[whole]) * area[cells[whole]][:, None]
    corners = corner_ids[whole].ravel()
    ell_v = np.stack([np.bincount(corners, weights=np.repeat(ell_cell[:, q] / 12.0, 4), minlength=nv)
                      for q in range(len(vals))], axis=1)
    vw = np.flatnonzero(ell_v.any(axis=1))
    parts = [(block, ut, up, ell_cell * (2.0 / 3.0)), (vblock[vw], v_ut[vw], v_up[vw], ell_v[vw])]
    if edge.any():
        ep, ew, owner = _edge_cell_nodes((h, w), cells[edge], north[edge] >= east[edge], hard, edge_nodes, curve,
                                         inside=inside)
        s2, i2, ut2, up2, in2 = locate(ep)
        mm = m_cell[edge][owner][in2]
        parts.append(((s2 * n_iv + i2)[in2], ut2[in2], up2[in2], lagrange_matrix(vals, mm) * ew[in2][:, None]))
    return parts


def _block_edges(axis, cmax, caps_u, caps_c, split, kink, frame):
    """The rule's block edges in the map's frame: circles ``(u, c)``, ``n·u = c`` (the lit cap,
    the penumbra band's far edge, the visible cap, the t-segments' rings) and the kink curve
    ``(u_source, u_pole, kink)`` (``None`` without a kink; :func:`_curve_value`)."""
    t_lo, t_hi = rule_segments(axis, cmax, caps_u, caps_c, split, crossings=True, kink=kink)
    circles = [(frame.T @ u, c) for u, c in [(caps_u[0], caps_c[0]), (caps_u[1], caps_c[1]), (axis, cmax)] +
               [(axis, np.cos(t)) for t in np.unique(np.concatenate([t_lo, t_hi]))]]
    return circles, None if kink is None else (frame.T @ caps_u[0], frame.T @ axis, kink)


def _side_codes(circles, curve):
    """``p ↦`` which side of each edge (``circles``, ``n·u = c``; the kink ``curve``,
    :func:`_curve_value`) the map-frame unit vectors p (P, 3) lie on, one bit an edge."""
    F = None if curve is None else _curve_value(curve)

    def sides(p):
        code = np.zeros(len(p), np.int64)
        for i, (u, c) in enumerate(circles):
            code |= (p @ u > c).astype(np.int64) << i
        if F is not None:
            code |= (F(p) > 0).astype(np.int64) << len(circles)
        return code
    return sides


def _located_vertices(shape, corner_ids, locate, n_iv):
    """The block (-1 outside), u_t and u_φ of every grid vertex (h + 1)·(w + 1) that
    ``corner_ids`` uses, each located once (others: block -1)."""
    h, w = shape
    nv = (h + 1) * (w + 1)
    used = np.zeros(nv, dtype=bool)
    used[corner_ids] = True
    used = np.flatnonzero(used)
    seg, itv, ut, up, ins = locate(_grid_vertices((h, w))[used])
    vblock, v_ut, v_up = np.full(nv, -1, np.int64), np.zeros(nv), np.zeros(nv)
    vblock[used] = np.where(ins, seg * n_iv + itv, -1)
    v_ut[used], v_up[used] = ut, up
    return vblock, v_ut, v_up


def _whole_panels(values, vals, frame, axis, cmax, lit_u, lit_c, circles, curve, sides, locate, n_iv):
    """The panels (:func:`_panel_rule`) wholly inside the region, on one side of every edge of
    the integrand: centre inside the lit (``lit_u·u > lit_c``), visible (``axis·u > cmax``)
    caps, no circle of ``circles`` that can meet the panel (|n₀·u - c| ≤ |∇| r + r²/2, r half
    its diagonal) and no kink ``curve`` within 1.5 × 1.25 panel half-diagonals
    (:func:`_edges_near_at`), at least 3 × 1.25 half-diagonals from the rule's pole (where the
    blocks' coordinates are singular), and all their nodes located inside, with the centre's ``sides``.
    The nodes may lie in different blocks (a t-ring or a whole ring's seam at φ = 0 between
    them): no edge of the integrand, whose blocks' interpolants each stand for it to their own
    accuracy. Returns the part ``(block, u_t, u_φ, ell)`` of their nodes and their cells, or
    ``None`` without panels."""
    pan = _panel_rule(values, tuple(vals))
    if pan is None:
        return None
    h, w = values.shape
    half = 1.25 * np.radians(0.75 * PANEL_CELLS * max(180.0 / h, 360.0 / w))
    # a panel's points lie within r of its centre (half its diagonal): a circle n·u = c meets it
    # only where |n₀·u - c| ≤ |∇(n·u)| r + r²/2 (n·u = cos of the angle to u, which moves by ≤ r)
    r = 0.5 * np.radians(PANEL_CELLS * np.hypot(180.0 / h, 360.0 / w))
    c = pan.centres @ frame.T
    sel = np.flatnonzero((c @ axis > cmax) & (c @ lit_u > lit_c) & (c @ axis < np.cos(3.0 * half)))
    sel = sel[~_edges_near_at(pan.lat[sel], pan.lon[sel], r, circles, curve, slack=0.5 * r * r, curve_half=half)[0]]
    kk = pan.points.shape[1]
    nodes = pan.points[sel].reshape(-1, 3)
    seg, itv, ut, up, ins = locate(nodes)
    blk = np.where(ins, seg * n_iv + itv, -1).reshape(-1, kk)
    sd = sides(nodes).reshape(-1, kk)
    ok = (blk >= 0).all(axis=1) & (sd == sd[:, :1]).all(axis=1)
    pts = np.repeat(ok, kk)
    return (blk[ok].ravel(), ut[pts], up[pts], pan.weights[sel[ok]].reshape(-1, len(vals))), pan.cells[sel[ok]].ravel()


@dataclass(frozen=True)
class PanelRule:
    """The body-fixed rule of a map's panels (:data:`PANEL_CELLS` square, up to
    :data:`PANEL_MAX_LAT`): K = :data:`PANEL_NODES` Gauss nodes in sin(lat) and in longitude."""

    lat: np.ndarray  # (N,) panel centres' latitudes [rad]
    lon: np.ndarray  # (N,) ... and longitudes [rad]
    centres: np.ndarray  # (N, 3) ... as unit vectors in the map's frame
    cells: np.ndarray  # (N, PANEL_CELLS²) the map cells of each panel (row-major ids)
    points: np.ndarray  # (N, K², 3) its nodes, unit vectors in the map's frame
    weights: np.ndarray  # (N, K², Q) ∫ φ_k(μ, λ) ℓ_q(m(μ, λ)) dμ dλ over the panel [sr]


_PANEL_RULES = BoundedCache(4)


def _panel_rule(values: np.ndarray, vals: tuple) -> PanelRule | None:
    """The map's :class:`PanelRule` for albedo nodes ``vals`` (memoised on the map's bytes).

    On a panel, the interpolant through its K×K nodes, ``Σ_k p(x_k) φ_k(μ, λ)`` with ``φ_k`` the
    product of the K-point Lagrange bases in μ = sin(lat) and in λ, stands for the integrand p;
    so ``∫ p ℓ_q(m) dA ≈ Σ_k p(x_k) W_kq`` with ``W_kq = Σ_cells ℓ_q(m_c) ∫_cell φ_k dμ dλ``:
    each cell's integral is exact (K Gauss points a cell in μ and in λ: φ_k has degree K - 1 in
    each), and the map enters only through its cells' values. ``None`` where the map's shape is
    not a whole number of panels."""
    values = np.ascontiguousarray(values, dtype=float)
    h, w = values.shape
    P, K = PANEL_CELLS, PANEL_NODES
    if h % P or w % P:
        return None
    key = (hashlib.blake2b(values.tobytes(), digest_size=16).hexdigest(), values.shape, vals, P, K)
    hit = _PANEL_RULES.get(key)
    if hit is not None:
        return hit
    g, gw = gauss_legendre(K)
    lat_edges = 90.0 - 180.0 * np.arange(h + 1) / h
    rows = np.flatnonzero(np.maximum(np.abs(lat_edges[:-P:P]), np.abs(lat_edges[P::P])) <= PANEL_MAX_LAT)
    mu_edges = np.sin(np.radians(lat_edges))  # decreasing
    lon_edges = np.radians(-180.0 + 360.0 * np.arange(w + 1) / w)

    def moments(edges_lo, edges_hi, nodes):
        """``∫ ℓ_a`` over each cell [lo, hi] for the Lagrange basis on ``nodes`` (K Gauss points a cell)."""
        x = edges_lo[:, None] + (edges_hi - edges_lo)[:, None] * g  # (P, K)
        return (lagrange_matrix(nodes, x.ravel()).reshape(P, K, K) * ((edges_hi - edges_lo)[:, None] * gw)[:, :, None]
                ).sum(axis=1).T  # (K nodes, P cells)
    cols = np.arange(w // P)
    lon_lo, lon_hi = lon_edges[:-1][:P], lon_edges[1:][:P]  # the first panel column's cells (all alike)
    lon_nodes = lon_edges[0] + (lon_edges[P] - lon_edges[0]) * g
    I_lon = moments(lon_lo, lon_hi, lon_nodes)  # (K, P)
    ell = lagrange_matrix(np.asarray(vals), values.ravel()).reshape(h // P, P, w // P, P, len(vals))[rows]
    mu_nodes = mu_edges[(rows + 1) * P][:, None] + (mu_edges[rows * P] - mu_edges[(rows + 1) * P])[:, None] * g
    I_mu = np.stack([moments(mu_edges[r * P + 1:(r + 1) * P + 1], mu_edges[r * P:(r + 1) * P], mu_nodes[i])
                     for i, r in enumerate(rows)])  # (R, K, P): cells' μ ranges, increasing μ in the moments
    W = np.einsum("rai,bj,ricjq->rcabq", I_mu, I_lon, ell)  # (R, C, K, K, Q)
    lon_n = (lon_nodes - lon_edges[0])[None, :] + lon_edges[cols * P][:, None]  # (C, K)
    cl = np.sqrt(1.0 - mu_nodes * mu_nodes)  # (R, K)
    M, C, L = (np.broadcast_to(a, (len(rows), len(cols), K, K)) for a in
               (mu_nodes[:, None, :, None], cl[:, None, :, None], lon_n[None, :, None, :]))
    pts = np.stack([C * np.cos(L), C * np.sin(L), M], axis=-1)
    lat_c = np.radians(0.5 * (lat_edges[rows * P] + lat_edges[(rows + 1) * P]))
    lon_c = 0.5 * (lon_edges[cols * P] + lon_edges[(cols + 1) * P])
    La, Lo = (a.ravel() for a in np.meshgrid(lat_c, lon_c, indexing="ij"))
    ids = np.arange(h * w).reshape(h // P, P, w // P, P)[rows].transpose(0, 2, 1, 3).reshape(-1, P * P)
    rule = PanelRule(lat=La, lon=Lo, centres=np.stack([np.cos(La) * np.cos(Lo), np.cos(La) * np.sin(Lo), np.sin(La)],
                                                      axis=1),
                     cells=ids, points=np.ascontiguousarray(pts.reshape(-1, K * K, 3)),
                     weights=W.reshape(-1, K * K, len(vals)))
    for a in (rule.lat, rule.lon, rule.centres, rule.cells, rule.points, rule.weights):
        a.setflags(write=False)
    _PANEL_RULES[key] = rule
    return rule


def _block_weights(blk, u_t, u_p, ell, shape, t_ord, p_ord) -> np.ndarray:
    """``W`` (S, order, n_iv, order, Q): each block's ``Σ_p ℓ_i(u_t,p) ℓ_j(u_φ,p) ell[p, q]`` over
    the points ``blk`` places in it, on its own Gauss orders (``t_ord`` (S,), ``p_ord`` (S, n_iv);
    the unused slots stay 0): one GEMM per block."""
    S, order, n_iv = shape
    W = np.zeros((S, order, n_iv, order, ell.shape[1]))
    srt = np.argsort(blk, kind="stable")  # the points of each block together, in their order
    bounds = np.searchsorted(blk[srt], np.arange(S * n_iv + 1))
    use_kernel = quadrature_kernels.available()
    for b in np.flatnonzero(np.diff(bounds)):
        sel = srt[bounds[b]:bounds[b + 1]]
        mt, mp = int(t_ord[b // n_iv]), int(p_ord[b // n_iv, b % n_iv])
        gt, gp = gauss_legendre(mt)[0], gauss_legendre(mp)[0]
        if use_kernel:
            A, Lp = quadrature_kernels.block_design(u_t[sel], u_p[sel], ell[sel], gt, gp)
        else:
            Lt, Lp = lagrange_matrix(gt, u_t[sel]), lagrange_matrix(gp, u_p[sel])
            A = (Lt[:, :, None] * ell[sel][:, None, :]).reshape(len(Lt), -1)  # (P, mt·Q)
        W[b // n_iv, :mt, b % n_iv, :mp] = (A.T @ Lp).reshape(mt, ell.shape[1], mp).transpose(0, 2, 1)
    return W


@functools.lru_cache(maxsize=4)
def _cell_centres(shape):
    """Every cell's centre in (sin lat, lon) as a unit vector in the map's frame (h·w, 3), and its
    area Δ(sin lat)·Δlon [sr] (h·w,)."""
    h, w = shape
    mu_edges = np.sin(np.radians(90.0 - 180.0 * np.arange(h + 1) / h))
    mu = 0.5 * (mu_edges[:-1] + mu_edges[1:])
    lon = np.radians(-180.0 + 360.0 * (np.arange(w) + 0.5) / w)
    M, L = np.meshgrid(mu, lon, indexing="ij")
    c = np.sqrt(np.clip(1.0 - M * M, 0.0, None))
    out = (np.stack([c * np.cos(L), c * np.sin(L), M], axis=-1).reshape(-1, 3),
           np.repeat((mu_edges[:-1] - mu_edges[1:]) * np.radians(360.0 / w), w))
    for a in out:
        a.setflags(write=False)
    return out


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


def _edge_cell_nodes(shape, cells, along_lon, circles, k: int, curve=None, inside=None):
    """Points (P, 3) in the map's frame, weights (P,) [sr] and owning cell (P,) over ``cells``.

    Every edge given is a circle ``n·u = c`` of ``circles`` (the caps' circles, and with
    ``cut_rings`` the rings t = const; u in the map's frame). Each cell takes k Gauss lines across the edges that
    cross it (``along_lon``, from :func:`_edges_near`: lines of constant longitude, cut in
    sin(lat), where the edges run more east-west; else lines of constant sin(lat), cut in
    longitude, where they run more north-south), each line cut
    where it meets a circle (closed form) or the kink ``curve`` ``(u, o, (a_s, a_d))``: ``n·u =
    kink_threshold(angle(n, o))``, found by bisection) and given k Gauss points per piece: each
    piece lies on one side of every edge, where the integrand is smooth (its points in whichever
    block holds them), so no edge is point-sampled.
    ``inside`` (``p ↦ bool``, optional): the region's test; pieces whose midpoint fails it (each
    lies wholly on one side of every edge) take no points."""
    h, w = shape
    cells = np.asarray(cells)
    row, col = cells // w, cells % w
    lat = (np.radians(90.0 - 180.0 * (row + 1) / h), np.radians(90.0 - 180.0 * row / h))
    mu_range = (np.sin(lat[0]), np.sin(lat[1]))
    lon_range = (np.radians(-180.0 + 360.0 * col / w), np.radians(-180.0 + 360.0 * (col + 1) / w))
    out = []
    for sel, cut_mu in ((np.flatnonzero(along_lon), True), (np.flatnonzero(~along_lon), False)):
        p, wt, own = _lines(cells[sel], (mu_range[0][sel], mu_range[1][sel]), (lon_range[0][sel], lon_range[1][sel]),
                            circles, k, cut_mu, curve, inside)
        out.append((p, wt, sel[own]))  # owners back to indices into ``cells``
    return tuple(np.concatenate(x) for x in zip(*out))


def _edges_near(shape, cells, circles, curve=None):
    """Whether an edge passes within each cell (its value at the cell's centre closer to the
    edge's than the cell's half-diagonal times its gradient), and the summed north and east
    gradients of the edges that do (which way they run)."""
    h, w = shape
    row, col = cells // w, cells % w
    return _edges_near_at(np.radians(90.0 - 180.0 * (row + 0.5) / h), np.radians(-180.0 + 360.0 * (col + 0.5) / w),
                          np.radians(0.75 * max(180.0 / h, 360.0 / w)), circles, curve)


def _edges_near_at(lat_c, lon_c, half, circles, curve=None, slack: float = 1e-12, curve_half=None):
    """:func:`_edges_near` around points (lat_c, lon_c) [rad], within ``half`` [rad] (plus
    ``slack`` in n·u, for the circles' curvature; the kink ``curve`` within 1.5 ``curve_half``,
    default ``half``: its gradient is by differences)."""
    north, east = np.zeros(len(lat_c)), np.zeros(len(lat_c))
    hit = np.zeros(len(lat_c), dtype=bool)
    cla, sla, clo, slo = np.cos(lat_c), np.sin(lat_c), np.cos(lon_c), np.sin(lon_c)
    for u, c in circles:
        horizontal = u[0] * clo + u[1] * slo
        g = cla * horizontal + sla * u[2]
        gn = -sla * horizontal + cla * u[2]
        ge = -u[0] * slo + u[1] * clo
        near = np.abs(g - c) <= half * np.hypot(gn, ge) + slack
        hit |= near
        north += np.where(near, np.abs(gn), 0.0)
        east += np.where(near, np.abs(ge), 0.0)
    if curve is not None:  # the kink curve: its gradient by differences (it is not a circle)
        F = _curve_value(curve)

        def at(la, lo):
            return np.stack([np.cos(la) * np.cos(lo), np.cos(la) * np.sin(lo), np.sin(la)], axis=-1)
        d = 1e-4
        g = F(at(lat_c, lon_c))
        gn = (F(at(lat_c + d, lon_c)) - F(at(lat_c - d, lon_c))) / (2 * d)
        ge = (F(at(lat_c, lon_c + d)) - F(at(lat_c, lon_c - d))) / (2 * d) / np.maximum(np.cos(lat_c), 1e-12)
        near = np.abs(g) <= 1.5 * (half if curve_half is None else curve_half) * np.hypot(gn, ge) + 1e-12
        hit |= near
        north += np.where(near, np.abs(gn), 0.0)
        east += np.where(near, np.abs(ge), 0.0)
    return hit, north, east


def _curve_value(curve):
    """``n ↦ n·u - kink_threshold(angle(n, o))`` for the kink ``curve`` (map-frame unit vectors)."""
    u, o, (a_s, a_d) = curve

    def F(n):
        return n @ u - kink_threshold(np.arccos(np.clip(n @ o, -1.0, 1.0)), a_s, a_d)
    return F


def _lines(cells, mu_range, lon_range, circles, k: int, cut_mu: bool, curve=None, inside=None):
    """:func:`_edge_cell_nodes` for cells whose lines all run one way: constant longitude (cut
    in μ = sin lat) with ``cut_mu``, else constant μ (cut in longitude)."""
    g, gw = gauss_legendre(k)
    fixed_range, cut_range = (lon_range, mu_range) if cut_mu else (mu_range, lon_range)
    fixed = fixed_range[0][:, None] + (fixed_range[1] - fixed_range[0])[:, None] * g  # (C, k) line positions
    fixed_w = (fixed_range[1] - fixed_range[0])[:, None] * gw
    lo = np.broadcast_to(cut_range[0][:, None], fixed.shape)
    hi = np.broadcast_to(cut_range[1][:, None], fixed.shape)
    cross = []
    for u, c in circles:
        if cut_mu:  # A cos lat + B sin lat = c along a meridian
            A, B = u[0] * np.cos(fixed) + u[1] * np.sin(fixed), np.full(fixed.shape, u[2])
            rho = np.hypot(A, B)
            ok = np.abs(c) < rho
            alpha = np.arccos(np.clip(c / np.where(ok, rho, 1.0), -1.0, 1.0))
            lats = [np.mod(np.arctan2(B, A) + sg * alpha + np.pi, 2 * np.pi) - np.pi for sg in (1.0, -1.0)]
            roots, lat_ok = [np.sin(la) for la in lats], [np.abs(la) <= np.pi / 2 for la in lats]
        else:  # along a parallel: cos lat (u_x cos λ + u_y sin λ) = c - u_z sin lat
            cl = np.sqrt(np.clip(1.0 - fixed * fixed, 0.0, None))
            rho = cl * np.hypot(u[0], u[1])
            rhs = c - u[2] * fixed
            ok = np.abs(rhs) < rho
            alpha = np.arccos(np.clip(rhs / np.where(ok, rho, 1.0), -1.0, 1.0))
            delta = np.arctan2(u[1], u[0])
            # the root's longitude, shifted into the cell's range modulo 2π
            roots = [np.mod(delta + sg * alpha - lo, 2 * np.pi) + lo for sg in (1.0, -1.0)]
            lat_ok = [True, True]
        for r, good in zip(roots, lat_ok):
            cross.append(np.where(ok & good & (r > lo) & (r < hi), r, np.nan))
    if curve is not None:
        cross += _curve_crossings(_curve_value(curve), fixed, lo, hi, cut_mu)
    pts = np.stack([lo, hi, *cross], axis=-1)  # (C, k, 2 + 2·circles)
    pts = np.sort(np.where(np.isnan(pts), lo[..., None], pts), axis=-1)
    a, b = pts[..., :-1], pts[..., 1:]  # pieces (C, k, m), most of them empty (no crossing)
    # pieces between two crossings of one circle met twice (a cap and the ring through it) are
    # ~1e-16 wide: their points sit on the circle, where a ring's intervals are degenerate
    cell, line, piece = np.nonzero(b - a > 1e-9 * (hi - lo)[..., None])  # the live pieces, in order
    a, b = a[cell, line, piece][:, None], b[cell, line, piece][:, None]
    if inside is not None:  # pieces outside the region (each wholly in or out): none of their points
        live = inside(_line_points(0.5 * (a + b).ravel(), fixed[cell, line], cut_mu))
        cell, line, a, b = cell[live], line[live], a[live], b[live]
    cut = (a + (b - a) * g).ravel()  # (live pieces · k) points along the lines
    wt = ((b - a) * gw * fixed_w[cell, line][:, None]).ravel()
    return _line_points(cut, np.repeat(fixed[cell, line], k), cut_mu), wt, np.repeat(cell, k)


def _line_points(cut, fx, cut_mu: bool) -> np.ndarray:
    """Unit vectors (map frame) at ``cut`` along lines of constant longitude ``fx`` (``cut_mu``:
    ``cut`` is μ = sin lat), else of constant μ ``fx`` (``cut``: longitudes)."""
    mu, lon = (cut, fx) if cut_mu else (fx, cut)
    cl = np.sqrt(np.clip(1.0 - mu * mu, 0.0, None))
    return np.stack([cl * np.cos(lon), cl * np.sin(lon), mu], axis=1)


def _curve_crossings(F, fixed, lo, hi, cut_mu: bool, samples: int = 8, steps: int = 6) -> list:
    """Where each line (``fixed`` (C, k), running from ``lo`` to ``hi`` in μ or longitude) meets
    ``F = 0``: a sign change between ``samples`` + 1 points, then the Illinois variant of regula
    falsi on those alone (bracketing, superlinear: F is smooth across a 1/8-cell step, so 6
    steps put every root within 1e-12 of a cell of F = 0, where 4
    did not and 30 halvings reached ~1e-11; ≤ one crossing per sub-interval; NaN where none)."""
    def point(v, fx):
        mu, lon = np.broadcast_arrays(*((v, fx) if cut_mu else (fx, v)))
        c = np.sqrt(np.clip(1.0 - mu * mu, 0.0, None))
        return np.stack([c * np.cos(lon), c * np.sin(lon), mu], axis=-1)
    edges = lo[..., None] + (hi - lo)[..., None] * np.linspace(0.0, 1.0, samples + 1)  # (C, k, s + 1)
    val = F(point(edges, fixed[..., None]))
    out = []
    for j in range(samples):
        root = np.full(fixed.shape, np.nan)
        idx = np.nonzero(np.sign(val[..., j]) * np.sign(val[..., j + 1]) < 0)
        a, b, fa, fx = edges[..., j][idx], edges[..., j + 1][idx], val[..., j][idx], fixed[idx]
        fb, side = val[..., j + 1][idx], np.zeros(len(a))
        for _ in range(steps):
            den = fb - fa
            m = np.where(den != 0.0, (a * fb - b * fa) / np.where(den != 0.0, den, 1.0), 0.5 * (a + b))
            m = np.where((m > a) & (m < b), m, 0.5 * (a + b))  # (a rounded secant: halve instead)
            fm = F(point(m, fx))
            left = np.sign(fm) == np.sign(fa)  # the root lies in [m, b]
            # Illinois: halve the value at an end kept twice in a row, so both ends converge
            fb = np.where(left, np.where(side == 1, 0.5 * fb, fb), fm)
            fa = np.where(left, fm, np.where(side == -1, 0.5 * fa, fa))
            side = np.where(left, 1, -1)
            a, b = np.where(left, m, a), np.where(left, b, m)
        root[idx] = np.where(np.abs(fa) < np.abs(fb), a, b)
        out.append(root)
    return out
