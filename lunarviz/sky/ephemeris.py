"""Dates and ephemerides, offline: where the Sun, Moon and observer are, and how the Moon is turned.

Everything is read from files that installed packages ship; nothing is downloaded at run time:

* positions: JPL DE421 (``de421.bsp``, 1899-07-28 to 2053-10-08) from the ``skyfield-data``
  package, read by skyfield with its built-in timescale (leap seconds and ΔT);
* the Moon's orientation: the lunar PCK kernels ``moon_pa_de421_1900-2050.bpc`` (principal-axis
  libration angles integrated with DE421, 1900-01-01 to 2051-01-01), ``moon_080317.tf`` and
  ``moon_assoc_me.tf`` that the ``lunarsky`` package ships. We only read its data files: its
  own frames fetch DE430 at run time and are not used. Selenographic coordinates are in the
  mean-Earth/polar-axis frame ``MOON_ME_DE421``;
* the Earth's orientation: skyfield's ITRS (IAU 2000A precession-nutation and ΔT; polar motion
  neglected, < 0.5″).

Positions are **geometric, geocentric, at the single instant t**, in ICRF (GCRS) axes, with
the Earth's centre at the origin. Light-time and aberration are neglected and that is the
physics of a detector that rests, to 1e-4, in the Earth's frame: over the 1.3 s the Moon's
light travels the Moon moves ≤ 1.3 km relative to the Earth (distance ≤ 1.3 km, direction
< 1″); the Sun's light reaches the Moon aberrated by ≤ 20.5″ (0.006° of phase angle) and the
Sun-Moon distance differs from the light-time one by ≤ 250 km (2e-6 relative). The scene is
static during one row (no motion blur). The physical constants stay the paper's
(:mod:`lunarviz.constants`): only positions and orientations come from the ephemeris.
"""

from __future__ import annotations

import importlib.util
import os
import re
import warnings
from dataclasses import dataclass
from datetime import datetime, timedelta, timezone

import numpy as np

from lunarviz.caches import register
from lunarviz.errors import LunarvizError

#: first and last instants [UTC] covered by both DE421 and the lunar PCK (the PCK is shorter)
VALID_START = datetime(1900, 1, 1, 0, 1, tzinfo=timezone.utc)  # the PCK starts 1900-01-01 00:00 TDB
VALID_STOP = datetime(2050, 12, 31, 23, 58, tzinfo=timezone.utc)  # the PCK ends 2051-01-01 00:00 TDB
VALID_RANGE = "1900-01-01T00:01 to 2050-12-31T23:58 UTC (DE421 and moon_pa_de421_1900-2050.bpc)"
MOON_FRAME = "MOON_ME_DE421"
_LUNAR_KERNELS = ("data/fk/satellites/moon_080317.tf", "data/fk/satellites/moon_assoc_me.tf",
                  "data/pck/moon_pa_de421_1900-2050.bpc")


def _package_dir(name: str) -> str:
    """Folder of an installed package, found without importing it (lunarsky's import is heavy)."""
    spec = importlib.util.find_spec(name)
    if spec is None or not spec.submodule_search_locations:
        raise LunarvizError(f"dates need the package {name!r}: pip install 'lunarviz' (it is a dependency)")
    return list(spec.submodule_search_locations)[0]


#: the loaded kernels, and the files they keep open (closed when the caches are released)
_KERNELS: dict = {}


def kernels():
    """``(timescale, de421, moon_me_frame)``, loaded once per process from packaged files
    (held until :func:`lunarviz.caches.release_caches`, which closes their files)."""
    if "loaded" not in _KERNELS:
        _KERNELS["loaded"] = _load_kernels()
    return _KERNELS["loaded"]


def _release_kernels() -> None:
    _KERNELS.pop("loaded", None)
    for f in _KERNELS.pop("files", []):
        f.close()


register(_release_kernels)


def _load_kernels():
    from skyfield.api import Loader
    from skyfield.planetarylib import PlanetaryConstants

    data = os.path.join(_package_dir("skyfield_data"), "data")
    with warnings.catch_warnings():  # skyfield-data warns that its (unused) IERS table aged
        warnings.simplefilter("ignore")
        load = Loader(data, verbose=False, expire=False)
        ts = load.timescale(builtin=True)
        eph = load("de421.bsp")
    files = _KERNELS.setdefault("files", [])
    files.append(eph)  # SpiceKernel.close() closes de421.bsp
    lunar = _package_dir("lunarsky")
    pc = PlanetaryConstants()
    for rel in _LUNAR_KERNELS:
        path = os.path.join(lunar, rel)
        if not os.path.exists(path):
            raise LunarvizError(f"lunar kernel {path} is missing; reinstall lunarsky")
        if rel.endswith(".bpc"):
            f = open(path, "rb")  # noqa: SIM115 (jplephem reads it lazily: kept open until released)
            files.append(f)
            pc.read_binary(f)
        else:
            with open(path, "rb") as f:
                pc.read_text(f)
    return ts, eph, pc.build_frame_named(MOON_FRAME)


# ---- times ------------------------------------------------------------------------------------
_STEP = re.compile(r"^\s*(\d+(?:\.\d*)?|\.\d+)\s*(s|sec|min|m|h|hr|d|day|days)\s*$")
_STEP_SECONDS = {"s": 1, "sec": 1, "min": 60, "m": 60, "h": 3600, "hr": 3600, "d": 86400, "day": 86400,
                 "days": 86400}
MAX_TIMES = 100_000


#: the longest time step [s]: the ephemeris's span (about 150 years)
MAX_STEP_S = 150 * 366 * 86400.0


def parse_time(text: str) -> datetime:
    """An ISO 8601 UTC time (``2025-03-14T06:58Z``, ``2025-03-14 06:58:00``, ``2025-03-14``) as an
    aware UTC datetime; one-line errors name a malformed or out-of-range time."""
    s = str(text).strip()
    try:
        t = datetime.fromisoformat(s.replace("z", "Z").replace("Z", "+00:00"))
    except ValueError:
        raise LunarvizError(f"time {text!r} is not an ISO 8601 time such as 2025-03-14T06:58Z") from None
    if t.tzinfo is None and len(s) > 10:  # (a date alone is a day, its midnight UTC)
        import warnings

        from lunarviz.errors import ZonelessTimeWarning
        warnings.warn("times without a zone are taken as UTC (e.g. 2026-01-15T03:00 means 03:00Z; write -08:00 "
                      "or +01:00 for a local time)", ZonelessTimeWarning, stacklevel=2)
    t = t.replace(tzinfo=timezone.utc) if t.tzinfo is None else t.astimezone(timezone.utc)
    if not (VALID_START <= t <= VALID_STOP):
        raise LunarvizError(f"time {text!r} is outside the ephemeris: valid {VALID_RANGE}")
    return t


def format_time(t: datetime) -> str:
    """Canonical row label: ``YYYY-MM-DDTHH:MM:SS.ffffffZ`` trimmed of zero fractions."""
    s = t.astimezone(timezone.utc).strftime("%Y-%m-%dT%H:%M:%S.%f").rstrip("0").rstrip(".")
    return s + "Z"


def parse_step(text: str) -> timedelta:
    m = _STEP.match(str(text).strip().lower())
    if not m or not 0 < float(m.group(1)) < float("inf"):
        raise LunarvizError(f"time step {str(text)[:40]!r} is not a positive step such as 30s, 10min, 1h or 1d")
    seconds = float(m.group(1)) * _STEP_SECONDS[m.group(2)]
    if seconds > MAX_STEP_S:
        raise LunarvizError(f"time step {str(text)[:40]!r} is longer than the ephemeris ({VALID_RANGE})")
    return timedelta(seconds=seconds)


def time_list(times: str | None = None, time_range: str | None = None) -> tuple[str, ...]:
    """Canonical UTC labels from ``--time ISO[,ISO...]`` or ``--time-range START,STOP,STEP``
    (STOP included when the steps land on it)."""
    if times is not None and time_range is not None:
        raise LunarvizError("give --time or --time-range, not both")
    if times is not None:
        parts = [p for p in str(times).split(",")]
        if not parts or any(not p.strip() for p in parts):
            raise LunarvizError(f"--time {times!r} has an empty entry")
        return tuple(format_time(parse_time(p)) for p in parts)
    parts = str(time_range).split(",")
    if len(parts) != 3:
        raise LunarvizError(f"--time-range {time_range!r} must be START,STOP,STEP (e.g. 2026-01-01,2026-01-30,1d)")
    a, b, step = parse_time(parts[0]), parse_time(parts[1]), parse_step(parts[2])
    if b < a:
        raise LunarvizError(f"--time-range {time_range!r}: STOP is before START")
    n = int((b - a) / step + 1e-9) + 1
    if n > MAX_TIMES:
        raise LunarvizError(f"--time-range {time_range!r} gives {n} times (more than {MAX_TIMES}); use a larger step")
    return tuple(format_time(a + k * step) for k in range(n))


def skyfield_time(label: str):
    ts, _, _ = kernels()
    return ts.from_datetime(parse_time(label))


# ---- the state of the sky -----------------------------------------------------------------------
@dataclass(frozen=True)
class SkyState:
    """Geometric geocentric positions [m] (ICRF axes) and orientations at one time.

    ``moon_rotation`` takes MOON_ME body coordinates to ICRF (``x_icrf = R @ x_me``);
    ``earth_rotation`` takes ITRS to ICRF.
    """

    time_utc: str
    sun: np.ndarray
    moon: np.ndarray
    moon_rotation: np.ndarray
    earth_rotation: np.ndarray


def sky_state(label: str) -> SkyState:
    """Sun and Moon (geometric, geocentric, ICRF) and the Moon's and Earth's orientation at ``label``."""
    from skyfield.framelib import itrs
    ts, eph, moon_frame = kernels()
    t = ts.from_datetime(parse_time(label))
    earth = eph["earth"]
    sun = (eph["sun"] - earth).at(t).position.m
    moon = (eph["moon"] - earth).at(t).position.m
    # Frame.rotation_at(t) rotates ICRF vectors into the frame; its transpose goes back
    r_me = np.asarray(moon_frame.rotation_at(t), dtype=float)
    r_itrs = np.asarray(itrs.rotation_at(t), dtype=float)
    return SkyState(label, np.asarray(sun, float), np.asarray(moon, float), r_me.T, r_itrs.T)


def selenographic(moon_rotation: np.ndarray, direction: np.ndarray) -> tuple[float, float]:
    """Selenographic (MOON_ME) latitude and east longitude [deg] of an ICRF direction from the
    Moon's centre; longitude in (-180°, 180°]."""
    v = moon_rotation.T @ np.asarray(direction, dtype=float)
    lat = np.degrees(np.arctan2(v[2], np.hypot(v[0], v[1])))
    lon = np.degrees(np.arctan2(v[1], v[0]))
    return float(lat), float(lon)
