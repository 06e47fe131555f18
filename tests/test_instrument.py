"""The measurement: instruments, frames in counts, the pipeline, the error budget and planning.

Independent references: photon statistics (a Poisson count's variance is its mean, read noise
adds σ², rounding to integers adds 1/12 ADU²; checked with χ² bounds from scipy), the
published V-band zero point in photons (≈ 1000 photons s⁻¹ cm⁻² Å⁻¹ for V = 0: Bessell, Castelli
& Plez 1998 give 3.631e-9 erg cm⁻² s⁻¹ Å⁻¹ at 5448 Å; the sky model is built from the energy
form), the sweep's p* (disk-integrated transport, a different code path from the camera and
the pipeline's patches), and coverage over seeds.

The instrument ``SMALL`` is salex on a 128 × 128 detector of 52 µm pixels (26.8″): the Moon
spans 70 pixels, enough for patches, and an image (one ray per pixel) takes a fraction of a second.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest
from scipy import stats

from lunarviz.api import Scene
from lunarviz.errors import LunarvizError
from lunarviz.instrument.detector import expected_counts, frames
from lunarviz.instrument.pipeline import measure
from lunarviz.instrument.spec import instrument_from_dict, load_instrument
from lunarviz.workflows.measurement import observation as observe
from lunarviz.workflows.measurement import observation_calibration, plan, simulate, sweep_p_star

SMALL = replace(load_instrument("salex"), width=128, height=128, pixel_size_um=52.0, supersample=1)
#: an exposure that leaves SMALL's brightest pixel (behind its mask) below the full well at 120°
SMALL_EXPOSURE_S = 0.002
#: the required bar for a noise-free measurement against the sweep's p*
NOISELESS_TOLERANCE = 1e-3


def run_cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "lunarviz", *args], capture_output=True, text=True, cwd=cwd)


#: the module's tests share module fixtures: they run on one worker (pytest-xdist's loadgroup)
pytestmark = pytest.mark.xdist_group("test_instrument")


@pytest.fixture(scope="module")
def small_observation():
    settings = Scene([120.0], brdfs="dhg").settings("raytrace")
    obs = observe(settings, 120.0, SMALL, SMALL_EXPOSURE_S)
    return settings, obs, observation_calibration(settings, 120.0, SMALL, obs)


def test_presets_load_and_state_their_sources():
    for name in ("salex", "bbso"):
        inst = load_instrument(name)
        assert inst.source and inst.description
        assert 0 < inst.fov_deg < 2 and inst.collecting_area_m2 > 0
    assert load_instrument("bbso").atmosphere is not None
    assert load_instrument("salex").atmosphere is None


@pytest.mark.parametrize("change, named", [({"gain_e_per_adu": -1}, "gain_e_per_adu"), ({"width": 3}, "width"),
                                           ({"band": "nope"}, "nope"), ({"gian": 1}, "gian"),
                                           ({"quantum_efficiency": [[500, 0.5], [600, 0.5]]}, "quantum_efficiency"),
                                           ({"bright_side_nd": 0}, "bright_side_nd"),
                                           ({"bias_adu": 70000}, "bias_adu"),
                                           # each crashed later with a traceback
                                           ({"quantum_efficiency": [[300, 0.0], [900, 0.0]]}, "quantum_efficiency"),
                                           ({"dark_current_e_per_s": 1e300}, "dark_current_e_per_s"),
                                           ({"aperture_m": 1000}, "aperture_m"),
                                           ({"halo": "1,3"}, "halo"), ({"psf": "gaussian:-1"}, "psf")])
def test_bad_instrument_values_are_refused_by_name(change, named):
    d = {**load_instrument("salex").to_dict(), **change}
    with pytest.raises(LunarvizError, match=named):
        instrument_from_dict(d)


def test_an_instrument_round_trips_through_its_dict():
    for name in ("salex", "bbso"):
        inst = load_instrument(name)
        assert instrument_from_dict(inst.to_dict()) == inst


def test_counts_have_poisson_plus_read_noise_statistics():
    # g (COUNTS − EXPECTED) has mean 0 and variance N + σ_r² + g²/12 per pixel (Poisson charge,
    # Gaussian read noise, rounding): pooled χ² over 64 × 64 pixels × 200 frames of charges from
    # 0 to 20,000 e-; bounds at the 1e-4 two-sided level of the χ² distribution
    inst = load_instrument("salex")
    rng = np.random.default_rng(0)
    electrons = rng.uniform(0, 20_000, (64, 64))
    electrons[:8] = 0.0  # read-noise-only pixels
    exp = expected_counts(electrons, inst)
    n = 200
    res = np.stack([(f.astype(float) - exp) * inst.gain_e_per_adu for f in frames(electrons, inst, n, seed=11)])
    var = electrons + inst.read_noise_e**2 + inst.gain_e_per_adu**2 / 12
    chi2 = float(np.sum(res**2 / var))
    dof = res.size
    assert stats.chi2.ppf(1e-4, dof) < chi2 < stats.chi2.ppf(1 - 1e-4, dof)
    # the mean: |z| < 4 for the pooled standardised mean
    z = float(np.sum(res / np.sqrt(var)) / np.sqrt(dof))
    assert abs(z) < 4
    # per pixel over frames too (the dark rows alone: read noise is not Poisson)
    chi2_dark = float(np.sum(res[:, :8] ** 2 / var[:8]))
    assert stats.chi2.ppf(1e-4, res[:, :8].size) < chi2_dark < stats.chi2.ppf(1 - 1e-4, res[:, :8].size)


def test_frames_are_seeded_and_independent_of_their_number():
    inst = load_instrument("salex")
    e = np.full((16, 16), 100.0)
    a = list(frames(e, inst, 3, seed=5))
    b = list(frames(e, inst, 5, seed=5))
    assert all(np.array_equal(x, y) for x, y in zip(a, b))
    assert not np.array_equal(a[0], a[1])


def test_saturation_clips_at_the_full_well():
    inst = load_instrument("salex")
    e = np.full((8, 8), 10 * inst.full_well_e)
    f = next(frames(e, inst, 1, seed=0))
    assert np.all(f <= inst.saturate_adu + 5 * inst.read_noise_e / inst.gain_e_per_adu)
    assert np.all(expected_counts(e, inst) == inst.saturate_adu)


def test_noiseless_measurement_recovers_the_sweeps_p_star(small_observation):
    # the required bar (1e-3); measured 1.4e-6 at 120° (uniform Earth: the patch and the disk
    # see the same Earth). The sweep is a different code path: disk-integrated transport
    settings, obs, cal = small_observation
    row = measure(obs.expected_counts, 1, cal)
    truth = sweep_p_star(settings, 120.0, SMALL)
    assert row["p_star"] == pytest.approx(truth, rel=NOISELESS_TOLERANCE)
    # the halo is load-bearing: the patch without its removal reads the scattered crescent
    y_no_halo = replace(cal, kernel=None)
    biased = measure(obs.expected_counts, 1, y_no_halo)["p_star"]
    assert abs(biased / truth - 1) > 10 * NOISELESS_TOLERANCE


def test_noiseless_measurement_of_a_cloudy_land_ocean_earth():
    # a non-uniform, coloured Earth: the pipeline's calibration Earth (uniform, grey) differs from
    # the scene's, so this tests the inversion itself. Against the sweep in the instrument's
    # photon band (S·T·QE·λ, what counts weigh): measured 1.0e-4 at 120° (the required bar 1e-3).
    # The sweep in the band S alone (`lunarviz sweep --band V`) differs by 1.1e-3 from both: the
    # Earth's p*(λ) varies across V, and the two responses weigh it differently
    settings = Scene([120.0], brdfs="dhg", earth_surface="landocean", clouds="zonal", moon_level=3,
                     earth_level=5).settings("raytrace")
    obs = observe(settings, 120.0, SMALL, SMALL_EXPOSURE_S)
    cal = observation_calibration(settings, 120.0, SMALL, obs)
    truth = sweep_p_star(settings, 120.0, SMALL)
    assert abs(truth - 0.3) > 5e-3  # the scene's Earth is not the calibration's
    assert measure(obs.expected_counts, 1, cal)["p_star"] == pytest.approx(truth, rel=NOISELESS_TOLERANCE)
    srf = sweep_p_star(settings, 120.0, SMALL, photon=False)
    assert 3e-4 < abs(srf / truth - 1) < 3e-3


def test_stated_sigma_covers_the_truth_over_seeds():
    # 80 seeded measurements at 120°: standardised errors with mean 0 (|mean| < 4/sqrt(80) = 0.45)
    # and variance 1 (χ² bounds at 1e-3 two-sided)
    settings = Scene([120.0], brdfs="dhg").settings("raytrace")
    res = simulate(settings, 120.0, SMALL, 80, seed=3, exposure_s=SMALL_EXPOSURE_S)
    truth = res["summary"]["p_star_sweep"]
    z = np.array([(r["p_star"] - truth) / r["p_star_sigma"] for r in res["rows"]])
    assert abs(z.mean()) < 4 / np.sqrt(len(z))
    dof = len(z) - 1
    assert stats.chi2.ppf(1e-3, dof) / dof < z.var(ddof=1) < stats.chi2.ppf(1 - 1e-3, dof) / dof
    row = res["rows"][0]
    for k in ("sigma_photon", "sigma_read_dark", "sigma_halo_fit", "sigma_lunar_model", "sigma_ephemeris",
              "sigma_band", "sigma_halo_shape", "sigma_nd_filter", "p_star_U_k2"):
        assert np.isfinite(row[k]) and row[k] >= 0
    assert row["p_star_U_k2"] == pytest.approx(2 * np.hypot(row["p_star_sigma"], row["p_star_sigma_systematic"]))


def test_plan_reaches_its_snr_in_simulated_frames(small_observation):
    # the required bar: frames at the planned exposure reach the SNR within 10 %; the SNR of the
    # earthlit patch's mean is counted over 300 frames (its own scatter is 4 %)
    settings, _, cal = small_observation
    p = plan(settings, 120.0, SMALL, 30.0)
    assert p["feasible"] and p["snr_at_exposure"] == pytest.approx(30.0)
    obs = observe(settings, 120.0, SMALL, p["exposure_s"])
    E = cal.patches.earthlit
    vals = np.array([np.mean(f[E], dtype=float) for f in frames(obs.electrons, SMALL, 300, seed=2)])
    signal = p["earthlit_signal_e_s"] * p["exposure_s"]
    assert signal / (np.std(vals, ddof=1) * SMALL.gain_e_per_adu) == pytest.approx(30.0, rel=0.10)
    # nothing saturates at it
    assert obs.expected_counts.max() < SMALL.saturate_adu
    # a target beyond the full well's reach is refused with the frames that would reach it
    far = plan(settings, 120.0, SMALL, 1e5)
    assert not far["feasible"] and far["exposure_s"] is None and far["frames_needed_at_saturation_exposure"] > 1


def test_plan_per_pixel_reaches_its_snr_in_simulated_frames(small_observation):
    # per pixel: each earthlit pixel's earthshine charge over its own scatter across 300 frames
    # (pixel by pixel, then averaged over the patch: the mean of ~thousands of 4 %-scatter
    # estimates), against the target within 10 %; the patch SNR it reports is the patch's own
    settings, _, cal = small_observation
    p = plan(settings, 120.0, SMALL, 3.0, per="pixel")
    assert p["feasible"] and p["snr_pixel_at_exposure"] == pytest.approx(3.0)
    obs = observe(settings, 120.0, SMALL, p["exposure_s"])
    E = cal.patches.earthlit
    stack = np.array([f[E] for f in frames(obs.electrons, SMALL, 300, seed=5)], dtype=float) * SMALL.gain_e_per_adu
    signal = p["earthlit_signal_e_s"] * p["exposure_s"]
    assert np.mean(signal / np.std(stack, axis=0, ddof=1)) == pytest.approx(3.0, rel=0.10)
    patch = plan(settings, 120.0, SMALL, p["snr_patch_at_exposure"])
    assert patch["exposure_s"] == pytest.approx(p["exposure_s"], rel=1e-9)
    assert p["brightest_pixel_e"] == pytest.approx(p["brightest_pixel_e_s"] * p["exposure_s"])
    assert p["brightest_pixel_fraction_of_full_well"] == pytest.approx(p["brightest_pixel_e"] / SMALL.full_well_e)


def test_sky_model_in_photons_matches_the_v_band_zero_point():
    # a 21 mag/arcsec² sky through the bbso instrument's V band: the electrons per pixel from the
    # energy zero point (lunarviz) against 1000 photons s-1 cm-2 Å-1 at V = 0 times ∫ S T Q dλ
    # (Å); they differ by the V band's photon-vs-energy weighting (λ/λ_V across the band): 3 %
    from lunarviz.instrument.response import electron_rate, photon_band
    from lunarviz.instrument.sky_background import ARCSEC2_SR, site_sky
    inst = load_instrument("bbso")
    sky = site_sky(90.0, 0.0, 21.0)  # zenith, no extinction: the dark sky at its zenith value
    band = photon_band(inst)
    width = float(np.trapezoid(band.response, band.wavelength_nm))
    omega = (inst.scale_arcsec**2) * ARCSEC2_SR
    ours = float(electron_rate(np.array(sky.dark_sky_radiance_w_m2_sr_nm * width), np.array(omega), inst))
    from lunarviz.spectral.bands import parse_band
    srf = parse_band("V")
    lam = np.arange(460.0, 720.0)
    stq = srf.at(lam) * inst.throughput(lam)
    photons = 1000 * 10 ** (-0.4 * 21.0) * inst.collecting_area_m2 * 1e4 * inst.scale_arcsec**2 \
        * float(np.sum(stq)) * 10.0  # per Å: 1 nm steps of 10 Å
    assert ours == pytest.approx(photons, rel=0.05)


def test_ground_site_frames_carry_extinction_and_sky():
    # BBSO on 2026-03-25 03:30 UTC: the Moon at 61° altitude; the sky is a uniform pedestal, the
    # Moon is dimmed by 10^(-0.4 k X)
    settings = Scene(time="2026-03-25T03:30Z", observer="site:34.26,-116.92,2067", brdfs="dhg").settings("raytrace")
    inst = replace(load_instrument("bbso"), width=128, height=128, pixel_size_um=96.0)
    obs = observe(settings, "2026-03-25T03:30:00Z", inst, 1e-4)
    assert obs.sky is not None and 0.7 < obs.sky.transmission < 0.9
    assert np.ptp(obs.rates["sky"]) / obs.rates["sky"].mean() < 0.01 and obs.rates["sky"].mean() > 0
    cal = observation_calibration(settings, "2026-03-25T03:30:00Z", inst, obs)
    row = measure(obs.expected_counts, 1, cal)
    # the sky is fitted off the limb (in electrons per second) and the ratio is extinction-free
    assert row["sky_e_s"] == pytest.approx(obs.rates["sky"].mean(), rel=0.02)
    assert row["p_star"] == pytest.approx(0.3, rel=NOISELESS_TOLERANCE)


def test_cli_image_measure_and_plan(tmp_path):
    inst = tmp_path / "small.toml"
    d = SMALL.to_dict()
    lines = [f"{k} = {json.dumps(v)}" for k, v in d.items()]
    inst.write_text("\n".join(lines) + "\n")
    fits_path = tmp_path / "f.fits"
    r = run_cli("image", "--phase", "120", "--instrument", str(inst), "--exposure", str(SMALL_EXPOSURE_S),
                "--frames", "4", "--seed", "7", "--out", str(fits_path), "--quiet")
    assert r.returncode == 0, r.stderr
    from astropy.io import fits
    with fits.open(fits_path) as h:
        assert h["COUNTS"].data.shape == (4, 128, 128)
        assert h["EXPECTED_COUNTS"].data.shape == (128, 128)
        for k in ("GAIN", "RDNOISE", "EXPTIME", "DARKCUR", "BIASLEV", "SATURATE"):
            assert k in h["COUNTS"].header and k in h["EXPECTED_COUNTS"].header
        assert h["COUNTS"].header["EXPTIME"] == SMALL_EXPOSURE_S
        assert "MOONSHINE_V" in h and "EARTHSHINE_V" in h
    out = tmp_path / "m.json"
    r = run_cli("measure", str(fits_path), "--expected", "--out", str(out), "--quiet")
    assert r.returncode == 0, r.stderr
    assert json.loads(out.read_text())["rows"][0]["p_star"] == pytest.approx(0.3, rel=NOISELESS_TOLERANCE)
    # `lunarviz plan` from the command line: the measurement page's first block runs it; its file
    # gives image its instrument, exposure and θ
    plan_file = tmp_path / "plan.json"
    r = run_cli("plan", "--instrument", str(inst), "--snr", "2", "--snr-of", "pixel", "--phase", "120",
                "--out", str(plan_file))
    assert r.returncode == 0, r.stderr
    assert "pixel 2" in r.stdout and "full well" in r.stdout
    planned = json.loads(plan_file.read_text())
    r = run_cli("image", "--plan", str(plan_file), "--out", str(tmp_path / "p.fits"), "--quiet")
    assert r.returncode == 0, r.stderr
    with fits.open(tmp_path / "p.fits") as h:
        assert h["COUNTS"].header["EXPTIME"] == pytest.approx(planned["exposure_s"], rel=1e-12)
        assert h[0].header["THETA"] == 120.0
    r = run_cli("image", "--plan", str(plan_file), "--exposure", "1", "--out", str(tmp_path / "q.fits"))
    assert r.returncode == 2 and "differs from the plan" in r.stderr and not (tmp_path / "q.fits").exists()


@pytest.mark.parametrize("args, named", [
    (["image", "--phase", "120", "--instrument", "nope", "--out", "x.fits"], "nope"),
    (["image", "--phase", "120", "--instrument", "salex", "--pixels", "64", "--out", "x.fits"], "--pixels"),
    (["image", "--phase", "120", "--instrument", "salex", "--frames", "0", "--out", "x.fits"], "--frames"),
    (["image", "--phase", "120", "--instrument", "salex", "--exposure", "-1", "--out", "x.fits"], "--exposure"),
    (["image", "--phase", "120", "--instrument", "salex", "--out", "x.png"], "x.png"),
    (["image", "--phase", "120", "--exposure", "1", "--out", "x.fits"], "--exposure"),
    (["measure"], "FITS"),
    (["measure", "missing.fits"], "missing.fits"),
    (["measure", "--simulate", "3", "--phase", "120"], "--instrument"),
    (["plan", "--instrument", "salex", "--snr", "-3", "--phase", "120"], "--snr"),
    (["plan", "--instrument", "salex", "--snr", "100"], "--phase"),
    (["plan", "--instrument", "salex", "--snr", "1e-300", "--phase", "120"], "--snr"),
    (["image", "--phase", "120", "--instrument", "salex", "--exposure", "1e-300", "--out", "x.fits"], "--exposure"),
    (["image", "--plan", "missing.json", "--out", "x.fits"], "missing.json"),
    (["measure", "--plan", "missing.json"], "--plan"),
    (["measure", "--simulate", "3", "--instrument", "salex"], "--phase"),
])
def test_bad_measurement_inputs_are_one_line(tmp_path, args, named):
    r = run_cli(*args, cwd=tmp_path)
    assert r.returncode == 2
    assert len(r.stderr.strip().splitlines()) == 1 and named in r.stderr
    assert not any(tmp_path.iterdir())


def test_a_full_well_below_the_read_noise_margin_plans_nothing(small_observation):
    # a 30 e- well under 10 e- read noise has no safe exposure at all
    settings, _, _ = small_observation
    tiny = replace(SMALL, full_well_e=30.0, read_noise_e=10.0, bias_adu=100.0)
    p = plan(settings, 120.0, tiny, 100.0)
    assert not p["feasible"] and p["saturation_exposure_s"] == 0.0
    assert p["frames_needed_at_saturation_exposure"] is None


def test_a_damaged_file_is_one_line(tmp_path, small_observation):
    from astropy.io import fits

    from lunarviz.instrument.frames import append_counts
    from lunarviz.workflows.measurement import measure_file
    settings, obs, _ = small_observation
    path = tmp_path / "f.fits"
    fits.PrimaryHDU().writeto(path)
    append_counts(path, obs, 120.0, json.dumps(settings.to_dict()), 2, 0)
    with fits.open(path, mode="update") as h:
        h["EXPECTED_COUNTS"].header["LVKEY"] = "not a phase"
    with pytest.raises(LunarvizError, match="LVKEY"):
        measure_file(path)


def _frames_file(tmp_path, small_observation, name="f.fits", frames=2):
    from astropy.io import fits

    from lunarviz.instrument.frames import append_counts
    settings, obs, _ = small_observation
    path = tmp_path / name
    fits.PrimaryHDU().writeto(path)
    append_counts(path, obs, 120.0, json.dumps(settings.to_dict()), frames, 0)
    return path


@pytest.mark.parametrize("edit, named", [
    # an edited key measured another scene's p* (0.16 at 140° for a true 0.30), exit 0
    (lambda h: h["EXPECTED_COUNTS"].header.__setitem__("LVKEY", "140"), "LVKEY = '140' is not a phase"),
    # EXPTIME of 1e-300: ZeroDivisionError in the noise model
    (lambda h: h["EXPECTED_COUNTS"].header.__setitem__("EXPTIME", 1e-300), "EXPTIME = 1e-300"),
])
def test_an_edited_frames_file_is_refused(tmp_path, small_observation, edit, named):
    from astropy.io import fits

    from lunarviz.workflows.measurement import measure_file
    path = _frames_file(tmp_path, small_observation)
    with fits.open(path, mode="update") as h:
        edit(h)
    with pytest.raises(LunarvizError, match=re.escape(named)):
        measure_file(path)


def test_frames_of_another_size_none_or_compressed_are_refused(tmp_path, small_observation):
    import gzip

    from astropy.io import fits

    from lunarviz.workflows.measurement import measure_file
    path = _frames_file(tmp_path, small_observation)
    crop = tmp_path / "crop.fits"
    with fits.open(path) as h:
        h["EXPECTED_COUNTS"].data = h["EXPECTED_COUNTS"].data[:64, :64]
        h["COUNTS"].data = h["COUNTS"].data[:, :64, :64]
        h.writeto(crop)
    with pytest.raises(LunarvizError, match=r"shape \(64, 64\) is not its instrument's 128x128"):
        measure_file(crop)  # (a broadcast ValueError in the pipeline before)
    empty = tmp_path / "empty.fits"
    with fits.open(path) as h:
        h["COUNTS"].data = h["COUNTS"].data[:0]
        h.writeto(empty)
    with pytest.raises(LunarvizError, match="COUNTS holds no frames"):
        measure_file(empty)  # (numpy's zero-size reduction error before)
    packed = tmp_path / "packed.fits"
    packed.write_bytes(gzip.compress(path.read_bytes()))
    with pytest.raises(LunarvizError, match="is compressed"):
        measure_file(packed)  # (a gzip bomb was inflated whole before)


def test_a_lunar_fit_must_hold_a_covariance(tmp_path, small_observation):
    # a NaN sigma gave a null uncertainty, correlations of -5 a wrong one, with exit 0
    from lunarviz.resources import DATA_DIR
    from lunarviz.workflows.measurement import measure_file
    path = _frames_file(tmp_path, small_observation)
    fit = json.loads((DATA_DIR / "lunar_fits" / "dhg_rolo_400-750.json").read_text())
    for name, change, named in (("nan", lambda d: d["sigma"].__setitem__("w", float("nan")), "sigma of w"),
                                ("neg", lambda d: d["sigma"].__setitem__("w", -1.0), "sigma of w"),
                                ("corr", lambda d: [d["correlation"][a].__setitem__(b, -5.0) for a in d["correlation"]
                                                    for b in d["correlation"][a] if a != b], "correlation[")):
        bad = json.loads(json.dumps(fit))
        change(bad)
        f = tmp_path / f"{name}.json"
        f.write_text(json.dumps(bad))
        with pytest.raises(LunarvizError, match=re.escape(named)):
            measure_file(path, lunar_fit=f)


def test_measure_of_a_file_refuses_the_options_it_would_ignore(tmp_path, small_observation):
    # --brdf and --earth-albedo were silently ignored (the file carries its own scene)
    import lunarviz
    path = _frames_file(tmp_path, small_observation)
    r = run_cli("measure", str(path), "--brdf", "lambert", "--earth-albedo", "0.5")
    assert r.returncode == 2 and "--brdf goes with --simulate" in r.stderr
    with pytest.raises(LunarvizError, match="drop earth_albedo"):
        lunarviz.measure(path, earth_albedo=0.5)


@pytest.mark.parametrize("name", ["../../escape", "/tmp/abs", "café", "a\nb", "x" * 41])
def test_an_instrument_name_is_not_a_path_nor_a_fits_breaker(name):
    # '../' in the name wrote the photon band's file outside the temporary folder; non-ASCII
    # names broke the FITS header (tracebacks)
    d = SMALL.to_dict()
    d["name"] = name
    with pytest.raises(LunarvizError, match="name = "):
        instrument_from_dict(d)


def test_an_instrument_file_with_a_huge_integer_or_deep_nesting_is_one_line(tmp_path):
    big = tmp_path / "big.toml"
    d = SMALL.to_dict()
    lines = [f"{k} = {json.dumps(v)}" for k, v in d.items() if k != "aperture_m"] + ["aperture_m = 1" + "0" * 400]
    big.write_text("\n".join(lines) + "\n")
    with pytest.raises(LunarvizError, match=r"aperture_m = 1000.*\.\.\. must be a positive number"):
        load_instrument(big)  # (TypeError from np.isfinite before)
    deep = tmp_path / "deep.toml"
    deep.write_text("source = " + "[" * 5000 + "]" * 5000 + "\n")
    with pytest.raises(LunarvizError, match="nested too deep"):
        load_instrument(deep)  # (RecursionError before)


def test_a_full_moon_plan_is_refused_before_tracing(monkeypatch):
    # plan --phase 0 traced the whole instrument image (100 s, 1.8 GB) before refusing: the
    # geometric patches refuse it first; tracing is stubbed to prove it is never reached
    from lunarviz.workflows import measurement, tasks
    monkeypatch.setattr(tasks, "image", lambda *a, **k: pytest.fail("traced before refusing"))
    settings = Scene([0.0], brdfs="dhg").settings("raytrace")
    with pytest.raises(LunarvizError, match="earthlit patch has 0 pixels"):
        measurement.plan(settings, 0.0, SMALL, 10.0)
