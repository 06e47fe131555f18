"""The real sky: a :class:`~lunarviz.geometry.scene_geometry.SceneGeometry` for a UTC time and an observer, and the
geometry fields of its row.

Positions and orientations come from :mod:`lunarviz.sky.ephemeris` (geometric, geocentric, ICRF);
the bodies' sizes and the Sun's power stay the paper's. The Moon's mesh is turned into the
MOON_ME frame and the Earth's into the ITRS, so a mesh's (lon, lat) lands where it belongs.

Occultation and shadow flags are geometric and judged at the Moon's and Sun's centres:

* ``moon_occulted``: the Moon's centre is below a site's horizon, or the Earth sphere
  (R_Earth of the paper) lies across the line from the detector to the Moon's centre. Every
  method then hides the lunar points the Earth hides (the analytic and reference methods by
  that same exact test per point, the ray tracer through Embree, or a site's horizon plane);
* ``observer_in_shadow``: the Sun's centre is hidden from the detector the same way (a site at
  night, a satellite in the Earth's umbra or penumbra centre line). It changes no number: the
  detector is not lit by what it measures.

There is no atmosphere: no refraction, extinction or umbral red light in eclipses.
"""

from __future__ import annotations

import numpy as np

from lunarviz.caches import memoize
from lunarviz.errors import LunarvizError
from lunarviz.geometry.scene_geometry import SceneGeometry, angle_between, unit
from lunarviz.sky.ephemeris import selenographic, sky_state
from lunarviz.sky.observers import Observer

#: an observer closer to the Earth's centre than this is inside the Earth: 50 km below the WGS84
#: polar radius (6356.8 km), below every site on the ground
MIN_OBSERVER_RADIUS_M = 6_306_000.0


@memoize(maxsize=256)
def sky_scene(label: str, observer: Observer = Observer()) -> tuple[SceneGeometry, dict]:
    """The scene at UTC ``label`` seen by ``observer``, and the row fields that describe it."""
    st = sky_state(label)
    det = observer.position(label)
    r = float(np.linalg.norm(det))
    if observer.kind != "geocentre" and r < MIN_OBSERVER_RADIUS_M:
        raise LunarvizError(f"observer {observer.spec!r} at {label} is {r / 1e3:.0f} km from the Earth's centre, "
                            f"inside the Earth (a decayed or stale TLE, or a wrong orbit)")
    up = observer.up(label)
    sc = SceneGeometry.from_vectors(st.sun, st.moon, None if observer.kind == "geocentre" else det,
                            moon_rotation=st.moon_rotation, earth_rotation=st.earth_rotation,
                            horizon_normal=up)
    info = sky_fields(sc, label, observer)
    return sc, info


def sky_fields(sc: SceneGeometry, label: str, observer: Observer) -> dict:
    """The per-row geometry fields of a dated scene (time, distances, libration, flags)."""
    det, M, S = sc.det, sc.moon, sc.sun
    r_me = sc.rotation("moon")
    sub_obs = selenographic(r_me, det - M)
    sub_sun = selenographic(r_me, S - M)
    clear_moon, clear_sun = sc.sight_lines_clear(np.stack([M, S]))
    info = {
        "time_utc": label,
        "observer": observer.spec,
        "phase_angle_deg": float(np.degrees(angle_between(S - M, det - M))),
        "theta_deg": sc.theta_deg,
        "beta_deg": sc.beta_deg,
        "observer_moon_distance_m": float(np.linalg.norm(M - det)),
        "sun_moon_distance_m": float(np.linalg.norm(S - M)),
        "sub_observer_lat_deg": sub_obs[0], "sub_observer_lon_deg": sub_obs[1],
        "sub_solar_lat_deg": sub_sun[0], "sub_solar_lon_deg": sub_sun[1],
        "moon_occulted": bool(not clear_moon),
        "observer_in_shadow": bool(not clear_sun),
    }
    if observer.kind == "site":
        up = np.asarray(sc.horizon_normal)
        info["moon_altitude_deg"] = float(90.0 - np.degrees(angle_between(up, M - det)))
    if observer.kind == "tle":
        info["tle_epoch_age_days"] = observer.epoch_age_days(label)
    info.update({"observer_x_m": float(det[0]), "observer_y_m": float(det[1]), "observer_z_m": float(det[2])})
    return info


def moon_direction_radec(sc: SceneGeometry) -> tuple[float, float]:
    """Right ascension and declination [deg] (ICRF) of the Moon's centre from the detector."""
    v = unit(sc.moon - sc.det)
    return float(np.degrees(np.arctan2(v[1], v[0])) % 360.0), float(np.degrees(np.arcsin(v[2])))
