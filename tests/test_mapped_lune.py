"""The lune rule on a mapped Moon (lunarviz.geometry.mapped_lune): the map's cells in the weights,
checked against a brute-force sum over the map's cells, the facets, and Embree."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import lunarviz
from lunarviz.geometry.mapped_lune import chebyshev_nodes, lagrange_matrix, lune_caps, mapped_lune_rule
from lunarviz.geometry.scene_geometry import SceneGeometry
from lunarviz.geometry.sphere_quadrature import cap_rule, gauss_legendre, rule_coordinates
from lunarviz.surfaces.maps import map_frame
from lunarviz.surfaces.moon_map import MoonAlbedoMap


def map_cell_nodes(shape: tuple[int, int], k: int):
    """The brute force's own points (no lunarviz quadrature): Gauss nodes of every cell of a
    lat/lon map of ``shape`` (rows from +90°, columns from -180°): k×k per cell in (sin lat,
    lon), where the area element is exactly dμ dλ. Returns unit vectors (cells, k², 3) in the
    map's frame and weights (cells, k²) [sr]."""
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
    return d.reshape(h * w, k * k, 3), np.ascontiguousarray(wts).reshape(h * w, k * k)


def test_rule_coordinates_find_the_rules_own_nodes():
    """Every live node of a cut, structured cap rule is located in its own block at its own
    Gauss variables (the t-substitution at tangent ends inverted exactly)."""
    ax = np.array([0.0, 0.0, 1.0])
    u = np.array([1.0, 0.0, 0.2]) / np.linalg.norm([1.0, 0.0, 0.2])
    cu = np.stack([u, u, -np.array([0.6, 0.0, 0.8])])
    cc, so = np.array([0.01, 0.03, 0.0]), np.array([False, True, True])
    n, w = cap_rule(ax[None], [0.1], cu[None], cc[None], so[None], 5, 4, phi_zero=-u[None], crossings=True,
                    structured=True)
    S, I = n.shape[1] // 5, n.shape[2]
    seg, itv, ut, up, ins = rule_coordinates(n[0].reshape(-1, 3), ax, 0.1, cu, cc, so, phi_zero=-u, crossings=True)
    live = w[0].ravel() > 0
    grid = np.meshgrid(np.arange(S), np.arange(5), np.arange(I), np.arange(4), indexing="ij")
    assert ins[live].all()
    assert np.array_equal(seg[live], grid[0].ravel()[live]) and np.array_equal(itv[live], grid[2].ravel()[live])
    assert np.allclose(ut[live], gauss_legendre(5)[0][grid[1].ravel()[live]], atol=1e-12)
    assert np.allclose(up[live], gauss_legendre(4)[0][grid[3].ravel()[live]], atol=1e-12)


def test_albedo_nodes_interpolate_hapke_in_its_albedo():
    """The rule shades each sample at 8 Chebyshev values of the map and interpolates: rough Hapke
    (rolo-fit-map's DHG, w up to 0.57) evaluated directly at 200 map values over 50 geometries
    agrees to 1e-6 (measured 5e-8 on the traced Moon; tolerance: 20x that)."""
    scene = lunarviz.Scene(phases=[60], moon_model="rolo-fit-map", brdfs=["dhg"])
    brdf = scene.settings("raytrace").brdf_models()["dhg"]
    rng = np.random.default_rng(1)
    mu0, mu = rng.uniform(0.05, 1, (50, 1)), rng.uniform(0.05, 1, 50)
    g = rng.uniform(0.02, 2.5, (50, 1))
    sh, ch = np.sin(g / 2), np.cos(g / 2)
    m = np.linspace(0.5, 1.0, 200)
    nodes = chebyshev_nodes(0.5, 1.0, 8)
    w = brdf.albedo_parameter

    def rf(a):
        return brdf.radiance_factor(mu0, mu, sh, ch, albedo=np.full((50, 1), a * w))[:, 0]
    at_nodes = np.stack([rf(a) for a in nodes], axis=1)  # (50, Q)
    interp = at_nodes @ lagrange_matrix(nodes, m).T  # (50, 200)
    direct = np.stack([rf(a) for a in m], axis=1)
    assert np.max(np.abs(interp / direct - 1)) < 1e-6


def test_albedo_nodes_in_gamma_interpolate_hapke_better_than_in_the_map_value():
    """Chebyshev nodes in γ = √(1 - w) (``GAMMA_NODES`` = 5, the rule's default where the BRDFs'
    scale is known) against 8 in m, for rolo-fit-map's DHG (w·m up to 0.57) over 400 geometries
    down to μ₀, μ = 0.02 and phases 0-172°, against the BRDF at 300 map values: measured 9.9e-7
    with 5 in γ (3.0e-8 with 6, 3.2e-5 with 4), 3.9e-5 with 5 in m and 4.2e-8 with 8 in m. The
    limit, 2e-6, tells 5 nodes in γ from 4 in γ and from 5 in m."""
    from lunarviz.geometry.mapped_lune import GAMMA_NODES, albedo_coordinate
    scene = lunarviz.Scene(phases=[60], moon_model="rolo-fit-map", brdfs=["dhg"])
    brdf = scene.settings("raytrace").brdf_models()["dhg"]
    rng = np.random.default_rng(1)
    mu0, mu = rng.uniform(0.02, 1, (400, 1)), rng.uniform(0.02, 1, 400)
    g = rng.uniform(0.0, 3.0, (400, 1))
    sh, ch = np.sin(g / 2), np.cos(g / 2)
    w = brdf.albedo_parameter
    m = np.linspace(0.5, 1.0, 300)

    def rf(a):
        return brdf.radiance_factor(mu0, mu, sh, ch, albedo=np.full((400, 1), a * w))[:, 0]
    direct = np.stack([rf(a) for a in m], axis=1)
    gamma = albedo_coordinate(m, w)
    nodes = chebyshev_nodes(gamma.min(), gamma.max(), GAMMA_NODES)
    at_nodes = np.stack([rf(a) for a in (1.0 - nodes ** 2) / w], axis=1)
    err = np.max(np.abs(at_nodes @ lagrange_matrix(nodes, gamma).T / direct - 1))
    assert GAMMA_NODES == 5 and err < 2e-6
    m_nodes = chebyshev_nodes(0.5, 1.0, GAMMA_NODES)  # (the same count in m errs 40x more)
    in_m = np.stack([rf(a) for a in m_nodes], axis=1) @ lagrange_matrix(m_nodes, m).T
    assert np.max(np.abs(in_m / direct - 1)) > 2e-6


@pytest.mark.parametrize("theta", [15.0, 100.0, 172.0])
def test_the_rule_in_gamma_gives_the_integral_in_the_map_value(theta, monkeypatch):
    """The mapped lune rule with its albedo nodes in γ (5) and in m (8) on rolo-fit-map's DHG,
    shaded through the same traced transport: the integrals agree to 1e-6 (the 5 nodes' own
    error: ≤ 1e-6 pointwise, at grazing geometries; 6 nodes agreed to 3.6e-8 on 24 orbit dates)."""
    from lunarviz.methods.tracer import estimators
    from lunarviz.scene import ResolvedScene
    s = ResolvedScene(method="raytrace", moon_model="rolo-fit-map", brdfs=("dhg",), rtol=1e-4, phases_deg=(theta,))
    out = {}
    for label in ("gamma", "m"):
        if label == "m":
            monkeypatch.setattr(estimators, "_albedo_scale", lambda ts, brdfs: 0.0)
        ts = estimators.TraceScene(SceneGeometry(theta), s.trace_settings(threads=1))
        out[label] = [estimators.trace_path(ts, p, s.brdf_models()).mean["dhg"] for p in ("moonshine", "earthshine")]
        assert ts.sampling.lune_rule_applies("sun") and ts.sampling.lune_rule_applies("earth")
        assert (ts.sampling.albedo_scale > 0) == (label == "gamma")
    np.testing.assert_allclose(out["gamma"], out["m"], rtol=1e-6, atol=0)


@pytest.mark.parametrize("theta, limit", [(10.0, 2e-6), (120.0, 1e-5)])
def test_mapped_lune_rule_against_a_brute_force_sum_over_the_cells(theta, limit):
    """∫ r(m(x)) f(x) dA for the synthetic map's 1° cells, a reflectance nonlinear in m and a
    Lommel-Seeliger f lit by a point Sun: the rule at order 16 against 10×10 Gauss points in
    every cell (:func:`map_cell_nodes`: no lune rule, no interpolation, no albedo nodes).
    Measured -2.5e-7 and 4.1e-6, where the brute force's own 6×6, 10×10 and 16×16 give 5e-7 and
    2.3-4.3e-6 (it point-samples the terminator and limb inside cells); limits ~2.5x the larger.
    (Not at θ = 170°: there the brute force's edge sampling swings by 3e-5.)"""
    sc = SceneGeometry(theta)
    values = np.asarray(MoonAlbedoMap.parse("synthetic").values(), float)
    fr, R = map_frame(sc, "moon"), sc.radii["moon"]

    def f(x, n):
        s = (sc.sun - x) / np.linalg.norm(sc.sun - x, axis=1)[:, None]
        o = (sc.det - x) / np.linalg.norm(sc.det - x, axis=1)[:, None]
        mu0, mu = np.clip((n * s).sum(1), 0, None), np.clip((n * o).sum(1), 0, None)
        return mu0 * mu / (mu0 + mu + 1e-300)

    def r(m, base):
        return base * (m + 0.3 * m**2 / (1.0 / 0.57 - m))
    x, n, dA, an = mapped_lune_rule(sc, sc.sun, 1.0, 16, values, fr)
    got = sum((r(an.values[q], f(x, n)) * dA * an.factors[:, q]).sum() for q in range(len(an.values)))
    pts, wts = map_cell_nodes(values.shape, 10)
    nn = pts.reshape(-1, 3) @ fr.T
    want = (r(np.repeat(values.ravel(), 100), f(sc.moon + R * nn, nn)) * wts.ravel()).sum() * R * R
    assert abs(got / want - 1) < limit


def _traced(theta, path, **kw):
    from lunarviz.methods.tracer.estimators import TraceScene, trace_path
    st = lunarviz.Scene(phases=[theta], brdfs=["dhg"], **kw).settings("raytrace")
    return st, lambda **t: trace_path(TraceScene(SceneGeometry(theta), replace(
        st.trace_settings(threads=1), occlusion=False, **t)), path, st.brdf_models()).mean["dhg"]


def test_traced_mapped_lune_agrees_with_the_facets():
    """The paper's smooth DHG on the synthetic map, θ = 60°: the mapped lune rule (order 16 and
    24 agree to 1e-8) against the facets, whose own error falls from 2.6e-5 (level 5) to 8.5e-6
    (level 6) toward it (measured). Tolerance 2e-5 on level 6."""
    _, run = _traced(60.0, "moonshine", moon_albedo_map="synthetic")
    lune = run(lune_order=16)
    assert abs(run(moon_level=6) / lune - 1) < 2e-5


def test_the_mapped_lune_rule_is_ray_traced(monkeypatch):
    """Embree answering "no hit": the mapped lune's moonshine vanishes (the rule only places
    samples and weights; their light is traced)."""
    from lunarviz.methods.tracer import embree_bodies
    _, run = _traced(90.0, "moonshine", moon_model="rolo-fit-map")
    assert run(lune_order=8) > 0
    monkeypatch.setattr(embree_bodies.EmbreeBody, "run_rays",
                        lambda self, o32, d32, query, dists=None, scene=None:
                        np.full(len(o32), -1, np.int32) if query == "INTERSECT" else np.zeros(len(o32), bool))
    assert run(lune_order=8) == 0.0


def test_a_tolerance_on_the_mapped_moon_takes_the_mapped_lune_rule():
    """``--rtol`` on rolo-fit-map: the mapped lune rule at the orders its model
    (``raytrace_lune_mapped``) gives, with that model's bounds; without a tolerance the default
    tolerance's (1e-4) choice, whose bounds meet it (the facets at level 4 err by 6e-4 on a map)."""
    from lunarviz.scene import ResolvedScene
    plan = ResolvedScene(method="raytrace", moon_model="rolo-fit-map", brdfs=("dhg",), rtol=1e-3).trace_plan()
    assert plan["settings"]["lune_order"] is not None
    assert all(plan["bounds"][("lune", p)] <= 1e-3 for p in ("moonshine", "earthshine"))
    kw = dict(method="raytrace", moon_model="rolo-fit-map", brdfs=("dhg",))
    default = ResolvedScene(**kw).trace_plan()
    assert default == ResolvedScene(**kw, rtol=1e-4).trace_plan()
    assert default["settings"]["lune_order"] is not None
    assert all(default["bounds"][("lune", p)] <= 1e-4 for p in ("moonshine", "earthshine"))


@pytest.mark.parametrize("theta, limit", [(10.0, 1e-8), (60.0, 1e-8), (150.0, 1e-7), (175.0, 3e-6), (179.3, 1e-7)])
def test_a_map_without_contrast_gives_the_plain_lune_rule(theta, limit):
    """A constant map (one albedo node) and μ0·μ lit by a point Sun: the weights (the whole cells'
    rectangle rule, the cut cells' lines split at every block edge) against the plain lune rule's
    sum (exact to ~1e-12 for this polynomial integrand). Measured 2.6e-10, 1.4e-9, 3.2e-8, 9.8e-7
    (θ = 175°) and 2e-10 (θ = 179.3°: a lune thinner than a cell, which slipped between a cell's
    centre and corners before cells near an edge were cut too: -4.6e-3); limits ~3x or 1e-7."""
    sc = SceneGeometry(theta)
    x, n, dA, an = mapped_lune_rule(sc, sc.sun, 1.0, 16, np.ones((180, 360)), map_frame(sc, "moon"))
    assert len(an.values) == 1
    axis, cmax, cu, cc, split, _, _ = lune_caps(sc, sc.sun, 1.0)
    nn, ww = cap_rule(axis[None], [cmax], cu, cc, split, 16, 16)
    o = (sc.det - sc.moon) / np.linalg.norm(sc.det - sc.moon)
    s = (sc.sun - sc.moon) / np.linalg.norm(sc.sun - sc.moon)

    def f(v):
        return np.clip(v @ o, 0, None) * np.clip(v @ s, 0, None)
    plain = float((f(nn[0]) * ww[0]).sum()) * sc.radii["moon"] ** 2
    assert abs((f(n) * dA * an.factors[:, 0]).sum() / plain - 1) < limit


def _disc_lit_lommel_seeliger(sc, src, radius):
    """μ0·μ/(μ0 + μ) with μ0 averaged over the source's uniform disc (12×24 points: smooth across
    the penumbra band, like the traced Sun's light) and μ toward the detector: ``f(x, n)``."""
    from lunarviz.geometry.sphere_quadrature import orthonormal_basis
    g, gw = gauss_legendre(12)
    r, ang = np.sqrt(g), 2 * np.pi * (np.arange(24) + 0.5) / 24  # r = √u: uniform in area

    def f(x, n):
        c = src - x
        d = np.linalg.norm(c, axis=1)
        a = c / d[:, None]
        e1, e2 = orthonormal_basis(a)
        ring = (np.cos(ang)[None, None, :, None] * e1[:, None, None, :]
                + np.sin(ang)[None, None, :, None] * e2[:, None, None, :])
        p = a[:, None, None, :] + (radius / d)[:, None, None, None] * r[None, :, None, None] * ring
        p /= np.linalg.norm(p, axis=-1, keepdims=True)
        mu0 = (np.clip(np.einsum("pabj,pj->pab", p, n), 0, None) * gw[None, :, None]).sum((1, 2)) / len(ang)
        o = (sc.det - x) / np.linalg.norm(sc.det - x, axis=1)[:, None]
        mu = np.clip((n * o).sum(1), 0, None)
        return mu0 * mu / (mu0 + mu + 1e-300)
    return f


def _lommel_seeliger_on_rule(sc, body: str, **rule):
    """The synthetic map times :func:`_disc_lit_lommel_seeliger` (lit by ``body``) integrated by
    the mapped lune rule of order 16 (cut at the kink on the Sun's path, as for a rough BRDF),
    with the rule's keywords ``rule``: ``(integral, number of nodes)``."""
    values = np.asarray(MoonAlbedoMap.parse("synthetic").values(), float)
    src, radius = getattr(sc, body), sc.radii[body]
    f = _disc_lit_lommel_seeliger(sc, src, radius)
    x, n, dA, an = mapped_lune_rule(sc, src, radius, 16, values, map_frame(sc, "moon"), kink=body == "sun", **rule)
    return sum((an.values[q] * f(x, n) * dA * an.factors[:, q]).sum() for q in range(len(an.values))), len(x)


def _dated_leo_scene(time: str):
    from lunarviz.scene import ResolvedScene
    return ResolvedScene(times=(time,), brdfs=("dhg",), method="raytrace",
                         observer="orbit:550,97.6,0,0").task(time)[0]


@pytest.mark.parametrize("scene, body, limit, fewer", [
    (lambda: SceneGeometry(30.0), "sun", 1e-8, True), (lambda: SceneGeometry(170.0), "sun", 1e-8, False),
    (lambda: SceneGeometry(175.0), "sun", 1e-7, False),
    (lambda: _dated_leo_scene("2026-01-14T01:00:00Z"), "sun", 1e-7, True),
    (lambda: _dated_leo_scene("2026-01-14T01:00:00Z"), "earth", 1e-7, True),
    (lambda: SceneGeometry(90.0), "earth", 1e-8, False)])
def test_thin_blocks_take_fewer_nodes_for_the_same_integral(scene, body, limit, fewer):
    """Blocks under 3° one way and the penumbra band's blocks, each under 1 % of the region,
    take a quarter of the order (THIN_WIDTH): the synthetic map under a disc-lit
    Lommel-Seeliger law, order 16, against the same rule at full order everywhere. Measured
    1.5e-9 (θ = 30°), 2.8e-10 (170°), 2.1e-8 (175°; with 5 % shares it was 1.9e-6 there), 2.7e-8 and
    1.5e-8 (the Sun's and the Earth's paths seen from a 550 km orbit,
    θ = 126°), 0 (the paper's Earth path: no block that thin and small); limits ~4x or 1e-8.
    At least a third fewer nodes away from crescents (at 170-175° the band's blocks are over 1 %:
    18 % fewer)."""
    sc = scene()
    (full, n_full), (thin, n_thin) = (_lommel_seeliger_on_rule(sc, body, thin=t) for t in (False, True))
    assert abs(thin / full - 1) < limit
    assert (n_thin < 2 / 3 * n_full) if fewer else n_thin <= n_full


def test_compiled_block_design_matches_lagrange_matrix():
    """The compiled design of a block (Lagrange rows in u_t times the albedo factors, and in u_φ)
    against :func:`lagrange_matrix`, points on the nodes included: equal to rounding."""
    from lunarviz.geometry import quadrature_kernels
    if not quadrature_kernels.available():
        pytest.skip("numba not available")
    rng = np.random.default_rng(3)
    gt, gp = gauss_legendre(24)[0], gauss_legendre(6)[0]
    ut, up = rng.random(500), rng.random(500)
    ut[:5], up[5:10] = gt[:5], gp[:5]  # exactly on nodes: unit rows
    ell = rng.random((500, 8))
    A, Lp = quadrature_kernels.block_design(ut, up, ell, gt, gp)
    want = (lagrange_matrix(gt, ut)[:, :, None] * ell[:, None, :]).reshape(500, -1)
    assert np.allclose(A, want, rtol=1e-12, atol=1e-14)
    assert np.allclose(Lp, lagrange_matrix(gp, up), rtol=1e-12, atol=1e-14)


def test_kink_crossings_are_found_to_rounding():
    """The i = e curve's crossings with the cut cells' lines (regula falsi, Illinois): at every
    root |F/F'| (the distance to the true root) is below 1e-12 of a cell, over random curves and
    lines of both directions, and the lines cross F = 0 as often as a 256-step scan of F finds
    (the rule's own scan takes 8 steps)."""
    from lunarviz.geometry.mapped_lune import _curve_crossings, _curve_value
    rng = np.random.default_rng(1)
    for _ in range(10):
        o, u = (v / np.linalg.norm(v) for v in rng.normal(size=(2, 3)))
        F = _curve_value((u, o, tuple(0.0045 * rng.random(2))))
        for cut_mu in (True, False):
            fixed = (rng.uniform(-3.1, 3.1, 500) if cut_mu else rng.uniform(-0.99, 0.99, 500))[:, None] \
                + np.linspace(0.0, 0.017, 3)
            lo = np.broadcast_to(rng.uniform(-0.99, 0.97, 500)[:, None] if cut_mu else
                                 rng.uniform(-3.1, 3.1, 500)[:, None], fixed.shape)
            hi = lo + 0.0175

            def at(v, fx):
                mu, lon = np.broadcast_arrays(*((v, fx) if cut_mu else (fx, v)))
                c = np.sqrt(np.clip(1.0 - mu * mu, 0.0, None))
                return np.stack([c * np.cos(lon), c * np.sin(lon), mu], axis=-1)
            roots = np.stack(_curve_crossings(F, fixed, lo, hi, cut_mu), axis=-1)
            found = np.isfinite(roots)
            r, fx = roots[found], np.broadcast_to(fixed[..., None], roots.shape)[found]
            slope = (F(at(r + 1e-7, fx)) - F(at(r - 1e-7, fx))) / 2e-7
            assert np.all(np.abs(F(at(r, fx)) / slope) < 1e-12 * 0.0175)
            dense = F(at(lo[..., None] + (hi - lo)[..., None] * np.linspace(0, 1, 257), fixed[..., None]))
            assert found.sum() == (np.sign(dense[..., :-1]) * np.sign(dense[..., 1:]) < 0).sum()


def test_panel_rule_integrates_quadratics_against_the_map_exactly():
    """The panels' body-fixed rule (mapped_lune._panel_rule: 3×3 nodes a panel of 4×4 cells):
    ``Σ_k p(x_k) W_kq`` summed over the albedo nodes with their values is ``Σ_cells m_c ∫_cell p
    dμ dλ`` for every p of degree ≤ 2 in μ = sin(lat) and in λ (the nodes' Lagrange basis
    reproduces it), here against the closed-form cell integrals of ``p = (1 + μ - 2μ²)(3 + λ +
    λ²/2)`` on the synthetic map (a map linear in m: the albedo nodes reproduce ``m`` too).
    Agreement to rounding (1e-12 relative), every panel."""
    from lunarviz.geometry import mapped_lune
    values = np.asarray(MoonAlbedoMap.parse("synthetic").values(), float)
    vals = chebyshev_nodes(values.min(), values.max(), 8)
    pan = mapped_lune._panel_rule(values, tuple(vals))
    mu, lon = pan.points[..., 2], np.arctan2(pan.points[..., 1], pan.points[..., 0])

    def p(mu, lon):
        return (1 + mu - 2 * mu**2) * (3 + lon + lon**2 / 2)
    got = np.einsum("nk,nkq,q->n", p(mu, lon), pan.weights, vals)
    h, w = values.shape
    mu_e = np.sin(np.radians(90.0 - 180.0 * np.arange(h + 1) / h))
    lon_e = np.radians(-180.0 + 360.0 * np.arange(w + 1) / w)
    Imu = (lambda a, b: (b - a) + (b**2 - a**2) / 2 - 2 * (b**3 - a**3) / 3)(mu_e[1:], mu_e[:-1])  # (h,)
    Ilon = (lambda a, b: 3 * (b - a) + (b**2 - a**2) / 2 + (b**3 - a**3) / 6)(lon_e[:-1], lon_e[1:])  # (w,)
    cell = (values * Imu[:, None] * Ilon[None, :]).ravel()
    want = cell[pan.cells].sum(axis=1)
    assert np.max(np.abs(got / want - 1)) < 1e-12
    half = 0.5 * mapped_lune.PANEL_CELLS * 180.0 / h  # a panel's half height [deg]
    assert np.all(np.abs(np.degrees(pan.lat)) + half <= mapped_lune.PANEL_MAX_LAT + 1e-9)


@pytest.mark.parametrize("scene, body, least", [
    (lambda: SceneGeometry(10.0), "sun", 2000), (lambda: SceneGeometry(60.0), "sun", 2000),
    (lambda: SceneGeometry(120.0), "sun", 1000), (lambda: SceneGeometry(150.0), "sun", 300),
    (lambda: SceneGeometry(60.0), "earth", 2000),
    (lambda: _dated_leo_scene("2026-01-03T10:00:00Z"), "sun", 2000),
    (lambda: _dated_leo_scene("2026-01-03T10:00:00Z"), "earth", 2000),
    (lambda: _dated_leo_scene("2026-01-14T01:00:00Z"), "sun", 1000)])
def test_whole_panels_give_the_cells_integral(scene, body, least, monkeypatch):
    """Panels of 4×4 cells that no block edge comes near take 9 body-fixed nodes (the panels'
    rule) in place of every cell's centre and corners: the synthetic map under a disc-lit
    Lommel-Seeliger law (the Sun's path cut at the kink, as for a rough BRDF), order 16, against
    the same rule without panels. Measured ≤ 3e-8 (a quadratic's error across 4° of a smooth
    integrand, times the map's contrast); limit 2e-7. ``least``: about half the panels' cells
    found (so the test covers them; a 30° crescent holds 38 panels)."""
    from lunarviz.geometry import mapped_lune
    sc = scene()
    found = []
    original = mapped_lune._whole_panels

    def spy(*args):
        out = original(*args)
        found.append(0 if out is None else len(out[1]))
        return out

    cells = _lommel_seeliger_on_rule(sc, body, panels=False)[0]
    monkeypatch.setattr(mapped_lune, "_whole_panels", spy)
    panels = _lommel_seeliger_on_rule(sc, body, panels=True)[0]
    assert found and found[0] >= least
    assert abs(panels / cells - 1) < 2e-7


@pytest.mark.parametrize("scene, body", [
    (lambda: SceneGeometry(10.0), "sun"), (lambda: SceneGeometry(60.0), "sun"), (lambda: SceneGeometry(140.0), "sun"),
    (lambda: SceneGeometry(60.0), "earth"), (lambda: _dated_leo_scene("2026-04-12T10:00:00Z"), "sun"),
    (lambda: _dated_leo_scene("2026-07-28T11:00:00Z"), "sun"),
    (lambda: _dated_leo_scene("2026-07-28T11:00:00Z"), "earth")])
def test_no_block_edge_crosses_a_whole_panel(scene, body, monkeypatch):
    """Every panel the rule takes whole, sampled on 12×12 points spanning its cells (edges and
    corners included): each edge of the integrand (the caps: terminator, the penumbra band's far
    edge, the limb, circles n·u = c in the map's frame; the i = e curve) keeps one sign over all
    of them, so no edge passes through a panel between its 3×3 nodes (the integrand test above is
    smooth across the terminator band and i = e, so it would hardly see one). The t-rings, which
    only part the coarse rule's blocks, may cross panels
    (test_cells_astride_a_ring_take_each_points_own_block). The edges are rebuilt here from
    ``lune_caps`` (not taken from the rule's own arguments)."""
    from lunarviz.geometry import mapped_lune
    sc = scene()
    values = np.asarray(MoonAlbedoMap.parse("synthetic").values(), float)
    seen = []
    original = mapped_lune._whole_panels

    def spy(*args):
        out = original(*args)
        seen.append((args, out))
        return out
    monkeypatch.setattr(mapped_lune, "_whole_panels", spy)
    mapped_lune_rule(sc, getattr(sc, body), sc.radii[body], 16, values, map_frame(sc, "moon"), kink=body == "sun")
    (args, out), = seen
    axis, cmax, cu, cc, _, _, kink = lune_caps(sc, getattr(sc, body), sc.radii[body], kink=body == "sun")
    fr = map_frame(sc, "moon")
    circles = [(fr.T @ cu[0, 0], cc[0, 0]), (fr.T @ cu[0, 1], cc[0, 1]), (fr.T @ axis, cmax)]
    curve = None if kink is None else (fr.T @ cu[0, 0], fr.T @ axis, kink)
    P = mapped_lune.PANEL_CELLS
    cells = out[1].reshape(-1, P * P)
    assert len(cells) > 10
    h, w = values.shape
    row, col = cells.min(axis=1) // w, cells.min(axis=1) % w  # each panel's north-west cell
    t = np.linspace(0.0, 1.0, 12)
    mu_n, mu_s = np.sin(np.radians(90.0 - 180.0 * row / h)), np.sin(np.radians(90.0 - 180.0 * (row + P) / h))
    lon_w = np.radians(-180.0 + 360.0 * col / w)
    mu = mu_s[:, None, None] + (mu_n - mu_s)[:, None, None] * t[None, :, None]
    lon = lon_w[:, None, None] + np.radians(360.0 * P / w) * t[None, None, :]
    mu, lon = np.broadcast_arrays(mu, lon)
    c = np.sqrt(1.0 - mu * mu)
    pts = np.stack([c * np.cos(lon), c * np.sin(lon), mu], axis=-1).reshape(len(cells), -1, 3)
    edges = [pts @ u - cc for u, cc in circles]
    if curve is not None:
        edges.append(mapped_lune._curve_value(curve)(pts.reshape(-1, 3)).reshape(len(cells), -1))
    for g in edges:
        assert np.all((g > 0).all(axis=1) | (g < 0).all(axis=1))


def test_a_map_of_round_off_contrast_takes_one_albedo_node():
    """A map whose values differ by round-off (1e-15: Chebyshev nodes would round onto each
    other, and the Lagrange weights were NaN) takes one node, its middle; the weights are those
    of a constant map."""
    sc = SceneGeometry(60.0)
    flat = np.ones((180, 360))
    near = flat + 1e-15 * np.random.default_rng(0).random(flat.shape)
    a = mapped_lune_rule(sc, sc.sun, 1.0, 12, near, map_frame(sc, "moon"))[3]
    b = mapped_lune_rule(sc, sc.sun, 1.0, 12, flat, map_frame(sc, "moon"))[3]
    assert len(a.values) == 1 and np.all(np.isfinite(a.factors))
    np.testing.assert_allclose(a.factors, b.factors, rtol=1e-12, atol=0)


@pytest.mark.parametrize("theta", [30.0, 120.0])
def test_point_source_calibration_on_the_traced_rule_against_a_cell_sum(theta):
    """The traced rows' point-source calibration on a mapped Moon runs on the mapped lune rules the
    trace used (the map's cells exact in their weights; sweeps._traced_rows): against a brute-force
    sum over every map cell (6×6 Gauss points a cell, the map's value per cell, no lune rule), both
    paths agree to 2e-4. Measured ≤ 6.6e-5 on 7 orbit dates, where the brute force point-samples
    the terminator and limb inside cells (its own error ~1e-5, test above) and the analytic grid of
    order 96 (the former calibration, reading the map at its nodes) erred by up to 2.1e-3."""
    from lunarviz.methods import analytic as A
    from lunarviz.methods.tracer.estimators import TraceScene, trace_path
    from lunarviz.scene import ResolvedScene
    s = ResolvedScene(method="raytrace", moon_model="rolo-fit-map", brdfs=("dhg",), rtol=1e-4, phases_deg=(theta,))
    sc, brdfs = SceneGeometry(theta), s.brdf_models()
    ts = TraceScene(sc, s.trace_settings(threads=1))
    for path in ("moonshine", "earthshine"):
        trace_path(ts, path, brdfs)
    rules = {b: ts.sampling.mapped_rule_used(b) for b in ("sun", "earth")}
    assert all(r is not None for r in rules.values())
    cal = replace(s.analytic_settings(), grid="converged", earth_law="lambert")
    got = A.analytic_irradiance(sc, brdfs, cal, rules=rules)["dhg"]
    amap = s.trace_settings().moon_map()
    values = np.asarray(amap.values(), float)
    pts, wts = map_cell_nodes(values.shape, 6)
    n = pts.reshape(-1, 3) @ map_frame(sc, "moon").T
    R = sc.radii["moon"]
    x, dA = sc.moon + R * n, wts.reshape(-1) * R * R
    per_point = np.repeat(values.reshape(-1), pts.shape[1])
    want = []
    for body in ("sun", "earth"):  # the points the source lights and the detector sees
        source = sc.sun if body == "sun" else sc.earth
        k = (np.einsum("ij,ij->i", n, source - x) > 0) & (np.einsum("ij,ij->i", n, sc.det - x) > 0)
        tr = A._point_source_transport(sc, x[k], n[k], dA[k], source, sc.solar_irradiance_at(x[k])) \
            if body == "sun" else A.earthshine_transport(sc, replace(cal, surfaces=None), rule=(x[k], n[k], dA[k]))
        tr.albedo, tr.albedo_absolute = per_point[k], amap.absolute
        want.append(tr.detector_irradiance(brdfs["dhg"]))
    np.testing.assert_allclose([got.moonshine_W_m2, got.earthshine_W_m2], want, rtol=2e-4, atol=0)


@pytest.mark.parametrize("theta, body", [(20.0, "sun"), (90.0, "sun"), (150.0, "sun"), (90.0, "earth"),
                                         (170.0, "earth")])
def test_cells_astride_a_ring_take_each_points_own_block(theta, body):
    """A cell or panel astride a t-ring (an edge of the coarse rule's blocks only: the integrand
    is smooth across it) takes its points in their own blocks instead of cutting the cell there:
    against cutting at the rings too (``cut_rings``, the error model's reference), the integral
    of the disc-lit Lommel-Seeliger law on the synthetic map agrees to 2e-7 (the difference of two
    blocks' interpolants where they meet, each as accurate as the rule: measured ≤ 5.9e-7 on 36
    orbit dates' traced paths, θ = 174.5° the largest; here ≤ 8.3e-9 (θ = 20°), and 1e-13 on the
    Earth's paths, whose cells no ring crosses apart from the caps' own; limit: 25x the largest)."""
    sc = SceneGeometry(theta)
    soft, cut = (_lommel_seeliger_on_rule(sc, body, cut_rings=c)[0] for c in (False, True))
    assert abs(soft / cut - 1) < 2e-7
    if body == "sun":  # (rings cross cells there: the two differ, by 2.7-8.3e-9)
        assert soft != cut
