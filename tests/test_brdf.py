"""Lunar BRDFs against an independent, textbook implementation and physical properties."""

import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import IntegrationWarning, quad

from lunarviz.photometry import brdf as B

DEG = np.pi / 180


# ---- an independent Hapke implementation, written straight from the papers ------------------
def h_chandrasekhar_integral(mu, w):
    """Exact H (isotropic) from Chandrasekhar's integral representation (1960, Eq. V.(44)):
    ln H(μ) = -(μ/π) ∫₀^{π/2} ln(1 - w θ cot θ) / (cos²θ + μ² sin²θ) dθ."""
    if mu == 0:
        return 1.0
    f = lambda t: np.log(1 - w * t / np.tan(t)) / (np.cos(t) ** 2 + mu**2 * np.sin(t) ** 2) if t > 0 else np.log(1 - w)
    with warnings.catch_warnings():
        # quad flags round-off at its 1e-13 target; the comparison below is the real check
        warnings.simplefilter("ignore", IntegrationWarning)
        v, _ = quad(f, 0, np.pi / 2, epsabs=1e-14, epsrel=1e-13, limit=400)
    return np.exp(-mu / np.pi * v)


def textbook_hapke(i, e, psi, w, h, B0, phase, hfun):
    mu0, mu = np.cos(i), np.cos(e)
    cg = np.cos(i) * np.cos(e) + np.sin(i) * np.sin(e) * np.cos(psi)
    g = np.arccos(np.clip(cg, -1, 1))
    Bg = B0 / (1 + np.tan(g / 2) / h)
    if phase[0] == "shg":
        xi = phase[1]
        p = (1 - xi**2) / (1 + 2 * xi * np.cos(g) + xi**2) ** 1.5
    else:
        b, c, conv = phase[1:]
        fwd = (1 - b**2) / (1 + 2 * b * np.cos(g) + b**2) ** 1.5
        bwd = (1 - b**2) / (1 - 2 * b * np.cos(g) + b**2) ** 1.5
        p = (1 + c) / 2 * fwd + (1 - c) / 2 * bwd if conv == "paper" else (1 + c) / 2 * bwd + (1 - c) / 2 * fwd
    gam = np.sqrt(1 - w)
    if hfun == "hapke1981":
        H = lambda x: (1 + 2 * x) / (1 + 2 * gam * x)
    elif hfun == "hapke2002":
        r0 = (1 - gam) / (1 + gam)
        H = lambda x: 1 / (1 - w * x * (r0 + (1 - 2 * r0 * x) / 2 * np.log((1 + x) / x)))
    else:
        H = lambda x: h_chandrasekhar_integral(x, w)
    return w / (4 * np.pi) / (mu0 + mu) * ((1 + Bg) * p + H(mu0) * H(mu) - 1)


ANGLES = [(75, 0, 0), (75, 40, 0), (75, 60, 180), (30, 45, 90), (10, 70, 135), (60, 60, 10), (85, 20, 180)]
#: Tolerance against the textbook form: both are float64 with no approximation beyond the
#: quadrature in the exact H (quad to 1e-13), and the textbook form's arccos(cos g) costs
#: ~1e-10 relative away from g = 0, so 1e-9 is far inside the required 1e-6 bar.
TEXTBOOK_REL = 1e-9


@pytest.mark.parametrize("hfun", B.H_FUNCTIONS)
@pytest.mark.parametrize("conv", B.DHG_CONVENTIONS)
def test_dhg_matches_textbook(hfun, conv):
    m = B.make_brdf("dhg", dhg_convention=conv, h_function=hfun)
    for i, e, psi in ANGLES:
        got = B.brdf_from_angles(m, i * DEG, e * DEG, psi * DEG)
        want = textbook_hapke(i * DEG, e * DEG, psi * DEG, 0.33, 0.017, 1.0, ("dhg", 0.308, 0.425, conv), hfun)
        assert got == pytest.approx(want, rel=TEXTBOOK_REL)


@pytest.mark.parametrize("hfun", B.H_FUNCTIONS)
def test_shg_matches_textbook(hfun):
    m = B.make_brdf("shg", h_function=hfun)
    for i, e, psi in ANGLES:
        got = B.brdf_from_angles(m, i * DEG, e * DEG, psi * DEG)
        want = textbook_hapke(i * DEG, e * DEG, psi * DEG, 0.33, 0.017, 1.0, ("shg", -0.075), hfun)
        assert got == pytest.approx(want, rel=TEXTBOOK_REL)


@pytest.mark.parametrize("w", [0.01, 0.33, 0.9, 0.999999])
def test_exact_h_matches_integral_representation(w):
    for mu in [0.0, 1e-6, 1e-3, 0.1, 0.5, 1.0]:
        assert B.h_exact(mu, w) == pytest.approx(h_chandrasekhar_integral(mu, w), rel=1e-10)


def test_exact_h_conservative_known_value():
    # H(1) = 2.9078 for w = 1 (Chandrasekhar 1960, Table XI)
    assert B.h_exact(1.0, 1.0) == pytest.approx(2.9078, abs=1e-4)
    assert B.h_exact(0.0, 1.0) == pytest.approx(1.0, abs=1e-12)


def test_lambert_is_albedo_over_pi():
    m = B.make_brdf("lambert")
    assert B.brdf_from_angles(m, 0.3, 0.7, 1.0) == pytest.approx(0.10 / np.pi)
    assert B.directional_hemispherical_reflectance(m, 0.6) == pytest.approx(0.10, rel=1e-12)


@pytest.mark.parametrize("name", ["shg", "dhg"])
@pytest.mark.parametrize("hfun", B.H_FUNCTIONS)
def test_reciprocity(name, hfun, rng):
    m = B.make_brdf(name, h_function=hfun)
    i, e, psi = rng.uniform(0, 89, 50) * DEG, rng.uniform(0, 89, 50) * DEG, rng.uniform(0, 360, 50) * DEG
    assert np.allclose(B.brdf_from_angles(m, i, e, psi), B.brdf_from_angles(m, e, i, psi), rtol=1e-13)


@pytest.mark.parametrize("name", ["shg", "dhg"])
@pytest.mark.parametrize("hfun", B.H_FUNCTIONS)
def test_directional_hemispherical_reflectance_below_one(name, hfun):
    m = B.make_brdf(name, h_function=hfun)
    for i in (0, 30, 60, 75, 89):
        r = B.directional_hemispherical_reflectance(m, np.cos(i * DEG))
        assert 0 < r < 1


def test_conservative_lambert_limit_of_dhr():
    # w = 1, isotropic phase (c = 0, b = 0), no surge: energy conservation makes the
    # directional-hemispherical reflectance exactly 1 with the exact H-function
    # (Chandrasekhar 1960; a classic check of H). Quadrature error of the 64-point rule ~1e-4.
    m = B.make_brdf("dhg", h_function="exact", params={"w": 1.0, "b": 0.0, "c": 0.0, "B0": 0.0})
    assert B.directional_hemispherical_reflectance(m, 0.5, n=128) == pytest.approx(1.0, abs=1e-3)


def test_dhg_mirror_relation():
    # P_hapke2012(g; b, c) = P_paper(π - g; b, c) = P_paper(g; b, -c)   (NOTES.md item 2)
    g = np.linspace(0, np.pi, 181)
    s, c = np.sin(g / 2), np.cos(g / 2)
    paper = B.DoubleHG(0.308, 0.425, "paper")
    h12 = B.DoubleHG(0.308, 0.425, "hapke2012")
    assert np.allclose(h12(s, c), paper(c, s), rtol=1e-14)  # π - g swaps the half angles
    assert np.allclose(h12(s, c), B.DoubleHG(0.308, -0.425, "paper")(s, c), rtol=1e-14)
    # and the conventions differ a lot for the paper's parameters (tens of percent at g = 0)
    assert h12(0.0, 1.0) / paper(0.0, 1.0) > 1.3


@pytest.mark.parametrize("phase", [B.SingleHG(-0.075), B.SingleHG(0.6), B.DoubleHG(0.308, 0.425),
                                   B.DoubleHG(0.9, -0.7, "hapke2012")])
def test_phase_functions_normalised(phase):
    # (1/4π) ∫ p dΩ = (1/2) ∫₀^π p(g) sin g dg = 1
    val, _ = quad(lambda g: phase(np.sin(g / 2), np.cos(g / 2)) * np.sin(g) / 2, 0, np.pi,
                  epsabs=1e-12, limit=400)
    assert val == pytest.approx(1.0, abs=1e-9)


def test_half_angle_precision_near_opposition():
    # g = 1e-9 rad between i = e and a tiny azimuth: the surge B(g) must see it
    s, c = B.half_angle_from_angles(0.5, 0.5 + 2e-9, 0.0)
    assert 2 * np.arctan2(s, c) == pytest.approx(2e-9, rel=1e-6)


@pytest.mark.parametrize("bad", [dict(w=1.5), dict(w=-0.1), dict(h=-1), dict(B0=-0.5), dict(b=1.0),
                                 dict(c=1.5), dict(xi=-1.0), dict(albedo=2)])
def test_parameter_validation_names_the_parameter(bad):
    name = next(iter(bad))
    model = {"xi": "shg", "albedo": "lambert"}.get(name, "dhg")
    with pytest.raises(ValueError, match=rf"{name}=.*allowed range"):
        B.make_brdf(model, params=bad)


def test_unknown_names_rejected():
    with pytest.raises(ValueError, match="unknown BRDF 'foo'"):
        B.make_brdf("foo")
    with pytest.raises(ValueError, match="H-function 'bogus'"):
        B.make_brdf("dhg", h_function="bogus")
    with pytest.raises(ValueError, match="convention 'x'"):
        B.make_brdf("dhg", dhg_convention="x")
    with pytest.raises(ValueError, match="unknown parameter 'xi'"):
        B.make_brdf("dhg", params={"xi": 0.1})


# ---- finiteness over the whole valid parameter space (NOTES.md numerics; stress) -----
unit_interval = st.floats(0.0, 1.0)
angles = st.sampled_from([0.0, 1e-12, 0.3, 1.0, np.pi / 2 - 1e-12, np.pi / 2])


@settings(max_examples=300, deadline=None)
@given(w=unit_interval, h=st.floats(0.0, 10.0), B0=st.floats(0.0, 10.0),
       b=st.floats(0.0, 1.0, exclude_max=True), c=st.floats(-1.0, 1.0),
       xi=st.floats(-1.0, 1.0, exclude_min=True, exclude_max=True),
       i=angles, e=angles, psi=st.sampled_from([0.0, 1e-9, np.pi / 2, np.pi]),
       hfun=st.sampled_from(B.H_FUNCTIONS), conv=st.sampled_from(B.DHG_CONVENTIONS),
       single=st.booleans())
def test_finite_everywhere(w, h, B0, b, c, xi, i, e, psi, hfun, conv, single):
    phase = B.SingleHG(xi) if single else B.DoubleHG(b, c, conv)
    m = B.Hapke(w=w, h=h, B0=B0, phase=phase, h_function=hfun)
    s, cc = B.half_angle_from_angles(i, e, psi)
    rf = m.radiance_factor(np.cos(i), np.cos(e), s, cc)
    f = m.brdf(np.cos(i), np.cos(e), s, cc)
    assert np.isfinite(rf) and rf >= 0
    assert np.isfinite(f) and f >= 0


def test_limits_h_to_zero_and_b_to_one():
    s, c = B.half_angle_from_angles(0.5, 0.6, 0.0)  # g = 0.1 rad
    surge = [B.Hapke(h=h).surge(s, c) for h in (1e-3, 1e-6, 1e-9, 0.0)]
    assert surge[-1] == 0.0 and all(np.diff(surge) <= 0)  # decreases monotonically to 0
    # b → 1: the lobe sharpens but stays finite away from its peak and at it
    for b in (0.9, 0.999, 1 - 1e-9):
        p = B.DoubleHG(b, 0.0)
        assert np.isfinite(p(0.0, 1.0)) and np.isfinite(p(1.0, 0.0))
