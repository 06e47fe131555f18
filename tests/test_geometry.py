import numpy as np
import pytest

from lunarviz.geometry.scene_geometry import SceneGeometry, angle_between, half_angle_sin_cos, unit


def test_angle_between_is_accurate_near_zero_and_pi():
    # A 1e-12 rad angle: arccos(cos g) would return 0 (cos g rounds to 1); Kahan's form keeps it.
    a = np.array([1.0, 0.0, 0.0])
    b = np.array([np.cos(1e-12), np.sin(1e-12), 0.0])
    assert angle_between(a, b) == pytest.approx(1e-12, rel=1e-6)
    assert angle_between(a, -b) == pytest.approx(np.pi - 1e-12, abs=1e-15)


def test_half_angle_identities():
    s, c = half_angle_sin_cos(unit(np.array([1.0, 0, 0])), unit(np.array([0.0, 1, 0])))
    assert s == pytest.approx(np.sin(np.pi / 4)) and c == pytest.approx(np.cos(np.pi / 4))


@pytest.mark.parametrize("theta", [0.0, 5.0, 90.0, 175.0, 180.0])
def test_angles_from_vectors(theta):
    sc = SceneGeometry(theta)
    # β is the Sun-Earth-Moon angle: exactly 180 - θ in the Eq. 3 frame
    assert sc.beta_deg == pytest.approx(180.0 - theta, abs=1e-9)
    assert sc.theta_from_vectors_deg == pytest.approx(theta, abs=1e-9)
    # α differs from θ by the solar parallax, at most asin(D_EM/D_SE) ≈ 0.146°
    assert abs(sc.alpha_deg - theta) <= np.degrees(np.arcsin(sc.d_em / sc.d_se)) + 1e-9


def test_detector_elsewhere_and_bad_scene():
    sc = SceneGeometry(90, detector=(7e6, 0, 0))
    assert np.allclose(sc.det, [7e6, 0, 0])
    assert not sc.detector_inside("earth")
    assert SceneGeometry(90).detector_inside("earth")
    with pytest.raises(ValueError, match="r_moon"):
        SceneGeometry(90, r_moon=-1)
    with pytest.raises(ValueError, match="theta"):
        SceneGeometry(float("nan"))
