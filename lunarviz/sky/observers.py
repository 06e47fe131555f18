"""Observers: where the detector is at a time, geocentric, in ICRF axes [m].

* ``geocentre`` — the Earth's centre (the paper's detector);
* ``site:LAT,LON[,HEIGHT_M]`` — a point on the WGS84 ellipsoid (geodetic latitude, east
  longitude [deg], height [m]); its horizon is the plane normal to the geodetic vertical, and
  the Moon's altitude is geometric (no refraction, no light-time);
* ``tle:FILE`` — a two-line element set propagated with SGP4 (skyfield's ``EarthSatellite``);
* ``orbit:ALT_KM,INC_DEG,RAAN_DEG,ARGLAT_DEG[,EPOCH]`` — a circular Keplerian orbit for design
  studies: altitude above the WGS84 equatorial radius, inclination and right ascension of the
  ascending node in ICRF (equator and equinox of J2000), argument of latitude at EPOCH (default:
  the first time of the run). Two-body motion with GM⊕ = 3.986004418e14 m³ s⁻² (IERS 2010);
  J2 nodal precession (≈ 5°/day in LEO) is neglected, so use a TLE for real spacecraft.

Observers are plain picklable records; skyfield objects are built in the worker that uses them.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from lunarviz.errors import LunarvizError
from lunarviz.sky.ephemeris import format_time, kernels, parse_time

#: WGS84 equatorial radius [m] (NIMA TR8350.2)
WGS84_A_M = 6_378_137.0
#: geocentric gravitational constant [m^3 s^-2] (IERS Conventions 2010, Table 1.1)
GM_EARTH = 3.986004418e14
#: the highest orbit accepted [km]: beyond ~ 1e5 km the observer is not "near the Earth"
MAX_ORBIT_KM = 100_000.0


@dataclass(frozen=True)
class Observer:
    """A parsed ``--observer`` value. ``kind`` is geocentre, site, tle or orbit."""

    kind: str = "geocentre"
    spec: str = "geocentre"
    lat_deg: float = 0.0
    lon_deg: float = 0.0
    height_m: float = 0.0
    tle: tuple = ()
    alt_km: float = 0.0
    inc_deg: float = 0.0
    raan_deg: float = 0.0
    arglat_deg: float = 0.0
    epoch_utc: str | None = None

    # ---- positions --------------------------------------------------------------------------
    def position(self, label: str) -> np.ndarray:
        """Geocentric position [m], ICRF axes, at the UTC time ``label``."""
        ts, _, _ = kernels()
        t = ts.from_datetime(parse_time(label))
        if self.kind == "geocentre":
            return np.zeros(3)
        if self.kind == "site":
            return np.asarray(self._site().at(t).position.m, dtype=float)
        if self.kind == "tle":
            sat = self._satellite(ts)
            pos = sat.at(t)
            err = getattr(pos, "message", None)
            p = np.asarray(pos.position.m, dtype=float)
            if not np.all(np.isfinite(p)):
                raise LunarvizError(f"SGP4 cannot propagate the TLE {self.spec!r} to {label}: {err}")
            return p
        return self._orbit_position(label)

    def epoch_age_days(self, label: str) -> float | None:
        """Days from a TLE's epoch to ``label`` (SGP4 degrades beyond days to weeks); None otherwise."""
        if self.kind != "tle":
            return None
        from sgp4.api import Satrec

        sat = Satrec.twoline2rv(self.tle[-2], self.tle[-1])
        t = parse_time(label)
        jd = (t - parse_time("2000-01-01T12:00Z")).total_seconds() / 86400 + 2451545.0
        return float(jd - (sat.jdsatepoch + sat.jdsatepochF))

    def up(self, label: str) -> np.ndarray | None:
        """Unit geodetic vertical (ICRF) of a site at ``label``; ``None`` for other observers."""
        if self.kind != "site":
            return None
        from skyfield.framelib import itrs

        ts, _, _ = kernels()
        t = ts.from_datetime(parse_time(label))
        la, lo = np.radians(self.lat_deg), np.radians(self.lon_deg)
        up_itrs = np.array([np.cos(la) * np.cos(lo), np.cos(la) * np.sin(lo), np.sin(la)])
        return np.asarray(itrs.rotation_at(t), dtype=float).T @ up_itrs

    def _site(self):
        from skyfield.toposlib import wgs84
        return wgs84.latlon(self.lat_deg, self.lon_deg, elevation_m=self.height_m)

    def _satellite(self, ts):
        from skyfield.sgp4lib import EarthSatellite
        name = self.tle[0] if len(self.tle) == 3 else None
        return EarthSatellite(self.tle[-2], self.tle[-1], name, ts)

    def _orbit_position(self, label: str) -> np.ndarray:
        r = WGS84_A_M + self.alt_km * 1e3
        n = np.sqrt(GM_EARTH / r**3)  # mean motion [rad/s]
        dt = (parse_time(label) - parse_time(self.epoch_utc)).total_seconds()
        u = np.radians(self.arglat_deg) + n * dt
        inc, node = np.radians(self.inc_deg), np.radians(self.raan_deg)
        # perifocal → ICRF for a circular orbit: R3(-Ω) R1(-i) (cos u, sin u, 0)
        return r * np.array([np.cos(node) * np.cos(u) - np.sin(node) * np.cos(inc) * np.sin(u),
                             np.sin(node) * np.cos(u) + np.cos(node) * np.cos(inc) * np.sin(u),
                             np.sin(inc) * np.sin(u)])

    def with_epoch(self, label: str) -> "Observer":
        """The orbit observer with its epoch defaulted to ``label`` (other observers unchanged)."""
        if self.kind == "orbit" and self.epoch_utc is None:
            from dataclasses import replace
            return replace(self, epoch_utc=label)
        return self


def _floats(text: str, what: str, n_min: int, n_max: int) -> list[float]:
    parts = text.split(",")
    if not (n_min <= len(parts) <= n_max):
        raise LunarvizError(f"--observer {what} needs {n_min}" + (f" to {n_max}" if n_max > n_min else "")
                            + f" comma-separated numbers, got {text!r}")
    try:
        vals = [float(p) for p in parts]
    except ValueError:
        raise LunarvizError(f"--observer {what}: {text!r} is not a list of numbers") from None
    if not all(np.isfinite(vals)):
        raise LunarvizError(f"--observer {what}: {text!r} has a non-finite number")
    return vals


def _site_height(text: str) -> float:
    """A site's height [m]: ``2067``, ``2067m`` or ``2.067km``. A bare number with a fraction below
    10 (``2.067``) is warned about: a height in kilometres written without its unit."""
    import warnings

    from lunarviz.errors import LunarvizWarning
    from lunarviz.parsing import LENGTH_M, parse_quantity
    h, with_unit = parse_quantity(text.strip(), "--observer site height", LENGTH_M, "m")
    if not with_unit and 0 < abs(h) < 10 and not h.is_integer():
        warnings.warn(f"--observer site height {text.strip()} is taken in metres (a site {h:g} m high); write "
                      f"{text.strip()}km for kilometres", LunarvizWarning, stacklevel=3)
    return h


def read_tle(path: str) -> tuple:
    """The (name,) line 1, line 2 of a TLE file, checked (format and checksums) by sgp4."""
    if not os.path.exists(path):
        raise LunarvizError(f"TLE file {path!r} does not exist")
    if not os.path.isfile(path):  # also refuses FIFOs and devices, which would block the read
        raise LunarvizError(f"TLE file {path!r} is not a file (a regular file is needed)")
    if os.path.getsize(path) > 1 << 20:
        raise LunarvizError(f"TLE file {path!r} is larger than 1 MiB: a TLE is two or three lines")
    try:
        with open(path, encoding="ascii", errors="strict") as f:
            lines = [ln.rstrip() for ln in f if ln.strip()]
    except (OSError, UnicodeDecodeError) as exc:
        raise LunarvizError(f"TLE file {path!r} cannot be read: {exc}") from None
    l1 = [i for i, ln in enumerate(lines) if ln.startswith("1 ")]
    if len(lines) not in (2, 3) or not l1 or l1[0] + 1 >= len(lines) or not lines[l1[0] + 1].startswith("2 "):
        raise LunarvizError(f"TLE file {path!r} is not one two-line element set (optional name line, "
                            f"then lines starting '1 ' and '2 ')")
    name = lines[0].strip() if l1[0] == 1 else None
    l1s, l2s = lines[l1[0]], lines[l1[0] + 1]
    from sgp4.api import Satrec
    from sgp4.io import verify_checksum
    try:
        verify_checksum(l1s, l2s)
        sat = Satrec.twoline2rv(l1s, l2s)
    except Exception as exc:  # sgp4 raises ValueError/IndexError on malformed elements
        raise LunarvizError(f"TLE file {path!r} is corrupt: {str(exc).splitlines()[0] if str(exc) else exc!r}") \
            from None
    if sat.error or not (0 < sat.no_kozai < 20):
        raise LunarvizError(f"TLE file {path!r} has invalid elements (SGP4 error {sat.error})")
    return (name, l1s, l2s) if name else (l1s, l2s)


def parse_observer(text: str | None) -> Observer:
    """An :class:`Observer` from ``--observer``; one-line errors name the bad value."""
    if text is None or str(text).strip() in ("", "geocentre", "geocenter"):
        return Observer()
    s = str(text).strip()
    kind, _, rest = s.partition(":")
    if kind == "site":
        parts = rest.split(",")
        if len(parts) not in (2, 3):
            _floats(rest, "site:LAT,LON[,HEIGHT_M]", 2, 3)  # (raises: the count named)
        lat, lon = _floats(",".join(parts[:2]), "site:LAT,LON[,HEIGHT_M]", 2, 2)
        h = _site_height(parts[2]) if len(parts) == 3 else 0.0
        if not -90 <= lat <= 90:
            raise LunarvizError(f"--observer site latitude {lat!r} deg must be in [-90, 90]")
        if not -360 <= lon <= 360:
            raise LunarvizError(f"--observer site longitude {lon!r} deg must be in [-360, 360]")
        if not -500 <= h <= 20_000:
            raise LunarvizError(f"--observer site height {h!r} m must be in [-500, 20000] (a site on the ground; "
                                f"use orbit: or tle: above)")
        return Observer("site", s, lat_deg=lat, lon_deg=((lon + 180) % 360) - 180, height_m=h)
    if kind == "tle":
        if not rest:
            raise LunarvizError("--observer tle: needs a file, e.g. tle:iss.txt")
        return Observer("tle", s, tle=read_tle(rest))
    if kind == "orbit":
        head, epoch = rest, None
        parts = rest.split(",")
        if len(parts) == 5:
            head, epoch = ",".join(parts[:4]), parts[4]
        alt, inc, raan, u = _floats(head, "orbit:ALT_KM,INC_DEG,RAAN_DEG,ARGLAT_DEG[,EPOCH]", 4, 4)
        if alt <= 0:
            raise LunarvizError(f"--observer orbit altitude {alt!r} km is at or below the Earth's surface")
        if alt > MAX_ORBIT_KM:
            raise LunarvizError(f"--observer orbit altitude {alt!r} km is above {MAX_ORBIT_KM:g} km")
        if not 0 <= inc <= 180:
            raise LunarvizError(f"--observer orbit inclination {inc!r} deg must be in [0, 180]")
        if epoch is not None:
            epoch = format_time(parse_time(epoch))
        return Observer("orbit", s, alt_km=alt, inc_deg=inc, raan_deg=raan, arglat_deg=u, epoch_utc=epoch)
    raise LunarvizError(f"--observer {s!r} is not geocentre, site:LAT,LON[,HEIGHT_M], tle:FILE or "
                        f"orbit:ALT_KM,INC_DEG,RAAN_DEG,ARGLAT_DEG")
