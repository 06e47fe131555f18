"""Dates as an observer thinks of them: one time a night over a span of nights or a lunation, kept
only where the Moon is up.

* ``--nights START,STOP[,HH:MM]``: every calendar date from START to STOP (both included) at the
  clock time HH:MM (default ``00:00``, the night's middle at a site). HH:MM is the site's local
  mean solar time (UTC plus its east longitude / 15 h); ``HH:MMZ`` is UTC and ``HH:MM+05:30`` a
  time zone's offset. Observers other than a site have no local time: UTC.
* ``--lunation DATE[,HH:MM]``: the same over the lunation that contains DATE, from the new Moon at
  or before it to the next (DE421 through skyfield's almanac; the geocentric new Moon), the
  times of its first and last days kept only inside it.

A time is kept when the Moon is up: some of its disc above a site's horizon plane, or not wholly
behind the Earth from a detector outside it (geometric: no refraction). The times of the
nights whose Moon is down are dropped, not computed (:func:`moon_up`).
"""

from __future__ import annotations

import re
from datetime import date, datetime, time, timedelta, timezone

from lunarviz.errors import LunarvizError
from lunarviz.sky.ephemeris import VALID_RANGE, format_time, kernels, parse_time
from lunarviz.sky.observers import Observer

_CLOCK = re.compile(r"^(\d{1,2}):(\d{2})(?:(Z)|([+-])(\d{2}):(\d{2}))?$", re.IGNORECASE)
#: the clock time of a night's date when none is given: local midnight (of the date's evening)
DEFAULT_CLOCK = "00:00"
#: the most nights a span may hold (a century)
MAX_NIGHTS = 36_600


def parse_clock(text: str, observer: Observer) -> timedelta:
    """The offset from a date's 00:00 UTC to clock time ``text`` (``HH:MM`` local mean solar time
    at a site, UTC elsewhere; ``HH:MMZ`` UTC; ``HH:MM±HH:MM`` a zone's offset)."""
    m = _CLOCK.match(str(text).strip())
    if not m or int(m.group(1)) > 23 or int(m.group(2)) > 59:
        raise LunarvizError(f"night time {text!r} is not a clock time HH:MM (local), HH:MMZ (UTC) or HH:MM+HH:MM")
    clock = timedelta(hours=int(m.group(1)), minutes=int(m.group(2)))
    if m.group(3):
        return clock
    if m.group(4):
        if int(m.group(5)) > 14 or int(m.group(6)) > 59:
            raise LunarvizError(f"night time {text!r}: a zone offset is at most ±14:00")
        zone = timedelta(hours=int(m.group(5)), minutes=int(m.group(6)))
        return clock - zone if m.group(4) == "+" else clock + zone
    if observer.kind == "site":  # local mean solar time: the Sun's mean hour angle at the site's meridian
        return clock - timedelta(hours=observer.lon_deg / 15.0)
    return clock


def _calendar_date(text: str, what: str) -> date:
    """A date (``2026-02-17``, or the date of an ISO time), inside the ephemeris; one-line errors
    name ``what`` and the value as given."""
    s = str(text).strip()
    try:
        d = date.fromisoformat(s)
    except ValueError:
        if "T" not in s:
            _bad_date(text, what)
        try:
            return parse_time(s).date()
        except LunarvizError:
            _bad_date(text, what)
    try:
        parse_time(d.isoformat())
    except LunarvizError:
        _bad_date(text, what)
    return d


def _bad_date(text: str, what: str):
    raise LunarvizError(f"{what} {text!r} is not a date such as 2026-02-17 (valid {VALID_RANGE})")


def moon_up(label: str, observer: Observer) -> bool:
    """Whether some of the Moon is up at UTC ``label`` for ``observer``: not wholly below a site's
    horizon, nor wholly behind the Earth from outside it."""
    from lunarviz.sky.dated_scene import sky_scene
    sc, _ = sky_scene(label, observer)
    return not sc.moon_wholly_hidden()  # (its margins keep a night whose Moon may show a sliver)


def night_times(start: str, stop: str, clock: str | None, observer: Observer, keep_all: bool = False) -> tuple:
    """UTC labels: one a night from date ``start`` to ``stop`` at ``clock`` (:func:`parse_clock`),
    those with the Moon up (every one with ``keep_all``)."""
    a, b = _calendar_date(start, "--nights START"), _calendar_date(stop, "--nights STOP")
    if b < a:
        raise LunarvizError(f"--nights {start},{stop}: STOP is before START")
    n = (b - a).days + 1
    if n > MAX_NIGHTS:
        raise LunarvizError(f"--nights {start},{stop} spans {n} nights (more than {MAX_NIGHTS})")
    offset = parse_clock(clock or DEFAULT_CLOCK, observer)
    labels = []
    for k in range(n):
        midnight = datetime.combine(a + timedelta(days=k), time(0), tzinfo=timezone.utc)
        try:
            labels.append(format_time(parse_time(format_time(midnight + offset))))
        except LunarvizError:
            raise LunarvizError(f"night {a + timedelta(days=k)} at {clock or DEFAULT_CLOCK} is outside the "
                                f"ephemeris (valid {VALID_RANGE})") from None
    if keep_all:
        return tuple(labels)
    obs = observer.with_epoch(labels[0])
    return tuple(t for t in labels if moon_up(t, obs))


def nights_option(text: str, observer: Observer) -> tuple:
    """``--nights START,STOP[,HH:MM]``: :func:`night_times` of the Moon-up nights."""
    parts = [p.strip() for p in str(text).split(",")]
    if len(parts) not in (2, 3) or not all(parts):
        raise LunarvizError(f"--nights {text!r} must be START,STOP[,HH:MM] (e.g. 2026-02-17,2026-03-18,03:00Z)")
    return night_times(parts[0], parts[1], parts[2] if len(parts) == 3 else None, observer)


def lunation(day: str) -> tuple[datetime, datetime]:
    """The new Moons (UTC, geocentric, DE421) at or before ``day`` and after it: the lunation that
    holds ``day`` (a date or an ISO time)."""
    from skyfield import almanac
    s = str(day).strip()
    t = parse_time(s) if "T" in s else datetime.combine(_calendar_date(s, "--lunation DATE"), time(0),
                                                        tzinfo=timezone.utc)
    ts, eph, _ = kernels()
    t0, t1 = ts.from_datetime(t - timedelta(days=31)), ts.from_datetime(t + timedelta(days=31))
    try:
        times, phases = almanac.find_discrete(t0, t1, almanac.moon_phases(eph))
    except Exception:  # noqa: BLE001 (skyfield's EphemerisRangeError near the ephemeris' ends)
        raise LunarvizError(f"--lunation {day!r}: its new Moons are outside the ephemeris (valid {VALID_RANGE})") \
            from None
    new = sorted(x.utc_datetime() for x, p in zip(times, phases) if p == 0)
    before = [x for x in new if x <= t]
    after = [x for x in new if x > t]
    if not before or not after:
        raise LunarvizError(f"--lunation {day!r}: no new Moon found on both sides within the ephemeris")
    return before[-1], after[0]


def lunation_option(text: str, observer: Observer) -> tuple:
    """``--lunation DATE[,HH:MM]``: one time a night (Moon up) from the lunation's new Moon to the next."""
    parts = [p.strip() for p in str(text).split(",")]
    if len(parts) not in (1, 2) or not all(parts):
        raise LunarvizError(f"--lunation {text!r} must be DATE[,HH:MM] (e.g. 2026-02-25,03:00Z)")
    new, nxt = lunation(parts[0])
    times = night_times(new.date().isoformat(), nxt.date().isoformat(), parts[1] if len(parts) == 2 else None,
                        observer)
    return tuple(t for t in times if new <= parse_time(t) < nxt)  # (the end days' times inside the lunation)
