"""The Sun and the Earth as extended sources seen from lunar surface points.

Shared by the exact reference (:mod:`lunarviz.methods.reference`) and the deterministic ray tracer
(:mod:`lunarviz.methods.tracer.estimators`): the product Gauss rule over the part of a source's sphere
that a lunar point sees above its horizon (and, for the Earth, that the Sun lights), and the
beams (directions, solid angles) toward its nodes. Regions are caps (docs: derivations, §1).
"""

from __future__ import annotations

import numpy as np

from lunarviz.geometry.scene_geometry import SceneGeometry, unit
from lunarviz.geometry import quadrature_kernels
from lunarviz.geometry.sphere_quadrature import cap_rule, orthonormal_basis


def sun_radiance(scene: SceneGeometry) -> float:
    """Radiance of the Sun's surface [W m⁻² sr⁻¹]: exitance Φ/(4πR²) = πL."""
    return scene.phi / (4 * np.pi**2 * scene.radii["sun"] ** 2)


def source_centre(scene: SceneGeometry, body: str) -> tuple[np.ndarray, float]:
    return {"sun": scene.sun, "earth": scene.earth}[body], scene.radii[body]


def horizon_cuts_source(scene: SceneGeometry, x, n, body: str) -> np.ndarray:
    """True where the tangent plane at x (normal n) intersects the source sphere."""
    c, R = source_centre(scene, body)
    return np.einsum("ij,ij->i", c - x, n) < R


def source_sphere_rule(scene: SceneGeometry, x, n, body: str, order: int, horizon: bool = True, pole=None,
                       roughness_cuts: bool = False):
    """Nodes m (B, K, 3) on the unit sphere of ``body`` and their solid-angle weights (B, K)
    over the part seen from x (B, 3) — above x's horizon when ``horizon`` (pass False where
    the horizon does not cut the source: the rule is then smaller) and, for the Earth, lit by
    the (point) Sun. Zero-weight nodes are dropped (rows padded to the longest).

    The polar coordinates are about the sub-x point (the visible cap's centre), or, with
    ``pole`` (B, 3) unit vectors from the source's centre, about those points: the visible cap
    is then one more cap of the rule, and the rings are cut where two caps' edges cross
    (:func:`zero_phase_points` puts the pole where a BRDF's opposition surge peaks)."""
    return _nonzero_first(*_sphere_rule_nodes(scene, x, n, body, order, horizon, pole, roughness_cuts))


def _sphere_rule_nodes(scene: SceneGeometry, x, n, body: str, order: int, horizon: bool, pole, roughness_cuts: bool):
    """:func:`source_sphere_rule`'s nodes (B, M, 3) and weights (B, M), zero weights in place."""
    c, R = source_centre(scene, body)
    xc = x - c
    dxc = np.linalg.norm(xc, axis=1)
    caps_u, caps_c = [], []
    if pole is not None:  # the part seen from x: the cap about the sub-x point
        caps_u.append(xc / dxc[:, None])
        caps_c.append(R / dxc)
    if horizon:
        caps_u.append(n)
        caps_c.append(np.einsum("ij,ij->i", xc, n) / R)
    if body == "earth":
        caps_u.append(np.broadcast_to(unit(scene.sun - c), n.shape))
        caps_c.append(np.full(len(n), R / np.linalg.norm(scene.sun - c)))
    split = [False] * len(caps_u)
    if pole is None:
        axis, cos_max, crossings = xc / dxc[:, None], R / dxc, False
    else:
        axis, cos_max, crossings = np.asarray(pole, dtype=float), np.full(len(x), -1.0), True
        if roughness_cuts:
            for u, cut in roughness_kink_cuts(scene, x, n, axis, body):
                caps_u.append(u)
                caps_c.append(cut)
                split.append(True)
    return cap_rule(axis, cos_max, np.stack(caps_u, 1) if caps_u else None,
                    np.stack(caps_c, 1) if caps_c else None, n_t=order, n_phi=order, crossings=crossings,
                    graded=pole is not None,
                    split_only=np.broadcast_to(np.array(split), (len(x), len(split))) if caps_u else None)


def source_sphere_beams(scene: SceneGeometry, x, n, body: str, order: int, horizon: bool = True, pole=None,
                        roughness_cuts: bool = False):
    """Unit directions (B, K, 3) and solid angles (B, K) [sr] of the beams from x toward the nodes
    of :func:`source_sphere_rule` (same arguments): :func:`source_beams` on its nodes, in one
    compiled pass where numba serves (:func:`lunarviz.geometry.quadrature_kernels.sphere_beams`;
    the same beams to rounding)."""
    m, w = _sphere_rule_nodes(scene, x, n, body, order, horizon, pole, roughness_cuts)
    if quadrature_kernels.available():
        c, R = source_centre(scene, body)
        return quadrature_kernels.sphere_beams(m, w, x, c, R)
    return source_beams(scene, x, body, *_nonzero_first(m, w))[1:]


def _nonzero_first(m, w):
    """A rule's nodes (B, M, 3) and weights (B, M) with each row's zero weights moved last (in
    order), cut to the longest row of positive weights (at least 1)."""
    nz = w > 0
    kmax = max(int(nz.sum(1).max(initial=0)), 1)
    sel = np.argsort(~nz, axis=1, kind="stable")[:, :kmax]
    return np.take_along_axis(m, sel[..., None], 1), np.take_along_axis(w, sel, 1)


def roughness_kink_cuts(scene, x, n, pole, body="earth"):
    """Two split-only caps ``(u, c)`` (B, 3), (B,) on ``body``'s unit sphere where a rough BRDF
    at x (B, 3) with normal n kinks, both through the zero-phase points ``pole``: the plane of n
    and the detector's direction o (relative azimuth ψ = 0 or π; exact, a plane through x cuts
    the sphere in a circle), and the circle through the pole tangent there to the curve i = e
    (the cone n·ω = n·o about x: its normal at the pole is the part of n across o)."""
    c, R = source_centre(scene, body)
    o = unit(scene.det - x)
    p = np.cross(n, o)
    pn = np.linalg.norm(p, axis=1)
    ok = pn > 1e-12
    # (n along o: no plane of the two, and no kink through the pole; any plane through n will do)
    p = np.where(ok[:, None], p / np.where(ok, pn, 1.0)[:, None], orthonormal_basis(n)[0])
    q = n - np.einsum("ij,ij->i", n, o)[:, None] * o
    qn = np.linalg.norm(q, axis=1)
    q = np.where((qn > 1e-12)[:, None], q / np.maximum(qn, 1e-300)[:, None], np.cross(p, o))
    return [(p, np.einsum("ij,ij->i", x - c, p) / R), (q, np.einsum("ij,ij->i", pole, q))]


def zero_phase_points(scene: SceneGeometry, x, body: str = "earth") -> np.ndarray:
    """(B, 3) unit vectors from ``body``'s centre to the points of its sphere where the light
    from x (B, 3) toward the detector would come from (phase angle 0: a BRDF's opposition
    surge and the i = e kink of its roughness): where the line from x through the detector
    first meets the sphere, or, where it misses, the point of the limb seen from x nearest to
    it. At the Earth's centre (the paper's detector), the sub-x point."""
    c, R = source_centre(scene, body)
    x = np.asarray(x, dtype=float)
    o = unit(scene.det - x)
    xc = x - c
    b = -np.einsum("ij,ij->i", xc, o)
    disc = R * R - (np.einsum("ij,ij->i", xc, xc) - b * b)
    hit = x + (b - np.sqrt(np.clip(disc, 0.0, None)))[:, None] * o
    # the limb point toward o: in the plane of (c - x, o), at the tangent angle from c - x
    to_c = -xc / np.linalg.norm(xc, axis=1)[:, None]
    side = o - np.einsum("ij,ij->i", o, to_c)[:, None] * to_c
    side_n = np.linalg.norm(side, axis=1)
    side = np.where(side_n[:, None] > 1e-300, side / np.maximum(side_n, 1e-300)[:, None], 0.0)
    d = np.linalg.norm(xc, axis=1)
    rho = np.arcsin(np.clip(R / d, 0.0, 1.0))
    limb = x + np.sqrt(np.clip(d * d - R * R, 0.0, None))[:, None] * (np.cos(rho)[:, None] * to_c
                                                                       + np.sin(rho)[:, None] * side)
    y = np.where((disc > 0)[:, None], hit, limb)
    return unit(y - c)


def source_beams(scene: SceneGeometry, x, body: str, m, w):
    """Source points y (B, K, 3), unit directions from x (B, K, 3) and the beams' solid angles
    seen from x [sr] (B, K): dΩ = cos_y R² dω / r² for a node of weight dω on the unit sphere."""
    c, R = source_centre(scene, body)
    y = c + R * m
    v = y - x[:, None, :]
    r = np.linalg.norm(v, axis=2)
    om = v / r[..., None]
    cos_y = np.clip(-np.einsum("bkj,bkj->bk", m, om), 0.0, None)
    return y, om, cos_y * R * R * w / r**2


def earth_radiance(scene: SceneGeometry, y, m, albedo: float) -> np.ndarray:
    """Radiance of the Lambertian Earth at points y with unit normals m, lit by a point Sun."""
    vs = scene.sun - y
    ds = np.linalg.norm(vs, axis=-1)
    mu_s = np.clip(np.einsum("...j,...j->...", m, vs) / ds, 0.0, None)
    return albedo / np.pi * scene.phi / (4 * np.pi * ds**2) * mu_s
