"""A mapped Earth (land, ocean, clouds): the map-cell reference against the exact Lambert-sphere
rule, the tracer's per-facet sums against both, and the bound its rows report."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lunarviz.methods import accuracy
from lunarviz.methods.analytic import lunar_surface_rule
from lunarviz.methods.map_cell_reference import cell_radiances, earth_cells, exact_unit_earthshine
from lunarviz.methods.tracer.estimators import TraceScene
from lunarviz.methods.transport import Transport, detector_geometry
from lunarviz.scene import ResolvedScene
from lunarviz.surfaces.maps import map_frame
from lunarviz.workflows.sweeps import run_phase

SITE = "site:34.26,-116.92,2067"


def _lunar_points(sc, order=5):
    """The exact reference's outer rule over the lunar sphere the Earth lights, seen by the detector."""
    x, n, dA = lunar_surface_rule(sc, sc.earth, sc.radii["earth"], order)
    mu, geom, o = detector_geometry(x, n, dA, sc.det, sc.det_normal)
    geom = np.where(sc.sight_lines_clear(x), geom, 0.0)
    k = geom > 0
    return x[k], n[k], mu[k], geom[k], o[k]


def _exact_unit_earthshine(sc, pts, brdfs, order=24):
    """The earthshine of an Earth of albedo 1 at the points: the exact reference's product rule
    about the zero-phase point, cut along the kinks (lunarviz.methods.sources; its own tests: the
    closed-form area of two caps, tests/test_zero_phase_rule.py)."""
    x, n, mu, geom, o = pts
    return exact_unit_earthshine(sc, x, n, o, mu, geom, brdfs, order)


@pytest.fixture(scope="module")
def thin_crescent():
    """θ = 20° of the paper's scene: the Earth a thin crescent seen from the Moon, its light along
    the limb and the terminator (where the tracer's per-facet sums erred most)."""
    s = ResolvedScene(method="raytrace", phases_deg=(20.0,), brdfs=("lambert", "dhg"), earth_surface="landocean",
                      clouds="zonal")
    sc = s.geometry(20.0)
    pts = _lunar_points(sc)
    return s, sc, pts, _exact_unit_earthshine(sc, pts, s.brdf_models())


def test_map_cell_reference_of_a_white_earth_is_the_exact_sphere_rule(thin_crescent):
    # an Earth of albedo 1 on 0.5° cells (split near the terminator and the limb): the centre rule
    # errs as the cells' second moments, ~(0.5°)² times the integrand's curvature (measured 2e-6
    # here, 5e-7 at the land mask's 0.1° cells two by two); tolerance 1e-5
    s, sc, pts, exact = thin_crescent
    x, n, mu, geom, o = pts
    cen, wts = earth_cells(sc, lambda d: np.ones(len(d)), (360, 720), np.eye(3))
    got = cell_radiances(sc, x, n, o, mu, cen, wts, s.brdf_models())
    for k in exact:
        assert float(got[k][:, 0] @ geom) == pytest.approx(exact[k], rel=1e-5)


def test_map_cell_weights_are_the_map_integrated_over_the_lit_earth():
    # a map of value 1 north of the equator and 0 south (cells aligned with the grid): the cells'
    # weights of the two halves add up to those of the white Earth, and each is its own share
    s = ResolvedScene(method="raytrace", phases_deg=(90.0,))
    sc = s.geometry(90.0)
    frame = map_frame(sc, "earth")  # (the θ scene's: the Sun on the Earth's equator)
    _, w1 = earth_cells(sc, lambda d: np.ones(len(d)), (180, 360), frame)
    _, wh = earth_cells(sc, lambda d: np.stack([d[:, 2] > 0, d[:, 2] <= 0], 1).astype(float), (180, 360), frame)
    assert wh.sum() == pytest.approx(w1.sum(), rel=1e-12)
    # (the Sun on the equator lights the two halves alike: they differ by the cells' rounding)
    assert wh[:, 0].sum() == pytest.approx(wh[:, 1].sum(), rel=1e-3)


def test_traced_mapped_earth_of_a_thin_crescent_meets_the_exact_sphere_rule(thin_crescent):
    # the tracer's per-facet sums (level 6), their albedo-1 part, against the exact rule: Lambert
    # within 5e-6 (measured 1.9e-6, 1.5e-6 along each cell's centre alone; 4.5e-5 before the facets
    # along the limb were split and the elements near it summed per lunar point, 1.1e-4 with the
    # first-order expansion about the Moon's centre); DHG within 5e-6 too (each cell's light along
    # its four points; measured 1.9e-6; along each cell's centre alone it erred by 2.8e-5 here)
    s, sc, pts, exact = thin_crescent
    x, n, mu, geom, o = pts
    ts = TraceScene(sc, s.trace_settings(threads=1))
    tr = ts.mapped_earth.transport(x, n, o, mu, geom)
    brdfs = s.brdf_models()
    got = {k: float(tr.radiances(b)[1] @ geom) for k, b in brdfs.items()}
    assert got["lambert"] == pytest.approx(exact["lambert"], rel=5e-6)
    assert got["dhg"] == pytest.approx(exact["dhg"], rel=5e-6)
    eps = accuracy.mapped_earth_epsilon(6, s.earth_model(), hapke=True, theta_deg=20.0)
    assert abs(got["dhg"] / exact["dhg"] - 1) <= eps["albedo 1"]


def test_traced_mapped_earth_under_the_opposition_surge_meets_the_exact_sphere_rule():
    # θ = 160° of the paper's scene: the lit Earth's disc nearest zero phase seen from the Moon,
    # where the Hapke surge curves the BRDF most across each cell of the disc. Along each cell's
    # centre alone, an Earth of albedo 1 erred by 8.2e-5 under DHG at every Earth level (the
    # mapped Earth's error model); along its four points (their mean and spread the cell's light's)
    # measured 3.5e-6 (SHG 3.5e-6, Lambert 3e-7): bar 1e-5, with room for the lunar points' spread
    s = ResolvedScene(method="raytrace", phases_deg=(160.0,), brdfs=("lambert", "shg", "dhg"),
                      earth_surface="landocean", clouds="zonal")
    sc = s.geometry(160.0)
    pts = _lunar_points(sc)
    x, n, mu, geom, o = pts
    brdfs = s.brdf_models()
    exact = _exact_unit_earthshine(sc, pts, brdfs)
    tr = TraceScene(sc, s.trace_settings(threads=1)).mapped_earth.transport(x, n, o, mu, geom)
    got = {k: float(tr.radiances(b)[1] @ geom) for k, b in brdfs.items()}
    for k in brdfs:
        assert got[k] == pytest.approx(exact[k], rel=1e-5)


def test_traced_mapped_earth_takes_embree_for_the_moons_shadow_on_the_earth():
    # the mapped Earth's light at the solar eclipse of 2026-08-12 (the Moon's shadow on the
    # Earth): which facets see the Sun past the Moon is traced with Embree. Told that the Moon
    # blocks nothing, the shadowed facets light up and the earthshine rises
    s = ResolvedScene(method="raytrace", times=("2026-08-12T17:46:00Z",), observer="geocentre",
                      earth_surface="landocean", brdfs=("lambert",))
    sc = s.geometry(s.times[0])
    x, n, mu, geom, o = _lunar_points(sc, 3)
    lam = s.brdf_models()["lambert"]
    ts = TraceScene(sc, s.trace_settings(threads=1))
    assert ts.sampling.moon_shadow_on_earth_possible()
    traced = float(ts.mapped_earth.transport(x, n, o, mu, geom).radiances(lam)[0] @ geom)
    stub = TraceScene(sc, s.trace_settings(threads=1))
    stub.bodies.moon.occluded = lambda origins, dirs, *a, **k: np.zeros(len(origins), dtype=bool)
    free = float(stub.mapped_earth.transport(x, n, o, mu, geom).radiances(lam)[0] @ geom)
    assert ts.sources.sun_visibility_of_earth().min() < 0.5  # (the umbra on some facets)
    assert 0 < traced < free * (1 - 1e-6)


def test_the_bound_takes_the_components_errors_about_the_best_reference_albedo():
    # made-up ε: albedo 1 errs by 1e-5, two components by 1e-4 each with opposite signs (they
    # cancel in their sum); albedos 0.2 and 0.3; I₁ = 1, E = 0.25. About ᾱ = 0: 0.2e-4 + 0.3e-4 =
    # 5e-5; about ᾱ = 0.2: 0.2e-5 + 0.1e-4 = 1.2e-5; about 0.3: 0.3e-5 + 0.1e-4 = 1.3e-5. The
    # bound is SAFETY × 1.2e-5 / 0.25
    eps = {"albedo 1": 1e-5, "a": 1e-4, "b": 1e-4}
    got = accuracy.mapped_earth_error(eps, {"a": 0.2, "b": 0.3}, 1.0, 0.25)
    assert got == pytest.approx(accuracy.SAFETY * 1.2e-5 / 0.25, rel=1e-12)
    assert math.isnan(accuracy.mapped_earth_error(eps, {"a": 0.2, "b": 0.3}, 1.0, 0.0))
    # no Earthlight at all: nothing to err by
    assert accuracy.mapped_earth_error(eps, {"a": 0.2, "b": 0.3}, 0.0, 0.0) == 0.0


def test_mapped_earth_rows_carry_their_models_bound_or_say_why():
    s = ResolvedScene(method="raytrace", times=("2026-02-20T03:00:00Z",), observer=SITE, brdfs=("lambert", "dhg"),
                      earth_surface="landocean", clouds="zonal", moon_model="paper")
    rows = run_phase(s, s.times[0])
    for r in rows:
        assert 0 < r["rtol"] < 1e-3 and r["no_bound_reason"] == ""
    # Lambert's ε are smaller than the Hapke BRDFs' (the disc cells' one direction each)
    by = {r["brdf"]: r["rtol"] for r in rows}
    assert by["lambert"] <= by["dhg"]
    # a level the model did not measure (it measured 4-7; a coarse level is as unmeasured as a
    # fine one, and traces in a fraction of the time): NaN and why
    r = run_phase(s.replace(earth_level=3), s.times[0])[0]
    assert math.isnan(r["rtol"]) and "mapped Earth at this Earth level" in r["no_bound_reason"]


def test_mapped_earth_rows_outside_the_models_phases_or_by_monte_carlo():
    from lunarviz.errors import LooseRowsWarning
    from lunarviz.workflows.sweeps import run_sweep
    # θ = 5°: a thinner crescent than the model's dates (10-170°): NaN and why
    s = ResolvedScene(method="raytrace", phases_deg=(5.0,), brdfs=("lambert",), earth_surface="landocean",
                      clouds="zonal")
    r = run_phase(s, 5.0)[0]
    assert math.isnan(r["rtol"]) and "outside theta = 10-170" in r["no_bound_reason"]
    # Monte Carlo over a mapped Earth: its own two standard errors (the model is the deterministic sums')
    mc = s.replace(estimator="montecarlo", rays=2000, runs=2, phases_deg=(60.0,))
    r = run_phase(mc, 60.0)[0]
    assert 0 < r["rtol"] == pytest.approx(2 * max(r["moonshine_std_W_m2"] / r["moonshine_W_m2"],
                                                  r["earthshine_std_W_m2"] / r["earthshine_W_m2"]) / math.sqrt(2))
    # a mapped run whose rows' bounds exceed the tolerance says so once (a level-4 Earth: its
    # components err by up to 8.7e-5 of an albedo-1 Earth, the model); a uniform Earth's coarse
    # facets (their bound foreseen by the plan) do not raise it
    with pytest.warns(LooseRowsWarning, match="mapped Earth"):
        run_sweep(s.replace(phases_deg=(60.0,), brdfs=("dhg",), earth_level=4), workers=1)
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("error", LooseRowsWarning)
        run_sweep(ResolvedScene(method="raytrace", phases_deg=(60.0,), brdfs=("lambert",), moon_level=3), workers=1)
        # the default level 6 meets the default tolerance on a Hapke Moon (its fields' model: each
        # component ≤ 1.1e-5: θ = 60° 9.3e-5; the facets' means, ≤ 7.4e-5, gave it 1.47e-4), and
        # so at θ = 165° does the band of 160-170° (its own dates: a table with θ = 10° too gave 1.2e-4)
        rows = run_sweep(s.replace(phases_deg=(60.0, 165.0), brdfs=("dhg",)), workers=1)["rows"]
        assert all(0 < r["rtol"] <= 1e-4 for r in rows), [r["rtol"] for r in rows]


def _components_against_map_cells(s, sc, pts, bar):
    """Each component of ``s``'s map, traced, against the map's own cells (as a share of an albedo-1
    Earth's earthshine): the largest difference over components and BRDFs, which must be ≤ ``bar``."""
    from lunarviz.surfaces.earth_spectra import components, weights_at
    x, n, mu, geom, o = pts
    surf = s.earth_model()
    names = components(surf)
    cen, wts = earth_cells(sc, lambda d: np.concatenate([np.ones((len(d), 1)), weights_at(surf, d)], 1),
                           (1800, 3600), map_frame(sc, "earth", 0.0), group=2)
    brdfs = s.brdf_models()
    ref = {k: geom @ L for k, L in cell_radiances(sc, x, n, o, mu, cen, wts, brdfs).items()}
    ts = TraceScene(sc, s.trace_settings(threads=1))
    ts.surfaces.earth_parts = names
    tr = ts.mapped_earth.transport(x, n, o, mu, geom)
    for c, name in enumerate(names):
        part = Transport(mu0=tr.mu0, sin_hg=tr.sin_hg, cos_hg=tr.cos_hg, e_beam=tr.e_beam_parts[name], mu=tr.mu,
                         geom=tr.geom)
        for k, b in brdfs.items():
            got = float(part.radiances(b)[0] @ geom)
            assert abs(got - ref[k][1 + c]) <= bar * ref[k][0], (name, k, got / ref[k][1 + c] - 1)
    return ts


def test_traced_map_components_of_a_thin_crescent_meet_the_map_cell_reference(thin_crescent):
    # each component of the land-ocean map with zonal clouds (ocean, vegetation, desert, snow,
    # cloud), traced at level 6, against the map's own cells (lunarviz.methods.map_cell_reference,
    # which shares neither the mesh nor its samples), as a share of an albedo-1 Earth's
    # earthshine. The facets' linear fields (576 points a facet) measured ≤ 3.3e-6 here; the
    # facets' means (81 points) erred by 7.4e-5 (vegetation) at this θ, half of it their
    # sampling noise and half a coastline's light put at its facet's centre: bar 2e-5
    s, sc, pts, _ = thin_crescent
    _components_against_map_cells(s, sc, pts, 2e-5)


def test_a_dated_mapped_earth_turns_with_the_earth_and_still_meets_the_map_cells():
    """On dates the mapped Earth's tessellation turns with the Earth (its facets' fields fitted once
    in its own frame, turned into the sky's): a crescent from Big Bear (θ = 30°, 2026-03-01T03:00Z),
    each component against the map's own cells as above: measured 2.5e-6 to 3e-6; bar 6e-6, twice
    that and under half what the fields' gradients left in the Earth's own axes (not turned into
    the sky's) err by, 1.3e-5 to 1.6e-5."""
    s = ResolvedScene(method="raytrace", times=("2026-03-01T03:00:00Z",), observer=SITE, brdfs=("lambert", "dhg"),
                      earth_surface="landocean", clouds="zonal", moon_model="paper")
    sc = s.geometry(s.times[0])
    ts = _components_against_map_cells(s, sc, _lunar_points(sc), 6e-6)
    E = ts.bodies.earth
    assert E.rotation is not None and np.array_equal(E.rotation, map_frame(sc, "earth", 0.0))
