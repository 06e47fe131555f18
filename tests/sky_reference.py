"""Independent real-sky geometry for the tests: NAIF's CSPICE (spiceypy) and astropy/ERFA.

Shares nothing with lunarviz or skyfield except the kernel *files* (the same DE421 and lunar
PCK, "an independent computation from the same DE421 ephemeris"):

* positions: ``spkpos(target, et, "J2000", "NONE", "EARTH")`` — geometric, geocentric; SPICE's
  J2000 frame is the ICRF for the DE4xx ephemerides;
* the Moon's orientation: ``pxform("J2000", "MOON_ME", et)`` with moon_080317.tf and
  moon_assoc_me.tf (MOON_ME → MOON_ME_DE421 → MOON_PA_DE421 from the binary PCK);
* ephemeris time: ET = (JD_UTC − 2451545) · 86400 + 37 s (leap seconds since 2017-01-01,
  IERS Bulletin C; none announced since) + 32.184 s (TT − TAI); TDB − TT (≤ 1.7 ms) neglected:
  the Moon moves 2 m in that time;
* a site's vertical and a satellite's GCRS position: astropy (ITRS → GCRS and TEME → GCRS
  through ERFA's IAU 2006/2000A), with the sgp4 package's own TEME output for the TLE.
"""

from __future__ import annotations

import os
import warnings
from datetime import datetime, timezone
from functools import lru_cache
from importlib.util import find_spec

import numpy as np

LEAP_SECONDS_SINCE_2017 = 37.0
TT_MINUS_TAI = 32.184


def _data(pkg, *rel):
    return os.path.join(list(find_spec(pkg).submodule_search_locations)[0], *rel)


@lru_cache(maxsize=1)
def spice():
    import spiceypy as sp
    for path in (_data("skyfield_data", "data", "de421.bsp"),
                 _data("lunarsky", "data", "fk", "satellites", "moon_080317.tf"),
                 _data("lunarsky", "data", "fk", "satellites", "moon_assoc_me.tf"),
                 _data("lunarsky", "data", "pck", "moon_pa_de421_1900-2050.bpc")):
        sp.furnsh(path)
    return sp


def et_of(iso: str) -> float:
    t = datetime.fromisoformat(iso.replace("Z", "+00:00")).astimezone(timezone.utc)
    assert t.year >= 2017, "the fixed leap-second count holds from 2017-01-01"
    j2000 = datetime(2000, 1, 1, 12, tzinfo=timezone.utc)
    return (t - j2000).total_seconds() + LEAP_SECONDS_SINCE_2017 + TT_MINUS_TAI


def geometry(iso: str) -> dict:
    """Geocentric geometric Sun and Moon [m] and the J2000 → MOON_ME rotation at ``iso``."""
    sp = spice()
    et = et_of(iso)
    sun = np.array(sp.spkpos("SUN", et, "J2000", "NONE", "EARTH")[0]) * 1e3
    moon = np.array(sp.spkpos("MOON", et, "J2000", "NONE", "EARTH")[0]) * 1e3
    return {"sun": sun, "moon": moon, "to_me": np.array(sp.pxform("J2000", "MOON_ME", et))}


def latlon(v):
    return np.degrees(np.arctan2(v[2], np.hypot(v[0], v[1]))), np.degrees(np.arctan2(v[1], v[0]))


def angle_deg(a, b):
    a, b = a / np.linalg.norm(a), b / np.linalg.norm(b)
    return np.degrees(2 * np.arctan2(np.linalg.norm(a - b), np.linalg.norm(a + b)))


def _astropy_offline():
    from astropy.utils import iers
    iers.conf.auto_download = False
    iers.conf.iers_degraded_accuracy = "ignore"
    iers.conf.auto_max_age = None


def site_gcrs(iso: str, lat, lon, h):
    """GCRS position [m] and unit geodetic vertical of a WGS84 site (astropy/ERFA)."""
    _astropy_offline()
    import astropy.units as u
    from astropy.coordinates import GCRS, ITRS, CartesianRepresentation, EarthLocation
    from astropy.time import Time
    t = Time(iso.replace("Z", ""), scale="utc")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        loc = EarthLocation.from_geodetic(lon * u.deg, lat * u.deg, h * u.m, ellipsoid="WGS84")
        up_itrs = np.array([np.cos(np.radians(lat)) * np.cos(np.radians(lon)),
                            np.cos(np.radians(lat)) * np.sin(np.radians(lon)), np.sin(np.radians(lat))])
        p = loc.get_itrs(obstime=t).transform_to(GCRS(obstime=t)).cartesian.xyz.to(u.m).value
        tip = ITRS(CartesianRepresentation(*(loc.get_itrs(obstime=t).cartesian.xyz.to(u.m).value + 1e6 * up_itrs),
                                           unit=u.m), obstime=t)
        q = tip.transform_to(GCRS(obstime=t)).cartesian.xyz.to(u.m).value
    up = (q - p) / np.linalg.norm(q - p)
    return np.asarray(p), up


def tle_gcrs(iso: str, line1: str, line2: str):
    """GCRS position [m] of a TLE satellite: the sgp4 package's TEME, turned by astropy."""
    _astropy_offline()
    import astropy.units as u
    from astropy.coordinates import GCRS, TEME, CartesianRepresentation
    from astropy.time import Time
    from sgp4.api import Satrec
    sat = Satrec.twoline2rv(line1, line2)
    t = Time(iso.replace("Z", ""), scale="utc")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        err, r, _ = sat.sgp4(t.jd1, t.jd2)
        assert err == 0
        teme = TEME(CartesianRepresentation(*r, unit=u.km), obstime=t)
        return np.asarray(teme.transform_to(GCRS(obstime=t)).cartesian.xyz.to(u.m).value)
