"""Earth albedo from the earthshine/moonshine ratio: paper Eqs. 15-17, Eq. 17 corrected (the
documentation's paper notes, item 4).

The equations::

    Eq. 15:  p_E f_E(β) = [p_b f_b(θ) / (p_a f_a(θ0))] · (E_a / E_b) · D_EM² D_SE² / (R_E² D_SM²)
    Eq. 16:  p*(β) = 3 / (2 f_L(β)) · p_E f_E(β)
    Eq. 17 (corrected):  A = (2/3) ∫_{-π}^{π} p* f_L |sin β| dβ = (4/3) ∫_0^π p*(β) f_L(β) sin β dβ

E_a is the earthshine and E_b the moonshine irradiance at the detector. The lunar terms are
the Moon's disk-integrated reflectance in each geometry, taken from a *calibration* transport
(see :func:`lunar_terms`): using the same transport that produced the fluxes makes the
inversion consistent; using the point-source model on extended-Earth fluxes reproduces the
paper's inversion and its bias (``table5_point_source_inversion`` of ``lunarviz paper``).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np

from lunarviz.errors import ApparentAlbedoWarning, LunarvizError
from lunarviz.geometry.scene_geometry import SceneGeometry
from lunarviz.photometry.earth_phase import lambert_phase_function


@dataclass(frozen=True)
class LunarTerms:
    """Lunar reflectance terms of Eq. 15 (dimensionless)."""

    pa_fa: float  # p_a f_a(θ0): the Moon lit by the Earth, seen from the detector
    pb_fb: float  # p_b f_b(θ): the Moon lit by the Sun, seen from the detector


def lunar_terms(scene: SceneGeometry, earthshine_cal: float, moonshine_cal: float,
                earth_albedo_cal: float) -> LunarTerms:
    """Lunar terms from a calibration transport's fluxes [W m⁻²].

    p_b f_b = E_b · D_EM² / (E_sun,M R_M²) and p_a f_a = E_a · D_EM² / (E_earth,M R_M²), where
    E_sun,M = Φ/(4π D_SM²) and E_earth,M = I_cal(β)/D_EM² with I_cal the Lambert-sphere
    intensity of the calibration Earth (albedo ``earth_albedo_cal``) at the Moon's centre.
    """
    d_em, d_sm, d_se = scene.d_em_actual, scene.d_sm, scene.d_se_actual
    r_m, r_e = scene.radii["moon"], scene.radii["earth"]
    beta = np.radians(scene.beta_deg)
    e_sun_m = scene.phi / (4 * np.pi * d_sm**2)
    intensity = (2 / 3) * earth_albedo_cal * r_e**2 * scene.phi / (4 * np.pi * d_se**2) \
        * lambert_phase_function(beta)
    e_earth_m = intensity / d_em**2
    pa = earthshine_cal * d_em**2 / (e_earth_m * r_m**2) if e_earth_m > 0 else np.nan
    pb = moonshine_cal * d_em**2 / (e_sun_m * r_m**2)
    return LunarTerms(float(pa), float(pb))


#: Below this disk-integrated lunar reflectance p_b f_b (≈ 1e-4 at θ = 175°, ≈ 1e-15 at new
#: Moon) the Moon shows no measurable sunlit side and Eq. 15 is a ratio of round-off or noise.
MIN_LUNAR_TERM = 1e-9


def geometric_albedo_term(scene: SceneGeometry, earthshine: float, moonshine: float,
                          terms: LunarTerms) -> float:
    """p_E f_E(β), paper Eq. 15; NaN where it is undefined: no moonshine (new Moon, eclipse,
    occultation), no earthlight on the Moon (full Moon), or no earthlit Moon in the detector's
    view (a detector behind the Moon)."""
    d_em, d_sm, d_se, r_e = scene.d_em_actual, scene.d_sm, scene.d_se_actual, scene.radii["earth"]
    # undefined without a measurable sunlit Moon (p_b f_b) or without a measurable earthlit
    # Moon seen from the detector (p_a f_a: e.g. a detector behind the Moon sees ~1e-16 W m-2)
    if not (moonshine > 0 and terms.pb_fb > MIN_LUNAR_TERM and terms.pa_fa > MIN_LUNAR_TERM
            and np.isfinite(terms.pa_fa)):
        return float("nan")
    val = (terms.pb_fb / terms.pa_fa) * (earthshine / moonshine) * d_em**2 * d_se**2 / (r_e**2 * d_sm**2)
    return float(val) if np.isfinite(val) else float("nan")


def apparent_albedo(beta_deg: float, pe_fe: float, min_phase_function: float = 1e-9) -> float:
    """p*(β) = 3 p_E f_E / (2 f_L(β)), paper Eq. 16; NaN where f_L(β) vanishes (β → 180°)."""
    f = float(lambert_phase_function(np.radians(beta_deg)))
    if not np.isfinite(pe_fe) or f < min_phase_function:
        return float("nan")
    return 1.5 * pe_fe / f


def bond_weights(beta_deg: np.ndarray) -> np.ndarray:
    """Weights w_k with (4/3) Σ w_k p*_k = (4/3) ∫₀^π p* f_L sin β dβ for piecewise-linear p*.

    The kernel K = f_L(β) sin β is known, so each hat function is integrated against it exactly
    (20-point Gauss-Legendre per segment: K is analytic, error at rounding level). Outside the
    sampled range p* is held constant at the end value. ``Σ w_k = ∫₀^π K = 3/4`` exactly, so a
    constant p* ≡ A returns A.
    """
    b = np.radians(np.asarray(beta_deg, dtype=float))
    order = np.argsort(b)
    bs = b[order]
    if np.any(np.diff(bs) <= 0):
        raise LunarvizError("Bond albedo needs distinct phase angles")
    x, wx = np.polynomial.legendre.leggauss(20)

    def kernel_integral(lo, hi, f):
        t = 0.5 * (hi - lo) * (x + 1) + lo
        return 0.5 * (hi - lo) * np.sum(wx * f(t) * lambert_phase_function(t) * np.sin(t))

    w = np.zeros(len(bs))
    if bs[0] > 0:
        w[0] += kernel_integral(0.0, bs[0], lambda t: np.ones_like(t))
    if bs[-1] < np.pi:
        w[-1] += kernel_integral(bs[-1], np.pi, lambda t: np.ones_like(t))
    for k in range(len(bs) - 1):
        lo, hi = bs[k], bs[k + 1]
        w[k] += kernel_integral(lo, hi, lambda t: (hi - t) / (hi - lo))
        w[k + 1] += kernel_integral(lo, hi, lambda t: (t - lo) / (hi - lo))
    out = np.empty_like(w)
    out[order] = w
    return out


def bond_albedo(beta_deg, p_star) -> float:
    """Bond albedo from sampled apparent albedo, corrected Eq. 17 (paper notes, item 4).

    Samples where p* is not finite (0/0 at β = 180°, eclipses) are dropped; the constant
    extension of :func:`bond_weights` covers them (their kernel weight is tiny: K ~ (π-β)³).
    """
    beta_deg = np.asarray(beta_deg, dtype=float)
    p_star = np.asarray(p_star, dtype=float)
    ok = np.isfinite(p_star)
    if ok.sum() < 2:
        return float("nan")
    _, idx = np.unique(beta_deg[ok], return_index=True)
    bd, ps = beta_deg[ok][idx], p_star[ok][idx]
    return float(4.0 / 3.0 * np.dot(bond_weights(bd), ps))


def warn_non_lambert_apparent_albedo(rows: list[dict]) -> None:
    """Warn once, after a run, when some rows' p* leaves 0-1, the range of a Lambert sphere's
    (its p* is its albedo at every β): Eq. 16 reads the Earth as a Lambert sphere, so such a p*
    is not an albedo (a physical Earth's crescent is brighter than a Lambert sphere's; near full
    Moon, β → 180°, f_L(β) → 0 and the earthlit Moon is a thin crescent)."""
    out = [r for r in rows if isinstance(r.get("apparent_albedo"), float) and math.isfinite(r["apparent_albedo"])
           and not 0.0 <= r["apparent_albedo"] <= 1.0]
    if out:
        worst = max(out, key=lambda r: abs(r["apparent_albedo"] - 0.5))
        at = worst.get("time_utc") or f"θ = {worst.get('theta_deg', float('nan')):g}°"
        warnings.warn(f"{len(out)} of {len(rows)} rows have an apparent albedo p* outside 0-1, which no Lambert "
                      f"sphere gives (its p* is its albedo at every phase): p* = {worst['apparent_albedo']:.3g} at "
                      f"{at} (Earth phase β = {worst.get('beta_deg', float('nan')):.1f}°); such a p* is not an "
                      "albedo: the Earth's phase law is not Lambert's there", ApparentAlbedoWarning, stacklevel=3)
