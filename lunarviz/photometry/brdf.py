"""Lunar BRDFs: Lambert and Hapke (paper Eq. 12) with single or double Henyey-Greenstein phase
functions (Eqs. 13-14), vectorised over float64 arrays.

Every model evaluates ``brdf(mu0, mu, sin_hg, cos_hg)`` [sr⁻¹] where ``mu0 = cos i``,
``mu = cos e`` and ``sin_hg``, ``cos_hg`` are the sine and cosine of *half* the phase angle g.
Passing the half-angle (from :func:`lunarviz.geometry.scene_geometry.half_angle_sin_cos` or
:func:`half_angle_from_angles`) keeps full precision near g = 0, where the opposition surge
lives, and near g = π, where a forward HG lobe with b → 1 lives (paper notes, "Numerics of the Hapke model").

``radiance_factor = brdf * mu0`` is finite even where μ0 + μ → 0 (the BRDF diverges there,
the reflected radiance does not); transport code uses it.

Options beyond the paper (off by default, so the defaults are the paper's model, bit for bit):
Hapke's macroscopic roughness θ̄ (1984) and the coherent-backscatter opposition effect (2002),
:mod:`lunarviz.photometry.roughness`. Neglected: the porosity factor K.

References
----------
Hapke, B. (1981) J. Geophys. Res. 86, 3039, doi:10.1029/JB086iB04p03039 (Eq. 12, H-function).
Hapke, B. (2002) Icarus 157, 523, doi:10.1006/icar.2002.6853 (improved H-function, Eq. 13).
Hapke, B. (2012) Theory of Reflectance and Emittance Spectroscopy, 2nd ed., Eq. 6.7 (DHG).
Chandrasekhar, S. (1960) Radiative Transfer, Ch. V (exact H-function for isotropic scattering).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

import lunarviz.constants as C
from lunarviz.caches import memoize
from lunarviz.errors import LunarvizError, unknown_choice
from lunarviz.options import BRDF_NAMES, BY_NAME, DHG_CONVENTIONS, H_FUNCTIONS, THETA_MOON_MODEL
from lunarviz.photometry.presets import moon_model_params
from lunarviz.photometry.roughness import azimuth_from_half_angle, coherent_backscatter, shadowing

#: parameters each named BRDF accepts (``--param``)
BRDF_PARAMETERS = {"lambert": ("albedo",),
                   "shg": ("w", "h", "B0", "xi", "theta_bar", "Bc0", "hc"),
                   "dhg": ("w", "h", "B0", "b", "c", "theta_bar", "Bc0", "hc")}

#: the ranges a fit to disk-integrated reflectance explores (θ̄ in degrees; ``map_contrast`` scales a
#: lunar albedo map's contrast): narrower than the models accept where wider values are unphysical
FIT_BOUNDS = {"w": (0.01, 0.99), "h": (0.001, 0.5), "B0": (0.0, 5.0), "b": (0.0, 0.95), "c": (-1.0, 1.0),
              "xi": (-0.95, 0.95), "theta_bar": (0.0, 45.0), "Bc0": (0.0, 3.0), "hc": (0.0005, 0.3),
              "albedo": (0.001, 1.0), "map_contrast": (0.0, 3.0)}

# Below this μ0 + μ (light arriving and leaving within ~1e-12 rad of the horizon, where cos 90°
# rounds to 6e-17) the bare BRDF's 1/(μ0 + μ) of Eq. 12 is singular and carries no light (its
# radiance factor BRDF·μ0 vanishes with μ0): the BRDF is returned as 0 there, not ~1e15.
_DOUBLE_GRAZING = 1e-12


def _check(name: str, value: float, lo: float, hi: float, lo_open=False, hi_open=False) -> float:
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise LunarvizError(f"BRDF parameter {name}={value!r} is not a number") from None
    ok = np.isfinite(value) and (value > lo if lo_open else value >= lo) and (
        value < hi if hi_open else value <= hi)
    if not ok:
        lb, rb = ("(" if lo_open else "["), (")" if hi_open else "]")
        raise LunarvizError(f"BRDF parameter {name}={value!r} is outside its allowed range {lb}{lo}, {hi}{rb}")
    return value


def half_angle_from_angles(i, e, azimuth) -> tuple[np.ndarray, np.ndarray]:
    """sin(g/2), cos(g/2) from incidence i, emission e and azimuth ψ [rad].

    Azimuth 0 puts the viewer on the source's side (``g = |i - e|``), π on the far side
    (g = i + e). Uses the cancellation-free identities
    ``sin²(g/2) = sin²((i-e)/2) + sin i sin e sin²(ψ/2)`` and
    ``cos²(g/2) = cos²((i+e)/2) + sin i sin e cos²(ψ/2)``.
    """
    i, e, a = (np.asarray(x, dtype=float) for x in (i, e, azimuth))
    sisе = np.sin(i) * np.sin(e)
    s2 = np.sin(0.5 * (i - e)) ** 2 + sisе * np.sin(0.5 * a) ** 2
    c2 = np.cos(0.5 * (i + e)) ** 2 + sisе * np.cos(0.5 * a) ** 2
    s2, c2 = np.clip(s2, 0.0, None), np.clip(c2, 0.0, None)
    norm = np.sqrt(s2 + c2)
    return np.sqrt(s2) / norm, np.sqrt(c2) / norm


# --------------------------------------------------------------------------------------------
# Phase functions (normalised to 1 over 4π sr, i.e. ∫ p dΩ / 4π = 1)
# --------------------------------------------------------------------------------------------
def _hg_lobe(x: float, sin_hg, cos_hg, backward: bool):
    """One HG lobe of asymmetry magnitude x ∈ [0, 1) in terms of the half phase angle.

    ``backward=True``: ``(1-x²)/(1 - 2x cos g + x²)^1.5`` peaks at g = 0 (backscatter);
    denominator written ``(1-x)² + 4x sin²(g/2)``. ``backward=False``: ``1 + 2x cos g + x²``
    ``= (1-x)² + 4x cos²(g/2)``, peaking at g = π (forward scattering).
    """
    t = sin_hg if backward else cos_hg
    return (1.0 - x * x) / ((1.0 - x) ** 2 + 4.0 * x * t * t) ** 1.5


@dataclass(frozen=True)
class SingleHG:
    """Single Henyey-Greenstein phase function, paper Eq. 13: ``(1-ξ²)/(1+2ξ cos g+ξ²)^1.5``.

    ξ < 0 scatters backward (toward g = 0); the paper's Table 2 has ξ = -0.075.
    """

    xi: float = -0.075

    def __post_init__(self):
        _check("xi", self.xi, -1.0, 1.0, lo_open=True, hi_open=True)

    def __call__(self, sin_hg, cos_hg):
        # 1 + 2ξ cos g + ξ² = 1 + 2|ξ|·(±cos g) + ξ²: a backward lobe of |ξ| for ξ < 0.
        return _hg_lobe(abs(self.xi), sin_hg, cos_hg, backward=self.xi < 0)

    @property
    def params(self) -> dict:
        return {"xi": self.xi}


@dataclass(frozen=True)
class DoubleHG:
    """Double Henyey-Greenstein phase function, paper Eq. 14, in two sign conventions.

    ``convention="paper"`` (as printed): weight (1+c)/2 on the lobe ``1 + 2b cos g + b²``,
    which peaks at g = π (forward). ``convention="hapke2012"``: weight (1+c)/2 on the backward
    lobe ``1 - 2b cos g + b²`` (c > 0 backscatters). They are mirror images:
    ``P_hapke2012(g; b, c) = P_paper(π - g; b, c) = P_paper(g; b, -c)`` (paper notes, item 2).
    """

    b: float = 0.308
    c: float = 0.425
    convention: str = BY_NAME["dhg_convention"].default

    def __post_init__(self):
        _check("b", self.b, 0.0, 1.0, hi_open=True)
        _check("c", self.c, -1.0, 1.0)
        if self.convention not in DHG_CONVENTIONS:
            raise unknown_choice("DHG convention", self.convention, DHG_CONVENTIONS)

    def __call__(self, sin_hg, cos_hg):
        fwd = _hg_lobe(self.b, sin_hg, cos_hg, backward=False)
        bwd = _hg_lobe(self.b, sin_hg, cos_hg, backward=True)
        w_plus, w_minus = 0.5 * (1.0 + self.c), 0.5 * (1.0 - self.c)
        if self.convention == "paper":
            return w_plus * fwd + w_minus * bwd
        return w_plus * bwd + w_minus * fwd

    @property
    def params(self) -> dict:
        return {"b": self.b, "c": self.c}


# --------------------------------------------------------------------------------------------
# Chandrasekhar H-functions for isotropic scatterers
# --------------------------------------------------------------------------------------------
def h_hapke1981(x, w: float):
    """Hapke (1981) approximation ``H(x) = (1+2x)/(1+2γx)``, ``γ = √(1-w)``."""
    g = np.sqrt(1.0 - w)
    return (1.0 + 2.0 * x) / (1.0 + 2.0 * g * x)


def h_hapke2002(x, w: float):
    """Hapke (2002) Eq. 13: ``H = [1 - w x (r0 + (1 - 2 r0 x)/2 · ln((1+x)/x))]⁻¹``.

    ``r0 = (1-γ)/(1+γ)``. ``x ln((1+x)/x) → 0`` as x → 0, so H(0) = 1 is set explicitly.
    """
    x = np.asarray(x, dtype=float)
    g = np.sqrt(1.0 - w)
    r0 = (1.0 - g) / (1.0 + g)
    safe = np.where(x > 0.0, x, 1.0)
    xlog = np.where(x > 0.0, x * (np.log1p(safe) - np.log(safe)), 0.0)
    return 1.0 / (1.0 - w * (r0 * x + 0.5 * (1.0 - 2.0 * r0 * x) * xlog))


@memoize(maxsize=64)
def _chandrasekhar_nodes(w: float, n: int = 96):
    """Gauss-Legendre nodes x_k ∈ (0, 1), weights and converged H(x_k) for albedo w.

    Solves ``1/H(x) = √(1-w) + (w/2) ∫₀¹ x' H(x')/(x + x') dx'`` (Chandrasekhar 1960,
    Eq. V.(43) rearranged; the form is contracting for w ≤ 1) by Newton iteration.
    Nodes are clustered toward 0 with x' = u³ so the near-singular kernel at small x is
    resolved; tests compare with the independent integral representation to 1e-10.
    """
    u, wu = np.polynomial.legendre.leggauss(n)
    u = 0.5 * (u + 1.0)
    xk = u**3
    wk = wu * 0.5 * 3.0 * u * u  # dx = 3u² du, du = dU/2
    g = np.sqrt(1.0 - w)
    H = h_hapke1981(xk, w)
    kern = 0.5 * w * xk[None, :] * wk[None, :] / (xk[:, None] + xk[None, :])
    # Newton on F(H) = H (g + K H) - 1 = 0: quadratic convergence, also in the conservative
    # case w = 1 where plain fixed-point iteration crawls.
    for _ in range(100):
        KH = kern @ H
        F = H * (g + KH) - 1.0
        J = np.diag(g + KH) + H[:, None] * kern
        step = np.linalg.solve(J, F)
        H = H - step
        if np.max(np.abs(step)) < 1e-15 * np.max(np.abs(H)):
            break
    return xk, wk, H


def h_exact(x, w: float):
    """Exact Chandrasekhar H-function for isotropic scattering with albedo w (Nyström).

    Evaluated anywhere on [0, 1] by the Nyström extension of the converged node values, which
    is exact at the nodes and gives H(0) = 1 to rounding.
    """
    x = np.asarray(x, dtype=float)
    xk, wk, Hk = _chandrasekhar_nodes(float(w))
    shape = x.shape
    xf = x.reshape(-1)
    out = np.empty_like(xf)
    g = np.sqrt(1.0 - w)
    step = 65536
    for a in range(0, xf.size, step):
        xs = xf[a:a + step]
        s = (xk * wk * Hk)[None, :] / (xs[:, None] + xk[None, :])
        out[a:a + step] = 1.0 / (g + 0.5 * w * s.sum(axis=1))
    return out.reshape(shape)


_H_IMPL = {"hapke1981": h_hapke1981, "hapke2002": h_hapke2002, "exact": h_exact}


# --------------------------------------------------------------------------------------------
# BRDF models
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Lambert:
    """Lambertian surface: ``BRDF = albedo / π`` [sr⁻¹]."""

    albedo: float = C.MOON_LAMBERT_ALBEDO
    name: str = field(default="lambert", compare=False)
    #: the radiance is linear in ``albedo``: a map's spread within a facet needs no correction
    linear_in_albedo = True

    def __post_init__(self):
        _check("albedo", self.albedo, 0.0, 1.0)

    @property
    def albedo_parameter(self) -> float:
        """The parameter an albedo map scales (:mod:`lunarviz.surfaces.maps`): ``albedo``."""
        return self.albedo

    def brdf(self, mu0, mu, sin_hg, cos_hg, albedo=None):
        """``albedo`` (an array broadcasting with the angles) replaces the scalar per sample."""
        a = self.albedo if albedo is None else albedo
        shape = np.broadcast(np.asarray(mu0), np.asarray(mu), np.asarray(sin_hg), np.asarray(a)).shape
        return np.broadcast_to(np.asarray(a, dtype=float) / np.pi, shape).copy()

    def radiance_factor(self, mu0, mu, sin_hg, cos_hg, albedo=None):
        """``BRDF · μ0`` [sr⁻¹]: reflected radiance per unit incident normal irradiance."""
        return self.brdf(mu0, mu, sin_hg, cos_hg, albedo) * np.clip(mu0, 0.0, 1.0)

    @property
    def params(self) -> dict:
        return {"albedo": self.albedo}

    def with_params(self, **kw) -> "Lambert":
        return replace(self, **kw)


@dataclass(frozen=True)
class Hapke:
    """Hapke BRDF for a smooth, semi-infinite surface [sr⁻¹].

    Paper Eq. 12::

        BRDF = w/(4π) · 1/(μ0 + μ) · {[1 + B(g)] p(g) + H(μ0) H(μ) - 1}
        B(g) = B0 h / (h + tan(g/2))           (finite as h → 0; B(0) = B0 for h > 0)

    Parameters
    ----------
    w : single-scattering albedo, [0, 1]
    h : opposition-surge width, [0, ∞) (h = 0 switches the surge off except at g = 0 exactly)
    B0 : opposition-surge amplitude, [0, ∞)
    phase : :class:`SingleHG` or :class:`DoubleHG`
    h_function : ``"hapke1981"`` (default; paper notes, item 3), ``"hapke2002"`` or ``"exact"``
    """

    w: float = 0.33
    h: float = 0.017
    B0: float = 1.0
    phase: SingleHG | DoubleHG = field(default_factory=DoubleHG)
    h_function: str = BY_NAME["h_function"].default
    name: str = field(default="hapke", compare=False)
    #: macroscopic roughness, mean slope angle θ̄ [deg] (Hapke 1984); 0 = smooth (the paper)
    theta_bar: float = 0.0
    #: coherent-backscatter amplitude B_C0 and width h_C (Hapke 2002); B_C0 = 0 = none (the paper)
    Bc0: float = 0.0
    hc: float = 0.05

    def __post_init__(self):
        _check("w", self.w, 0.0, 1.0)
        _check("h", self.h, 0.0, np.inf, hi_open=True)
        _check("B0", self.B0, 0.0, np.inf, hi_open=True)
        _check("theta_bar", self.theta_bar, 0.0, 60.0, hi_open=True)
        _check("Bc0", self.Bc0, 0.0, np.inf, hi_open=True)
        _check("hc", self.hc, 0.0, np.inf, lo_open=True, hi_open=True)
        if self.h_function not in H_FUNCTIONS:
            raise unknown_choice("H-function", self.h_function, H_FUNCTIONS)

    @property
    def rough(self) -> bool:
        """Roughness or coherent backscatter switched on (else the paper's smooth model)."""
        return self.theta_bar > 0.0 or self.Bc0 > 0.0

    @property
    def albedo_parameter(self) -> float:
        """The parameter an albedo map scales (:mod:`lunarviz.surfaces.maps`): ``w``."""
        return self.w

    def _w(self, albedo):
        if albedo is None:
            return self.w
        if self.h_function == "exact":
            raise LunarvizError("the exact H-function takes one w, not a per-facet map: use h_function "
                                "hapke1981 or hapke2002 with an albedo map")
        return albedo

    def _rough_r(self, mu0, mu, sin_hg, cos_hg, w=None):
        """Bidirectional reflectance r = BRDF·μ0 with roughness and coherent backscatter,
        Hapke (1984) Eq. 51 and Hapke (2002) Eq. 8 (:mod:`lunarviz.photometry.roughness`)."""
        mu0 = np.clip(mu0, 0.0, 1.0)
        mu = np.clip(mu, 0.0, 1.0)
        psi = azimuth_from_half_angle(mu0, mu, sin_hg)
        mu0e, mue, S = shadowing(mu0, mu, psi, np.radians(self.theta_bar))
        w = self.w if w is None else w
        br = (1.0 + self.surge(sin_hg, cos_hg)) * self.phase(sin_hg, cos_hg) + self.H(mu0e, w) * self.H(mue, w) - 1.0
        if self.Bc0 > 0.0:
            br = br * (1.0 + self.Bc0 * coherent_backscatter(sin_hg, cos_hg, self.hc))
        s = mu0e + mue
        frac = np.where(s > 0.0, mu0e / np.where(s > 0.0, s, 1.0), 0.0)
        return w / (4.0 * np.pi) * frac * br * S

    def H(self, x, w=None):
        """Chandrasekhar's H(x) for this model's w (or ``w``, an array broadcasting with x)."""
        return _H_IMPL[self.h_function](np.clip(x, 0.0, 1.0), self.w if w is None else w)

    def surge(self, sin_hg, cos_hg):
        """Opposition surge ``B(g) = B0 h/(h + tan(g/2)) = B0 h cos/(h cos + sin)`` (half angles)."""
        num = self.h * cos_hg
        den = num + sin_hg
        at_zero = den <= 0.0  # only for h = 0 at g = 0 exactly, or g = π with h·0
        return self.B0 * np.where(at_zero, np.where(sin_hg <= 0.0, 1.0, 0.0), num / np.where(at_zero, 1.0, den))

    def _bracket(self, mu0, mu, sin_hg, cos_hg, w=None):
        mu0 = np.clip(mu0, 0.0, 1.0)
        mu = np.clip(mu, 0.0, 1.0)
        return mu0, mu, (1.0 + self.surge(sin_hg, cos_hg)) * self.phase(sin_hg, cos_hg) + \
            self.H(mu0, w) * self.H(mu, w) - 1.0

    def brdf(self, mu0, mu, sin_hg, cos_hg, albedo=None):
        """``albedo`` (an array of w broadcasting with the angles) replaces w per sample."""
        w = self._w(albedo)
        if self.rough:
            r = self._rough_r(mu0, mu, sin_hg, cos_hg, w)
            m0 = np.clip(mu0, 0.0, 1.0)
            live = (m0 > 0.0) & (m0 + np.clip(mu, 0.0, 1.0) > _DOUBLE_GRAZING)
            return np.where(live, r / np.where(live, m0, 1.0), 0.0)
        mu0, mu, br = self._bracket(mu0, mu, sin_hg, cos_hg, w)
        s = mu0 + mu
        return np.where(s > _DOUBLE_GRAZING, w / (4.0 * np.pi) * br / np.where(s > _DOUBLE_GRAZING, s, 1.0), 0.0)

    def radiance_factor(self, mu0, mu, sin_hg, cos_hg, albedo=None):
        """``BRDF · μ0`` [sr⁻¹], written ``w/(4π) · μ0/(μ0+μ) · {…}``: finite at grazing."""
        w = self._w(albedo)
        if self.rough:
            return self._rough_r(mu0, mu, sin_hg, cos_hg, w)
        mu0, mu, br = self._bracket(mu0, mu, sin_hg, cos_hg, w)
        s = mu0 + mu
        frac = np.where(s > 0.0, mu0 / np.where(s > 0.0, s, 1.0), 0.0)
        return w / (4.0 * np.pi) * frac * br

    @property
    def params(self) -> dict:
        extra = {"theta_bar": self.theta_bar, "Bc0": self.Bc0, "hc": self.hc} if self.rough else {}
        return {"w": self.w, "h": self.h, "B0": self.B0, **self.phase.params, **extra}

    def with_params(self, **kw) -> "Hapke":
        phase_kw = {k: kw.pop(k) for k in list(kw) if k in ("xi", "b", "c")}
        phase = replace(self.phase, **phase_kw) if phase_kw else self.phase
        return replace(self, phase=phase, **kw)


def brdf_from_angles(model, i, e, azimuth):
    """BRDF [sr⁻¹] of ``model`` at incidence i, emission e, azimuth ψ [rad] (see
    :func:`half_angle_from_angles` for the azimuth convention)."""
    s, c = half_angle_from_angles(i, e, azimuth)
    # (sin(π/2 − x): exactly 0 at 90°, where cos rounds to 6e-17)
    return model.brdf(np.sin(np.pi / 2 - np.asarray(i, dtype=float)), np.sin(np.pi / 2 - np.asarray(e, dtype=float)),
                      s, c)


def make_brdf(name: str, *, dhg_convention: str = BY_NAME["dhg_convention"].default,
              h_function: str = BY_NAME["h_function"].default, params: dict | None = None,
              moon_model: str | None = THETA_MOON_MODEL):
    """Build a named BRDF, with the parameters of preset ``moon_model`` (``paper`` or a fitted
    set, :mod:`lunarviz.photometry.presets`) and optional overrides ``params`` on top.

    ``lambert``: Lambert, albedo 0.10 (paper Table 5). ``shg``: Hapke with SHG,
    ``dhg``: Hapke with DHG; both with the paper's Table 2 parameters (Apollo 11 soil 10084,
    750 nm): w = 0.33, h = 0.017, B0 = 1, ξ = -0.075 / b = 0.308, c = 0.425.
    """
    key = str(name).strip().lower()
    moon_model = THETA_MOON_MODEL if moon_model is None else moon_model  # (a table has no date)
    if key in BRDF_NAMES and moon_model != THETA_MOON_MODEL:
        params = {**moon_model_params(moon_model, key), **(params or {})}
    if params is not None and not isinstance(params, dict):
        raise LunarvizError(f"params {params!r} must be a mapping {{name: value}}")
    params = dict(params or {})
    if key == "lambert":
        allowed = set(BRDF_PARAMETERS["lambert"])
        model = Lambert()
    elif key == "shg":
        allowed = set(BRDF_PARAMETERS["shg"])
        model = Hapke(phase=SingleHG(-0.075), h_function=h_function, name="shg")
    elif key == "dhg":
        allowed = set(BRDF_PARAMETERS["dhg"])
        model = Hapke(phase=DoubleHG(0.308, 0.425, dhg_convention), h_function=h_function, name="dhg")
    else:
        raise unknown_choice("BRDF", name, BRDF_NAMES)
    bad = sorted(set(params) - allowed)
    if bad:
        raise LunarvizError(f"unknown parameter {bad[0]!r} for BRDF {key!r}: allowed {', '.join(sorted(allowed))}")
    return model.with_params(**params) if params else model


def directional_hemispherical_reflectance(model, mu0: float, n: int = 64) -> float:
    """∫ BRDF μ dΩ over the outgoing hemisphere for incidence cos i = mu0 (Gauss quadrature)."""
    x, wx = np.polynomial.legendre.leggauss(n)
    mu = 0.5 * (x + 1.0)
    wmu = 0.5 * wx
    psi = np.linspace(0.0, 2 * np.pi, 2 * n, endpoint=False) + np.pi / (2 * n)
    MU, PSI = np.meshgrid(mu, psi, indexing="ij")
    i = np.arccos(mu0)
    e = np.arccos(MU)
    f = brdf_from_angles(model, np.full_like(MU, i), e, PSI) * MU
    return float(np.sum(f * wmu[:, None]) * (2 * np.pi / (2 * n)))
