"""The compiled kernels (shading and ray kernels) against the numpy BRDFs (lunarviz.photometry.brdf)

The numpy implementation is the reference (itself tested against textbook formulas in
test_brdf.py); the kernel must reproduce it to rounding (1e-13 relative: different summation
order only) for every model it takes, with and without per-sample albedo and unit-albedo beams.
"""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from lunarviz.methods.tracer import ray_kernels
from lunarviz.photometry import shading_kernels
from lunarviz.photometry.brdf import make_brdf

pytestmark = pytest.mark.skipif(not (ray_kernels.available() and shading_kernels.available()),
                                reason="numba not available")

MODELS = [("dhg", {}), ("shg", {}), ("dhg", {"h_function": "hapke2002"}), ("dhg", {"dhg_convention": "hapke2012"}),
          ("shg", {"params": {"xi": 0.3}}), ("dhg", {"params": {"h": 0.0}})]


@pytest.mark.parametrize("name, kw", MODELS)
def test_kernel_matches_numpy(name, kw):
    rng = np.random.default_rng(1)
    N, K = 3000, 40
    mu0 = rng.uniform(-0.2, 1, (N, K))
    mu = rng.uniform(0, 1, N)
    g = rng.uniform(0, np.pi, (N, K))
    g[:, 0] = 0.0  # exact backscatter: the surge's h = 0 branch
    sh, ch = np.sin(g / 2), np.cos(g / 2)
    e = rng.uniform(0, 1, (N, K))
    e[rng.random((N, K)) < 0.3] = 0
    eu = 2 * e + (e == 0) * rng.uniform(0, 1, (N, K))
    al = rng.uniform(0.05, 0.95, N)
    m = make_brdf(name, **kw)
    for albedo in (None, al):
        a2 = None if albedo is None else albedo[:, None]
        rf = m.radiance_factor(np.clip(mu0, 0, 1), mu[:, None], sh, ch, albedo=a2)
        L, Lu = shading_kernels.hapke_radiances(m, mu0, mu, sh, ch, e, eu, albedo)
        np.testing.assert_allclose(L, (rf * e).sum(1), rtol=1e-13, atol=0)
        np.testing.assert_allclose(Lu, (rf * eu).sum(1), rtol=1e-13, atol=0)


ROUGH = [("dhg", {"params": {"theta_bar": 20.0}}), ("shg", {"params": {"theta_bar": 35.0, "xi": 0.3}}),
         ("dhg", {"h_function": "hapke2002", "params": {"theta_bar": 10.0}}),
         ("dhg", {"dhg_convention": "hapke2012", "params": {"theta_bar": 25.0, "Bc0": 0.4, "hc": 0.06}}),
         ("dhg", {"params": {"theta_bar": 30.0, "h": 0.0}})]


@pytest.mark.parametrize("name, kw", ROUGH)
def test_rough_kernel_at_albedo_nodes_matches_numpy(name, kw):
    """The mapped lune rule's compiled rough Hapke (rough_kernels: each beam's geometry once,
    the H-functions per map value) against the numpy reference (Hapke._rough_r broadcast over
    the values, as Transport takes it without numba): relative to each sample's largest term,
    to rounding (1e-12: the kernel takes sin i as √(1 - μ0²) where numpy takes sin(arccos μ0)),
    with grazing and normal incidence and emission, i = e, g = 0 and π, dark beams."""
    from lunarviz.photometry import rough_kernels
    rng = np.random.default_rng(4)
    N, K, Q = 2000, 12, 8
    mu0, mu = rng.uniform(-0.2, 1, (N, K)), rng.uniform(0, 1, N)
    mu0[:40], mu0[40:80], mu[80:120], mu[120:160] = 0.0, 1.0, 0.0, 1.0
    mu0[160:200] = mu[160:200, None]
    g = rng.uniform(0, np.pi, (N, K))
    g[200:240], g[240:260] = 0.0, np.pi
    sh, ch = np.sin(g / 2), np.cos(g / 2)
    e = rng.uniform(0, 1, (N, K))
    e[rng.random((N, K)) < 0.3] = 0
    eu = 2 * e + (e == 0) * rng.uniform(0, 1, (N, K))
    w, F = np.linspace(0.15, 0.65, Q), rng.uniform(-0.2, 1, (N, Q))
    m = make_brdf(name, **kw)
    assert rough_kernels.handles(m)
    rf = m.radiance_factor(np.clip(mu0, 0, 1)[:, None, :], mu[:, None, None], sh[:, None, :], ch[:, None, :],
                           albedo=w[None, :, None])  # (N, Q, K)
    L, Lu = rough_kernels.rough_node_radiances(m, mu0, mu, sh, ch, e, eu, w, F)
    for got, beams in ((L, e), (Lu, eu)):
        want = np.einsum("nqk,nk,nq->n", rf, beams, F)
        scale = np.einsum("nqk,nk,nq->n", np.abs(rf), beams, np.abs(F))
        assert np.all(np.abs(got - want) <= 1e-12 * scale)
    assert not rough_kernels.handles(make_brdf("dhg")) and not rough_kernels.handles(make_brdf("lambert"))



@pytest.mark.parametrize("theta_bar, Bc0, hc", [(20.0, 0.0, 0.05), (25.0, 0.4, 0.06), (5.0, 1.0, 0.1)])
def test_rough_geometry_kernel_matches_numpy(theta_bar, Bc0, hc):
    """The spectral shading's compiled rough geometry (rough_kernels.rough_geometry: Hapke 1984's
    effective cosines and shadowing with Hapke 2002's coherent backscatter, per beam) against the
    numpy reference (roughness.shadowing, coherent_backscatter): to rounding (1e-12 on these O(1)
    values) wherever ψ is not within 1e-3 rad of 0 or π, where ψ = 2 asin √q is ill-conditioned in q
    (the two take sin i differently: 1e-16 in q moves ψ by ~1e-8 there; 1e-7 at these θ̄ ≤ 25°);
    finite at grazing and normal incidence and emission, i = e, g = 0, g = π, g = |i - e|, g = i + e
    and double grazing (i = e = 90°, ψ = π: no light, S = 0, where the slope terms' denominator
    vanishes)."""
    from lunarviz.photometry import rough_kernels
    from lunarviz.photometry.roughness import azimuth_from_half_angle, coherent_backscatter, shadowing
    rng = np.random.default_rng(7)
    N, K = 2000, 12
    mu0, mu = rng.uniform(-0.2, 1, (N, K)), rng.uniform(0, 1, N)
    mu0[:40], mu0[40:80], mu[80:120], mu[120:160] = 0.0, 1.0, 0.0, 1.0
    mu0[160:200] = mu[160:200, None]
    g = rng.uniform(0, np.pi, (N, K))
    g[200:240], g[240:260] = 0.0, np.pi
    i, e = np.arccos(np.clip(mu0, 0, 1)), np.arccos(mu)[:, None]
    g[260:300] = np.minimum(i + e, np.pi)[260:300]  # ψ = π: the light leaves opposite the Sun's azimuth
    g[300:340] = np.abs(i - e)[300:340]  # ψ = 0: the light leaves on the Sun's side
    mu0[340:360, :4], mu[340:360], g[340:360, :4] = 0.0, 0.0, np.pi  # double grazing, ψ = π
    sh, ch = np.sin(g / 2), np.cos(g / 2)
    got = rough_kernels.rough_geometry(mu0, mu, sh, ch, np.radians(theta_bar), Bc0, hc)
    psi = azimuth_from_half_angle(np.clip(mu0, 0, 1), mu[:, None], sh)
    mu0e, mue, S = shadowing(mu0, mu[:, None], psi, np.radians(theta_bar))
    S = S * (1.0 + Bc0 * coherent_backscatter(sh, ch, hc))
    ill = (psi > np.pi - 1e-3) | (psi < 1e-3)
    assert ill.any() and (~ill).sum() > ill.size // 4  # (beams with g outside [|i - e|, i + e] have ψ = 0 or π)
    for a, b in zip(got, (mu0e, mue, S)):
        b = np.broadcast_to(b, mu0.shape)
        assert np.all(np.isfinite(a))
        assert np.abs(a - b)[~ill].max() <= 1e-12 and np.abs(a - b)[ill].max() <= 1e-7
    assert np.all(got[2][340:360, :4] == 0.0)

def test_models_the_kernel_leaves_to_numpy():
    assert shading_kernels.hapke_codes(make_brdf("lambert")) is None
    assert shading_kernels.hapke_codes(make_brdf("dhg", h_function="exact")) is None
    assert shading_kernels.hapke_codes(make_brdf("dhg", params={"theta_bar": 20.0})) is None


@pytest.mark.parametrize("theta", [2.0, 60.0, 120.0, 178.0])
def test_earth_beams_kernel_matches_numpy_rule(theta):
    """kernels.sphere_cap_beams (compiled one-cap rules) against the numpy reference
    source_beams(source_sphere_rule(...)): same beams, to rounding (1e-12: sin/cos of two
    libraries), at lunar points all over the Moon, from a gibbous to a crescent Earth, and for
    the Sun cut by the horizon."""
    from lunarviz.geometry.scene_geometry import SceneGeometry, unit
    from lunarviz.methods.sources import source_beams, source_sphere_rule
    sc = SceneGeometry(theta)
    rng = np.random.default_rng(2)
    n = unit(rng.normal(size=(500, 3)))
    x = sc.moon + sc.radii["moon"] * n
    m, w = source_sphere_rule(sc, x, n, "earth", 6, horizon=False)
    _, om_ref, omega_ref = source_beams(sc, x, "earth", m, w)
    R = sc.radii["earth"]
    cs = sc.sun - sc.earth
    om, omega = ray_kernels.sphere_cap_beams(x, sc.earth, R, unit(cs), R / np.linalg.norm(cs), 6, 6)
    assert omega.shape == omega_ref.shape
    np.testing.assert_allclose(omega, omega_ref, rtol=1e-12, atol=1e-12 * omega_ref.max())
    live = omega_ref > 0
    np.testing.assert_allclose(om[live], om_ref[live], rtol=0, atol=1e-13)
    # the Sun cut by each point's horizon (the penumbra rows): one cap per row
    cut = np.einsum("ij,ij->i", sc.sun - x, n) < sc.radii["sun"]
    xs, ns = x[cut], n[cut]
    m, w = source_sphere_rule(sc, xs, ns, "sun", 6, horizon=True)
    _, om_ref, omega_ref = source_beams(sc, xs, "sun", m, w)
    Rs = sc.radii["sun"]
    om, omega = ray_kernels.sphere_cap_beams(xs, sc.sun, Rs, ns, np.einsum("ij,ij->i", xs - sc.sun, ns) / Rs, 6, 6)
    assert omega.shape == omega_ref.shape
    np.testing.assert_allclose(omega, omega_ref, rtol=1e-12, atol=1e-12 * omega_ref.max())


def test_ray_kernels_match_numpy():
    rng = np.random.default_rng(3)
    o = rng.normal(size=(400, 3)) * 3
    d = rng.normal(size=(400, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    c = np.array([0.1, 0.2, -0.3])
    tmax = rng.uniform(0, 6, 400)
    ob, t0, live = ray_kernels.ray_starts(o, d, c, 1.5, tmax)
    b = -np.einsum("ij,ij->i", o - c, d)
    disc = 1.5**2 - (np.einsum("ij,ij->i", o - c, o - c) - b * b)
    t0_ref = np.clip(b - np.sqrt(np.clip(disc, 0, None)), 0, None)
    np.testing.assert_allclose(t0, t0_ref, rtol=1e-14, atol=1e-14)
    np.testing.assert_array_equal(live, (disc > 0) & (b + np.sqrt(np.clip(disc, 0, None)) > 0) & (t0_ref < tmax))
    idx = np.flatnonzero(live)
    o32, d32 = ray_kernels.ray_batch32(ob, d, t0, idx)
    np.testing.assert_array_equal(o32, ((o - c)[idx] + t0[idx, None] * d[idx]).astype(np.float32))
    om = rng.normal(size=(40, 7, 3))
    omega, mu0 = rng.uniform(-1, 1, (40, 7)), rng.uniform(-1, 1, (40, 7))
    bi, ki, xs, ns, ds = ray_kernels.live_beams(o[:40], d[:40], om, omega, mu0)
    rb, rk = np.nonzero((omega > 0) & (mu0 > 0))
    np.testing.assert_array_equal(bi, rb)
    np.testing.assert_array_equal(ki, rk)
    np.testing.assert_array_equal(ds, om[rb, rk])
    np.testing.assert_array_equal(xs, o[rb])


def test_sweep_rows_equal_with_and_without_numba():
    """The whole raytrace pipeline with LUNARVIZ_NUMBA=0 (numpy) gives the same rows to 1e-12
    (the compiled Earth rule calls numba's sin/cos/arccos where numpy calls its own: 1-ulp
    differences in the nodes, ~3e-13 relative at a θ = 172° crescent)."""
    code = ("import json; from lunarviz.scene import ResolvedScene; from lunarviz.workflows.sweeps import run_phase; "
            "s = ResolvedScene(method='raytrace', phases_deg=(120.0,), moon_level=3, moon_albedo_map='synthetic'); "
            "u = ResolvedScene(method='raytrace', moon_level=3, occlusion=False); "
            "print(json.dumps([[r['moonshine_W_m2'], r['earthshine_W_m2']] for r in run_phase(s, 120.0) "
            "+ run_phase(u, 30.0) + run_phase(u, 172.0)]))")
    out = {}
    for flag in ("0", "1"):
        env = {**os.environ, "LUNARVIZ_NUMBA": flag}
        p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
        assert p.returncode == 0, p.stderr
        out[flag] = np.array(eval(p.stdout.strip()))  # noqa: S307 (our own JSON list)
    np.testing.assert_allclose(out["1"], out["0"], rtol=1e-12, atol=0)


def test_unwritable_numba_cache_does_not_stop_lunarviz():
    """A read-only install (numba: "cannot cache function ...: no locator available") compiles
    without the on-disk cache instead of failing."""
    code = ("import numba\n"
            "orig = numba.njit\n"
            "def njit(*a, **kw):\n"
            "    if kw.get('cache'):\n"
            "        raise RuntimeError('cannot cache function: no locator available')\n"
            "    return orig(*a, **kw)\n"
            "numba.njit = njit\n"
            "from lunarviz.photometry import shading_kernels\n"
            "from lunarviz.photometry.brdf import make_brdf\n"
            "import numpy as np\n"
            "f = np.full\n"
            "L, _ = shading_kernels.hapke_radiances(make_brdf('dhg'), f((2, 3), 0.5), f(2, 0.5), f((2, 3), 0.1), "
            "f((2, 3), 0.99), np.ones((2, 3)))\n"
            "print(shading_kernels.available(), bool(np.all(L > 0)))\n")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    assert p.stdout.split() == ["True", "True"]


@pytest.mark.parametrize("theta", [3.0, 90.0, 177.0])
def test_monte_carlo_earth_directions_kernel_matches_numpy(theta, monkeypatch):
    """The compiled Monte Carlo Earth sampler against the numpy one, fed the same uniforms
    (same generator state): same directions and weights to rounding (1e-12, sin/cos of two
    libraries; the weight's pdf table is the same piecewise-constant one)."""
    from lunarviz.geometry.scene_geometry import SceneGeometry, unit
    from lunarviz.methods.tracer.estimators import TraceScene, TraceSettings
    ts = TraceScene(SceneGeometry(theta), TraceSettings(moon_level=2))
    rng = np.random.default_rng(4)
    n = unit(rng.normal(size=(3000, 3)))
    xs = ts.scene.moon + ts.scene.radii["moon"] * n
    d_fast, w_fast = ts.montecarlo._earth_lit_directions(xs, np.random.default_rng(9))
    monkeypatch.setattr(ray_kernels, "_NUMBA", False)
    d_ref, w_ref = ts.montecarlo._earth_lit_directions(xs, np.random.default_rng(9))
    assert np.all(np.isfinite(d_fast)) and np.all(w_fast >= 0)
    # Each path's choice of table cell (u against the cdf) and of "lit" (hw > 0) is a branch on
    # sums the two compute in different orders, so a sample on a branch's edge may land in the
    # neighbouring cell on one CPU and not on another (seen at θ = 3°, where the lit sliver makes
    # the table nearly flat: 16 of 3000). Each path stays unbiased (its weight uses the cell it
    # sampled); the comparison must not hinge on those flips. So: every other sample agrees to
    # rounding, flips are rare (< 2 %), and both estimates of the lit solid angle agree within
    # 4 standard errors of their difference.
    same = np.isclose(w_fast, w_ref, rtol=1e-10, atol=1e-12 * w_ref.max()) & \
        np.all(np.isclose(d_fast, d_ref, rtol=0, atol=1e-12), axis=1)
    assert same.mean() > 0.98, f"{np.count_nonzero(~same)} of {len(same)} samples differ"
    np.testing.assert_allclose(w_fast[same], w_ref[same], rtol=1e-10, atol=1e-12 * w_ref.max())
    diff = w_fast - w_ref
    assert abs(diff.mean()) <= 4 * diff.std() / np.sqrt(len(diff)) + 1e-12 * w_ref.max()



def test_lambert_kernel_matches_numpy():
    """Lambert's compiled sum against Lambert.radiance_factor (1e-13: summation order only)."""
    rng = np.random.default_rng(5)
    N, K = 2000, 30
    mu0 = rng.uniform(-0.2, 1.1, (N, K))
    e = rng.uniform(0, 1, (N, K))
    e[rng.random((N, K)) < 0.3] = 0
    eu = 2 * e
    al = rng.uniform(0.05, 0.95, N)
    m = make_brdf("lambert")
    for albedo in (None, al):
        rf = m.radiance_factor(mu0, 1.0, 0.0, 1.0, albedo=None if albedo is None else albedo[:, None])
        L, Lu = shading_kernels.lambert_radiances(m, mu0, e, eu, albedo)
        np.testing.assert_allclose(L, (rf * e).sum(1), rtol=1e-13, atol=0)
        np.testing.assert_allclose(Lu, (rf * eu).sum(1), rtol=1e-13, atol=0)


@pytest.mark.parametrize("theta", [30.0, 90.0, 176.0])
def test_fused_beam_transport_matches_numpy_path(theta, tmp_path, monkeypatch):
    """DeterministicTransport._fused_beam_transport (the compiled pass from rule to Embree's rays, radiance
    and shadow rays) against the numpy path (beam_angles, live_beams, source_radiance) on a
    cratered Moon with self-shadowing and occlusion on: the same rays cast and source facets hit
    (exactly: both send the same float32 rays to Embree), the same totals to rounding (1e-12:
    sin/cos of two libraries in the rules, and summation order) and per-facet arrays to 1e-10 of
    their largest value: a facet's sum is more sensitive, because the Earth rule's half-widths are
    arccos(q) with q near ±1 at the terminator's tangent (conditioning 1/√(1−q²)), which turns
    1-ulp node differences into ~1e-11 of one facet (9e-12 measured before the fused path, 1.6e-11
    with it, θ = 30°). θ = 176°: the Earth's horizon-cut rows and the Sun's eclipse/penumbra
    groups take the generic beam_rays."""
    from lunarviz.bodies import shapes
    from lunarviz.constants import R_MOON_M
    from lunarviz.geometry.scene_geometry import SceneGeometry
    from lunarviz.methods.tracer.estimators import TraceScene, TraceSettings, trace_path
    path = tmp_path / "craters.ply"
    shapes.write_mesh(shapes.craters(R_MOON_M, 4, 60, 50e3, 300e3, seed=3), path)
    models = {b: make_brdf(b) for b in ("lambert", "shg", "dhg")}

    def run():
        ts = TraceScene(SceneGeometry(theta), TraceSettings(moon_mesh=str(path), occlusion=True, threads=1))
        res = {p: trace_path(ts, p, models, keep_facets=True) for p in ("moonshine", "earthshine")}
        return ts, res
    ts_f, fused = run()
    assert ts_f.bodies.self_shadows()
    monkeypatch.setattr(ray_kernels, "_NUMBA", False)
    monkeypatch.setattr(shading_kernels, "_NUMBA", False)
    ts_n, ref = run()
    assert ts_f.rays_cast == ts_n.rays_cast
    for b in ("sun", "earth"):
        np.testing.assert_array_equal(ts_f.source_hits[b], ts_n.source_hits[b])
    for p in fused:
        for k in models:
            assert fused[p].mean[k] > 0
            np.testing.assert_allclose(fused[p].mean[k], ref[p].mean[k], rtol=1e-12)
        for key, v in ref[p].facets.items():
            np.testing.assert_allclose(fused[p].facets[key], v, rtol=0, atol=1e-10 * max(np.abs(v).max(), 1e-300))
    np.testing.assert_allclose(fused["earthshine"].mean_unit["dhg"], ref["earthshine"].mean_unit["dhg"], rtol=1e-12)


def test_cone_rule_kernel_matches_numpy():
    """kernels.cone_rule (the Sun's cone beams) against sphere_quadrature.cone_rule: the same
    operations in the same order, so the same nodes and weights to 1e-15 (rounding of fused
    multiply-adds at most), for cones from the Sun's 0.27° to a near hemisphere."""
    from lunarviz.geometry.sphere_quadrature import cone_rule
    rng = np.random.default_rng(6)
    axis = rng.normal(size=(300, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    axis[0] = [1.0, 0.0, 0.0]  # the basis helper's switch at |a_x| = 0.9
    sin_rho = np.concatenate([[4.65e-3, 0.999999], rng.uniform(1e-4, 0.99, 298)])
    for n_psi, n_phi in ((2, 4), (8, 16)):
        d, w = ray_kernels.cone_rule(axis, sin_rho, n_psi, n_phi)
        d_ref, w_ref = cone_rule(axis, sin_rho, n_psi, n_phi)
        np.testing.assert_allclose(w, w_ref, rtol=1e-15, atol=0)
        np.testing.assert_allclose(d, d_ref, rtol=0, atol=1e-15)


@pytest.mark.parametrize("name, kw", ROUGH[:3])
def test_rough_kernel_shades_each_samples_own_albedo_as_numpy(name, kw):
    """The facets' samples (each its own w, or the pair w ± σ of its map spread; none: the
    BRDF's w) through the compiled rough kernel (Transport.radiances) against the numpy reference
    (Hapke._rough_r per sample, as without numba), relative to each sample's largest term: 1e-12."""
    from lunarviz.methods.transport import Transport
    from lunarviz.photometry import rough_kernels
    rng = np.random.default_rng(5)
    N, K = 1500, 10
    mu0, mu = rng.uniform(-0.2, 1, (N, K)), rng.uniform(0, 1, N)
    g = rng.uniform(0, np.pi, (N, K))
    e = rng.uniform(0, 1, (N, K))
    e[rng.random((N, K)) < 0.3] = 0
    m = make_brdf(name, **kw)
    for albedo, spread in ((None, None), (rng.uniform(0.5, 1.5, N), None),
                           (rng.uniform(0.5, 1.5, N), rng.uniform(0, 0.2, N))):
        tr = Transport(mu0=np.clip(mu0, 0, 1), sin_hg=np.sin(g / 2), cos_hg=np.cos(g / 2), e_beam=e, mu=mu,
                       geom=np.ones(N), e_beam_unit=2 * e, albedo=albedo, albedo_std=spread)
        got, got_u = tr.radiances(m)
        pair = tr._albedo_pair(m)
        ws = pair if pair is not None else [tr.sample_albedo(m)]
        rf = [m.radiance_factor(tr.mu0, mu[:, None], tr.sin_hg, tr.cos_hg, albedo=w) for w in ws]
        want = sum(np.sum(r * e, axis=1) for r in rf) / len(rf)
        scale = sum(np.sum(np.abs(r) * e, axis=1) for r in rf) / len(rf)
        assert rough_kernels.handles(m) and np.all(np.abs(got - want) <= 1e-12 * scale + 1e-300)
        assert np.all(np.abs(got_u - 2 * want) <= 2e-12 * scale + 1e-300)


@pytest.mark.parametrize("thin", [False, True])
def test_cap_rule_nodes_kernel_matches_numpy(thin, monkeypatch):
    """cap_rule's nodes and weights written by the compiled kernel against its numpy expression:
    the same arithmetic in the same order, the rings (their t and weights) and their φ-intervals too
    (compiled where a ring has two caps or a cut); bar 1e-15 on the nodes and, on the weights,
    1e-15 relative or 1e-15 of the largest: numba's arccos, sin and cos may differ from numpy's by
    an ulp, which moves an interval's end by an ulp of 2π (measured: 5e-14 relative on a narrow
    interval's weight, 4e-18 absolute). Two caps, one a split-only cut, crossings; and one axis
    with the thin blocks' padded orders."""
    from lunarviz.geometry import quadrature_kernels
    from lunarviz.geometry.sphere_quadrature import cap_rule
    if not quadrature_kernels.available():
        pytest.skip("numba not in use")
    rng = np.random.default_rng(11)
    B = 1 if thin else 40
    axis = rng.normal(size=(B, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    caps = axis[:, None, :] + 0.3 * rng.normal(size=(B, 2, 3))
    caps /= np.linalg.norm(caps, axis=2, keepdims=True)
    cos_max = np.cos(rng.uniform(0.5, 1.0, B))
    kw = dict(caps_u=caps, caps_c=np.cos(rng.uniform(0.3, 0.8, (B, 2))), split_only=np.array([[False, True]] * B),
              n_t=8, n_phi=8, crossings=True)
    if thin:
        kw.update(structured=True, thin=(0.05, 4, 0.01))
    got = cap_rule(axis, cos_max, **kw)
    monkeypatch.setattr(quadrature_kernels, "_NUMBA", False)
    ref = cap_rule(axis, cos_max, **kw)
    assert got[1].sum() > 0
    np.testing.assert_allclose(got[0], ref[0], rtol=0, atol=1e-15)
    np.testing.assert_allclose(got[1], ref[1], rtol=1e-15, atol=1e-15 * ref[1].max())


def test_source_sphere_beams_kernel_matches_numpy(monkeypatch):
    """The Earth's rule about the zero-phase point as beams (sources.source_sphere_beams: the rule's
    nonzero nodes first, then source_beams), compiled in one pass against numpy's sort, gather and
    source_beams: the same directions to the bit, and the same solid angles but where a node
    grazes the Earth's limb seen from the point (cos_y, a dot product near 0, summed in another
    order than numpy's einsum: 0 against ~1e-52 sr), so bar 1e-15 of each row's largest beam; the
    padded slots hold the rows' zero weights. Lunar points on a real orbit date, some whose
    horizon cuts the Earth, with and without the roughness's cuts."""
    from lunarviz.geometry import quadrature_kernels
    from lunarviz.methods.sources import source_sphere_beams, zero_phase_points
    from lunarviz.scene import ResolvedScene
    if not quadrature_kernels.available():
        pytest.skip("numba not in use")
    sc = ResolvedScene(method="raytrace", observer="orbit:550,97.6,0,0",
                       times=("2026-02-11T18:00Z",)).geometry("2026-02-11T18:00Z")
    rng = np.random.default_rng(3)
    n = rng.normal(size=(60, 3)) + 2.0 * (sc.earth - sc.moon) / np.linalg.norm(sc.earth - sc.moon)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    x = sc.moon + sc.radii["moon"] * n
    pole = zero_phase_points(sc, x)
    for horizon in (False, True):
        for cuts in (False, True):
            kw = dict(horizon=horizon, pole=pole, roughness_cuts=cuts)
            got = source_sphere_beams(sc, x, n, "earth", 6, **kw)
            monkeypatch.setattr(quadrature_kernels, "_NUMBA", False)
            ref = source_sphere_beams(sc, x, n, "earth", 6, **kw)
            monkeypatch.setattr(quadrature_kernels, "_NUMBA", True)
            assert got[1].shape == ref[1].shape and (ref[1] > 0).sum() > 100 and (ref[1] == 0).any()
            np.testing.assert_allclose(got[0], ref[0], rtol=0, atol=1e-15)
            assert np.all(np.abs(got[1] - ref[1]) <= 1e-15 * ref[1].max(axis=1, keepdims=True))


def _cut_points(seed: int, count: int, tilt: float):
    """Lunar points (x, normals n, directions o toward the Earth) of the paper's scene at θ = 60°
    whose horizons cut the Earth: normals within ``tilt`` (about 1.5°) of the plane normal to the
    Earth's direction."""
    from lunarviz.geometry.scene_geometry import SceneGeometry, unit
    sc = SceneGeometry(60.0)
    to_earth = unit(sc.earth - sc.moon)
    rng = np.random.default_rng(seed)
    n = unit(np.cross(to_earth, rng.normal(size=(count, 3))) + rng.uniform(-tilt, tilt, (count, 1)) * to_earth)
    return sc.moon + sc.radii["moon"] * n, n, np.tile(to_earth, (count, 1))


def _cut_point_earth():
    """A fresh mapped Earth (level 4, land-ocean with zonal clouds) of :func:`_cut_points`' scene."""
    from lunarviz.geometry.scene_geometry import SceneGeometry
    from lunarviz.methods.tracer.estimators import TraceScene, TraceSettings
    ts = TraceScene(SceneGeometry(60.0), TraceSettings(moon_level=2, earth_level=4, earth_surface="landocean",
                                                       clouds="zonal"))
    return ts.mapped_earth


def test_mapped_earth_cut_sums_kernel_matches_numpy(monkeypatch):
    """The mapped Earth's exact per-element sums at lunar points whose horizon cuts the Earth,
    compiled (earth_kernels.element_sums with horizons) against the numpy path: the same beams to rounding (1e-10:
    the order of the sums differs; an element within rounding of a point's horizon could flip,
    which random points do not meet)."""
    from lunarviz.methods.tracer import earth_kernels
    if not earth_kernels.available():
        pytest.skip("numba not installed: the numpy path is the only one")
    x, n, o = _cut_points(seed=8, count=40, tilt=0.025)

    def beams():
        tr = _cut_point_earth().transport(x, n, o, np.ones(40), np.ones(40))
        return tr.e_beam, tr.e_beam_unit
    fast = beams()
    monkeypatch.setattr(earth_kernels, "_NUMBA", False)
    slow = beams()
    assert slow[1].sum() > 0
    for a, b in zip(fast, slow):
        np.testing.assert_allclose(a, b, rtol=1e-10, atol=1e-12 * b.max())


def test_mapped_earth_cut_points_see_every_element_above_their_horizon(monkeypatch):
    """At lunar points whose horizon cuts the Earth the mapped Earth expands the cells wholly above
    the horizon about the Moon's centre and sums the crossed cells' elements one by one. The
    independent route: every element above the point's horizon and facing it summed by brute
    force here, L1A·cos_y/r²; each point's light over all cells agrees to 1e-6 (the expansion's
    own error, as at points that see the whole Earth: 4e-7 at this θ = 60°, up to 2-3e-6 at a
    thin crescent, θ = 10°), compiled and numpy, and some of the points have cells on both sides
    of their horizon (the classification is exercised)."""
    from lunarviz.methods.tracer import earth_kernels
    x, n, o = _cut_points(seed=9, count=30, tilt=0.02)
    for compiled in (True, False):
        monkeypatch.setattr(earth_kernels, "_NUMBA", compiled and earth_kernels.available())
        earth = _cut_point_earth()
        got = earth.transport(x, n, o, np.ones(30), np.ones(30)).e_beam_unit.sum(axis=1)
        el = earth.earth_elements()
        v = x[:, None, :] - el["y"][None, :, :]
        r2 = np.einsum("bkj,bkj->bk", v, v)
        seen = (np.einsum("bkj,kj->bk", v, el["m"]) > 0) & (np.einsum("bkj,bj->bk", v, n) < 0)
        ref = np.sum(np.where(seen, el["L1A"] * np.einsum("bkj,kj->bk", v, el["m"]) / r2**1.5, 0.0), axis=1)
        assert ref.max() > 0 and ((ref > 0) & (ref < ref.max() * 0.5)).any()  # (partly seen Earths)
        np.testing.assert_allclose(got, ref, rtol=1e-6, atol=1e-12 * ref.max())
        h = np.einsum("bj,bcj->bc", n, el["centre"][None] - x[:, None])
        assert ((h > el["radius"]).any(1) & (np.abs(h) <= el["radius"]).any(1)).sum() >= 10


def test_jittered_facet_points_kernel_matches_numpy(monkeypatch):
    """The map averages' jittered points per facet (maps.facet_points), compiled, against the numpy
    path: the same points to rounding (1e-15 of the radius; the sums' order differs), and a date's
    facets alone (``rows``: their random draws skipped to, PCG64's advance) bit for bit the whole
    mesh's, with the generator left where the whole draw leaves it (rows that neither start at the
    first facet nor end at the last: both skips are taken); a generator that cannot skip (Philox's
    advance counts blocks, not draws) and a 32-bit value buffered take the whole draw."""
    import trimesh

    from lunarviz.surfaces import maps
    ico = trimesh.creation.icosphere(subdivisions=3)
    V, F = ico.vertices * 6.371e6, ico.faces
    rows = np.flatnonzero(ico.face_normals @ np.array([0.3, 0.5, 0.8]) > 0.2)
    rows = rows[(rows > 0) & (rows < len(F) - 1)]
    assert rows[0] > 0 and rows[-1] < len(F) - 1
    got = maps.facet_points(V, F, 5, np.random.default_rng(3))
    for make in (lambda: np.random.default_rng(3), lambda: np.random.Generator(np.random.Philox(3))):
        for buffered in (False, True):
            rng_rows, rng_whole = make(), make()
            if buffered:
                rng_rows.integers(0, 9, dtype=np.uint32), rng_whole.integers(0, 9, dtype=np.uint32)
            part = maps.facet_points(V, F, 5, rng_rows, rows)
            whole = maps.facet_points(V, F, 5, rng_whole)
            assert np.array_equal(part, whole[rows])
            assert rng_rows.integers(0, 2**32, dtype=np.uint32) == rng_whole.integers(0, 2**32, dtype=np.uint32)
    monkeypatch.setattr(maps, "_NUMBA", False)
    want = maps.facet_points(V, F, 5, np.random.default_rng(3))
    assert np.abs(got - want).max() <= 1e-15 * 6.371e6
