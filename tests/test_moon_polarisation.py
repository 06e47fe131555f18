"""The Moon's polarised light (lunarviz.photometry.moon_polarisation, ``sweep --stokes``).

References, written here apart from the package:

* LIME's coefficients as its file holds them (``LIME_MODEL_COEFS_20251010_V01.nc``, variables
  ``dolp_coeff_neg``/``dolp_coeff_pos``, 440 and 675 nm columns), evaluated as its toolbox does: the
  quintic at the *signed* phase (negative before full Moon). This checks the packaged table's
  branches and its rewriting of the waxing polynomial in |g|.
* Published whole-Moon polarimetry, for the model's physics rather than its digits: Lyot (1929,
  thesis, Ann. Obs. Meudon 8; summarised by the Observatoire de Paris): the polarisation plane
  turns below about 30° of phase (the negative branch), and the disc's maximum near the quarters
  is 66 per mille waxing and 88 per mille waning (visual), the waning Moon's maria polarising more.
* The bright limb's position angle from right ascension and declination (Meeus 1998,
  *Astronomical Algorithms*, Eq. 48.5), a different construction from the package's projection.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import lunarviz
from lunarviz.errors import LunarvizError, UnpolarisedRowsWarning
from lunarviz.photometry import moon_polarisation as mp

# dolp_coeff_neg / dolp_coeff_pos of LIME_MODEL_COEFS_20251010_V01.nc, a0..a5, as stored there
LIME_NEG = {440: (2.87792066e-03, 2.38522593e-03, 1.50563090e-04, 3.00444216e-06, 2.76409324e-08, 9.62701573e-11),
            675: (1.06366966e-03, 1.96817091e-03, 1.24189125e-04, 2.48675023e-06, 2.23972506e-08, 7.56512059e-11)}
LIME_POS = {440: (2.74066487e-03, -2.33776924e-03, 1.56357272e-04, -3.28719962e-06, 3.40411063e-08, -1.37341862e-10),
            675: (1.43541349e-03, -2.01755992e-03, 1.33481862e-04, -2.78402921e-06, 2.74315671e-08, -1.04263549e-10)}


def lime(signed_phase, wavelength):
    """The toolbox's P: the positive (waning) polynomial for a positive phase, else the negative one."""
    a = LIME_POS[wavelength] if signed_phase > 0 else LIME_NEG[wavelength]
    return sum(c * signed_phase ** i for i, c in enumerate(a))


@pytest.mark.parametrize("wavelength", [440, 675])
@pytest.mark.parametrize("phase", [2.0, 10.0, 23.0, 45.0, 75.0, 90.0])
def test_table_is_lime(wavelength, phase):
    """The packaged rows give LIME's polynomial for both branches (to the 9 digits copied)."""
    assert mp.disc_polarisation(phase, wavelength, "waxing") == pytest.approx(lime(-phase, wavelength), rel=1e-7,
                                                                               abs=1e-10)
    assert mp.disc_polarisation(phase, wavelength, "waning") == pytest.approx(lime(phase, wavelength), rel=1e-7,
                                                                               abs=1e-10)


def test_range_and_interpolation():
    """NaN outside 2-90° and 350-1640 nm; linear in λ between nodes; the mean branch their mean."""
    assert np.isnan(mp.disc_polarisation([1.9, 90.1], 550, "waning")).all()
    assert np.isnan(mp.disc_polarisation(45, [349.0, 1641.0], "waning")).all()
    mid = mp.disc_polarisation(60, 0.5 * (440 + 500), "waxing")
    ends = mp.disc_polarisation(60, [440, 500], "waxing")
    assert mid == pytest.approx(0.5 * (ends[0] + ends[1]))
    both = mp.disc_polarisation(60, 550, "waxing") + mp.disc_polarisation(60, 550, "waning")
    assert mp.disc_polarisation(60, 550, "mean") == pytest.approx(0.5 * both)
    with pytest.raises(ValueError, match="branch"):
        mp.disc_polarisation(60, 550, "full")


def test_published_features():
    """Against the Moon's observed polarisation (Lyot 1929), as a check of the physics the table carries:

    * a negative branch near opposition that turns positive below 30° (the inversion angle);
    * the waning disc more polarised than the waxing one: Lyot's ratio at the quarters is 88/66 =
      1.33; the model's at 90° must lie within 1.15-1.55 (historical visual polarimetry, and the
      quarter's phase angle not exactly 90°);
    * the maxima's size: Lyot's visual 6.6 % and 8.8 %; the model at 550 nm within 35 % of them (LIME's
      photometer calibration against a visual polarimeter of 1929: a check of the quantity and its units,
      not a precision test; the model is 24-26 % lower).
    * bluer light more polarised (Umov's law: the Moon is darker in the blue)."""
    g = np.arange(2.0, 30.01, 0.25)
    for branch in ("waxing", "waning"):
        for lam in (440, 550, 675, 870):
            p = mp.disc_polarisation(g, lam, branch)
            assert p[g == 10.0] < 0
            sign_change = g[1:][np.diff(np.sign(p)) > 0]
            assert len(sign_change) == 1 and 18.0 < sign_change[0] < 30.0
    wax, wan = mp.disc_polarisation(90, 550, "waxing"), mp.disc_polarisation(90, 550, "waning")
    assert 1.15 < wan / wax < 1.55
    assert abs(wax / 0.066 - 1) < 0.35 and abs(wan / 0.088 - 1) < 0.35
    p = mp.disc_polarisation(90, [440, 500, 675], "waning")
    assert p[0] > p[1] > p[2]


def test_sweep_rows_carry_the_disc_polarisation():
    """Spectral rows: Q = −P I in the scattering plane's frame, U = 0, DoLP |P|, AoLP 90° (positive
    branch) or 0° (negative); the intensities identical to a run without --stokes."""
    kw = dict(method="analytic", phases=[60, 170], wavelengths="440,675", brdfs=("dhg",))
    with pytest.warns(UnpolarisedRowsWarning, match="2 of 4 rows"):
        ds = lunarviz.sweep(stokes=True, **kw)
    plain = lunarviz.sweep(**kw)
    assert "moonshine_Q" not in plain and "scattering_plane_position_angle" not in ds
    np.testing.assert_array_equal(ds["moonshine"].values, plain["moonshine"].values)
    alpha = float(ds["alpha"].values[0])
    for j, lam in enumerate((440, 675)):
        p = 0.5 * (lime(alpha, lam) + lime(-alpha, lam))  # the θ scene: the mean of the branches
        i = float(ds["moonshine"].values[0, 0, j])
        assert float(ds["moonshine_Q"].values[0, 0, j]) == pytest.approx(-p * i, rel=1e-6)
        assert float(ds["moonshine_U"].values[0, 0, j]) == 0.0
        assert float(ds["moonshine_dolp"].values[0, 0, j]) == pytest.approx(abs(p), rel=1e-6)
        assert float(ds["moonshine_aolp"].values[0, 0, j]) == 90.0
    assert np.isnan(ds["moonshine_dolp"].values[0, 1]).all()  # θ = 170°: beyond the model's 90°


def test_band_is_moonshine_weighted():
    """A band's Q is ∫ −P(λ) E(λ) S(λ) dλ: its P lies between the band's extreme node values and
    near the mid-band value (the V band, 470-700 nm: P is linear in λ between nodes, so the weighted
    mean is P at the band's effective wavelength, within ~10 nm of 550 nm: 1 %; measured 0.1 %)."""
    ds = lunarviz.sweep(method="analytic", phases=[45], bands="V", brdfs=("lambert",), stokes=True)
    alpha = float(ds["alpha"].values[0])
    p_band = float(ds["moonshine_dolp"].values[0, 0, 0])
    p_edges = mp.disc_polarisation(alpha, [470.0, 700.0], "mean")
    assert min(p_edges) < p_band < max(p_edges)
    assert p_band == pytest.approx(float(mp.disc_polarisation(alpha, 550.0, "mean")), rel=0.01)


def test_dated_rows_take_their_branch_and_sky_angle():
    """A waxing and a waning date: each row's P is its branch's (LIME's signed phase), and the
    scattering plane's position angle is the bright limb's of Meeus Eq. 48.5 from RA and Dec."""
    from lunarviz.sky.dated_scene import sky_scene
    from lunarviz.sky.observers import Observer
    times = ("2026-03-01T05:00Z", "2026-03-06T11:00Z")  # before and after the full Moon of 2026-03-03
    ds = lunarviz.sweep(method="analytic", time=list(times), wavelengths="675", brdfs=("lambert",), stokes=True)
    for t, sign in zip(range(2), (-1, 1)):
        g = float(ds["phase_angle"].values[t])
        assert float(ds["moonshine_dolp"].values[0, t, 0]) == pytest.approx(abs(lime(sign * g, 675)), rel=1e-6)
    for t, label in enumerate(times):
        sc, _ = sky_scene(label, Observer())

        def ra_dec(v):
            v = v / np.linalg.norm(v)
            return math.atan2(v[1], v[0]), math.asin(v[2])
        (a_m, d_m), (a_s, d_s) = ra_dec(sc.moon - sc.det), ra_dec(sc.sun - sc.det)
        da = a_s - a_m
        chi = math.degrees(math.atan2(math.cos(d_s) * math.sin(da),
                                      math.sin(d_s) * math.cos(d_m) - math.cos(d_s) * math.sin(d_m) * math.cos(da)))
        got = float(ds["scattering_plane_position_angle"].values[t])
        assert (got - chi + 180.0) % 360.0 - 180.0 == pytest.approx(0.0, abs=1e-9)


def test_skipped_rows_and_refusals():
    """A Moon below the horizon: Q = U = 0 and no degree of polarisation; a grey run refuses --stokes."""
    rows = lunarviz.run(method="raytrace", time="2026-03-10T05:00Z", observer="site:34.26,-116.92,2067",
                        wavelengths="550", brdfs=("lambert",), stokes=True)["rows"]
    assert rows[0]["skip_reason"] and rows[0]["moonshine_Q_W_m2_nm"] == 0.0 and math.isnan(rows[0]["moonshine_dolp"])
    with pytest.raises(LunarvizError, match="stokes needs wavelengths or band"):
        lunarviz.sweep(method="analytic", phases=[60], stokes=True)
    with pytest.raises(LunarvizError, match="image has no Stokes output"):
        lunarviz.image(phases=[45], bands="V", stokes=True, pixels=(16, 16))


def test_mirror_scenes_agree():
    """The θ scene at θ and 360° − θ is one scene mirrored in its plane: the same Stokes rows."""
    ds = lunarviz.sweep(method="analytic", phases=[45, 315], bands="V", brdfs=("dhg",), stokes=True)
    for name in ("moonshine", "moonshine_Q", "moonshine_dolp"):
        v = ds[name].values[0, :, 0]
        assert v[1] == pytest.approx(v[0], rel=1e-12)
    assert (ds["moonshine_U"].values == 0).all()
