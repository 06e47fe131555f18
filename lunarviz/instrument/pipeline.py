"""The measurement: from frames in counts to the Earth's apparent albedo p*, with its noise.

What an earthshine observer does (Qiu et al. 2003, JGR 108, 4709, Sec. 3; Goode et al. 2001):

1. **Calibrate the counts**: ``Y = ((C̄ − bias) g − D t)/t`` [e⁻ s⁻¹] per pixel from the mean
   frame C̄; behind the bright-side mask divide by its transmission τ.
2. **Choose patches** from the ephemeris (:mod:`lunarviz.instrument.disc`): an *earthlit* patch
   on the dark side (0.55-1 radii from the centre, within 30° of the anti-solar direction, clear
   of the terminator and the limb by :meth:`~lunarviz.instrument.spec.Instrument.margin_px`), a
   *sunlit* patch within 30° of the solar direction (inside the lit region, a third of the margin
   from its edges),
   and the *sky* off the dark limb (beyond the margin, within 90° of the anti-solar direction).
3. **Remove the scattered light.** The instrument's halo is ``(1 − f) P + f K ⊛ P`` with K the
   halo's shape (from the instrument file: measured in the lab) and P the image before the halo;
   the sky adds a constant b. Off the limb P = 0, so there ``Y = f (K ⊛ P) + b``: f and b are
   fitted by weighted least squares on the sky pixels, then ``P = (Y − b − f K ⊛ P)/(1 − f)`` on
   the disc, and the two steps repeat (the fixed point converges as (f/(1−f))ⁿ; six rounds;
   ordinary least squares: see :func:`remove_halo`).
   BBSO fit the sky off the limb with a smooth function and extrapolate it under the patch; the
   halo's known shape extrapolates with physics instead of a polynomial, so its residual is the
   fit's noise (the halo-shape term of the error budget tests the shape's own uncertainty).
4. **The ratio and its inversion.** ``R = P̄_earthlit / P̄_sunlit``; the same ratio of a model of
   the observation (the lunar photometric model lit by a uniform Lambert Earth of albedo A,
   through the PSF: :class:`Calibration`) gives ``R_A``, and ``p* = A R / R_A`` (paper Eqs. 15-16:
   the lunar terms p_a f_a, p_b f_b and the distances are those of the model; earthshine is linear
   in the Earth's albedo). Extinction dims both patches alike and cancels.

Noise (1σ, in p*): photon noise of both patches, read and dark noise, and the halo fit's
covariance propagated to the earthlit patch. They are independent and random between
measurements: ``p_star_sigma`` is their quadrature sum. Systematic terms are in
:mod:`lunarviz.instrument.budget`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lunarviz.errors import LunarvizError
from lunarviz.geometry.scene_geometry import SceneGeometry
from lunarviz.instrument.disc import DiscGeometry, masked_pixels
from lunarviz.instrument.observation import instrument_camera, optics_kernels
from lunarviz.instrument.optics import apply_optics
from lunarviz.instrument.spec import Instrument

#: the most rounds of the halo fit's fixed point (its error shrinks as (f/(1−f))ⁿ: 1e-12 for
#: f = 0.03 after six); it stops earlier when f and b change by less than HALO_TOLERANCE (relative)
HALO_ROUNDS = 6
HALO_TOLERANCE = 1e-7
#: the fewest pixels a patch (and the sky) may have
MIN_PATCH_PIXELS = 16
MIN_SKY_PIXELS = 64
#: patches lie within this angle of the solar (sunlit) or anti-solar (earthlit) direction [deg]
PATCH_HALF_ANGLE_DEG = 30.0
#: the earthlit patch starts this far from the centre [radii]
EARTHLIT_INNER_RADII = 0.55


@dataclass
class Patches:
    earthlit: np.ndarray  # (H, W) bool
    sunlit: np.ndarray
    sky: np.ndarray
    disc: np.ndarray  # where the image before the halo may be non-zero (the disc and the PSF's reach)


def select_patches(geom: DiscGeometry, lit: np.ndarray, margin_px: float, masked: np.ndarray,
                   where: str = "") -> Patches:
    """The patches of step 2; ``lit`` is where the model's Moon is sunlit (before the PSF)."""
    from scipy.ndimage import binary_dilation, binary_erosion
    shape = lit.shape
    r, along, ang = geom.coordinates(shape)
    m = margin_px / geom.radius_px
    it = max(int(np.ceil(margin_px)), 1)
    near_lit = binary_dilation(lit, iterations=it)
    # the sunlit patch keeps a third of the margin from the terminator and the limb: the model has
    # the same PSF, and the mask's edge lies a full margin beyond the lit region
    lit_core = binary_erosion(lit, iterations=max(int(np.ceil(margin_px / 3)), 1))
    mask_edge = np.zeros(shape, bool)
    if masked.any():
        mask_edge = binary_dilation(masked, iterations=it) & binary_dilation(~masked, iterations=it)
    earthlit = ((r >= EARTHLIT_INNER_RADII) & (r <= 1 - m) & (ang >= 180 - PATCH_HALF_ANGLE_DEG) & ~near_lit
                & ~masked & ~mask_edge)
    sunlit = (ang <= PATCH_HALF_ANGLE_DEG) & lit_core & ~mask_edge
    if masked.any():
        sunlit &= masked
    sky = (r >= 1 + m) & (ang >= 90) & ~masked & ~mask_edge
    for name, sel, need in (("earthlit", earthlit, MIN_PATCH_PIXELS), ("sunlit", sunlit, MIN_PATCH_PIXELS),
                            ("sky", sky, MIN_SKY_PIXELS)):
        if int(sel.sum()) < need:
            raise LunarvizError(f"{where}phase angle {geom.phase_deg:.1f} deg: the {name} patch has {int(sel.sum())} "
                                f"pixels (< {need}); the dark or the lit side is too thin, or the frame too small")
    return Patches(earthlit, sunlit, sky, r <= 1 + m)


def check_patches(geometry, inst) -> None:
    """Refuse, before any image is traced, a task whose patches cannot be selected: a geometric
    sphere's sunlit region (n·s > 0 on the disc, α the phase angle) stands in for the model's image
    (the PSF's reach and the margins are the same), so a full Moon is refused in milliseconds."""
    camera = instrument_camera(inst)
    geom, _, masked = masked_pixels(geometry, camera, inst.bright_side_nd, inst.margin_px())
    r, along, _ = geom.coordinates((camera.height, camera.width))
    a = np.radians(geom.phase_deg)
    lit = (r <= 1) & (along * np.sin(a) + np.sqrt(np.clip(1 - r * r, 0, 1)) * np.cos(a) > 0)
    select_patches(geom, lit, inst.margin_px(), masked)


@dataclass
class HaloFit:
    image: np.ndarray  # P: the image before the halo and the sky [e⁻ s⁻¹]
    fraction: float  # f
    sky: float  # b [e⁻ s⁻¹ per pixel]
    covariance: np.ndarray  # (2, 2) of (f, b)
    kp: np.ndarray  # K ⊛ P


def remove_halo(y: np.ndarray, var_y: np.ndarray, patches: Patches, kernel: np.ndarray | None) -> HaloFit:
    """Step 3 on the calibrated image ``y`` [e⁻ s⁻¹] with per-pixel variances ``var_y``.

    Ordinary least squares on the sky pixels (their variances hardly differ: read noise and a
    faint halo): weights from the data's own counts would bias the fit low (a pixel that fell low
    by chance would weigh more). Its covariance is the sandwich ``(AᵀA)⁻¹ Aᵀ V A (AᵀA)⁻¹`` with V
    the pixels' variances."""
    from scipy.signal import fftconvolve
    sky = patches.sky
    v = var_y[sky]
    p = np.where(patches.disc, y, 0.0)
    f, b = 0.0, 0.0
    kp = np.zeros_like(y)
    for _ in range(HALO_ROUNDS if kernel is not None else 1):
        f_prev, b_prev = f, b
        if kernel is not None:
            kp = fftconvolve(p, kernel, mode="same")
            A = np.stack([kp[sky], np.ones(int(sky.sum()))], axis=1)
        else:
            A = np.ones((int(sky.sum()), 1))
        inv = np.linalg.inv(A.T @ A)
        sol = inv @ (A.T @ y[sky])
        cov_fit = inv @ ((A.T * v) @ A) @ inv
        if kernel is not None:
            f, b = float(sol[0]), float(sol[1])
            cov = cov_fit
        else:
            b = float(sol[0])
            cov = np.array([[0.0, 0.0], [0.0, cov_fit[0, 0]]])
        p = np.where(patches.disc, (y - b - f * kp) / (1.0 - f), 0.0)
        if (abs(f - f_prev) <= HALO_TOLERANCE * max(abs(f), 1e-6)
                and abs(b - b_prev) <= HALO_TOLERANCE * max(abs(b), 1.0)):
            break
    return HaloFit(p, f, b, cov, kp)


@dataclass
class Calibration:
    """The model of an observation that the pipeline compares with: the patches, the modelled
    ratio R_A and what the calibration Earth's albedo A is."""

    instrument: Instrument
    exposure_s: float
    geometry: DiscGeometry
    patches: Patches
    masked: np.ndarray
    transmission: float  # the mask's τ (1: none)
    model_ratio: float  # R_A
    albedo: float  # A
    kernel: np.ndarray | None  # the halo's shape K (unit sum)


def calibrate(geometry: SceneGeometry, inst: Instrument, exposure_s: float, rates: dict, earth_albedo: float,
              key="") -> Calibration:
    """The pipeline's model of an observation: a uniform Lambert Earth of ``earth_albedo``.

    Parameters
    ----------
    geometry : SceneGeometry
        The task's bodies and detector.
    inst : Instrument
        The instrument.
    exposure_s : float
        Exposure [s].
    rates : dict
        The model Earth's photoelectron rates before the optics [e⁻ s⁻¹ per pixel]
        (``Observation.raw_rates`` of its image).
    earth_albedo : float
        The model Earth's Lambert albedo A.
    key : float or str
        The task's phase θ or time, which error messages name.

    Returns
    -------
    Calibration
        The patches, the model's earthlit/sunlit ratio R_A and A.
    """
    camera = instrument_camera(inst)
    psf, halo = optics_kernels(inst, camera)
    geom, mask, masked = masked_pixels(geometry, camera, inst.bright_side_nd, inst.margin_px())
    where = f"{key}: "
    patches = select_patches(geom, rates["moonshine"] > 0, inst.margin_px(), masked, where)
    es = apply_optics(rates["earthshine"], psf, None)
    ms = apply_optics(rates["moonshine"], psf, None)
    sunlit = float(np.mean((ms + es)[patches.sunlit]))
    if not sunlit > 0:
        raise LunarvizError(f"{where}the model's sunlit patch is dark")
    ratio = float(np.mean(es[patches.earthlit])) / sunlit
    return Calibration(inst, float(exposure_s), geom, patches, masked, mask.transmission if mask else 1.0,
                       ratio, float(earth_albedo), None if halo is None else halo[1])


@dataclass
class Noise:
    """Per-pixel variances of the calibrated image Y [(e⁻ s⁻¹)²], split by source."""

    photon: np.ndarray
    read_dark: np.ndarray

    @property
    def total(self) -> np.ndarray:
        return self.photon + self.read_dark


def calibrated_image(mean_counts: np.ndarray, n_frames: int, cal: Calibration) -> tuple[np.ndarray, Noise]:
    """Step 1: Y [e⁻ s⁻¹] from the mean of ``n_frames`` frames [ADU], and its variances (from the data)."""
    inst, t = cal.instrument, cal.exposure_s
    charge = (np.asarray(mean_counts, dtype=float) - inst.bias_adu) * inst.gain_e_per_adu
    dark = inst.dark_current_e_per_s * t
    scale = np.where(cal.masked, 1.0 / cal.transmission, 1.0)
    y = (charge - dark) / t * scale
    photon = np.maximum(charge - dark, 0.0) / (t * t * n_frames) * scale**2
    read_dark = (dark + inst.read_noise_e**2 + inst.gain_e_per_adu**2 / 12.0) / (t * t * n_frames) * scale**2
    return y, Noise(photon, read_dark)


def patch_mean_variance(var: np.ndarray, sel: np.ndarray, f: float) -> float:
    n = int(sel.sum())
    return float(np.sum(var[sel])) / n**2 / (1.0 - f) ** 2


def measure(mean_counts: np.ndarray, n_frames: int, cal: Calibration, peak_counts: np.ndarray | None = None) -> dict:
    """Steps 1-4 on the mean of ``n_frames`` frames: p* and its noise terms (1σ, in p*).

    ``peak_counts``: each pixel's highest count over the frames (default ``mean_counts``); a patch
    or sky pixel at the saturation level is refused (its charge is lost, not measured)."""
    pt = cal.patches
    inst = cal.instrument
    peak = mean_counts if peak_counts is None else peak_counts
    used = pt.earthlit | pt.sunlit | pt.sky
    # a full well reads SATURATE ± the read noise: five of its σ below counts as saturated
    n_sat = int(np.count_nonzero(used & (peak >= inst.saturate_adu - 5 * inst.read_noise_e / inst.gain_e_per_adu)))
    if n_sat:
        raise LunarvizError(f"{n_sat} patch or sky pixels reach the saturation level ({inst.saturate_adu:g} "
                            f"ADU) at exposure {cal.exposure_s:g} s: a shorter exposure (lunarviz plan)")
    y, noise = calibrated_image(mean_counts, n_frames, cal)
    fit = remove_halo(y, noise.total, pt, cal.kernel)
    f = fit.fraction
    pe, ps = float(np.mean(fit.image[pt.earthlit])), float(np.mean(fit.image[pt.sunlit]))
    if not (pe > 0 and ps > 0):
        raise LunarvizError(f"the earthlit ({pe:.3g}) or sunlit ({ps:.3g}) patch is not positive after the halo's "
                            f"removal: too little signal (a longer exposure or more frames)")
    ratio = pe / ps
    p_star = cal.albedo * ratio / cal.model_ratio
    rel2 = {}
    for name, var in (("photon", noise.photon), ("read_dark", noise.read_dark)):
        rel2[name] = patch_mean_variance(var, pt.earthlit, f) / pe**2 + patch_mean_variance(var, pt.sunlit, f) / ps**2
    kp_e = float(np.mean(fit.kp[pt.earthlit]))
    g = np.array([(pe - kp_e) / (1.0 - f), -1.0 / (1.0 - f)])
    rel2["halo"] = float(g @ fit.covariance @ g) / pe**2
    sig = {k: p_star * np.sqrt(v) for k, v in rel2.items()}
    return {"p_star": p_star, "p_star_sigma": float(np.sqrt(sum(s**2 for s in sig.values()))),
            "sigma_photon": sig["photon"], "sigma_read_dark": sig["read_dark"], "sigma_halo_fit": sig["halo"],
            "ratio_observed": ratio, "ratio_model": cal.model_ratio, "halo_fraction": f, "sky_e_s": fit.sky,
            "earthlit_e_s": pe, "sunlit_e_s": ps, "earthlit_pixels": int(pt.earthlit.sum()),
            "sunlit_pixels": int(pt.sunlit.sum()), "sky_pixels": int(pt.sky.sum()), "frames": int(n_frames)}
