"""Product Gauss rules over regions of the unit sphere bounded by circles (spherical caps).

Every region that lunarviz integrates over is an intersection of caps ``{n : n·u > c}``:
a body's surface seen from a point (``n·(P - O) > R``), the part lit by a point source
(``n·(S - O) > R``), the part above a facet's horizon, and the band where an extended source of
radius ρ is partly below the horizon (``R - ρ < n·(S - O) < R + ρ``, an exact plane condition).
The integrands are smooth inside such pieces, so Gauss-Legendre in polar coordinates about an
axis converges spectrally once the φ-range of every ring is cut at the cap boundaries and the
t-range at the rings tangent to them. Derivation: the documentation's *Derivations* page (cap splitting).

All functions are vectorised over a batch B of independent rules.
"""

from __future__ import annotations

import functools

import numpy as np

from lunarviz.geometry import quadrature_kernels


def orthonormal_basis(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors (B, 3) completing ``axis`` (B, 3) to a right-handed basis."""
    axis = np.asarray(axis, dtype=float)
    helper = np.where(np.abs(axis[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    e1 = np.cross(axis, helper)
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    e2 = np.cross(axis, e1)
    return e1, e2


def polar_basis(axis: np.ndarray, phi_zero=None) -> tuple[np.ndarray, np.ndarray]:
    """The directions φ = 0 and φ = 90° (B, 3) about ``axis`` (B, 3) of :func:`cap_rule`: φ = 0
    toward ``phi_zero``'s azimuth where given (and not along the axis), else arbitrary."""
    e1, e2 = orthonormal_basis(axis)
    if phi_zero is None:
        return e1, e2
    pz = np.asarray(phi_zero, dtype=float)
    pz = pz - np.einsum("bj,bj->b", pz, axis)[:, None] * axis
    norm = np.linalg.norm(pz, axis=1, keepdims=True)
    ok = norm > 1e-12
    e1 = np.where(ok, pz / np.where(ok, norm, 1.0), e1)
    return e1, np.cross(axis, e1)


def gauss_legendre(n: int):
    """Gauss-Legendre nodes and weights of order ``n`` on [0, 1] (computed once per order:
    numpy's ``leggauss`` takes up to ~5 ms, and a dated sweep asks for the same few orders
    thousands of times; fresh copies, so callers and compiled kernels see ordinary arrays)."""
    x, w = _gauss_legendre(int(n))
    return x.copy(), w.copy()


@functools.lru_cache(maxsize=64)
def _gauss_legendre(n: int):
    x, w = np.polynomial.legendre.leggauss(n)
    return 0.5 * (x + 1.0), 0.5 * w


def cap_rule(axis, cos_max, caps_u=None, caps_c=None, split_only=None, n_t: int = 16,
             n_phi: int = 16, phi_zero=None, crossings: bool = False,
             structured: bool = False, kink=None, thin=None, graded: bool = False, ring_cap=None,
             near_pole: bool = False):
    """Nodes and solid-angle weights over ``{n·axis ≥ cos_max} ∩ caps``, for a batch.

    Parameters
    ----------
    axis : (B, 3) unit vectors, pole of the polar coordinates (t, φ).
    cos_max : (B,) cosine of the region's polar radius.
    caps_u : (B, k, 3) unit vectors; caps_c : (B, k) thresholds. A node counts only where
        ``n·u > c`` for every cap that is not ``split_only``; split-only caps just cut the
        rule where the integrand has a kink (e.g. a penumbra edge).
    split_only : (B, k) bool or None.
    n_t, n_phi : Gauss points per t-segment and per φ-interval.
    phi_zero : (B, 3) or None, a direction whose azimuth about ``axis`` is φ = 0 (default: an
        arbitrary one). Put it opposite the caps' common azimuth and no ring's arc wraps through
        φ = 0, so every (t-segment, φ-interval) block is one smooth patch.
    crossings : also cut the t-range at the rings through the points where two cap boundaries
        cross (there the order of a ring's breakpoints changes).
    structured : return nodes (B, R, I, n_phi, 3) and weights (B, R, I, n_phi): R = S·n_t rings
        (S t-segments of n_t rings), I φ-intervals per ring (inside ones first, in φ order).
    kink : ``(a_s, a_d)`` or None (B = 1 only): also cut where ``n·u_0 = kink_threshold(t, a_s,
        a_d)`` (u_0 the first cap's direction; a curve, not a circle: its tangent and crossing
        rings are found numerically). About the detector, this is where the angles to a source
        at distance R/a_s along u_0 and to the detector at distance R/a_d are equal (i = e).
    thin : ``(width, order, share)`` or None (with ``structured`` only): blocks narrower than
        ``width`` [rad of arc] in t (a t-segment) or in φ (an interval's widest ring), and the
        penumbra band's blocks across φ, that hold under ``share`` of the region's solid angle
        (:func:`_thin_orders`), take ``order`` Gauss points that way instead of ``n_t``/``n_phi``;
        their unused slots have zero weight.

    ring_cap : ``(u, c_of_t)`` or None (B = 1 only): one more constraint ``n·u > c_of_t(t)``, its
        threshold a function of the ring's t: no circle on the sphere, but on each ring about
        ``axis`` a circle's points (the Earth's limb seen from a detector near it, on the lunar
        sphere about that detector); tangents and crossings found numerically (:func:`_ring_cap_cuts`).
    near_pole : also cut at 2, 4, 8, ... times each tangent ring's radius t* < t_max/8 (B = 1):
        a boundary passing t* from the pole leaves the ring integral a singularity at t = 0, t*
        before its segment, where Gauss-Legendre converges ~ (1 + √(t*/L))^-2n.
    graded : also grade the t-segments toward a tangent ring just outside them
        (:func:`_cap_rings`): where a crossing ring lies next to a tangent one (a thin crescent's
        horns seen about a pole off its centre). Without it, the rule is the one
        :func:`rule_coordinates` inverts.

    Returns
    -------
    nodes : (B, M, 3) unit vectors; weights : (B, M) solid angle [sr]: without ``structured``, each
        row's nodes ring by ring, only the rings' φ-intervals inside the region, then zero-weight
        padding to the longest row (:func:`_inside_intervals`); structured, 0 outside the region.
    With ``thin``, also the orders ``(t_orders (B, S), phi_orders (B, S, I))`` actually used.
    """
    axis = np.asarray(axis, dtype=float)
    B = axis.shape[0]
    cos_max = np.broadcast_to(np.asarray(cos_max, dtype=float), (B,))
    caps_u, caps_c, split_only, k = _rule_caps(B, caps_u, caps_c, split_only, ring_cap, thin)
    e1, e2 = polar_basis(axis, phi_zero)
    t_max = np.arccos(np.clip(cos_max, -1.0, 1.0))
    # cap geometry in the polar frame
    ua = np.einsum("bkj,bj->bk", caps_u, axis)
    u1 = np.einsum("bkj,bj->bk", caps_u, e1)
    u2 = np.einsum("bkj,bj->bk", caps_u, e2)
    t_u = np.arctan2(np.hypot(u1, u2), ua)  # (B, k)
    phi_u = np.arctan2(u2, u1)
    caps_c, split_only, t_u, phi_u, extra, tangent = _cuts(axis, caps_u, caps_c, split_only, t_u, phi_u, t_max,
                                                           crossings, kink)
    ring = None if ring_cap is None else (k, ring_cap[1])
    if ring is not None:
        extra, tangent = _ring_cap_cuts(ring, caps_c, t_u, phi_u, t_max, extra, tangent)
    extra, tangent = _near_pole_cuts(t_u, caps_c, t_max, extra, tangent) if near_pole else (extra, tangent)
    t_orders = None
    if thin is not None:  # the blocks at full order first: their widths and shares of the region
        t, wt = _cap_rings(t_u, caps_c, t_max, n_t, extra, tangent, graded=graded)
        p_lo, p_hi, inside = _ring_intervals(np.sin(t), np.cos(t), t_u, phi_u, _ring_thresholds(caps_c, kink, t, ring),
                                             split_only)
        t_orders, phi_orders = _thin_orders(t_u, caps_c, t_max, extra, tangent, t, wt, phi_u, split_only, kink,
                                            p_lo, p_hi, inside, n_t, n_phi, thin)
    t, wt = _cap_rings(t_u, caps_c, t_max, n_t, extra, tangent, t_orders, graded=graded)
    st, ct = np.sin(t), np.cos(t)
    p_lo, p_hi, inside = _ring_intervals(st, ct, t_u, phi_u, _ring_thresholds(caps_c, kink, t, ring), split_only)
    fx, fw = gauss_legendre(n_phi)
    if thin is not None:
        fx, fw = _padded_gauss(n_phi, np.repeat(phi_orders, n_t, axis=1))  # (B, R, I, n_phi)
    elif not structured:  # only the intervals inside the region: the same nodes, ~3x fewer to write
        st, ct, wt, p_lo, p_hi, inside = _inside_intervals(st, ct, wt, p_lo, p_hi, inside)
    if quadrature_kernels.available():  # the same arithmetic, each node written once
        nodes, w = quadrature_kernels.cap_nodes(axis, e1, e2, st, ct, wt, p_lo, p_hi, inside, fx, fw)
    else:
        phi = p_lo[..., None] + (p_hi - p_lo)[..., None] * fx  # (B, R, I, n_phi)
        wphi = ((p_hi - p_lo) * inside)[..., None] * fw
        w = wt[:, :, None, None] * wphi
        sphi, cphi = np.sin(phi), np.cos(phi)
        stt = st[:, :, None, None]
        nodes = (ct[:, :, None, None, None] * axis[:, None, None, None, :]
                 + stt[..., None] * (cphi[..., None] * e1[:, None, None, None, :]
                                     + sphi[..., None] * e2[:, None, None, None, :]))
    if thin is not None:
        return nodes, w, (t_orders, phi_orders)
    if structured:
        return nodes, w
    return nodes.reshape(B, -1, 3), w.reshape(B, -1)


def _rule_caps(B: int, caps_u, caps_c, split_only, ring_cap, thin):
    """:func:`cap_rule`'s caps as arrays ``(caps_u (B, k'), caps_c, split_only, k)``: none given,
    none; the ring cap appended as one more column (static threshold 2, so the closed forms skip
    it; its index ``k``, the number of caps given)."""
    if caps_u is None:
        caps_u = np.zeros((B, 0, 3))
        caps_c = np.zeros((B, 0))
    caps_u = np.asarray(caps_u, dtype=float)
    caps_c = np.asarray(caps_c, dtype=float)
    k = caps_u.shape[1]
    if split_only is None:
        split_only = np.zeros((B, k), dtype=bool)
    split_only = np.broadcast_to(np.asarray(split_only, dtype=bool), (B, k))
    if ring_cap is not None:
        if B != 1 or thin is not None:
            raise ValueError("a ring cap takes one rule (B = 1), without thin blocks")
        caps_u = np.concatenate([caps_u, np.asarray(ring_cap[0], dtype=float).reshape(1, 1, 3)], axis=1)
        caps_c = np.concatenate([caps_c, [[2.0]]], axis=1)
        split_only = np.concatenate([split_only, [[False]]], axis=1)
    return caps_u, caps_c, split_only, k


def _inside_intervals(st, ct, wt, p_lo, p_hi, inside):
    """The rings' φ-intervals inside the region, each row's in ring order (as a ring lists them:
    inside ones first), as rings of one interval each: ``(st, ct, wt)`` (B, P) and ``(p_lo, p_hi,
    inside)`` (B, P, 1), P the most a row has (at least 1); a row's spare slots are empty
    intervals of zero weight about the axis (t = 0). :func:`cap_rule`'s nodes of positive weight
    are then the same, in the same order, and the padding between rings is gone."""
    if quadrature_kernels.available():  # (the same copies, ring by ring)
        return quadrature_kernels.inside_intervals(st, ct, wt, p_lo, p_hi, inside)
    B, R, n_iv = p_lo.shape
    rows, flat = np.nonzero(inside.reshape(B, -1))
    counts = np.bincount(rows, minlength=B)
    P = max(int(counts.max(initial=0)), 1)
    slot = np.arange(len(rows)) - np.repeat(np.cumsum(counts) - counts, counts)
    ring, itv = np.divmod(flat, n_iv)
    out = [np.zeros((B, P)), np.ones((B, P)), np.zeros((B, P))]
    for a, src in zip(out, (st, ct, wt)):
        a[rows, slot] = src[rows, ring]
    lo, hi, ins = np.zeros((B, P, 1)), np.zeros((B, P, 1)), np.zeros((B, P, 1), dtype=bool)
    lo[rows, slot, 0], hi[rows, slot, 0], ins[rows, slot, 0] = p_lo[rows, ring, itv], p_hi[rows, ring, itv], True
    return (*out, lo, hi, ins)


def _cap_dot(st, ct, t_u, phi_u, phi, j: int):
    """``n·u_j`` (B, R, I) for cap j at the rings' polar angles (``st``, ``ct`` (B, R)) and
    azimuths ``phi`` (B, R, I) about the rule's axis (``t_u``, ``phi_u`` (B, k): the caps' own)."""
    return ct[:, :, None] * np.cos(t_u)[:, None, j:j + 1] + \
        st[:, :, None] * np.sin(t_u)[:, None, j:j + 1] * np.cos(phi - phi_u[:, None, j:j + 1])


def _padded_gauss(n: int, orders: np.ndarray):
    """Gauss-Legendre nodes and weights on [0, 1] of ``orders`` (any shape, each ≤ n) in n slots
    (..., n): the unused slots at the node 1/2 with weight 0."""
    table_x, table_w = np.full((n + 1, n), 0.5), np.zeros((n + 1, n))
    for m in np.unique(orders):
        table_x[m, :m], table_w[m, :m] = gauss_legendre(int(m))
    return table_x[orders], table_w[orders]


def _thin_orders(t_u, caps_c, t_max, extra, tangent, t, wt, phi_u, split_only, kink, p_lo, p_hi, inside,
                 n_t: int, n_phi: int, thin):
    """Gauss orders of :func:`cap_rule`'s blocks, from its full-order rings and intervals: in t
    (B, S), ``thin[1]`` for a t-segment narrower than ``thin[0]`` [rad]; across φ (B, S, I),
    ``thin[1]`` for a block whose widest ring's arc is under ``thin[0]`` or that lies in a
    penumbra band (its middle node outside a split-only cap that is not the kink: the source
    partly below the horizon, so the integrand is O(ρ); its profile across the band is smooth
    inside, with (·)^{3/2} ends); ``n_t``/``n_phi`` otherwise. Only where the segment or block
    holds under ``thin[2]`` of the region's solid angle: a region that is thin as a whole (a
    crescent near new Moon) keeps its orders, as its integrand varies across it."""
    B, R, n_iv = p_lo.shape
    S = R // n_t
    st, ct = np.sin(t), np.cos(t)
    width, order, share_max = thin
    area = (wt[..., None] * (p_hi - p_lo) * inside).reshape(B, S, n_t, n_iv).sum(axis=2)  # (B, S, I) [sr]
    share = area / np.maximum(area.sum(axis=(1, 2), keepdims=True), 1e-300)
    t_lo, t_hi, _, _ = t_segments(t_u, caps_c, t_max, extra, tangent)
    t_orders = np.where((t_hi - t_lo < width) & (share.sum(axis=2) < share_max), min(order, n_t), n_t)
    arc = ((p_hi - p_lo) * st[..., None]).reshape(B, S, n_t, n_iv).max(axis=2)
    band = np.zeros((B, S, n_iv), dtype=bool)
    thr = _ring_thresholds(caps_c, kink, t)
    pm = 0.5 * (p_lo + p_hi)
    for j in range(caps_c.shape[1]):
        if not split_only[:, j].any() or (kink is not None and j == caps_c.shape[1] - 1):
            continue
        below = (_cap_dot(st, ct, t_u, phi_u, pm, j) < thr[:, :, j:j + 1]) & split_only[:, None, j:j + 1]
        band |= below.reshape(B, S, n_t, n_iv)[:, :, n_t // 2]
    return t_orders, np.where(((arc < width) | band) & (share < share_max), min(order, n_phi), n_phi)


def kink_threshold(t, a_s: float, a_d: float):
    """``n·u_0`` where i = e on a sphere of radius R seen from the detector at distance R/a_d along
    the pole, at polar angle t, for a source at R/a_s along u_0: cos e = (cos t - a_d)/√(1 - 2 a_d
    cos t + a_d²) exactly (it depends on t alone), and cos i = z - a_s(1 - z²) + O(a_s²) for
    z = n·u_0, so z = v + a_s(1 - v²) with v = cos e."""
    y = np.cos(t)
    v = (y - a_d) / np.sqrt(1.0 - 2.0 * a_d * y + a_d * a_d)
    return v + a_s * (1.0 - v * v)


def _with_kink(kink, caps_c, split_only, t_u, phi_u, t_max):
    """The caps with the kink curve appended (a cut about the first cap's direction; static
    threshold 2, so the closed-form tangencies skip it) and its tangent rings and crossings
    with the caps about the same direction (numerical: ``extra``, ``tangent`` flags)."""
    if kink is None:
        return caps_c, split_only, t_u, phi_u, None, None
    if caps_c.shape[0] != 1:
        raise ValueError("a kink cut takes one rule (B = 1)")
    a_s, a_d = kink
    tu = float(t_u[0, 0])
    grid = np.linspace(0.0, float(t_max[0]), 2049)[1:-1]
    same = [float(c) for c, u in zip(caps_c[0], t_u[0]) if abs(u - tu) < 1e-12 and -1.0 < c < 1.0]
    fns = [(lambda t: kink_threshold(t, a_s, a_d) - np.cos(t - tu), True),  # tangent rings (|q| = 1)
           (lambda t: kink_threshold(t, a_s, a_d) - np.cos(t + tu), True)]
    fns += [(lambda t, c=c: kink_threshold(t, a_s, a_d) - c, False) for c in same]  # crossings
    roots, flags = [], []
    for f, tangent in fns:
        found = _sign_roots(f, grid)
        roots += found
        flags += [tangent] * len(found)
    return (np.concatenate([caps_c, [[2.0]]], axis=1), np.concatenate([split_only, [[True]]], axis=1),
            np.concatenate([t_u, t_u[:, :1]], axis=1), np.concatenate([phi_u, phi_u[:, :1]], axis=1),
            np.array([roots]).reshape(1, -1), np.array([flags], bool).reshape(1, -1))


def _cuts(axis, caps_u, caps_c, split_only, t_u, phi_u, t_max, crossings: bool, kink):
    """The caps with the kink appended (:func:`_with_kink`) and the extra t-cuts: the kink's
    rings and, with ``crossings``, the rings where two caps' boundaries cross
    (:func:`_boundary_crossings`), with their tangent flags."""
    caps_c, split_only, t_u, phi_u, extra, tangent = _with_kink(kink, caps_c, split_only, t_u, phi_u, t_max)
    if crossings:
        cross = _boundary_crossings(axis, caps_u, caps_c[:, :caps_u.shape[1]])
        extra = cross if extra is None else np.concatenate([extra, cross], axis=1)
        tangent = None if tangent is None else np.concatenate([tangent, np.zeros(cross.shape, bool)], axis=1)
    return caps_c, split_only, t_u, phi_u, extra, tangent


def _ring_thresholds(caps_c, kink, t, ring=None):
    """Thresholds per ring (B, R, k): the caps' own, the kink curve's at each ring's t, and the
    ring cap's (``ring``: its column and its threshold's function of t)."""
    c = np.broadcast_to(caps_c[:, None, :], (t.shape[0], t.shape[1], caps_c.shape[1])).copy()
    if kink is not None:
        c[:, :, -1] = kink_threshold(t, *kink)
    if ring is not None:
        c[:, :, ring[0]] = ring[1](t)
    return c


def _sign_roots(f, grid) -> list:
    """The roots of ``f`` between the points of ``grid`` where its sign changes (NaN: no
    change), each bisected to rounding."""
    v = f(grid)
    roots = []
    for i in np.flatnonzero(np.sign(v[:-1]) * np.sign(v[1:]) < 0):
        lo, hi = grid[i], grid[i + 1]
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if np.sign(f(mid)) == np.sign(f(lo)) else (lo, mid)
        roots.append(0.5 * (lo + hi))
    return roots


def _near_pole_cuts(t_u, caps_c, t_max, extra, tangent):
    """``extra``, ``tangent`` (B = 1) with the geometric cuts of :func:`cap_rule`'s ``near_pole``:
    2^k t* (k ≥ 1) below t_max/2 for each tangent radius t* < t_max/8, the caps' (closed form) and
    those among ``extra`` flagged tangent (a ring cap's or a kink's, found numerically)."""
    radii = list(_tangent_radii(t_u, caps_c, t_max)[0])
    if extra is not None and tangent is not None:
        radii += [float(r) for r, f in zip(extra[0], tangent[0]) if f and np.isfinite(r)]
    top = float(t_max[0])
    cuts = [r * 2.0**k for r in radii if np.isfinite(r) and 0.0 < r < top / 8
            for k in range(1, 64) if r * 2.0**k < top / 2]
    return _appended_cuts(extra, tangent, cuts, [False] * len(cuts))


def _ring_cap_cuts(ring, caps_c, t_u, phi_u, t_max, extra, tangent):
    """The t-cuts a ring cap (column ``ring[0]``, threshold ``ring[1](t)``) adds to ``extra`` and
    ``tangent`` (B = 1): its tangent rings (where its threshold reaches cos(t ∓ t_u), the ring's
    extremes of n·u) and the rings through its crossings with every other cap's boundary (where
    that cap's n·u_m - c_m changes sign at the ring cap's breakpoints φ_u ± arccos q)."""
    j, fn = ring
    tu, pu = float(t_u[0, j]), float(phi_u[0, j])
    top = float(t_max[0])
    # (a uniform grid, and a geometric one below its first step: a boundary passing nearer the pole
    # than t_max/2048 is tangent there, and near_pole's cuts need that radius)
    grid = np.unique(np.concatenate([np.geomspace(top * 1e-12, top / 2048, 64), np.linspace(0.0, top, 2049)[1:-1]]))
    roots = _sign_roots(lambda t: fn(t) - np.cos(t - tu), grid) + _sign_roots(lambda t: fn(t) - np.cos(t + tu), grid)
    flags = [True] * len(roots)
    for m in range(caps_c.shape[1]):
        c_m = float(caps_c[0, m])
        if m == j or not -1.0 < c_m < 1.0:
            continue
        tm, pm = float(t_u[0, m]), float(phi_u[0, m])
        for sgn in (1.0, -1.0):
            def g(t, sgn=sgn, tm=tm, pm=pm, c_m=c_m):
                st, ct = np.sin(t), np.cos(t)
                with np.errstate(divide="ignore", invalid="ignore"):
                    q = (fn(t) - ct * np.cos(tu)) / (st * np.sin(tu))
                phi = pu + sgn * np.arccos(np.clip(q, -1.0, 1.0))
                val = st * np.sin(tm) * np.cos(phi - pm) + ct * np.cos(tm) - c_m
                return np.where(np.abs(q) < 1.0, val, np.nan)  # (no breakpoint on that ring: no crossing)
            found = _sign_roots(g, grid)
            roots += found
            flags += [False] * len(found)
    return _appended_cuts(extra, tangent, roots, flags)


def _appended_cuts(extra, tangent, cuts: list, flags: list):
    """``extra`` (1, m) and ``tangent`` with the t-cuts ``cuts`` and their tangent ``flags`` appended
    (:func:`t_segments`' inputs; none: unchanged)."""
    if not cuts:
        return extra, tangent
    new_t, new_f = np.array([cuts], dtype=float), np.array([flags], bool)
    if extra is None:
        return new_t, new_f
    old_f = np.zeros(extra.shape, bool) if tangent is None else tangent
    return np.concatenate([extra, new_t], axis=1), np.concatenate([old_f, new_f], axis=1)


def _boundary_crossings(axis, caps_u, caps_c) -> np.ndarray:
    """Polar angles t (B, 2·pairs) about ``axis`` of the points where two cap boundaries cross
    (NaN where they do not): the line of the planes ``n·u_a = c_a``, ``n·u_b = c_b`` meets the
    unit sphere at ``α u_a + β u_b ± γ u_a×u_b``."""
    B, k = caps_c.shape
    out = []
    for a in range(k):
        for b in range(a + 1, k):
            ua, ub, ca, cb = caps_u[:, a], caps_u[:, b], caps_c[:, a], caps_c[:, b]
            G = np.einsum("bj,bj->b", ua, ub)
            det = 1.0 - G * G
            ok = det > 1e-12
            det = np.where(ok, det, 1.0)
            al, be = (ca - cb * G) / det, (cb - ca * G) / det
            p0 = al[:, None] * ua + be[:, None] * ub
            x = np.cross(ua, ub)
            g2 = (1.0 - np.einsum("bj,bj->b", p0, p0)) / np.where(ok, det, 1.0)
            ok &= g2 >= 0.0
            g = np.sqrt(np.where(ok, g2, 0.0))
            for sgn in (1.0, -1.0):
                p = p0 + sgn * g[:, None] * x
                t = np.arccos(np.clip(np.einsum("bj,bj->b", p, axis), -1.0, 1.0))
                out.append(np.where(ok, t, np.nan))
    return np.stack(out, axis=1) if out else np.zeros((B, 0))


def _tangent_candidates(t_u, caps_c):
    """The polar radii (B, 3k) where a ring about the pole may be tangent to a cap boundary
    (nearest, farthest and through the antipode), and where the cap has a boundary at all
    (``real``: a cap with |c| >= 1 has none)."""
    a = np.arccos(np.clip(caps_c, -1.0, 1.0))
    cand = np.concatenate([np.abs(t_u - a), t_u + a, 2 * np.pi - t_u - a], axis=1)
    return cand, np.tile((caps_c > -1.0) & (caps_c < 1.0), 3)


def t_segments(t_u, caps_c, t_max, extra=None, tangent=None):
    """The t-segments of :func:`cap_rule`: ``(t_lo, t_hi, tangent_lo, tangent_hi)`` (B, S), split
    where a ring becomes tangent to a cap boundary (``tangent_*``: that end is tangent) and at
    the polar angles ``extra`` (B, m; NaN: none; tangent where ``tangent`` (B, m) says so),
    empty segments dropped."""
    B = t_u.shape[0]
    # t segments: split where a ring becomes tangent to a cap boundary
    cand, real = _tangent_candidates(t_u, caps_c)
    cand = np.where(real, np.clip(cand, 0.0, t_max[:, None]), 0.0)
    if extra is not None and extra.shape[1]:  # crossings are cuts, not tangencies (plain Gauss ends)
        cross = np.where(np.isfinite(extra), np.clip(extra, 0.0, t_max[:, None]), 0.0)
    else:
        cross = np.zeros((B, 0))
    pts = np.concatenate([np.zeros((B, 1)), cand, cross, t_max[:, None]], axis=1)
    cross_tangent = np.zeros(cross.shape, bool) if tangent is None or not cross.shape[1] else \
        tangent & (cross > 0) & (cross < t_max[:, None])
    is_tangent = np.concatenate([np.zeros((B, 1), bool), (cand > 0) & (cand < t_max[:, None]),
                                 cross_tangent, np.zeros((B, 1), bool)], axis=1)
    srt = np.argsort(pts, axis=1, kind="stable")
    tb = np.take_along_axis(pts, srt, 1)
    sing = np.take_along_axis(is_tangent, srt, 1)
    t_lo, t_hi = tb[:, :-1], tb[:, 1:]  # (B, S)
    s_lo, s_hi = sing[:, :-1], sing[:, 1:]
    # drop the segments that are empty in every row (most candidates coincide or are clipped)
    nonempty = t_hi > t_lo
    keep = max(int(nonempty.sum(1).max(initial=0)), 1)
    sel = np.argsort(~nonempty, axis=1, kind="stable")[:, :keep]
    t_lo, t_hi = np.take_along_axis(t_lo, sel, 1), np.take_along_axis(t_hi, sel, 1)
    t_hi = np.where(np.take_along_axis(nonempty, sel, 1), t_hi, t_lo)
    return t_lo, t_hi, np.take_along_axis(s_lo, sel, 1), np.take_along_axis(s_hi, sel, 1)


def _tangent_radii(t_u, caps_c, t_max) -> np.ndarray:
    """The polar radii (B, 3k) where a ring is tangent to a cap boundary, inside (0, t_max)
    (NaN elsewhere): :func:`t_segments`' tangent ends."""
    cand, real = _tangent_candidates(t_u, caps_c)
    return np.where(real & (cand > 0.0) & (cand < t_max[:, None]), cand, np.nan)


def _near_tangents(radii, t_lo, t_hi, s_lo, s_hi):
    """For each t-segment (B, S), the tangent radius just below its start and just above its
    end, where one lies outside the segment closer than the segment is long (NaN: none, or that
    end is itself tangent)."""
    L = (t_hi - t_lo)[:, :, None]
    r = radii[:, None, :]
    with np.errstate(invalid="ignore"):
        below = np.where((r < t_lo[:, :, None]) & (t_lo[:, :, None] - r < L), r, -np.inf).max(axis=2)
        above = np.where((r > t_hi[:, :, None]) & (r - t_hi[:, :, None] < L), r, np.inf).min(axis=2)
    below = np.where(np.isfinite(below) & ~s_lo & (t_hi > t_lo), below, np.nan)
    above = np.where(np.isfinite(above) & ~s_hi & (t_hi > t_lo), above, np.nan)
    return below, above


def _graded_segments(t_u, caps_c, t_max, extra, tangent):
    """:func:`t_segments` for :func:`cap_rule`'s ``graded`` rule, with each segment's anchors
    (:func:`_near_tangents`); a segment singular or nearly so at both ends, not both tangent, is
    cut at its middle (each half then has one such end)."""
    radii = _tangent_radii(t_u, caps_c, t_max)
    t_lo, t_hi, s_lo, s_hi = t_segments(t_u, caps_c, t_max, extra, tangent)
    below, above = _near_tangents(radii, t_lo, t_hi, s_lo, s_hi)
    both = (s_lo | np.isfinite(below)) & (s_hi | np.isfinite(above)) & ~(s_lo & s_hi)
    if both.any():
        mid = np.where(both, 0.5 * (t_lo + t_hi), np.nan)
        extra = mid if extra is None else np.concatenate([extra, mid], axis=1)
        tangent = None if tangent is None else np.concatenate([tangent, np.zeros(mid.shape, bool)], axis=1)
        t_lo, t_hi, s_lo, s_hi = t_segments(t_u, caps_c, t_max, extra, tangent)
        below, above = _near_tangents(radii, t_lo, t_hi, s_lo, s_hi)
    # one anchor a segment: the closer (a half's far one, the old segment's end, lies about its
    # own length away and may count by rounding), none across a tangent end
    use_above = np.isfinite(above) & ~s_lo & (~np.isfinite(below) | (above - t_hi < t_lo - below))
    return t_lo, t_hi, s_lo, s_hi, np.where(use_above | s_hi, np.nan, below), np.where(use_above, above, np.nan)


def _cap_rings(t_u, caps_c, t_max, n_t: int, extra=None, tangent=None, orders=None, graded: bool = False):
    """Polar rings t (B, R) of :func:`cap_rule` and their weights ``dt·sin t`` (B, R): Gauss
    segments between the polar radii where a ring becomes tangent to a cap boundary (``orders``
    (B, S) ≤ n_t points in a segment, the rest of its n_t rings weightless; default n_t)."""
    B = t_u.shape[0]
    if graded:
        t_lo, t_hi, s_lo, s_hi, below, above = _graded_segments(t_u, caps_c, t_max, extra, tangent)
    else:
        t_lo, t_hi, s_lo, s_hi = t_segments(t_u, caps_c, t_max, extra, tangent)
    u, gw = gauss_legendre(n_t) if orders is None else _padded_gauss(n_t, orders)
    if quadrature_kernels.available():  # the same arithmetic, node by node
        none = np.full(t_lo.shape, np.nan)
        t, wt = quadrature_kernels.cap_rings(t_lo, t_hi, s_lo, s_hi, below if graded else none,
                                             above if graded else none, u, gw)
        return t.reshape(B, -1), wt.reshape(B, -1)
    s_lo, s_hi = s_lo[:, :, None], s_hi[:, :, None]
    # Next to a tangent ring t* the φ-half-width of a ring behaves like √|t - t*|, so the ring
    # integral has a square-root singularity there; the substitution t - t* ∝ u² at such ends
    # (smoothstep 3u² - 2u³ when both ends are tangent) makes it analytic in u. Ends that are
    # not tangent keep plain Gauss-Legendre (exact for polynomials of degree 2n - 1).
    f_both, j_both = u * u * (3.0 - 2.0 * u), 6.0 * u * (1.0 - u)
    f_lo, j_lo = u * u, 2.0 * u
    f_hi, j_hi = 1.0 - (1.0 - u) ** 2, 2.0 * (1.0 - u)
    f = np.where(s_lo & s_hi, f_both, np.where(s_lo, f_lo, np.where(s_hi, f_hi, u)))
    jac = np.where(s_lo & s_hi, j_both, np.where(s_lo, j_lo, np.where(s_hi, j_hi, 1.0)))
    t = t_lo[:, :, None] + (t_hi - t_lo)[:, :, None] * f  # (B, S, n_t)
    dt = (t_hi - t_lo)[:, :, None] * jac
    if graded:
        # A tangent radius t* just outside a segment (closer than its length: a crossing ring
        # next to a tangent one, as at a thin crescent's horns) leaves √|t - t*| nearly singular
        # inside it, and Gauss-Legendre converges only algebraically. The substitution
        # t = t* ± s², s linear in u, makes it analytic (at t* itself, the u² map above).
        for anchor, sign in ((below, 1.0), (above, -1.0)):
            on = np.isfinite(anchor)[:, :, None]
            if not on.any():
                continue
            a = np.where(on[..., 0], anchor, t_lo)[:, :, None]
            s0 = np.sqrt(np.abs(t_lo[:, :, None] - a))
            s1 = np.sqrt(np.abs(t_hi[:, :, None] - a))
            sv = s0 + (s1 - s0) * u
            t = np.where(on, a + sign * sv * sv, t)
            dt = np.where(on, 2.0 * sv * np.abs(s1 - s0), dt)
    wt = dt * gw * np.sin(t)
    return t.reshape(B, -1), wt.reshape(B, -1)  # (B, R) rings


def _ring_intervals(st, ct, t_u, phi_u, caps_c, split_only):
    """φ-intervals ``(p_lo, p_hi, inside)`` (B, R, I) of every ring of :func:`cap_rule`: the
    ring cut at every cap's boundary, ``inside`` where an interval lies in every constraint cap."""
    B, R = st.shape
    k = caps_c.shape[-1]
    cr = caps_c if caps_c.ndim == 3 else caps_c[:, None, :]  # thresholds per ring (B, R, k) or per rule
    if quadrature_kernels.available() and (k > 1 or split_only.any()):  # the same arithmetic, ring by ring
        return quadrature_kernels.ring_intervals(st, ct, t_u, phi_u, cr, split_only)
    # φ breakpoints on every ring for every cap
    stu, ctu = np.sin(t_u)[:, None, :], np.cos(t_u)[:, None, :]
    den = st[:, :, None] * stu
    num = cr - ct[:, :, None] * ctu
    with np.errstate(divide="ignore", invalid="ignore"):
        q = np.where(np.abs(den) > 1e-300, num / den, np.where(num < 0, -np.inf, np.inf))
    hw = np.arccos(np.clip(q, -1.0, 1.0))  # half-width of the arc inside each cap (π: whole ring)
    pu = phi_u[:, None, :]
    if k <= 1 and not split_only.any():
        # fast path: the region of a ring is one arc centred on the cap's azimuth
        if k == 0:
            p_lo, p_hi = np.zeros((B, R, 1)), np.full((B, R, 1), 2 * np.pi)
        else:
            p_lo, p_hi = pu - hw, pu + hw
        return p_lo, p_hi, np.ones(p_lo.shape, dtype=bool)
    partial = (q > -1.0) & (q < 1.0)
    b_lo = np.where(partial, np.mod(pu - hw, 2 * np.pi), 0.0)
    b_hi = np.where(partial, np.mod(pu + hw, 2 * np.pi), 0.0)
    pb = np.concatenate([np.zeros((B, R, 1)), b_lo, b_hi, np.full((B, R, 1), 2 * np.pi)], axis=2)
    pb = np.sort(pb, axis=2)
    p_lo, p_hi = pb[:, :, :-1], pb[:, :, 1:]  # (B, R, 2k+1)
    # which φ-intervals lie inside every constraint cap: test the interval midpoints
    pm = 0.5 * (p_lo + p_hi)
    inside = np.ones(pm.shape, dtype=bool)
    for j in range(k):
        inside &= (_cap_dot(st, ct, t_u, phi_u, pm, j) > cr[:, :, j:j + 1]) | split_only[:, None, j:j + 1]
    # keep only intervals that are inside somewhere (and non-empty)
    inside &= p_hi > p_lo
    keep = max(int(inside.sum(2).max(initial=0)), 1)
    sel = np.argsort(~inside, axis=2, kind="stable")[:, :, :keep]
    p_lo, p_hi = np.take_along_axis(p_lo, sel, 2), np.take_along_axis(p_hi, sel, 2)
    return p_lo, p_hi, np.take_along_axis(inside, sel, 2)


def _one_rule(axis, cos_max, caps_u, caps_c, split_only, phi_zero, crossings: bool, kink):
    """One rule's polar frame and caps (the kink appended), and its extra t-cuts, as
    :func:`cap_rule` builds them."""
    ax = np.asarray(axis, dtype=float)[None, :]
    cu, cc = np.asarray(caps_u, float)[None], np.asarray(caps_c, float)[None]
    so = np.asarray(split_only, bool)[None]
    e1, e2 = polar_basis(ax, None if phi_zero is None else np.asarray(phi_zero, float)[None, :])
    t_max = np.arccos(np.clip(np.atleast_1d(np.asarray(cos_max, float)), -1.0, 1.0))
    ua, u1, u2 = (np.einsum("bkj,bj->bk", cu, v) for v in (ax, e1, e2))
    t_u, phi_u = np.arctan2(np.hypot(u1, u2), ua), np.arctan2(u2, u1)
    cc, so, t_u, phi_u, extra, tangent = _cuts(ax, cu, cc, so, t_u, phi_u, t_max, crossings, kink)
    return ax, e1, e2, t_max, cc, so, t_u, phi_u, extra, tangent


def rule_segments(axis, cos_max, caps_u, caps_c, split_only, crossings: bool = False, kink=None):
    """The t-segment bounds ``(t_lo, t_hi)`` (S,) of one rule of :func:`cap_rule` (arguments as
    for :func:`rule_coordinates`)."""
    *_, t_max, cc, _, t_u, _, extra, tangent = _one_rule(axis, cos_max, caps_u, caps_c, split_only, None,
                                                         crossings, kink)
    t_lo, t_hi, _, _ = t_segments(t_u, cc, t_max, extra, tangent)
    return t_lo[0], t_hi[0]


def rule_coordinates(points, axis, cos_max, caps_u, caps_c, split_only, phi_zero=None, crossings: bool = False,
                     kink=None):
    """Where unit vectors ``points`` (P, 3) lie in one rule of :func:`cap_rule` (``axis`` (3,),
    ``caps_u`` (k, 3), ``caps_c``, ``split_only`` (k,), ``kink`` as there): ``(segment, interval,
    u_t, u_φ, inside)`` (P,), with ``u_t, u_φ ∈ [0, 1]`` the Gauss variables of the point's block
    (the t-substitution at tangent ends inverted), ``inside`` False outside the region."""
    p = np.asarray(points, dtype=float)
    ax, e1, e2, t_max, cc, so, t_u, phi_u, extra, tangent = _one_rule(axis, cos_max, caps_u, caps_c, split_only,
                                                                      phi_zero, crossings, kink)
    t = np.arccos(np.clip(p @ ax[0], -1.0, 1.0))
    phi = np.mod(np.arctan2(p @ e2[0], p @ e1[0]), 2 * np.pi)
    t_lo, t_hi, s_lo, s_hi = (a[0] for a in t_segments(t_u, cc, t_max, extra, tangent))
    if quadrature_kernels.available() and (cc.shape[1] > 1 or so.any()):  # (the general ring intervals)
        kink_c = kink_threshold(t, *kink) if kink is not None else np.zeros(len(t))
        return quadrature_kernels.locate(p, ax[0], e1[0], e2[0], t_max[0], t_u[0], phi_u[0], cc[0], so[0],
                                         t_lo, t_hi, s_lo, s_hi, kink_c, cc.shape[1] - 1 if kink else -1)
    seg = np.clip(np.searchsorted(t_hi, t, side="right"), 0, len(t_hi) - 1)
    inside = (t <= t_max[0]) & (t >= t_lo[seg]) & (t_hi[seg] > t_lo[seg])
    v = np.clip((t - t_lo[seg]) / np.where(t_hi[seg] > t_lo[seg], t_hi[seg] - t_lo[seg], 1.0), 0.0, 1.0)
    lo, hi = s_lo[seg], s_hi[seg]
    u_t = np.where(lo & hi, 0.5 - np.sin(np.arcsin(np.clip(1.0 - 2.0 * v, -1.0, 1.0)) / 3.0),
                   np.where(lo, np.sqrt(v), np.where(hi, 1.0 - np.sqrt(1.0 - v), v)))
    p_lo, p_hi, ins = (a[0] for a in _ring_intervals(np.sin(t)[None], np.cos(t)[None], t_u, phi_u,
                                                     _ring_thresholds(cc, kink, t[None]), so))
    width = p_hi - p_lo
    d = np.mod(phi[:, None] - p_lo, 2 * np.pi)
    hit = ins & (d < width) & (width > 0)
    interval = np.argmax(hit, axis=1)
    inside &= hit.any(axis=1)
    rows = np.arange(len(p))
    u_phi = np.clip(d[rows, interval] / np.where(width[rows, interval] > 0, width[rows, interval], 1.0), 0.0, 1.0)
    return seg, interval, u_t, u_phi, inside


def cone_rule(axis, sin_rho, n_psi: int = 2, n_phi: int = 4):
    """Directions (B, n_psi·n_phi, 3) and solid angles (B, n_psi·n_phi) [sr] filling the cone
    of half-angle ρ = asin(sin_rho) about ``axis`` (B, 3).

    Gauss-Legendre in u = 1 - cos ψ (dΩ = du dφ, so the weights sum to the cone's solid
    angle 2π(1 - cos ρ) exactly) and the midpoint rule in φ (spectral for periodic
    integrands). For a small source fully above the horizon the integrand is nearly constant
    across the cone, so a handful of directions is exact to ~1e-8.
    """
    axis = np.asarray(axis, dtype=float)
    sin_rho = np.asarray(sin_rho, dtype=float)
    u_max = sin_rho**2 / (1.0 + np.sqrt(1.0 - sin_rho**2))  # 1 - cos ρ without cancellation
    gx, gw = gauss_legendre(n_psi)
    u = u_max[:, None] * gx  # (B, n_psi)
    wu = u_max[:, None] * gw
    cpsi = 1.0 - u
    spsi = np.sqrt(np.clip(u * (2.0 - u), 0.0, None))
    phi = (np.arange(n_phi) + 0.5) * (2 * np.pi / n_phi)
    e1, e2 = orthonormal_basis(axis)
    d = (cpsi[:, :, None, None] * axis[:, None, None, :]
         + spsi[:, :, None, None] * (np.cos(phi)[None, None, :, None] * e1[:, None, None, :]
                                      + np.sin(phi)[None, None, :, None] * e2[:, None, None, :]))
    w = np.broadcast_to((wu * (2 * np.pi / n_phi))[:, :, None], (len(axis), n_psi, n_phi))
    return d.reshape(len(axis), -1, 3), w.reshape(len(axis), -1)


def compact(nodes: np.ndarray, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Drop zero-weight nodes of a single rule (nodes (M, 3), weights (M,))."""
    keep = weights > 0.0
    return nodes[keep], weights[keep]
