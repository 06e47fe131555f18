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

import lunarviz.constants as C
from lunarviz.errors import LunarvizError


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
    cancelling subtraction (paper notes, "Numerics of the Hapke model").
    """
    d, p = a - b, a + b
    s2 = np.einsum("...j,...j->...", d, d)
    c2 = np.einsum("...j,...j->...", p, p)
    norm = np.sqrt(s2 + c2)  # = 2 up to rounding; renormalise so s² + c² = 1
    return np.sqrt(s2) / norm, np.sqrt(c2) / norm


def segment_hits_sphere(a: np.ndarray, b: np.ndarray, c: np.ndarray, r: float) -> np.ndarray:
    """Whether the segment from ``a`` (3,) to each of ``b`` (n, 3) passes within ``r`` of ``c``."""
    d = np.asarray(b, dtype=float) - a
    L2 = np.einsum("ij,ij->i", d, d)
    t = np.clip(np.einsum("ij,j->i", d, c - a) / np.where(L2 > 0, L2, 1.0), 0.0, 1.0)
    closest = a + t[:, None] * d
    return np.einsum("ij,ij->i", closest - c, closest - c) < r * r


#: the closest a detector may be to the Moon's centre [lunar radii]: near the surface one facet
#: fills the view and the per-facet rules are wrong (1 km above the sub-solar point gives 0.11
#: W m-2 where the exact answer is 57.8)
MIN_DETECTOR_MOON_RADII = 10.0


@dataclass(frozen=True)
class SceneGeometry:
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
    sun_position, moon_position : (3,) tuples or None
        A general scene (dates, :func:`lunarviz.sky.dated_scene.sky_scene`): the Sun's and Moon's centres
        [m] relative to the Earth's centre. Both or neither; when given, θ, ``d_se`` and ``d_em``
        are derived from them (use :meth:`from_vectors`).
    moon_rotation, earth_rotation : 3×3 nested tuples or None
        Orientation of the body's mesh frame: ``x_scene = R @ x_body``. ``None`` is the identity
        (the θ scene: mesh axes are scene axes).
    horizon_normal : (3,) tuple or None
        For a detector standing on the Earth (a site): the unit geodetic vertical. The Earth
        then hides what lies below the detector's horizon plane (instead of the model sphere,
        whose surface may pass above or below a site on the WGS84 ellipsoid by up to 22 km).
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
    sun_position: tuple | None = None
    moon_position: tuple | None = None
    moon_rotation: tuple | None = None
    earth_rotation: tuple | None = None
    horizon_normal: tuple | None = None

    @classmethod
    def from_vectors(cls, sun, moon, detector=None, moon_rotation=None, earth_rotation=None,
                     horizon_normal=None, **kw) -> "SceneGeometry":
        """A scene from the Sun's, Moon's and detector's positions [m] relative to the Earth."""
        sun, moon = (np.asarray(v, dtype=float) for v in (sun, moon))
        det = None if detector is None else tuple(float(c) for c in detector)

        def tup(m):
            return None if m is None else tuple(tuple(float(c) for c in row) for row in np.asarray(m, float))
        beta = float(np.degrees(angle_between(sun, moon)))
        return cls(180.0 - beta, detector=det, d_se=float(np.linalg.norm(sun)), d_em=float(np.linalg.norm(moon)),
                   sun_position=tuple(map(float, sun)), moon_position=tuple(map(float, moon)),
                   moon_rotation=tup(moon_rotation), earth_rotation=tup(earth_rotation),
                   horizon_normal=None if horizon_normal is None else tuple(map(float, horizon_normal)), **kw)

    @property
    def general(self) -> bool:
        """True for a scene placed by position vectors (not by the paper's θ)."""
        return self.moon_position is not None

    def __post_init__(self):
        for name in ("d_se", "d_em", "r_sun", "r_earth", "r_moon", "phi_sun", "scale"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise LunarvizError(f"scene parameter {name}={v!r} must be a positive finite number")
        if not np.isfinite(self.theta_deg):
            raise LunarvizError(f"phase theta={self.theta_deg!r} deg must be finite")
        if (self.sun_position is None) != (self.moon_position is None):
            raise LunarvizError("a general scene needs both sun_position and moon_position")
        if self.general:
            d_sm = float(np.linalg.norm(np.subtract(self.sun_position, self.moon_position)))
            if self.d_em <= self.r_earth + self.r_moon or self.d_se <= self.r_sun + self.r_earth \
                    or d_sm <= self.r_sun + self.r_moon:
                raise LunarvizError("bodies overlap: check the positions and the radii")
        elif self.d_em <= self.r_earth + self.r_moon or self.d_se <= self.r_sun + self.d_em + self.r_moon:
            raise LunarvizError("bodies overlap: check d_se, d_em and the radii")
        if self.detector is not None:
            det = np.asarray(self.detector, dtype=float)
            if det.shape != (3,) or not np.all(np.isfinite(det)):
                raise LunarvizError(f"detector position {self.detector!r} must be three finite numbers [m]")
            for body in ("sun", "moon"):
                if self.detector_inside(body):
                    where = tuple(float(c) for c in det)
                    raise LunarvizError(f"detector position {where} m is inside the {body.capitalize()}")
            d_moon = float(np.linalg.norm(self.det - self.moon))
            if d_moon < MIN_DETECTOR_MOON_RADII * self.radii["moon"]:
                raise LunarvizError(
                    f"detector position {tuple(float(c) for c in det)} m is {d_moon / 1e3:.0f} km from the Moon's "
                    f"centre: "
                    f"the methods assume a detector at least {MIN_DETECTOR_MOON_RADII:g} lunar radii away (facets "
                    f"closer than that subtend more than their flat-facet and far-source rules resolve)")

    # --- positions [m] -------------------------------------------------------------------
    @property
    def sun(self) -> np.ndarray:
        """Sun centre [m], paper Eq. 3 (or as given)."""
        if self.sun_position is not None:
            return np.asarray(self.sun_position, dtype=float) * self.scale
        return np.array([0.0, 0.0, -self.d_se]) * self.scale

    @property
    def earth(self) -> np.ndarray:
        """Earth centre [m] (origin), paper Eq. 3."""
        return np.zeros(3)

    @property
    def moon(self) -> np.ndarray:
        """Moon centre [m], paper Eq. 3 (or as given)."""
        if self.moon_position is not None:
            return np.asarray(self.moon_position, dtype=float) * self.scale
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

    @property
    def sky_north(self) -> np.ndarray:
        """The sky's north in scene axes, "up" in every picture: the ICRF pole (z) on dates; in the
        θ scene, which has no sky, the orbit's normal +x (both bodies' north poles there)."""
        return np.array([0.0, 0.0, 1.0]) if self.general else np.array([1.0, 0.0, 0.0])

    def rotation(self, body: str) -> np.ndarray | None:
        """Body-to-scene rotation matrix of ``body``'s mesh, or ``None`` for the identity."""
        r = {"moon": self.moon_rotation, "earth": self.earth_rotation}.get(body)
        return None if r is None else np.asarray(r, dtype=float)

    def sight_lines_clear(self, points: np.ndarray) -> np.ndarray:
        """Whether the Earth leaves the straight line from each point ((n, 3) m) to the detector free.

        A site (``horizon_normal``) sees what is above its horizon plane. Otherwise the Earth is
        the model sphere; a detector in or on it (the paper's, at the centre) is never hidden.
        This is the analytic test of the analytic and reference methods; the ray tracer asks
        Embree instead (except for a site's horizon plane).
        """
        p = np.asarray(points, dtype=float)
        det = self.det
        if self.horizon_normal is not None:
            return (p - det) @ np.asarray(self.horizon_normal) > 0.0
        if self.detector_inside("earth"):
            return np.ones(len(p), dtype=bool)
        return ~segment_hits_sphere(det, p, self.earth, self.radii["earth"])

    def moon_wholly_hidden(self, margin: float = 1e-3) -> bool:
        """True when no point of the Moon can reach the detector: the whole lunar sphere is below
        a site's horizon plane, or behind the Earth's disc seen from an outside detector, with
        margins: the Moon grown by ``margin`` and the Earth shrunk by ten times it (1 %, more than
        the 0.2 % by which a packaged icosphere of level ≥ 3 falls inside its sphere). Methods
        may skip such a date: every lunar point is hidden anyway."""
        v = self.moon - self.det
        d = float(np.linalg.norm(v))
        rho_m = float(np.arcsin(min(1.0, self.radii["moon"] * (1 + margin) / d)))
        if self.horizon_normal is not None:
            alt = np.pi / 2 - angle_between(np.asarray(self.horizon_normal, dtype=float), v)
            return bool(alt < -rho_m)
        if self.detector_inside("earth"):
            return False
        w = self.earth - self.det
        de = float(np.linalg.norm(w))
        rho_e = float(np.arcsin(min(1.0, self.radii["earth"] * (1 - 10 * margin) / de)))
        return bool(de < d and angle_between(v, w) < rho_e - rho_m)

    def moon_wholly_in_umbra(self, margin: float = 1e-3) -> bool:
        """True when every point of the Moon (its sphere grown by ``margin``) sees the whole Sun's
        disc behind the Earth's (the Earth shrunk by ten times ``margin``, as in
        :meth:`moon_wholly_hidden`): a total eclipse, in which no lunar point is sunlit or sees a
        sunlit point of the Earth (the Earth's lit points seen from inside its umbra lie beyond
        its limb). Conservative: from the Moon's centre, the discs' separation plus the most a
        lunar point's offset can move each direction and grow the Sun's disc, against the
        Earth's disc shrunk by the same offset. No atmosphere (no refracted umbral light)."""
        r_m = self.radii["moon"] * (1 + margin)
        vs, ve = self.sun - self.moon, self.earth - self.moon
        ds, de = float(np.linalg.norm(vs)), float(np.linalg.norm(ve))
        if de <= r_m or ds <= de:
            return False
        rho_s = float(np.arcsin(min(1.0, self.radii["sun"] / (ds - r_m))))
        rho_e = float(np.arcsin(min(1.0, self.radii["earth"] * (1 - 10 * margin) / (de + r_m))))
        reach = angle_between(vs, ve) + r_m / (de - r_m) + r_m / (ds - r_m)
        return bool(reach + rho_s < rho_e)

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
