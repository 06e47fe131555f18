"""Scene geometry: body positions from the orbital angle (paper Eq. 3) and angles from vectors.

Frame (paper Fig. 2): Earth at the origin, Sun at ``(0, 0, -D_SE)``, Moon at
``(0, D_EM sin θ, D_EM cos θ)``; θ = 0 is full Moon (and, in exact geometry, a total lunar
eclipse), θ = 180° new Moon. All angles here are computed from the actual position vectors,
with Kahan's ``angle = 2 atan2(|a - b|, |a + b|)`` for unit vectors, which keeps full precision
near 0 and π. We neglect light-travel time and the Earth's and Moon's orbital motion during a
measurement (a static scene).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import constants as C


def unit(v: np.ndarray) -> np.ndarray:
    """Unit vectors along the last axis of ``v`` ((..., 3))."""
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def angle_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle [rad] between vectors ``a`` and ``b`` ((..., 3)), accurate near 0 and π.

    Kahan, "Mindless" (2006), Sec. 12: ``2 atan2(|â - b̂|, |â + b̂|)``.
    """
    ua, ub = unit(a), unit(b)
    return 2.0 * np.arctan2(np.linalg.norm(ua - ub, axis=-1), np.linalg.norm(ua + ub, axis=-1))


def half_angle_sin_cos(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``sin(g/2)`` and ``cos(g/2)`` of the angle g between unit vectors a and b ((..., 3)).

    ``|a - b| = 2 sin(g/2)`` and ``|a + b| = 2 cos(g/2)`` exactly, so neither is formed by a
    cancelling subtraction (NOTES.md, "Numerics of the Hapke model").
    """
    d, p = a - b, a + b
    s2 = np.einsum("...j,...j->...", d, d)
    c2 = np.einsum("...j,...j->...", p, p)
    norm = np.sqrt(s2 + c2)  # = 2 up to rounding; renormalise so s² + c² = 1
    return np.sqrt(s2) / norm, np.sqrt(c2) / norm


@dataclass(frozen=True)
class Scene:
    """Positions and radii of the Sun, Earth, Moon and detector [m], in the geocentric frame.

    Parameters
    ----------
    theta_deg : float
        Orbital angle θ of paper Eq. 3 [deg], 0 ≤ θ ≤ 180 (other values are accepted: the
        Moon simply continues its circle).
    detector : (3,) array or None
        Detector position [m]; ``None`` puts it at the Earth's centre (the paper's choice).
        The detector faces the Moon's centre.
    scale : float
        Multiplies every length (for scale-invariance tests). The Sun's power is scaled by
        ``scale²`` with it (:attr:`phi`), so every irradiance is invariant under ``scale``.
    """

    theta_deg: float
    detector: tuple[float, float, float] | None = None
    d_se: float = C.D_SE_M
    d_em: float = C.D_EM_M
    r_sun: float = C.R_SUN_M
    r_earth: float = C.R_EARTH_M
    r_moon: float = C.R_MOON_M
    phi_sun: float = C.PHI_SUN_W
    scale: float = 1.0

    def __post_init__(self):
        for name in ("d_se", "d_em", "r_sun", "r_earth", "r_moon", "phi_sun", "scale"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"scene parameter {name}={v!r} must be a positive finite number")
        if not np.isfinite(self.theta_deg):
            raise ValueError(f"phase theta={self.theta_deg!r} deg must be finite")
        if self.d_em <= self.r_earth + self.r_moon or self.d_se <= self.r_sun + self.d_em + self.r_moon:
            raise ValueError("bodies overlap: check d_se, d_em and the radii")

    # --- positions [m] -------------------------------------------------------------------
    @property
    def sun(self) -> np.ndarray:
        """Sun centre [m], paper Eq. 3."""
        return np.array([0.0, 0.0, -self.d_se]) * self.scale

    @property
    def earth(self) -> np.ndarray:
        """Earth centre [m] (origin), paper Eq. 3."""
        return np.zeros(3)

    @property
    def moon(self) -> np.ndarray:
        """Moon centre [m], paper Eq. 3."""
        t = np.radians(self.theta_deg)
        return np.array([0.0, self.d_em * np.sin(t), self.d_em * np.cos(t)]) * self.scale

    @property
    def det(self) -> np.ndarray:
        """Detector position [m]; the Earth's centre unless given."""
        if self.detector is None:
            return self.earth.copy()
        return np.asarray(self.detector, dtype=float) * self.scale

    @property
    def det_normal(self) -> np.ndarray:
        """Unit normal of the detector: it faces the Moon's centre."""
        return unit(self.moon - self.det)

    @property
    def radii(self) -> dict[str, float]:
        return {"sun": self.r_sun * self.scale, "earth": self.r_earth * self.scale,
                "moon": self.r_moon * self.scale}

    def detector_inside(self, body: str) -> bool:
        """True when the detector sits in or on ``body`` (that body then does not block it)."""
        centre = {"sun": self.sun, "earth": self.earth, "moon": self.moon}[body]
        return bool(np.linalg.norm(self.det - centre) <= self.radii[body] * (1 + 1e-9))

    @property
    def phi(self) -> float:
        """Solar radiant flux [W] in the (possibly scaled) scene: ``phi_sun * scale²``."""
        return self.phi_sun * self.scale**2

    # --- angles [deg] ----------------------------------------------------------------------
    @property
    def alpha_deg(self) -> float:
        """Lunar phase angle α: Sun-Moon-detector angle [deg]."""
        return float(np.degrees(angle_between(self.sun - self.moon, self.det - self.moon)))

    @property
    def beta_deg(self) -> float:
        """Earth's phase angle β seen from the Moon's centre: Sun-Earth-Moon angle [deg]."""
        return float(np.degrees(angle_between(self.sun - self.earth, self.moon - self.earth)))

    @property
    def theta_from_vectors_deg(self) -> float:
        """θ recovered from the vectors: 180° minus the Sun-Earth-Moon angle [deg]."""
        return 180.0 - self.beta_deg

    # --- distances [m] and far-field irradiances [W m-2] -------------------------------------
    @property
    def d_sm(self) -> float:
        """Sun-Moon centre distance D_SM [m]."""
        return float(np.linalg.norm(self.sun - self.moon))

    @property
    def d_se_actual(self) -> float:
        return float(np.linalg.norm(self.sun - self.earth))

    @property
    def d_em_actual(self) -> float:
        return float(np.linalg.norm(self.moon - self.earth))

    def solar_irradiance_at(self, points: np.ndarray) -> np.ndarray:
        """Irradiance [W m-2] normal to the Sun direction at ``points`` ((n, 3) m): Φ/(4π d²).

        Exact for a uniform Lambertian sphere seen whole (paper Eq. 6-7).
        """
        d2 = np.sum((np.asarray(points) - self.sun) ** 2, axis=-1)
        return self.phi / (4.0 * np.pi * d2)
