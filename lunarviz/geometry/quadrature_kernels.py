"""Compiled :func:`lunarviz.geometry.sphere_quadrature.rule_coordinates`: one pass per point,
the same arithmetic as the numpy path (its ring breakpoints, sorted; its interval midpoint test),
so the same blocks and coordinates to rounding (tests/test_mapped_lune.py compares them).
Used by the mapped lune rule, which locates ~10⁵ map points per path and date."""

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
            den = st * np.sin(t_u[j])
            num = (kink_c[i] if j == kink_j else caps_c[j]) - ctt * np.cos(t_u[j])
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
                ndotu = ctt * np.cos(t_u[j]) + st * np.sin(t_u[j]) * np.cos(pm - phi_u[j])
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


_NUMBA = compiled.available()
if _NUMBA:
    try:
        _locate = compiled.jit(_locate, nogil=True)
    except Exception:  # noqa: BLE001 (a numba that cannot compile: the numpy path)
        _NUMBA = False
