"""Albedo inversion (Eqs. 15-17, NOTES.md item 4)."""

import numpy as np
import pytest

from lunarviz.geometry.scene_geometry import SceneGeometry
from lunarviz.methods.analytic import AnalyticSettings, analytic_irradiance
from lunarviz.photometry import albedo_inversion as alb
from lunarviz.scene import ResolvedScene
from lunarviz.workflows.sweeps import run_sweep


def test_bond_weights_integrate_the_kernel_exactly():
    beta = np.arange(0, 181, 5.0)
    w = alb.bond_weights(beta)
    assert w.sum() == pytest.approx(0.75, rel=1e-14)  # ∫₀^π f_L sin β dβ = 3/4
    assert alb.bond_albedo(beta, np.full(beta.size, 0.37)) == pytest.approx(0.37, rel=1e-13)
    # a sparse, irregular grid with a 0/0 end point dropped still integrates a constant exactly
    beta = np.array([0, 20, 33, 90, 150, 180.0])
    p = np.array([0.2, 0.2, 0.2, 0.2, 0.2, np.nan])
    assert alb.bond_albedo(beta, p) == pytest.approx(0.2, rel=1e-13)


def test_bond_of_linear_apparent_albedo():
    # p*(β) = a + bβ is integrated exactly by the hat-function weights
    from scipy.integrate import quad

    from lunarviz.photometry.earth_phase import lambert_phase_function
    beta = np.arange(0, 181, 10.0)
    p = 0.3 + 0.01 * np.radians(beta)
    exact = 4 / 3 * quad(lambda b: (0.3 + 0.01 * b) * lambert_phase_function(b) * np.sin(b), 0, np.pi)[0]
    assert alb.bond_albedo(beta, p) == pytest.approx(exact, rel=1e-12)


def test_analytic_sweep_recovers_bond_albedo():
    # Consistency check, not physics: the lunar terms are calibrated with the same transport
    # that made the fluxes, so any fluxes give back the input 0.3 (an algebraic identity up to
    # the Bond quadrature). Bar: 0.3000 ± 0.0003 for the Lambert, SHG and DHG Moons.
    res = run_sweep(ResolvedScene())
    for b in ("lambert", "shg", "dhg"):
        assert res["bond_albedo"][b]["analytic"] == pytest.approx(0.3, abs=3e-4)
    rows = [r for r in res["rows"] if r["theta_deg"] == 0.0]
    assert all(np.isnan(r["apparent_albedo"]) for r in rows)  # 0/0 at full Moon, handled


def test_inversion_recovers_a_different_true_albedo():
    # Consistency check: fluxes from an Earth of albedo 0.22, lunar terms from the model's 0.3
    # Earth: the inversion must return 0.22 (earthshine is linear in the Earth's albedo)
    for theta in (40.0, 100.0, 160.0):
        sc = SceneGeometry(theta)
        lam = {"dhg": __import__("lunarviz.photometry.brdf", fromlist=["x"]).make_brdf("dhg")}
        true = analytic_irradiance(sc, lam, AnalyticSettings(earth_albedo=0.22))["dhg"]
        cal = analytic_irradiance(sc, lam)["dhg"]
        terms = alb.lunar_terms(sc, cal.earthshine_W_m2, cal.moonshine_W_m2, 0.3)
        pe = alb.geometric_albedo_term(sc, true.earthshine_W_m2, true.moonshine_W_m2, terms)
        assert alb.apparent_albedo(sc.beta_deg, pe) == pytest.approx(0.22, rel=1e-10)


def test_inversion_measures_a_non_spherical_earth():
    # Physics, not algebra: the earthshine of a ray-traced *oblate* Earth mesh (flattening 0.2
    # along x, ⟂ to the Sun and the Moon at θ = 90°), inverted with lunar terms calibrated on
    # the model sphere, must give p* = 0.3 × (the oblate Earth's Lambert phase integral over
    # the sphere's), 0.7615 by independent parametric quadrature (tests/test_meshes.py).
    # Budget 1.5 %: the beams over the mesh's bounding cone (order 24) and the far-field ratio.
    import sys
    from pathlib import Path
    sys.path.insert(0, str(Path(__file__).parent))
    import tempfile

    import independent as ind

    from lunarviz import constants as C
    from lunarviz.bodies import shapes
    from lunarviz.workflows.sweeps import run_phase
    x, n, w = ind.ellipsoid_surface(0.8, 1.0, 1.0, n=300)
    xs, ns, ws = ind.ellipsoid_surface(1.0, 1.0, 1.0, n=300)
    far = lambda n, w: np.sum(np.clip(n @ [0, 0, -1.0], 0, None) * np.clip(n @ [0, 1.0, 0], 0, None) * w)
    ratio = far(n, w) / far(ns, ws)
    with tempfile.TemporaryDirectory() as d:
        Re = C.R_EARTH_M
        path = str(Path(d) / "oblate_earth.ply")
        shapes.write_mesh(shapes.ellipsoid(0.8 * Re, Re, Re, level=5), path)
        s = ResolvedScene(brdfs=("lambert",), phases_deg=(90.0,), method="raytrace", earth_mesh=path,
                          earth_order=24, moon_level=3, occlusion=False)
        row = run_phase(s, 90.0)[0]
    assert row["apparent_albedo"] == pytest.approx(0.3 * ratio, rel=1.5e-2)


def test_printed_eq8_biases_the_inversion_by_three_halves():
    res = run_sweep(ResolvedScene(earth_law="paper_eq8", brdfs=("lambert",)))
    assert res["bond_albedo"]["lambert"]["analytic"] == pytest.approx(0.45, abs=5e-4)


def test_no_measurable_moonshine_gives_undefined_apparent_albedo():
    # new Moon: the ray tracer's moonshine is round-off (~1e-18 W m⁻²); Eq. 15 must not turn
    # that into a number (it would bias the Bond integral through its β ≈ 0 weight)
    sc = SceneGeometry(180.0)
    tiny = alb.LunarTerms(pa_fa=0.1, pb_fb=1e-15)
    assert np.isnan(alb.geometric_albedo_term(sc, 1e-8, 1e-18, tiny))
    ok = alb.LunarTerms(pa_fa=0.1, pb_fb=1e-4)
    assert np.isfinite(alb.geometric_albedo_term(sc, 1e-8, 1e-7, ok))
