"""The error budget of a measured p*: its systematic terms, and the totals.

The random terms (photon, read and dark noise, the halo fit) come with each measurement
(:func:`lunarviz.instrument.pipeline.measure`). The systematic terms below are the same for every
frame of a pointing; each is a standard uncertainty (1σ) in p*:

* ``lunar_model``: the lunar photometric model's parameters, with the covariance of a
  ``lunarviz fit`` result (default: the packaged fits of the BRDF to ROLO, 400-750 nm,
  ``lunarviz/data/lunar_fits``), propagated to the ratio of the model's mean reflectance over the
  two patches (each pixel's geometry; central differences): ``σ² = gᵀ C g``,
  ``g = ∂ ln(ρ_earthlit/ρ_sunlit)/∂p`` at the fit's parameters (whose covariance it is), over the
  fitted parameters; one the fit left at a bound of its range has no meaningful linearised
  variance and is held fixed (θ̄ = 45° of the DHG fit to ROLO), the others taking their
  covariance conditional on it (they are correlated beyond 0.95). The earthlit patch
  is seen at opposition (phase ≈ 0), where ROLO has no data: the B0/h part is an extrapolation
  of the fit. A Lambert Moon's albedo cancels: 0.
* ``halo_shape``: the halo's power-law index known to ±0.1: half the change of p* when the
  pipeline's kernel uses INDEX ± 0.1 on the same frames (infinite where either leaves the earthlit
  patch without light: the halo then swamps the earthshine).
* ``nd_filter``: the bright-side mask's transmission calibration (the instrument's
  ``bright_side_nd_sigma``, relative; p* is proportional to it).
* ``ephemeris``: the Earth-Moon distance known to ``EPHEMERIS_SIGMA_KM`` (earthshine falls as
  D_EM⁻², so 2σ_D/D_EM relative).
* ``band``: the band's centre known to the instrument's ``band_centre_sigma_nm``: the model Earth's
  p*(λ) slope (lunarviz's land-ocean Earth with zonal clouds and surface spectra, the scene's
  Moon; analytic sweeps 10 nm either side of the band's centre) times that uncertainty.

The total is the quadrature sum of all; ``p_star_U_k2`` is it times 2 (coverage ≈ 95 %, as LIME
reports its lunar irradiance uncertainty).
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np

from lunarviz.errors import LunarvizError
from lunarviz.geometry.scene_geometry import SceneGeometry, half_angle_sin_cos
from lunarviz.instrument.disc import surface_points
from lunarviz.instrument.observation import instrument_camera
from lunarviz.instrument.optics import parse_halo
from lunarviz.instrument.pipeline import measure
from lunarviz.photometry.brdf import FIT_BOUNDS, make_brdf
from lunarviz.resources import DATA_DIR

#: packaged ``lunarviz fit`` results whose covariance stands for the lunar model's uncertainty
LUNAR_FITS = {"dhg": DATA_DIR / "lunar_fits" / "dhg_rolo_400-750.json",
              "shg": DATA_DIR / "lunar_fits" / "shg_rolo_400-750.json"}
#: the Earth-Moon distance's standard uncertainty [km] (DE440-class ephemerides are at the metre
#: level; 1 km also covers a LEO observer's orbit determination)
EPHEMERIS_SIGMA_KM = 1.0
#: the halo index's standard uncertainty
HALO_INDEX_SIGMA = 0.1
#: half the wavelength step of the band term's finite difference [nm]
BAND_STEP_NM = 10.0
#: the expansion factor of ``p_star_U_k2``
COVERAGE_K = 2.0


def _check_covariance(path, free: list, sig: np.ndarray, corr: np.ndarray) -> None:
    """A fit's σ finite, non-negative and within ten times its parameter's range (FIT_BOUNDS), and
    its correlation a correlation matrix (finite, symmetric, unit diagonal, entries in [−1, 1],
    no negative eigenvalue beyond rounding), else a one-line error naming the first bad value."""
    for k, v in zip(free, sig):
        span = np.subtract(*FIT_BOUNDS[k][::-1]) if k in FIT_BOUNDS else np.inf
        if not (np.isfinite(v) and 0 <= v <= 10 * span):
            raise LunarvizError(f"--lunar-fit {str(path)!r}: sigma of {k} = {float(v)!r} is not a standard "
                                f"uncertainty (finite, in [0, {10 * span:g}])")
    tol = 1e-6
    if not np.all(np.isfinite(corr)) or np.any(np.abs(corr) > 1 + tol) or np.any(np.abs(np.diag(corr) - 1) > tol) \
            or np.any(np.abs(corr - corr.T) > tol):
        bad = np.argwhere(~np.isfinite(corr) | (np.abs(corr) > 1 + tol) | (np.abs(corr - corr.T) > tol)
                          | (np.eye(len(free), dtype=bool) & (np.abs(corr - 1) > tol)))
        a, b = bad[0] if len(bad) else (0, 0)
        raise LunarvizError(f"--lunar-fit {str(path)!r}: correlation[{free[a]}][{free[b]}] = {float(corr[a, b])!r} "
                            f"is not that of a correlation matrix (finite, symmetric, in [-1, 1], 1 on the diagonal)")
    if len(free) and np.linalg.eigvalsh(0.5 * (corr + corr.T)).min() < -1e-6:
        raise LunarvizError(f"--lunar-fit {str(path)!r}: the correlation matrix is not positive semi-definite "
                            f"(a variance would be negative)")


def read_fit(path) -> dict:
    """A ``lunarviz fit`` JSON: params, the free parameters, sigma and correlation."""
    try:
        d = json.loads(Path(path).read_text(encoding="utf-8"))
        free = list(d["free"])
        if len(set(free)) != len(free) or not all(isinstance(k, str) for k in free):
            raise ValueError("free parameters listed twice")
        if any(isinstance(d["sigma"][k], bool) for k in free):
            raise TypeError("a sigma is not a number")
        sig = np.array([float(d["sigma"][k]) for k in free])
        corr = np.array([[float(d["correlation"][a][b]) for b in free] for a in free])
        params = {k: float(v) for k, v in d["params"].items()}
        brdf = str(d["brdf"])
        conventions = {k: d.get("settings", {}).get(k) for k in ("h_function", "dhg_convention")}
        at_bound = {k: k in FIT_BOUNDS and min(params[k] - FIT_BOUNDS[k][0], FIT_BOUNDS[k][1] - params[k])
                    < 1e-6 * (FIT_BOUNDS[k][1] - FIT_BOUNDS[k][0]) for k in free}
    except (OSError, ValueError, KeyError, TypeError, RecursionError, OverflowError) as exc:
        raise LunarvizError(f"--lunar-fit {str(path)!r}: not a lunarviz fit result ({type(exc).__name__})") from None
    _check_covariance(path, free, sig, corr)
    return {"brdf": brdf, "params": params, "free": free, "covariance": corr * np.outer(sig, sig), "path": str(path),
            "at_bound": at_bound, "conventions": conventions}


def _patch_geometry(sc, camera, sel: np.ndarray, source: np.ndarray):
    """(μ0, μ, sin g/2, cos g/2) arrays at the pixels ``sel`` (every 1 in k, at most ~400) lit
    from ``source`` [m]."""
    y, x = np.nonzero(sel)
    step = max(len(x) // 400, 1)
    p, nrm = surface_points(sc, camera, x[::step], y[::step])
    s = source[None, :] - p
    s /= np.linalg.norm(s, axis=1, keepdims=True)
    o = sc.det[None, :] - p
    o /= np.linalg.norm(o, axis=1, keepdims=True)
    sin_hg, cos_hg = half_angle_sin_cos(s, o)
    return np.clip(np.einsum("ij,ij->i", nrm, s), 0.0, 1.0), np.einsum("ij,ij->i", nrm, o), sin_hg, cos_hg


def lunar_model_sigma(brdf: str, conventions: dict, geometry: SceneGeometry, cal, fit_path=None) -> tuple[float, str]:
    """Relative σ of p* from the lunar model's parameters (see the module docstring).

    Parameters
    ----------
    brdf : str
        The scene's lunar BRDF (``lambert``, ``shg``, ``dhg``).
    conventions : dict
        The scene's ``h_function`` and ``dhg_convention``, against which the fit is checked.
    geometry : SceneGeometry
        The task's bodies and detector (each patch pixel's angles).
    cal : Calibration
        The pipeline's calibration (its patches).
    fit_path : path, optional
        A ``lunarviz fit`` result (default: the packaged fit of ``brdf`` to ROLO).

    Returns
    -------
    (float, str)
        The relative σ and where its covariance came from.
    """
    if brdf == "lambert":
        return 0.0, "a Lambert Moon's albedo cancels in the ratio"
    path = fit_path or LUNAR_FITS.get(brdf)
    fit = read_fit(path)
    if fit["brdf"] != brdf:
        raise LunarvizError(f"--lunar-fit {str(path)!r} fits {fit['brdf']!r}, the scene's BRDF is {brdf!r}")
    differ = [f"{k} {v!r} (the scene: {conventions[k]!r})" for k, v in fit["conventions"].items()
              if v is not None and v != conventions[k]]
    if differ and fit_path is not None:  # the user's own fit must describe the scene's model
        raise LunarvizError(f"--lunar-fit {str(path)!r} was fitted with {differ[0]}")
    sc = geometry
    camera = instrument_camera(cal.instrument)
    ge = _patch_geometry(sc, camera, cal.patches.earthlit, sc.earth)
    gs = _patch_geometry(sc, camera, cal.patches.sunlit, sc.sun)
    # the gradient at the fit's own parameters: the covariance belongs to them (its valleys of
    # correlated parameters lie where the fit put them; at other parameters, e.g. the paper's, the
    # same covariance is not consistent and overstates several-fold). A parameter the fit left at
    # a bound of its range has no meaningful linearised variance: it is held fixed (θ̄ = 45° for
    # DHG), and the others take their covariance conditional on it
    params = {k: v for k, v in fit["params"].items() if k != "map_contrast"}
    free = [k for k in fit["free"] if k != "map_contrast" and not fit["at_bound"][k]]
    fixed = [k for k in fit["free"] if k not in free]
    ia, ib = [fit["free"].index(k) for k in free], [fit["free"].index(k) for k in fixed]
    C = fit["covariance"]
    cov = C[np.ix_(ia, ia)]
    if ib:  # the others' covariance given the fixed ones (conditional, not marginal: they are correlated)
        cov = cov - C[np.ix_(ia, ib)] @ np.linalg.pinv(C[np.ix_(ib, ib)]) @ C[np.ix_(ib, ia)]

    def log_ratio(p):  # the patches' mean radiance factors (the patch means of the pipeline)
        m = make_brdf(brdf, dhg_convention=conventions["dhg_convention"], h_function=conventions["h_function"],
                      params=p)
        return float(np.log(np.mean(m.radiance_factor(*ge)) / np.mean(m.radiance_factor(*gs))))

    grad = np.zeros(len(free))
    for n, k in enumerate(free):
        lo, hi = FIT_BOUNDS[k]
        step = 1e-4 * (hi - lo)
        up, dn = min(params[k] + step, hi), max(params[k] - step, lo)
        grad[n] = (log_ratio({**params, k: up}) - log_ratio({**params, k: dn})) / (up - dn)
    note = f"; fitted with {', '.join(differ)}" if differ else ""
    return float(np.sqrt(max(grad @ cov @ grad, 0.0))), f"covariance of {', '.join(free)} in {path}{note}"


def halo_shape_sigma(mean_counts, n_frames: int, cal, p_star: float) -> float:
    """Relative σ of p* from the halo index's uncertainty (refits with INDEX ± σ)."""
    inst = cal.instrument
    if cal.kernel is None:
        return 0.0
    vals = [float(v) for v in inst.halo.split(",")]
    camera = instrument_camera(inst)
    pix = float(np.degrees(camera.scale_rad)) * 3600.0
    out = []
    for sgn in (1, -1):
        text = ",".join(str(v) for v in [vals[0], vals[1] + sgn * HALO_INDEX_SIGMA] + vals[2:])
        k = parse_halo(text, pix, (camera.height, camera.width))[1]
        try:
            out.append(measure(mean_counts, n_frames, replace(cal, kernel=k))["p_star"])
        except LunarvizError:  # the halo's uncertainty alone swallows the earthlit patch
            return float("inf")
    return abs(out[0] - out[1]) / 2.0 / p_star


def ephemeris_sigma(geometry: SceneGeometry) -> float:
    """Relative σ of p* from the Earth-Moon distance (``EPHEMERIS_SIGMA_KM``; earthshine ∝ D_EM⁻²)."""
    return 2.0 * EPHEMERIS_SIGMA_KM * 1e3 / float(geometry.d_em_actual)


def band_slope_sigma(p_low: float, p_high: float, inst) -> float:
    """Relative σ of p* from the band centre's uncertainty: the slope of p*(λ) between the band's
    centre ∓ ``BAND_STEP_NM`` (``p_low``, ``p_high``) times the instrument's ``band_centre_sigma_nm``."""
    if not (np.isfinite(p_low) and np.isfinite(p_high)) or p_low + p_high <= 0:
        return float("nan")
    return abs(p_high - p_low) / (2 * BAND_STEP_NM) * inst.band_centre_sigma_nm / (0.5 * (p_low + p_high))


def systematics(lunar_model: tuple[float, str], geometry: SceneGeometry, cal, band: float) -> dict:
    """The pointing's systematic terms, relative (multiply by p*): the lunar model's
    (:func:`lunar_model_sigma`), the ND filter's, the ephemeris' and the band's (``band``)."""
    model, source = lunar_model
    return {"lunar_model": model, "nd_filter": cal.instrument.bright_side_nd_sigma if cal.transmission < 1 else 0.0,
            "ephemeris": ephemeris_sigma(geometry), "band": band, "lunar_model_source": source}


def with_budget(row: dict, rel: dict, halo_shape_rel: float) -> dict:
    """``row`` plus ``sigma_<term>`` for each systematic term, the totals and ``p_star_U_k2``."""
    p = row["p_star"]
    terms = {f"sigma_{k}": p * v for k, v in rel.items() if not k.endswith("_source")}
    terms["sigma_halo_shape"] = p * halo_shape_rel
    sys = float(np.sqrt(sum(v**2 for v in terms.values())))
    total = float(np.hypot(row["p_star_sigma"], sys))
    return {**row, **{k: float(v) for k, v in terms.items()}, "p_star_sigma_systematic": sys,
            "p_star_sigma_total": total, "p_star_U_k2": COVERAGE_K * total}
