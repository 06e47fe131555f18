"""Compiled kernels of the mapped lune rule (:mod:`lunarviz.geometry.mapped_lune`), which
locates ~10⁵ map points per path and date and sums them into each block's weights:

* :func:`locate`, compiled :func:`lunarviz.geometry.sphere_quadrature.rule_coordinates`: one pass
  per point, the same arithmetic as the numpy path (its ring breakpoints, sorted; its interval
  midpoint test), so the same blocks and coordinates to rounding;
* :func:`block_design`: a block's Lagrange rows in u_t and u_φ (barycentric form, as
  :func:`lunarviz.geometry.mapped_lune.lagrange_matrix`) and their product with the points'
  albedo-node factors, written once (the numpy path builds three temporaries of that size);
* :func:`cap_nodes`: :func:`lunarviz.geometry.sphere_quadrature.cap_rule`'s nodes and weights,
  each written once in the numpy path's arithmetic order (it builds five temporaries of the
  output's size: ~10⁶ nodes for a date's Earth beams);
* :func:`ring_intervals`: :func:`lunarviz.geometry.sphere_quadrature.cap_rule`'s φ-intervals of
  every ring (each ring cut at every cap's boundary, its inside intervals first), one ring at a
  time in the numpy path's arithmetic (it builds a dozen (B, R, k) temporaries and sorts them),
  a cap that misses a ring decided once for it;
* :func:`cap_rings`: :func:`lunarviz.geometry.sphere_quadrature.cap_rule`'s rings and their weights
  from its t-segments (the end maps at tangent rings, the graded anchors), node by node in the
  numpy path's arithmetic (a dozen (B, S, n) temporaries there);
* :func:`sphere_beams`: a source sphere's rule, its zero-weight nodes moved last, as the beams
  seen from each point (:func:`lunarviz.methods.sources.source_beams`' directions and solid
  angles), in one pass (the numpy path sorts, gathers and builds six temporaries of that size);
  the same directions, and the same solid angles to rounding (a node grazing the source's limb
  sums its cos_y in another order than numpy's einsum).

Both agree with their numpy paths to rounding (docs: accuracy)."""

from __future__ import annotations

import numpy as np

import lunarviz.compiled as compiled


def available() -> bool:
    """Whether the compiled kernel is in use."""
    return _NUMBA


def _locate(p, axis, e1, e2, t_max, t_u, phi_u, caps_c, split, t_lo, t_hi, s_lo, s_hi, kink_c, kink_j,
            seg_out, itv_out, ut_out, up_out, in_out):
    """For each unit vector p[i]: its t-segment, φ-interval (inside ones counted in φ order),
    Gauss variables and whether it lies in the rule's region (see ``rule_coordinates``); cap
    ``kink_j`` (if ≥ 0) has the threshold ``kink_c[i]`` at each point."""
    two_pi = 2.0 * np.pi
    k = caps_c.shape[0]
    S = t_lo.shape[0]
    br = np.empty(2 * k + 2)
    stu, ctu = np.sin(t_u), np.cos(t_u)  # (the same values the numpy path takes, once)
    for i in range(p.shape[0]):
        in_out[i] = False
        ct = p[i, 0] * axis[0] + p[i, 1] * axis[1] + p[i, 2] * axis[2]
        t = np.arccos(min(1.0, max(-1.0, ct)))
        if t > t_max:
            continue
        phi = np.arctan2(p[i, 0] * e2[0] + p[i, 1] * e2[1] + p[i, 2] * e2[2],
                         p[i, 0] * e1[0] + p[i, 1] * e1[1] + p[i, 2] * e1[2]) % two_pi
        s = 0
        while s < S - 1 and t >= t_hi[s]:
            s += 1
        if t < t_lo[s] or not t_hi[s] > t_lo[s]:
            continue
        v = min(1.0, max(0.0, (t - t_lo[s]) / (t_hi[s] - t_lo[s])))
        if s_lo[s] and s_hi[s]:
            u = 0.5 - np.sin(np.arcsin(min(1.0, max(-1.0, 1.0 - 2.0 * v))) / 3.0)
        elif s_lo[s]:
            u = np.sqrt(v)
        elif s_hi[s]:
            u = 1.0 - np.sqrt(1.0 - v)
        else:
            u = v
        st, ctt = np.sin(t), np.cos(t)
        br[0] = 0.0
        br[1] = two_pi
        for j in range(k):
            den = st * stu[j]
            num = (kink_c[i] if j == kink_j else caps_c[j]) - ctt * ctu[j]
            if abs(den) > 1e-300:
                q = num / den
            else:
                q = -np.inf if num < 0 else np.inf
            if -1.0 < q < 1.0:
                hw = np.arccos(q)
                br[2 + j] = (phi_u[j] - hw) % two_pi
                br[2 + k + j] = (phi_u[j] + hw) % two_pi
            else:
                br[2 + j] = 0.0
                br[2 + k + j] = 0.0
        br.sort()
        count = 0
        for m in range(2 * k + 1):
            lo, hi = br[m], br[m + 1]
            if not hi > lo:
                continue
            pm = 0.5 * (lo + hi)
            ok = True
            for j in range(k):
                if split[j]:
                    continue
                ndotu = ctt * ctu[j] + st * stu[j] * np.cos(pm - phi_u[j])
                if not ndotu > caps_c[j]:
                    ok = False
                    break
            if not ok:
                continue
            if lo <= phi < hi:
                seg_out[i] = s
                itv_out[i] = count
                ut_out[i] = u
                up_out[i] = min(1.0, max(0.0, (phi - lo) / (hi - lo)))
                in_out[i] = True
                break
            count += 1


def locate(p, axis, e1, e2, t_max, t_u, phi_u, caps_c, split, t_lo, t_hi, s_lo, s_hi, kink_c, kink_j: int):
    """Run the kernel; returns ``(segment, interval, u_t, u_φ, inside)`` (P,)."""
    n = len(p)
    seg, itv = np.zeros(n, np.int64), np.zeros(n, np.int64)
    ut, up, ins = np.zeros(n), np.zeros(n), np.zeros(n, np.bool_)
    _locate(np.ascontiguousarray(p, dtype=np.float64), axis, e1, e2, float(t_max), t_u, phi_u, caps_c,
            np.asarray(split, np.bool_), t_lo, t_hi, np.asarray(s_lo, np.bool_), np.asarray(s_hi, np.bool_),
            np.asarray(kink_c, np.float64), int(kink_j), seg, itv, ut, up, ins)
    return seg, itv, ut, up, ins


def _lagrange_row(x, nodes, bw, out):
    """``out[i] = ℓ_i(x)`` on ``nodes`` with barycentric weights ``bw`` (exactly 1 at a node)."""
    n = len(nodes)
    for i in range(n):
        if x == nodes[i]:
            for j in range(n):
                out[j] = 0.0
            out[i] = 1.0
            return
    total = 0.0
    for i in range(n):
        out[i] = bw[i] / (x - nodes[i])
        total += out[i]
    for i in range(n):
        out[i] /= total


def _block_design(u_t, u_p, ell, gt, bt, gp, bp, A, Lp):
    mt, q = len(gt), ell.shape[1]
    row = np.empty(mt)
    for k in range(len(u_t)):
        _lagrange_row(u_t[k], gt, bt, row)
        for i in range(mt):
            for j in range(q):
                A[k, i * q + j] = row[i] * ell[k, j]
        _lagrange_row(u_p[k], gp, bp, Lp[k])


def _cap_nodes(axis, e1, e2, st, ct, wt, p_lo, p_hi, inside, fx, fw, nodes, w):
    B, R, n_iv, n = fx.shape
    for b in range(B):
        for r in range(R):
            s_t, c_t = st[b, r], ct[b, r]
            for i in range(n_iv):
                lo = p_lo[b, r, i]
                d = p_hi[b, r, i] - lo
                dw = d * inside[b, r, i]
                for j in range(n):
                    phi = lo + d * fx[b, r, i, j]
                    cp, sp = np.cos(phi), np.sin(phi)
                    for c in range(3):
                        nodes[b, r, i, j, c] = c_t * axis[b, c] + s_t * (cp * e1[b, c] + sp * e2[b, c])
                    w[b, r, i, j] = wt[b, r] * (dw * fw[b, r, i, j])


def cap_nodes(axis, e1, e2, st, ct, wt, p_lo, p_hi, inside, fx, fw) -> tuple[np.ndarray, np.ndarray]:
    """Nodes (B, R, I, n, 3) and solid-angle weights (B, R, I, n) of the rings (``st``, ``ct``,
    ``wt`` (B, R)) and φ-intervals (``p_lo``, ``p_hi``, ``inside`` (B, R, I)) about ``axis`` with
    the polar basis ``e1``, ``e2`` (B, 3), at the Gauss variables ``fx`` and weights ``fw`` on
    [0, 1] ((n,), or (B, R, I, n) for padded orders)."""
    B, R, n_iv = p_lo.shape
    n = np.shape(fx)[-1]
    fx4 = np.broadcast_to(np.asarray(fx, dtype=np.float64), (B, R, n_iv, n))
    fw4 = np.broadcast_to(np.asarray(fw, dtype=np.float64), (B, R, n_iv, n))
    nodes, w = np.empty((B, R, n_iv, n, 3)), np.empty((B, R, n_iv, n))
    _cap_nodes(axis, e1, e2, st, ct, wt, p_lo, p_hi, inside.astype(np.float64), fx4, fw4, nodes, w)
    return nodes, w


def _ring_intervals(st, ct, t_u, phi_u, cr, split, p_lo, p_hi, inside, counts):
    """Every ring's φ-intervals (see ``sphere_quadrature._ring_intervals``): its breakpoints at
    every cap's boundary, sorted, and whether each interval's midpoint lies in every constraint
    cap; the inside intervals first (in φ order), then the others; ``counts`` the inside ones.
    A cap whose boundary misses the ring (``|q| ≥ 1``) holds all of it or none, decided once for
    the ring from q (the numpy path's midpoint test gives the same, to rounding), and the few
    breakpoints are sorted by insertion: ~2.5x faster than a midpoint test per cap and interval."""
    two_pi = 2.0 * np.pi
    B, R = st.shape
    k = t_u.shape[1]
    n = 2 * k + 1
    pb = np.empty(2 * k + 2)
    lo, hi, ins = np.empty(n), np.empty(n), np.empty(n, dtype=np.bool_)
    stu, ctu = np.empty(k), np.empty(k)
    state = np.empty(k, dtype=np.int64)  # 0: the cap cuts the ring (midpoint test); 1: holds it all; -1: none
    for b in range(B):
        for j in range(k):  # (a row's caps: the same values as at every ring)
            stu[j], ctu[j] = np.sin(t_u[b, j]), np.cos(t_u[b, j])
        for r in range(R):
            pb[0], pb[2 * k + 1] = 0.0, two_pi
            for j in range(k):
                den = st[b, r] * stu[j]
                num = cr[b, r, j] - ct[b, r] * ctu[j]
                if abs(den) > 1e-300:
                    q = num / den
                else:
                    q = -np.inf if num < 0 else np.inf
                if -1.0 < q < 1.0:
                    hw = np.arccos(q)
                    pb[1 + j] = (phi_u[b, j] - hw) % two_pi
                    pb[1 + k + j] = (phi_u[b, j] + hw) % two_pi
                    state[j] = 0
                else:
                    pb[1 + j] = 0.0
                    pb[1 + k + j] = 0.0
                    state[j] = 1 if q <= -1.0 else -1
            for a in range(1, 2 * k + 2):
                v = pb[a]
                c = a - 1
                while c >= 0 and pb[c] > v:
                    pb[c + 1] = pb[c]
                    c -= 1
                pb[c + 1] = v
            for i in range(n):
                lo[i], hi[i] = pb[i], pb[i + 1]
                ok = hi[i] > lo[i]
                if ok:
                    pm = 0.5 * (lo[i] + hi[i])
                    for j in range(k):
                        if split[b, j] or state[j] == 1:
                            continue
                        if state[j] < 0:
                            ok = False
                            break
                        dot = ct[b, r] * ctu[j] + st[b, r] * stu[j] * np.cos(pm - phi_u[b, j])
                        if not dot > cr[b, r, j]:
                            ok = False
                            break
                ins[i] = ok
            c = 0
            for first in (True, False):
                for i in range(n):
                    if ins[i] == first:
                        p_lo[b, r, c], p_hi[b, r, c], inside[b, r, c] = lo[i], hi[i], ins[i]
                        c += 1
            counts[b, r] = int(ins.sum())


def ring_intervals(st, ct, t_u, phi_u, cr, split_only):
    """``sphere_quadrature._ring_intervals`` (arguments as there; thresholds ``cr`` (B, k) or
    (B, R, k)) compiled: ``(p_lo, p_hi, inside)`` (B, R, I), I the most inside intervals of a ring
    (at least 1)."""
    B, R = st.shape
    k = t_u.shape[1]
    f = np.ascontiguousarray
    cr3 = f(np.broadcast_to(cr if np.ndim(cr) == 3 else np.asarray(cr)[:, None, :], (B, R, k)), dtype=np.float64)
    n = 2 * k + 1
    p_lo, p_hi, inside = np.empty((B, R, n)), np.empty((B, R, n)), np.empty((B, R, n), dtype=np.bool_)
    counts = np.empty((B, R), dtype=np.int64)
    _ring_intervals(f(st, dtype=np.float64), f(ct, dtype=np.float64), f(t_u, dtype=np.float64),
                    f(phi_u, dtype=np.float64), cr3, f(split_only, dtype=np.bool_), p_lo, p_hi, inside, counts)
    keep = max(int(counts.max(initial=0)), 1)
    return p_lo[:, :, :keep], p_hi[:, :, :keep], inside[:, :, :keep]


def _sphere_beams(m, w, x, c, R, om, omega):
    B, M = w.shape
    K = omega.shape[1]
    for b in range(B):
        j = 0
        for live in (True, False):  # the nonzero weights first, then the zero ones, each in order (stable)
            for k in range(M):
                if j == K:
                    break
                if (w[b, k] > 0.0) != live:
                    continue
                v0 = (c[0] + R * m[b, k, 0]) - x[b, 0]
                v1 = (c[1] + R * m[b, k, 1]) - x[b, 1]
                v2 = (c[2] + R * m[b, k, 2]) - x[b, 2]
                r = np.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
                o0, o1, o2 = v0 / r, v1 / r, v2 / r
                cos_y = max(-(m[b, k, 0] * o0 + m[b, k, 1] * o1 + m[b, k, 2] * o2), 0.0)
                om[b, j, 0], om[b, j, 1], om[b, j, 2] = o0, o1, o2
                omega[b, j] = cos_y * R * R * w[b, k] / (r * r)
                j += 1


def sphere_beams(m, w, x, c, R: float) -> tuple[np.ndarray, np.ndarray]:
    """Unit directions (B, K, 3) from points x (B, 3) toward the nodes m (B, M, 3) of a rule on
    the unit sphere of a source (centre c, radius R) and their solid angles seen from x (B, K)
    [sr], ``cos_y R² w / r²`` (:func:`lunarviz.methods.sources.source_beams`), each row's nodes of
    positive weight ``w`` (B, M) first in their order, then its zero-weight ones: K is the most
    nodes of positive weight in a row (at least 1, at most M)."""
    w = np.ascontiguousarray(w, dtype=np.float64)
    K = min(max(int((w > 0).sum(1).max(initial=0)), 1), w.shape[1])
    om, omega = np.empty((len(w), K, 3)), np.empty((len(w), K))
    _sphere_beams(np.ascontiguousarray(m, dtype=np.float64), w, np.ascontiguousarray(x, dtype=np.float64),
                  np.ascontiguousarray(c, dtype=np.float64), float(R), om, omega)
    return om, omega


def _cap_rings(t_lo, t_hi, s_lo, s_hi, below, above, u, gw, t, wt):
    B, S, n = u.shape
    for b in range(B):
        for s in range(S):
            lo, hi = t_lo[b, s], t_hi[b, s]
            tl, th = s_lo[b, s], s_hi[b, s]
            for i in range(n):
                x = u[b, s, i]
                if tl and th:
                    f, jac = x * x * (3.0 - 2.0 * x), 6.0 * x * (1.0 - x)
                elif tl:
                    f, jac = x * x, 2.0 * x
                elif th:
                    f, jac = 1.0 - (1.0 - x) * (1.0 - x), 2.0 * (1.0 - x)
                else:
                    f, jac = x, 1.0
                tt = lo + (hi - lo) * f
                dt = (hi - lo) * jac
                for a, sign in ((below[b, s], 1.0), (above[b, s], -1.0)):
                    if np.isfinite(a):
                        s0 = np.sqrt(np.abs(lo - a))
                        s1 = np.sqrt(np.abs(hi - a))
                        sv = s0 + (s1 - s0) * x
                        tt = a + sign * sv * sv
                        dt = 2.0 * sv * np.abs(s1 - s0)
                t[b, s, i] = tt
                wt[b, s, i] = dt * gw[b, s, i] * np.sin(tt)


def cap_rings(t_lo, t_hi, s_lo, s_hi, below, above, u, gw) -> tuple[np.ndarray, np.ndarray]:
    """``sphere_quadrature._cap_rings``' rings t (B, S, n) and weights ``dt·w·sin t`` from its
    t-segments (``t_lo``, ``t_hi``, tangent ends ``s_lo``, ``s_hi``, graded anchors ``below``,
    ``above`` (B, S); NaN: none) and the Gauss variables ``u`` and weights ``gw`` on [0, 1] ((n,),
    or (B, S, n) for padded orders): the numpy path's arithmetic, node by node."""
    f = np.ascontiguousarray
    B, S = t_lo.shape
    n = np.shape(u)[-1]
    u3 = f(np.broadcast_to(np.asarray(u, dtype=np.float64), (B, S, n)))
    g3 = f(np.broadcast_to(np.asarray(gw, dtype=np.float64), (B, S, n)))
    t, wt = np.empty((B, S, n)), np.empty((B, S, n))
    _cap_rings(f(t_lo, dtype=np.float64), f(t_hi, dtype=np.float64), f(s_lo, dtype=np.bool_), f(s_hi, dtype=np.bool_),
               f(below, dtype=np.float64), f(above, dtype=np.float64), u3, g3, t, wt)
    return t, wt


def _inside_intervals(st, ct, wt, p_lo, p_hi, inside, st2, ct2, wt2, lo2, hi2, ins2):
    B, R, n_iv = p_lo.shape
    for b in range(B):
        j = 0
        for r in range(R):
            for i in range(n_iv):
                if inside[b, r, i]:
                    st2[b, j], ct2[b, j], wt2[b, j] = st[b, r], ct[b, r], wt[b, r]
                    lo2[b, j, 0], hi2[b, j, 0], ins2[b, j, 0] = p_lo[b, r, i], p_hi[b, r, i], True
                    j += 1


def inside_intervals(st, ct, wt, p_lo, p_hi, inside):
    """``sphere_quadrature._inside_intervals``: the rings' inside φ-intervals, each row's in ring
    order, as rings of one interval each (B, P), P the most a row has (at least 1); the spare slots
    empty intervals of zero weight about the axis (t = 0). Copies only: the same numbers."""
    B = st.shape[0]
    P = max(int(inside.reshape(B, -1).sum(axis=1).max(initial=0)), 1)
    st2, ct2, wt2 = np.zeros((B, P)), np.ones((B, P)), np.zeros((B, P))
    lo2, hi2, ins2 = np.zeros((B, P, 1)), np.zeros((B, P, 1)), np.zeros((B, P, 1), dtype=np.bool_)
    f = np.ascontiguousarray
    _inside_intervals(f(st, dtype=np.float64), f(ct, dtype=np.float64), f(wt, dtype=np.float64),
                      f(p_lo, dtype=np.float64), f(p_hi, dtype=np.float64), f(inside, dtype=np.bool_),
                      st2, ct2, wt2, lo2, hi2, ins2)
    return st2, ct2, wt2, lo2, hi2, ins2


def barycentric_weights(nodes: np.ndarray) -> np.ndarray:
    """``1/Π_{j≠i}(x_i - x_j)``: the barycentric weights of Lagrange interpolation on ``nodes``."""
    diff = nodes[:, None] - nodes[None, :]
    np.fill_diagonal(diff, 1.0)
    return 1.0 / diff.prod(axis=1)


def block_design(u_t, u_p, ell, gt, gp):
    """``(A, Lp)`` of one block: ``A[k, i·Q + q] = ℓ_i(u_t[k]) ell[k, q]`` (P, mt·Q) on the
    nodes ``gt`` and ``Lp[k, j] = ℓ_j(u_p[k])`` (P, mp) on ``gp``, so the block's weights are
    ``A.T @ Lp`` (one GEMM)."""
    P = len(u_t)
    A, Lp = np.empty((P, len(gt) * ell.shape[1])), np.empty((P, len(gp)))
    _block_design(np.ascontiguousarray(u_t, dtype=np.float64), np.ascontiguousarray(u_p, dtype=np.float64),
                  np.ascontiguousarray(ell, dtype=np.float64), gt, barycentric_weights(gt), gp,
                  barycentric_weights(gp), A, Lp)
    return A, Lp


_NUMBA = compiled.available()
if _NUMBA:
    try:
        _locate = compiled.jit(_locate, nogil=True)
        _lagrange_row = compiled.jit(_lagrange_row, nogil=True)
        _block_design = compiled.jit(_block_design, nogil=True)
        _cap_nodes = compiled.jit(_cap_nodes, nogil=True)
        _sphere_beams = compiled.jit(_sphere_beams, nogil=True)
        _ring_intervals = compiled.jit(_ring_intervals, nogil=True)
        _cap_rings = compiled.jit(_cap_rings, nogil=True)
        _inside_intervals = compiled.jit(_inside_intervals, nogil=True)
    except Exception:  # noqa: BLE001 (a numba that cannot compile: the numpy path)
        _NUMBA = False
