"""The extended-source reference: limits and self-convergence."""

import pytest

from lunarviz.geometry.scene_geometry import SceneGeometry
from lunarviz.methods.analytic import analytic_irradiance
from lunarviz.methods.reference import ReferenceSettings, reference_irradiance


@pytest.mark.parametrize("theta", [30.0, 150.0])
def test_reference_tends_to_point_sources_as_radii_shrink(theta, paper_brdfs):
    # Shrinking the Sun and the Earth (keeping Φ and the Earth's intensity law) must recover the
    # point-source analytic method. The earthshine difference is first order in the Earth's
    # angular radius ρ over the surge width h (B(g) has a cusp at g = 0): 1.2e-3 at 1e-2 of the
    # real radius, 1.2e-5 at 1e-4 for the Hapke Moons; 2e-5 allows for that.
    sc = SceneGeometry(theta, r_sun=6.957e8 * 1e-4, r_earth=6.378e6 * 1e-4)
    ref = reference_irradiance(sc, paper_brdfs, ReferenceSettings(24, 6))
    pt = analytic_irradiance(sc, paper_brdfs)
    for k in paper_brdfs:
        assert ref[k].moonshine_W_m2 == pytest.approx(pt[k].moonshine_W_m2, rel=1e-6)
        assert ref[k].earthshine_W_m2 == pytest.approx(pt[k].earthshine_W_m2, rel=2e-5)


@pytest.mark.parametrize("theta", [5.0, 90.0, 175.0])
def test_reference_self_converged(theta, paper_brdfs):
    sc = SceneGeometry(theta)
    a = reference_irradiance(sc, paper_brdfs, ReferenceSettings(24, 8))
    b = reference_irradiance(sc, paper_brdfs, ReferenceSettings(32, 12))
    for k in paper_brdfs:
        assert a[k].moonshine_W_m2 == pytest.approx(b[k].moonshine_W_m2, rel=1e-5)
        assert a[k].earthshine_W_m2 == pytest.approx(b[k].earthshine_W_m2, rel=1e-5)


def test_extended_earth_differs_from_point_for_hapke(paper_brdfs):
    # The opposition surge (h = 0.017 rad) varies across the 0.95°-radius Earth: the
    # extended Earth gives noticeably less Hapke earthshine than a point (NOTES.md), while a
    # Lambert Moon sees only the small finite-distance effect.
    sc = SceneGeometry(90.0)
    ref = reference_irradiance(sc, paper_brdfs, ReferenceSettings(16, 6), paths=("earthshine",))
    pt = analytic_irradiance(sc, paper_brdfs)
    assert abs(ref["lambert"].earthshine_W_m2 / pt["lambert"].earthshine_W_m2 - 1) < 0.02
    for k in ("shg", "dhg"):
        assert ref[k].earthshine_W_m2 / pt[k].earthshine_W_m2 < 0.93
