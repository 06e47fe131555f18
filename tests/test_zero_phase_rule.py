"""The Earth's beam rule about the zero-phase point (a detector off the Earth's centre): its
graded t-segments, and the tracer's beams that meet the Earth where the rule's nodes are."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from lunarviz.geometry.scene_geometry import unit
from lunarviz.geometry.sphere_quadrature import cap_rule
from lunarviz.methods import sources
from lunarviz.methods.tracer import ray_kernels
from lunarviz.methods.tracer.trace_scene import TraceScene
from lunarviz.scene import ResolvedScene

ORBIT = "orbit:550,97.6,0,0"


def cap_intersection_area(a: float, b: float, d: float) -> float:
    """Solid angle of the intersection of two caps of angular radii a, b whose centres are d
    apart, partly overlapping (Tovchigrechko & Vakser 2001, Proteins 44, eq. for two spherical
    caps; checked here against 4·10⁶ Monte Carlo directions to its 1σ of 3e-3 sr)."""
    ca, cb, cd, sa, sb, sd = np.cos(a), np.cos(b), np.cos(d), np.sin(a), np.sin(b), np.sin(d)
    return 2 * (np.pi - np.arccos((cd - ca * cb) / (sa * sb)) - ca * np.arccos((cb - cd * ca) / (sd * sa))
                - cb * np.arccos((ca - cd * cb) / (sd * sb)))


def _crescent_about_a_night_pole():
    """The Earth seen from the Moon's sub-Earth point at θ = 11° from Paranal (2026-02-01T03:00Z),
    on the Earth's unit sphere: the visible cap (about the sub-Moon point), the lit cap (about the
    sub-Sun point) and the zero-phase pole on the night side, 0.885 rad from the first centre.
    Rings about that pole cross the crescent's horns 0.0023 rad and 0.0010 rad from rings
    tangent to the terminator."""
    s = ResolvedScene(observer="site:-24.63,-70.40,2635", times=("2026-02-01T03:00:00Z",))
    sc = s.geometry(s.times[0])
    c, R = sc.earth, sc.radii["earth"]
    x = (sc.moon + sc.radii["moon"] * unit(c - sc.moon))[None]
    pole = sources.zero_phase_points(sc, x)
    d_x, d_s = np.linalg.norm(x[0] - c), np.linalg.norm(sc.sun - c)
    cu = np.stack([unit(x[0] - c), unit(sc.sun - c)])[None]
    cc = np.array([[R / d_x, R / d_s]])
    a, b = np.arccos(cc[0])
    return pole, cu, cc, (a, b, np.arccos(cu[0, 0] @ cu[0, 1]))


@pytest.mark.parametrize("order, tol", [(6, 1e-5), (10, 1e-7)])
def test_graded_rule_meets_the_closed_form_area_of_a_crescent_about_an_off_centre_pole(order, tol):
    """The rule's solid angle against the closed form: graded, order 6 errs by 5.4e-6 and 10 by
    3.3e-8 (measured; tolerances 2-3x above). The plain rule, whose rings next to the horns see a
    near-singular √|t - t*|, errs by 9.0e-4 at order 10 (only algebraic convergence)."""
    pole, cu, cc, (a, b, d) = _crescent_about_a_night_pole()
    exact = cap_intersection_area(a, b, d)
    _, w = cap_rule(pole, np.full(1, -1.0), cu, cc, n_t=order, n_phi=order, crossings=True, graded=True)
    assert abs(w.sum() / exact - 1) < tol
    _, w_plain = cap_rule(pole, np.full(1, -1.0), cu, cc, n_t=order, n_phi=order, crossings=True)
    assert abs(w_plain.sum() / exact - 1) > 100 * abs(w.sum() / exact - 1)


def test_graded_rule_converges_where_the_plain_rule_stalls():
    """Refinement never worse: on the crescent the graded rule's error falls with the order
    (5.4e-6, 3.3e-8, 2.5e-10 at 6, 10, 14: measured), each below the one before."""
    pole, cu, cc, (a, b, d) = _crescent_about_a_night_pole()
    exact = cap_intersection_area(a, b, d)
    errs = [abs(cap_rule(pole, np.full(1, -1.0), cu, cc, n_t=o, n_phi=o, crossings=True, graded=True)[1].sum()
                / exact - 1) for o in (6, 10, 14)]
    assert errs[0] > errs[1] > errs[2]


def _lunar_points(sc, k=12):
    """k points of the Moon's sphere within 60° of the sub-Earth point, their normals."""
    rng = np.random.default_rng(3)
    to_e = unit(sc.earth - sc.moon)
    n = unit(to_e + 0.8 * rng.normal(size=(k, 3)))
    n = n[n @ to_e > 0.5]
    return sc.moon + sc.radii["moon"] * n, n


@pytest.mark.parametrize("compiled", [True, False])
def test_traced_earth_beams_bring_the_light_of_the_rule_nodes_on_a_thin_crescent(monkeypatch, compiled):
    """On 2026-01-03T05:00Z from a 550 km orbit the Earth seen from the Moon is a 5° crescent:
    its light lies next to the limb. Each Earth beam the tracer sends through Embree must bring
    the radiance of its rule node (the exact sphere hit from the lunar point itself): the sum over
    the rule's nodes of L·mu0·dΩ, computed without rays, within rounding (3e-10 measured: the
    hit found again along a unit direction, near grazing; 1e-8 allowed). Rays lifted
    0.17 m off the surface and refined from there grazed the limb ~1.5 km off their nodes, or
    missed it: 2e-5 low, at every Earth order. With Embree's answers all misses, the traced
    irradiance is zero (the rays are load-bearing)."""
    if not compiled:
        monkeypatch.setattr(ray_kernels, "available", lambda: False)
    s = ResolvedScene(method="raytrace", brdfs=("lambert",), observer=ORBIT, times=("2026-01-03T05:00:00Z",))
    sc = s.geometry(s.times[0])
    st = replace(s.trace_settings(1, s.trace_plan(sc.theta_deg)), earth_pole="detector")
    ts = TraceScene(sc, st)
    x, n = _lunar_points(sc)
    assert not sources.horizon_cuts_source(sc, x, n, "earth").any()
    o = unit(sc.det - x)
    ones = np.ones(len(x))
    tr = ts.deterministic.beam_transport(x, n, o, ones, ones, "earth", 10)
    traced = (tr.e_beam * tr.mu0).sum(axis=1)
    m, w = sources.source_sphere_rule(sc, x, n, "earth", 10, horizon=False, pole=sources.zero_phase_points(sc, x))
    y, om, omega = sources.source_beams(sc, x, "earth", m, w)
    L = sources.earth_radiance(sc, y, m, st.earth_albedo)
    direct = (L * omega * np.clip(np.einsum("bkj,bj->bk", om, n), 0.0, None)).sum(axis=1)
    assert direct.min() > 0
    np.testing.assert_allclose(traced, direct, rtol=1e-8)
    monkeypatch.setattr(type(ts.earth), "run_rays", lambda self, o32, d32, q, dists=None, scene=None:
                        np.full(len(o32), -1, dtype=np.int64))
    dark = ts.deterministic.beam_transport(x, n, o, ones, ones, "earth", 10)
    assert not np.any(dark.e_beam)


def test_kink_cuts_lie_on_the_kinks_and_leave_the_region_whole():
    """The two split-only caps of the cut rule (:func:`sources.roughness_kink_cuts`): the first's
    boundary lies in the plane of the lunar normal and the detector's direction through the lunar
    point (ψ = 0 or π), the second's passes through the zero-phase point where i = e (both to
    rounding, 1e-12); cutting along them leaves the region itself whole: the cut and plain rules
    integrate the Earth's Lambertian light alike (both converged: 1e-12 measured, 1e-9 allowed)."""
    s = ResolvedScene(observer=ORBIT, times=("2026-11-18T07:00:00Z",))
    sc = s.geometry(s.times[0])
    x, n = _lunar_points(sc)
    pole = sources.zero_phase_points(sc, x)
    (p, cp), (q, cq) = sources.roughness_kink_cuts(sc, x, n, pole)
    c, R = sc.earth, sc.radii["earth"]
    o = unit(sc.det - x)
    # points of the first boundary: the circle m·p = cp on the unit sphere
    e1 = unit(np.cross(p, pole))
    e2 = np.cross(p, e1)
    r = np.sqrt(1 - cp**2)
    for ang in (0.3, 1.7, 4.0):
        m = cp[:, None] * p + r[:, None] * (np.cos(ang) * e1 + np.sin(ang) * e2)
        v = c + R * m - x
        assert np.allclose(np.einsum("ij,ij->i", v, np.cross(n, o)) / np.linalg.norm(v, axis=1), 0, atol=1e-12)
    assert np.allclose(np.einsum("ij,ij->i", pole, q), cq, atol=1e-12)
    y = c + R * pole
    cos_i = np.einsum("ij,ij->i", unit(y - x), n)
    hit = np.linalg.norm(np.cross(unit(y - x), o), axis=1) < 1e-9  # (the line through the detector meets the Earth)
    assert hit.any() and np.allclose(cos_i[hit], np.einsum("ij,ij->i", o, n)[hit], atol=1e-9)

    def light(cuts):
        m, w = sources.source_sphere_rule(sc, x, n, "earth", 14, horizon=False, pole=pole, roughness_cuts=cuts)
        yy, om, omega = sources.source_beams(sc, x, "earth", m, w)
        L = sources.earth_radiance(sc, yy, m, 0.3)
        return (L * omega * np.clip(np.einsum("bkj,bj->bk", om, n), 0.0, None)).sum(axis=1)
    np.testing.assert_allclose(light(True), light(False), rtol=1e-9)


def test_graded_rule_after_a_split_grades_toward_the_closer_tangent_ring():
    """Three caps and a pole where a segment tangent at its start and nearly so past its end is
    cut in two: the upper half has the far tangent ring (the old start) about its own length
    below and a close one 8e-4 rad above. Graded toward the far one it erred by 9.2e-6 at order
    16; toward the closer, the rule meets the region's solid angle to rounding (1e-14 measured,
    1e-11 allowed). The reference: the plain rule about the first cap's centre (another pole,
    whose orders 100 and 140 agree to 1e-12)."""
    u = np.array([[0.240807156230047, -0.01448386961572132, 0.9704649045840621],
                  [0.7219883526728091, -0.20868310048018357, -0.6596849112862756],
                  [-0.7953930199891183, -0.5965437414429579, -0.10717046373804508]])
    c = np.array([-0.4896992336773893, -0.2511594409845841, -0.25448019567804514])
    pole = np.array([[-0.05530757374573775, 0.10824663421489285, -0.9925843734753771]])
    _, w_ref = cap_rule(u[:1], c[:1], u[None, 1:], c[None, 1:], n_t=140, n_phi=140, crossings=True)
    for order in (16, 24):
        _, w = cap_rule(pole, np.full(1, -1.0), u[None], c[None], n_t=order, n_phi=order, crossings=True, graded=True)
        assert abs(w.sum() / w_ref.sum() - 1) < 1e-11


def test_a_tolerance_takes_the_cheaper_rule_that_meets_it(monkeypatch):
    """``off_centre_earth_rule``: of the plain and cut rules, the smallest order of each whose
    measured error meets the limit, the one that took less time; the more accurate where neither
    meets it; the plain rule's fallback orders without tables. Tables made up here (not the
    measured ones), so each branch is decided by construction."""
    from lunarviz.methods import accuracy
    plain = {"orders": [7, 10], "max_rel_error": {"paper": {"7": 1e-4, "10": 1e-5}},
             "seconds": {"paper": {"7": 0.1, "10": 0.2}}}
    cut = {"orders": [5, 7], "max_rel_error": {"paper": {"5": 5e-5, "7": 1e-6}},
           "seconds": {"paper": {"5": 0.3, "7": 0.5}}}
    monkeypatch.setattr(accuracy, "error_models",
                        lambda: {"earth_rule_off_centre": plain, "earth_rule_off_centre_cut": cut})
    assert accuracy.off_centre_earth_rule(2e-4, False) == (7, False)   # both meet it: plain 7 is cheaper
    assert accuracy.off_centre_earth_rule(6e-5, False) == (10, False)  # plain 10 (0.2 s) before cut 5 (0.3 s)
    assert accuracy.off_centre_earth_rule(5e-6, False) == (7, True)    # only the cut rule meets it
    assert accuracy.off_centre_earth_rule(1e-9, False) == (7, True)    # none: the more accurate
    monkeypatch.setattr(accuracy, "error_models", lambda: {})
    assert accuracy.off_centre_earth_rule(1e-4, False) == (max(accuracy.DEFAULT_EARTH_ORDERS), False)


def _horizon_band_earthlight(pole: str, label: str = "2026-05-10T00:00:00Z", orbit: str = ORBIT):
    """``earthlight(order, asked=None, summed=True)``: (Σ L μ0 dΩ per sample, beams) of the Earth's
    rule about the zero-phase point (``pole``: ``detector`` or ``detector-cut``) at eight lunar
    samples whose horizon cuts the Earth (0.3 of its angular radius below the plane through the
    Moon's centre facing it), ``asked`` the band's order (``None``: the rule's own choice)."""
    s = ResolvedScene(method="raytrace", brdfs=("dhg",), observer=orbit, times=(label,))
    sc = s.geometry(label)
    st = replace(s.trace_settings(1, s.trace_plan(sc.theta_deg)), earth_pole=pole)
    to_e = unit(sc.earth - sc.moon)
    e1 = unit(np.cross(to_e, [0.3, 0.5, 0.8]))
    ang = np.linspace(0, 2 * np.pi, 9)[:-1, None]
    rho = sc.radii["earth"] / np.linalg.norm(sc.earth - sc.moon)
    n = unit(np.sin(0.3 * rho) * to_e + np.cos(0.3 * rho) * (np.cos(ang) * e1 + np.sin(ang) * np.cross(to_e, e1)))
    x = sc.moon + sc.radii["moon"] * n
    assert sources.horizon_cuts_source(sc, x, n, "earth").all()
    o, ones = unit(sc.det - x), np.ones(len(x))

    def earthlight(order, asked=None, summed=True):
        ts = TraceScene(sc, replace(st, earth_horizon_order=asked))
        ts.sampling.summed = summed  # (as trace_path sets it for a row's sum)
        tr = ts.deterministic.beam_transport(x, n, o, ones, ones, "earth", order)
        return (tr.e_beam * tr.mu0).sum(axis=1), np.count_nonzero(tr.e_beam)
    return earthlight


def test_lunar_samples_whose_horizon_cuts_the_earth_take_a_coarser_rule_that_refines_with_the_order():
    """Samples whose horizon cuts the Earth (the earthlight's penumbra band: 0.3 of the Earth's
    angular radius below the plane through the Moon's centre facing the Earth, at 2026-05-10T00:00Z
    from orbit, θ = 91°) take the zero-phase rule at :func:`horizon_band_order` of the row's
    order where they are summed into a row (the same beams as asking for that order there), and
    the full order where each is shaded for itself (per-facet arrays, images). Their earthlight (Σ L μ0 dΩ, traced)
    against the rule at order 24 errs by 2.0e-2, 4.7e-4 and 4.5e-7 at row orders 12, 21 and 30
    (measured; band orders 4, 7 and 10; a third of the one before is allowed): refining the
    Earth's order refines these samples too. At order 14 the band takes order 5 with under a
    third of the full order's beams: the band holds at most 3.4e-4 of a Hapke row's earthshine
    from an orbit or a site, so the row moves by up to ~2e-5 (measured: 1.8e-5 over the year's
    hourly orbit dates at order 12), inside its bound (~1e-4, from the error model measured with
    this rule)."""
    from lunarviz.methods.tracer.settings import HORIZON_CUT_LEAST_ORDER, horizon_band_order
    earthlight = _horizon_band_earthlight("detector")
    ref = earthlight(24, 24)[0]
    # per-facet arrays and images shade each sample for itself: the full order
    np.testing.assert_array_equal(earthlight(14, summed=False)[0], earthlight(14, 14)[0])
    assert [horizon_band_order(k) for k in (3, 8, 14, 20, 24)] == [3, HORIZON_CUT_LEAST_ORDER, 5, 7, 8]
    coarse, beams = earthlight(14)
    same, same_beams = earthlight(14, 5)
    np.testing.assert_array_equal(coarse, same)
    assert beams == same_beams < earthlight(14, 14)[1] / 3
    errs = [np.max(np.abs(earthlight(k)[0] / ref - 1)) for k in (12, 21, 30)]
    assert all(a > 3 * b for a, b in zip(errs, errs[1:])) and errs[-1] < 1e-6


def test_a_moon_partly_hidden_by_the_earths_limb_keeps_the_band_at_half_the_order():
    """A second before the Moon sets behind the Earth from the orbit at one epoch
    (2026-10-28T16:00:02Z, θ = 34°, 3.4 % of the Moon's diameter in sight, the lune rule cut where
    the view ends): what is left in sight lies near the lunar limb, where the band of samples whose
    horizon cuts the Earth is, so that band carries more of the row. With the band at order 4 the
    plain rule at order 12 erred by 7.4e-5 against the cut rule at order 24 (SHG), beyond twice its
    table (3.5e-5: the factor a row's bound takes); with the band at half the order, as a cut view
    takes it, 4.6e-5 (measured). Bar: twice the table; it sits between the two."""
    from lunarviz.methods import accuracy
    from lunarviz.methods.tracer.estimators import trace_path
    from lunarviz.methods.tracer.settings import horizon_band_order
    assert [horizon_band_order(k, view_cut=True) for k in (4, 8, 12, 14)] == [4, 6, 6, 7]
    label = "2026-10-28T16:00:02Z"
    s = ResolvedScene(method="raytrace", brdfs=("lambert", "shg", "dhg"), moon_model="paper", rtol=1e-4,
                      observer=ORBIT + ",2026-01-01T00:00Z", times=(label,))
    sc = s.geometry(label)
    base = s.trace_settings(1, s.trace_plan(sc.theta_deg))
    assert base.earth_pole == "detector" and base.earth_order == 12

    def earthshine(order, pole, band=None):
        pair = None if base.lune_source_orders is None else (base.lune_source_orders[0], order)
        st = replace(base, earth_pole=pole, earth_order=order, earth_horizon_order=band, lune_source_orders=pair)
        ts = TraceScene(sc, st)
        return trace_path(ts, "earthshine", s.brdf_models()).mean, ts
    ref = earthshine(24, "detector-cut", 24)[0]
    got, ts = earthshine(12, "detector")
    assert ts.sampling.edges_found("earth")
    err = max(abs(got[k] / ref[k] - 1) for k in ref)
    assert err < accuracy.SAFETY * accuracy.off_centre_earth_error(12, False, False)


def test_the_rule_cut_along_the_kinks_keeps_its_full_order_where_the_horizon_cuts_the_earth():
    """The rule cut along the roughness's kinks (taken where a tolerance asks for more than the
    plain rule's orders give) traces the samples whose horizon cuts the Earth at its own order:
    with that band at order 6, as the plain rule takes it, rows from a 550 km orbit on
    2026-05-18T13:00Z (θ = 155°, the paper's Moon) stayed ~1e-6 off the rule at order 24 for cut
    orders 7, 8 and 10 alike, beyond the cut rule's error model at order 10 (1.3e-7 measured with
    the band at order 6, 5.6e-8 with this rule; scripts/off_centre_earth_model.py). Here, eight
    such samples (2026-05-10T00:00Z, as above): the same beams as asking for the order there, and
    their earthlight within 1e-8 of order 24 at order 10
    (measured 1.1e-11; with the band at order 6, 1.9e-6, which fails: the bar sits between,
    well above rounding)."""
    from lunarviz.methods.tracer.settings import horizon_band_order
    assert [horizon_band_order(k, cut=True) for k in (4, 8, 14)] == [4, 8, 14]
    earthlight = _horizon_band_earthlight("detector-cut")
    ref = earthlight(24, 24)[0]
    full, beams = earthlight(10)
    same, same_beams = earthlight(10, 10)
    np.testing.assert_array_equal(full, same)
    assert beams == same_beams
    assert np.max(np.abs(full / ref - 1)) < 1e-8
