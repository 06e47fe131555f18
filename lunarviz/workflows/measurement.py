"""End-to-end measurements: frames written by ``lunarviz image --instrument`` measured
(``lunarviz measure FILE``), simulated measurements with their error budget
(``lunarviz measure --simulate N``), and exposure planning (``lunarviz plan``).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from lunarviz.errors import LunarvizError
from lunarviz.instrument import budget
from lunarviz.instrument.budget import halo_shape_sigma, with_budget
from lunarviz.instrument.detector import frames as draw_frames
from lunarviz.instrument.frames import read_frames
from lunarviz.instrument.observation import (
    MAX_EXPOSURE_S,
    MIN_EXPOSURE_S,
    Observation,
    check_exposure,
    instrument_camera,
    observe,
)
from lunarviz.instrument.pipeline import Calibration, calibrate, check_patches, measure
from lunarviz.instrument.response import instrument_request, photon_band, write_band_csv
from lunarviz.instrument.spec import Instrument, instrument_from_dict
from lunarviz.options import model_earth
from lunarviz.scene import ResolvedScene
from lunarviz.spectral.bands import parse_band
from lunarviz.workflows import tasks
from lunarviz.workflows.sweeps import run_sweep

#: the most simulated measurements in one run
MAX_SIMULATIONS = 100_000
#: the most frames stacked per measurement
MAX_FRAMES = 10_000
#: the expected charge of the brightest pixel plus this many standard deviations stays below the
#: saturation level in a planned exposure
SATURATION_SIGMAS = 5.0


def instrument_scene(scene, inst: Instrument):
    """The scene an instrument images: one lunar BRDF, in the instrument's band."""
    if len(scene.brdfs) != 1:
        raise LunarvizError(f"an instrument images one lunar BRDF: got {','.join(scene.brdfs)} (give one --brdf)")
    if scene.wavelengths is not None:
        raise LunarvizError("--instrument images in its own band: drop --wavelengths")
    if scene.bands is not None and str(scene.bands).strip() != inst.band:
        raise LunarvizError(f"--band {scene.bands!r} differs from the instrument's band {inst.band!r}")
    return replace(scene, bands=inst.band)


def observation(scene, key, inst: Instrument, exposure_s: float | None = None, trace_scene=None) -> Observation:
    """The noise-free observation by ``inst`` of task ``key`` (θ [deg] or a UTC time) of ``scene``:
    its camera's image in its band and photon band, then the optics, atmosphere and mask
    (:func:`lunarviz.instrument.observation.observe`)."""
    t = check_exposure(inst, exposure_s)
    scene = instrument_scene(scene, inst)
    geometry = scene.geometry(key)
    check_patches(geometry, inst)  # (a full Moon refused before its image is traced)
    res = tasks.image(scene, key, instrument_camera(inst), instrument_request(inst, scene.solar_spectrum),
                      trace_scene)
    return observe(res, geometry, scene.brdfs[0], inst, t)


def model_earth_scene(scene):
    """``scene`` with the uniform Lambert Earth of its ``earth_albedo``: what the pipeline's model
    (and every inversion) assumes."""
    return replace(scene, **model_earth(scene))


def calibration(scene, key, inst: Instrument, exposure_s: float, rates: dict | None = None) -> Calibration:
    """The pipeline's model of an observation of task ``key``: the model Earth's image
    (``rates``: its photoelectron rates before the optics, when the caller has them)."""
    scene = instrument_scene(scene, inst)
    model = model_earth_scene(scene)
    if rates is None:
        rates = observation(model, key, inst, exposure_s).raw_rates
    return calibrate(model.geometry(key), inst, exposure_s, rates, scene.earth_albedo, key)


def observation_calibration(settings, key, inst: Instrument, obs):
    """The pipeline's model of an observation; the observation's own rates when its Earth is the
    calibration's (a uniform Lambert Earth), saving a second image."""
    uniform = settings.earth_surface == "uniform" and settings.clouds == "none"
    return calibration(settings, key, inst, obs.exposure_s, rates=obs.raw_rates if uniform else None)


def _model_sweep(scene) -> dict:
    """A sweep the measurement makes for its own model (p* in a band, its slope): its rows' bounds
    are not the user's rows', so their warnings are not shown."""
    import warnings

    from lunarviz.errors import LooseRowsWarning, UnboundedRowsWarning
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnboundedRowsWarning)
        warnings.simplefilter("ignore", LooseRowsWarning)
        return run_sweep(scene, progress=False)


def band_sigma(scene, key, inst: Instrument) -> float:
    """Relative σ of p* from the band centre's uncertainty (:mod:`lunarviz.instrument.budget`): the
    model Earth's p*(λ) from analytic sweeps ``BAND_STEP_NM`` either side of the band's centre."""
    if inst.band_centre_sigma_nm == 0:
        return 0.0
    c = parse_band(inst.band).centre_nm
    step = budget.BAND_STEP_NM
    # (the analytic method takes the packaged spheres: a traced run's mesh options are dropped)
    model = replace(scene, method="analytic", earth_surface="landocean", clouds="zonal", bands=None,
                    moon_mesh=None, earth_mesh=None, sun_mesh=None, moon_level=None, earth_level=None,
                    sun_level=None,
                    wavelengths=f"{c - step:.6f},{c + step:.6f}", earth_spectra="surface",
                    phases_deg=(float(key),) if scene.times is None else scene.phases_deg,
                    times=None if scene.times is None else (str(key),))
    rows = [r for r in _model_sweep(model)["rows"] if r["brdf"] == scene.brdfs[0]]
    p = {r["wavelength_nm"]: r["apparent_albedo"] for r in rows}
    return budget.band_slope_sigma(p[min(p)], p[max(p)], inst)


def systematics(scene, key, cal: Calibration, fit_path=None) -> dict:
    """The pointing's systematic terms, relative (multiply by p*; :mod:`lunarviz.instrument.budget`)."""
    geometry = scene.geometry(key)
    conventions = {"h_function": scene.h_function, "dhg_convention": scene.dhg_convention}
    lunar = budget.lunar_model_sigma(scene.brdfs[0], conventions, geometry, cal, fit_path)
    return budget.systematics(lunar, geometry, cal, band_sigma(scene, key, cal.instrument))


def sweep_p_star(settings, key, inst: Instrument, photon: bool = True) -> float:
    """p* of ``lunarviz sweep`` (ray traced) for the same scene and key: in the instrument's photon
    band S·T·QE·λ (what its counts weigh; ``photon``), or in its band S as ``--band`` gives it.

    The two differ where the Earth's p*(λ) varies across the band (≈ 1e-3 in V for a land-ocean
    Earth with clouds; not at all for a grey Earth)."""
    import tempfile
    from pathlib import Path

    s = instrument_scene(settings, inst)
    s = replace(s, method="raytrace", phases_deg=(float(key),) if s.times is None else s.phases_deg,
                times=None if s.times is None else (str(key),))
    if not photon:
        return float(_model_sweep(s)["rows"][0]["apparent_albedo"])
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "photon_band.csv"  # (a fixed name: the instrument's own is not a path)
        write_band_csv(photon_band(inst), path)
        return float(_model_sweep(replace(s, bands=str(path)))["rows"][0]["apparent_albedo"])


def check_count(n: int, what: str, hi: int) -> int:
    """``n`` as an integer from 1 to ``hi``, or a one-line error naming ``what``."""
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not 1 <= n <= hi:
        raise LunarvizError(f"{what} {n!r} must be an integer from 1 to {hi}")
    return int(n)


def check_seed(seed) -> int:
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= seed < 2**63:
        raise LunarvizError(f"--seed {seed!r} must be a non-negative integer")
    return int(seed)


def simulate(settings, key, inst: Instrument, n: int, seed: int, exposure_s: float | None = None,
             frames: int = 1, lunar_fit=None, progress: bool = False) -> dict:
    """``n`` measurements of ``frames`` frames each (measurement i, frame j drawn from
    ``default_rng([seed, i, j])``): rows with p*, its noise and the error budget; a summary of the
    standardised errors against the sweep's p* in the instrument's photon band
    (``p_star_sweep``; ``p_star_sweep_band``: in its band S, as ``lunarviz sweep --band``)."""
    n = check_count(n, "--simulate", MAX_SIMULATIONS)
    frames = check_count(frames, "--frames-per-measurement", MAX_FRAMES)
    seed = check_seed(seed)
    obs = observation(settings, key, inst, exposure_s)
    cal = observation_calibration(settings, key, inst, obs)
    noiseless = measure(obs.expected_counts, 1, cal)
    rel = systematics(instrument_scene(settings, inst), key, cal, lunar_fit)
    halo_rel = halo_shape_sigma(obs.expected_counts, 1, cal, noiseless["p_star"])
    truth = sweep_p_star(settings, key, inst)
    it = range(n)
    if progress:
        from tqdm import tqdm
        it = tqdm(it, desc="measure", unit="measurement", leave=False)
    rows = []
    e = obs.electrons
    for i in it:
        stack, peak = np.zeros(e.shape), np.zeros(e.shape)
        for f in draw_frames(e, inst, frames, seed, stream=(i,)):
            stack += f
            np.maximum(peak, f, out=peak)
        row = with_budget(measure(stack / frames, frames, cal, peak), rel, halo_rel)
        rows.append({"measurement": i, **row})
    z = np.array([(r["p_star"] - truth) / r["p_star_sigma"] for r in rows])
    summary = {"p_star_sweep": truth, "p_star_sweep_band": sweep_p_star(settings, key, inst, photon=False),
               "p_star_noiseless": noiseless["p_star"],
               "noiseless_relative_error": noiseless["p_star"] / truth - 1,
               "measurements": n, "standardised_error_mean": float(z.mean()),
               "standardised_error_variance": float(z.var(ddof=1)) if n > 1 else float("nan"),
               "coverage_1sigma": float(np.mean(np.abs(z) <= 1)), "coverage_k2_random": float(np.mean(np.abs(z) <= 2))}
    return {"key": str(key), "instrument": inst.to_dict(), "exposure_s": obs.exposure_s, "frames": frames,
            "seed": seed, "sky_model": obs.sky_note, "lunar_model_uncertainty": rel["lunar_model_source"],
            "summary": summary, "rows": rows}


def measure_file(path, use_expected: bool = False, lunar_fit=None) -> dict:
    """Measure the frames of a ``lunarviz image --instrument`` FITS file (``use_expected``: its
    noise-free ``EXPECTED_COUNTS``)."""
    fr = read_frames(path, use_expected)
    try:
        settings = ResolvedScene.from_dict(fr.settings)
        inst = instrument_from_dict(fr.instrument, f"{str(path)!r} instrument")
        key = fr.key if settings.times is not None else float(fr.key)
        exposure = float(fr.header["EXPTIME"])
    except (ValueError, TypeError, KeyError, OverflowError) as exc:
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise LunarvizError(f"{str(path)!r}: its LVSETTNG, LVINSTR, LVKEY or EXPTIME card is damaged ({msg})") from None
    # the key must be one the stored settings image (an edited θ would measure another scene's p*)
    keys = settings.times if settings.times is not None else settings.phases_deg
    if key not in keys:
        raise LunarvizError(f"{str(path)!r}: LVKEY = {fr.key!r} is not a phase or time of its own LVSETTNG "
                            f"({', '.join(str(k) for k in keys[:3])}{', ...' if len(keys) > 3 else ''}): the file "
                            f"was edited")
    if not (np.isfinite(exposure) and MIN_EXPOSURE_S <= exposure <= MAX_EXPOSURE_S):
        raise LunarvizError(f"{str(path)!r}: EXPTIME = {exposure!r} is outside [{MIN_EXPOSURE_S:g}, "
                            f"{MAX_EXPOSURE_S:g}] s")
    counts_t = fr.counts_header.get("EXPTIME") if fr.counts_header is not None else None
    if counts_t is not None and not np.isclose(float(counts_t), exposure, rtol=1e-9):
        raise LunarvizError(f"{str(path)!r}: EXPTIME of EXPECTED_COUNTS ({exposure!r}) and of COUNTS ({counts_t!r}) "
                            f"differ: the file was edited")
    if fr.expected.shape != (inst.height, inst.width):
        raise LunarvizError(f"{str(path)!r}: EXPECTED_COUNTS of shape {fr.expected.shape} is not its instrument's "
                            f"{inst.height}x{inst.width} pixels")
    cal = calibration(settings, key, inst, exposure)
    if fr.counts is None:
        mean, n = fr.expected, 1
    else:
        n = fr.counts.shape[0]
        mean = np.mean(fr.counts, axis=0, dtype=float)
    row = measure(mean, n, cal, None if fr.counts is None else fr.counts.max(axis=0))
    rel = systematics(instrument_scene(settings, inst), key, cal, lunar_fit)
    row = with_budget(row, rel, halo_shape_sigma(mean, n, cal, row["p_star"]))
    if fr.counts is not None and n >= 2:
        # the earthlit patch frame by frame: the scatter of its mean count is the single-frame noise
        t, g = exposure, inst.gain_e_per_adu
        per_frame = np.array([np.mean(f[cal.patches.earthlit], dtype=float) for f in fr.counts]) * g
        row["earthlit_snr_per_frame"] = float(row["earthlit_e_s"] * t / np.std(per_frame, ddof=1))
    return {"file": str(path), "key": fr.key, "instrument": inst.name, "exposure_s": exposure,
            "lunar_model_uncertainty": rel["lunar_model_source"], "rows": [row]}


def read_plan(path) -> dict:
    """A ``lunarviz plan --out`` file: its instrument, exposure [s] and key (θ or UTC time), checked."""
    import json
    from pathlib import Path
    p = Path(path)
    if not p.is_file():
        raise LunarvizError(f"plan {str(path)!r}: no such file")
    if p.stat().st_size > 1 << 20:
        raise LunarvizError(f"plan {str(path)!r} is larger than 1 MiB: not a plan file")
    try:
        d = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError, RecursionError) as exc:
        raise LunarvizError(f"plan {str(path)!r} is not readable JSON ({type(exc).__name__})") from None
    if not isinstance(d, dict) or not all(isinstance(d.get(k), str) for k in ("instrument_spec", "key")):
        raise LunarvizError(f"plan {str(path)!r} is not a lunarviz plan file (no instrument_spec and key)")
    t = d.get("exposure_s")
    key = d["key"].strip()
    try:
        ok_key = key.endswith("Z") or 0 <= float(key) <= 360
    except ValueError:
        ok_key = False
    if not ok_key or "," in key:
        raise LunarvizError(f"plan {str(path)!r}: key {d['key']!r} is not one phase θ [deg] or one UTC time")
    if d.get("feasible") is not True or isinstance(t, bool) or not isinstance(t, (int, float)):
        raise LunarvizError(f"plan {str(path)!r} found no exposure that reaches its SNR unsaturated: plan again with a "
                            "lower --snr, or several frames")
    if not (MIN_EXPOSURE_S <= t <= MAX_EXPOSURE_S):  # (comparisons: an integer of 400 digits, NaN fail)
        raise LunarvizError(f"plan {str(path)!r}: exposure_s {t!r} is outside [{MIN_EXPOSURE_S:g}, "
                            f"{MAX_EXPOSURE_S:g}] s")
    return {"instrument_spec": d["instrument_spec"], "exposure_s": float(t), "key": key}


#: what a plan's SNR is of: the earthlit patch's mean charge, or one of its pixels
SNR_OF = ("patch", "pixel")


def plan(settings, key, inst: Instrument, snr: float, obs=None, cal=None, per: str = "patch") -> dict:
    """The exposure [s] at which the earthlit patch (``per="patch"``: its mean charge, what the
    pipeline measures) or its average pixel (``per="pixel"``) reaches ``snr`` in one frame with the
    brightest pixel unsaturated (its expected charge + 5σ below the saturation level), or the
    statement that none does and how many frames of the longest safe exposure would. Both SNRs are
    reported at the exposure chosen, with the brightest pixel's charge against the full well.
    ``obs``, ``cal``: the observation (any exposure: rates do not depend on it) and its
    calibration, when the caller has them."""
    if not (np.isfinite(snr) and 1e-3 <= snr <= 1e6):
        raise LunarvizError(f"--snr {snr!r} must be a number in [0.001, 1e6]")
    if per not in SNR_OF:
        raise LunarvizError(f"SNR of {per!r} must be one of {', '.join(SNR_OF)}")
    from lunarviz.instrument.observation import optics_kernels
    from lunarviz.instrument.optics import apply_optics
    obs = obs if obs is not None else observation(settings, key, inst, 1.0)
    cal = cal if cal is not None else observation_calibration(settings, key, inst, obs)
    E = cal.patches.earthlit
    n = int(E.sum())
    psf, _ = optics_kernels(inst, instrument_camera(inst))
    trans = obs.sky.transmission if obs.sky is not None else 1.0
    signal = float(np.mean(apply_optics(obs.raw_rates["earthshine"], psf, None)[E])) * trans  # [e⁻ s⁻¹]
    total = obs.rate_e_s + inst.dark_current_e_per_s
    read2 = inst.read_noise_e**2 + inst.gain_e_per_adu**2 / 12.0
    # the variance of one pixel's charge (B t + C) and of the patch's mean (its sum over n²)
    noise = {"pixel": (float(np.mean(total[E])), read2), "patch": (float(np.sum(total[E])) / n**2, read2 / n)}

    def snr_at(t, of=per):
        B, C = noise[of]
        return signal * t / np.sqrt(B * t + C)

    B, C = noise[per]
    a2, s2 = signal**2, snr**2
    t_snr = (s2 * B + np.sqrt((s2 * B) ** 2 + 4 * a2 * s2 * C)) / (2 * a2)
    level = min(inst.full_well_e, (inst.adc_max - inst.bias_adu) * inst.gain_e_per_adu)
    peak = float(total.max())
    # x + k sqrt(x + σ_r²) = level with x = peak t: y = sqrt(x + σ_r²) solves y² + k y − (level + σ_r²) = 0
    k, r2 = SATURATION_SIGMAS, inst.read_noise_e**2
    y = (-k + np.sqrt(k * k + 4 * (level + r2))) / 2
    t_sat = float(max(y * y - r2, 0.0) / peak)
    feasible = bool(MIN_EXPOSURE_S <= t_snr <= t_sat)
    snr_sat = float(snr_at(t_sat)) if t_sat > 0 else 0.0
    # no frame count when even the read noise alone reaches the saturation margin
    frames_needed = int(np.ceil((snr / snr_sat) ** 2)) if snr_sat > 0 and (snr / snr_sat) ** 2 < 1e12 else None
    t = float(t_snr) if feasible else t_sat
    out = {"key": str(key), "instrument": inst.name,
           "snr_target": float(snr), "snr_of": per, "feasible": feasible,
           "exposure_s": float(t_snr) if feasible else None, "saturation_exposure_s": t_sat,
           "snr_at_saturation_exposure": snr_sat,
           "frames_needed_at_saturation_exposure": frames_needed,
           "earthlit_pixels": n, "earthlit_signal_e_s": signal,
           "brightest_pixel_e_s": peak, "saturation_level_e": float(level), "full_well_e": float(inst.full_well_e),
           "snr_patch_at_exposure": float(snr_at(t, "patch")), "snr_pixel_at_exposure": float(snr_at(t, "pixel")),
           "brightest_pixel_e": float(peak * t), "brightest_pixel_fraction_of_full_well": float(peak * t
                                                                                               / inst.full_well_e),
           "snr_definition": "patch: the mean earthshine charge of the earthlit patch (halo and sky excluded) over "
                             "the standard deviation of the patch's mean charge in one frame (photon noise of all its "
                             "light, dark and read noise; lunarviz measure reports the same from frames as "
                             "earthlit_snr_per_frame); pixel: the same for one pixel of the patch (its mean light)",
           "at_exposure": "the SNRs and the brightest pixel at exposure_s, or at saturation_exposure_s when no "
                          "exposure reaches the target"}
    if feasible:
        out["snr_at_exposure"] = float(snr_at(t_snr))
    return out
