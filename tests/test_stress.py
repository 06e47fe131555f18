"""Numerical stress tests: extremes, limits, bounded memory, no NaN or inf."""

import tracemalloc

import numpy as np
import pytest

from lunarviz.geometry.scene_geometry import SceneGeometry
from lunarviz.methods.analytic import analytic_irradiance
from lunarviz.methods.tracer.estimators import TraceScene, TraceSettings, trace_path
from lunarviz.photometry import brdf as B


def test_single_scattering_albedo_limits():
    s, c = B.half_angle_from_angles(0.6, 0.4, 1.0)
    # w → 0: the BRDF vanishes linearly (Eq. 12 is w × bounded)
    vals = [B.Hapke(w=w).brdf(np.cos(0.6), np.cos(0.4), s, c) for w in (1e-3, 1e-6, 1e-9, 0.0)]
    assert vals[-1] == 0.0 and vals[1] / vals[0] == pytest.approx(1e-3, rel=1e-2)
    # reflectance grows monotonically with w, up to w = 1 with every H-function, finite
    for hfun in B.H_FUNCTIONS:
        dhr = [B.directional_hemispherical_reflectance(B.Hapke(w=w, h_function=hfun), 0.5)
               for w in (0.1, 0.5, 0.9, 0.99, 1.0)]
        assert all(np.diff(dhr) > 0) and np.all(np.isfinite(dhr))


@pytest.mark.parametrize("xi", [-1 + 1e-9, 1 - 1e-9])
def test_hg_asymmetry_extremes_stay_finite(xi):
    g = np.linspace(0, np.pi, 721)
    p = B.SingleHG(xi)(np.sin(g / 2), np.cos(g / 2))
    assert np.all(np.isfinite(p)) and np.all(p >= 0)


@pytest.mark.parametrize("c", [-1.0, 1.0])
def test_dhg_pure_lobes(c):
    # |c| = 1 puts all weight on one lobe: the two conventions are then pure mirror lobes
    paper = B.DoubleHG(0.5, c, "paper")
    h12 = B.DoubleHG(0.5, c, "hapke2012")
    g = np.linspace(0, np.pi, 91)
    s, cc = np.sin(g / 2), np.cos(g / 2)
    assert np.allclose(paper(s, cc), h12(cc, s))


def test_grazing_geometry_radiance_finite_and_vanishing():
    m = B.make_brdf("dhg")
    for mu0, mu in [(0.0, 0.0), (0.0, 1e-300), (1e-300, 0.0), (1e-12, 1e-12)]:
        rf = m.radiance_factor(mu0, mu, 0.3, np.sqrt(1 - 0.09))
        assert np.isfinite(rf) and rf >= 0
    # BRDF·μ0 → 0 as μ0 → 0 at fixed μ (no light at grazing incidence)
    assert m.radiance_factor(1e-12, 0.5, 0.3, np.sqrt(1 - 0.09)) < 1e-10


@pytest.mark.parametrize("theta", [0.0, 180.0])
def test_end_phases_finite_everywhere(theta, paper_brdfs):
    res = analytic_irradiance(SceneGeometry(theta), paper_brdfs)
    for v in res.values():
        assert np.isfinite(v.moonshine_W_m2) and np.isfinite(v.earthshine_W_m2)
    for occlusion in (True, False):
        ts = TraceScene(SceneGeometry(theta), TraceSettings(occlusion=occlusion))
        for path in ("moonshine", "earthshine"):
            r = trace_path(ts, path, paper_brdfs, keep_facets=True)
            assert all(np.isfinite(v) and v >= 0 for v in r.mean.values())
            assert all(np.all(np.isfinite(a)) for a in r.facets.values())
    # eclipse: zero moonshine at θ = 0; new Moon: no sunlit side toward the detector
    ms0 = trace_path(TraceScene(SceneGeometry(0.0), TraceSettings()), "moonshine", paper_brdfs).mean
    assert all(v == 0.0 for v in ms0.values())


def test_memory_bounded_for_many_rays(paper_brdfs):
    # 2 million Monte Carlo rays at once would need > 2 GB of arrays; batched, the peak
    # stays at a few hundred MB (CHUNK = 16384 samples per batch)
    lam = {"lambert": paper_brdfs["lambert"]}
    ts = TraceScene(SceneGeometry(90.0), TraceSettings(estimator="montecarlo", rays=2_000_000, occlusion=False))
    tracemalloc.start()
    r = trace_path(ts, "moonshine", lam)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    assert peak < 300e6
    assert r.std["lambert"] / r.mean["lambert"] < 2e-4  # and the many rays were all used


def test_float32_trap_naive_geocentric_would_fail():
    # The trap NOTES.md describes: casting rays from the Sun's true position in a geocentric
    # float32 frame. Our body-centred frames hit the same facets as an exact float64 answer.
    from lunarviz.bodies.meshes import unit_icosphere
    from lunarviz.methods.tracer.embree_bodies import EmbreeBody
    sc = SceneGeometry(60.0)
    moon = EmbreeBody(unit_icosphere(6), sc.moon, scale=sc.r_moon)
    rng = np.random.default_rng(1)
    facing = np.flatnonzero(np.einsum("ij,ij->i", moon.normals, sc.sun - moon.centroids) > 0)
    targets = moon.centroids[rng.choice(facing, 2000)]
    origin = np.broadcast_to(sc.sun, targets.shape)
    d = (targets - origin) / np.linalg.norm(targets - origin, axis=1, keepdims=True)
    hits = moon.intersect(origin, d)
    # each ray aimed from the Sun (1.5e11 m away) at a Sun-facing facet's centroid must land
    # on it: within 1 m (a geocentric float32 cast would scatter them by ~16 km, NOTES.md)
    assert hits.hit.all()
    assert np.max(np.linalg.norm(hits.point - targets, axis=1)) < 1.0
