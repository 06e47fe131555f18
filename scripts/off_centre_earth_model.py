"""The error model of the Earth's beam rules about the zero-phase point, measured with the detector
off the Earth's centre (dates from a low orbit and from ground sites).

    python scripts/off_centre_earth_model.py [--write] [--every-hours H] [--nights N] [--out DIR] [--held-out]

For a detector off the Earth's centre, the deterministic tracer takes the Earth's beams in polar
coordinates about each lunar sample's zero-phase point (:func:`lunarviz.methods.sources.zero_phase_points`),
where a BRDF's opposition surge peaks and its roughness kinks: the ``plain`` rule
(``earth_pole="detector"``: the visible disc, the lit cap and the horizon as its caps) and the rule
``cut`` along the roughness's kinks too (``earth_pole="detector-cut"``,
:func:`lunarviz.methods.sources.roughness_kink_cuts`). This script measures, for each Earth order
of each, the largest relative error of the earthshine over dates, BRDFs (Lambert, SHG, DHG) and
lunar models (the paper's, rolo-fit-map on its map) against the cut rule at Earth order 24
(everything else the settings ``--rtol 1e-4`` choose: lune rule or facets), and the mean time of a
date's earthshine trace (what a tolerance weighs to choose between them). A larger order is never
allowed more error than a smaller one (the table is made non-increasing: refinement never loosens
a bound).

Dates: every ``--dates``-th of 2026's hours from a 550 km sun-synchronous orbit, at each date's own
epoch (``orbit:550,97.6,0,0``) and at one for all (``orbit:550,97.6,0,0,2026-01-01T00:00Z``: the
detector moving along the orbit), the orbit's places where the zero-phase point lies on the
Earth's lit limb (:func:`limb_observers`), and nights from Big Bear (``site:34.26,-116.92,2067``) and Paranal
(``site:-24.63,-70.40,2635``) at 03:00 and 08:00 UTC; dates whose Moon is hidden, eclipsed,
or whose θ lies outside 5-175° are left out. ``--write`` stores the table in
``lunarviz/data/error_models.json`` (keys ``earth_rule_off_centre`` and ``earth_rule_off_centre_cut``);
the report goes to ``benchmarks/error_models/off_centre_earth.md`` and ``.json``.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import sys
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: the two rules about the zero-phase point (their ``earth_pole``) and the Earth orders measured
VARIANTS = {"plain": ("detector", (5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 20)),
            "cut": ("detector-cut", (4, 5, 6, 7, 8, 10))}
#: each variant's table in lunarviz/data/error_models.json
TABLE_KEYS = {"plain": "earth_rule_off_centre", "cut": "earth_rule_off_centre_cut"}
#: the reference: the rule cut along the kinks, at this order
REFERENCE_ORDER = 24
BRDFS = ("lambert", "shg", "dhg")
MOONS = ("paper", "rolo-fit-map")
#: the orbit twice: at each date's own epoch (the default of a date run alone: the detector at one
#: point of its orbit on every date) and at one epoch for all (the detector moving along it); the
#: first alone missed the places where the zero-phase point lies on the Earth's lit limb (1.7x the
#: table there at order 11), the second alone the first's worst places for the cut rule (3.6x at
#: order 6); then the sites
ORBITS = ("orbit:550,97.6,0,0", "orbit:550,97.6,0,0,2026-01-01T00:00Z")
OBSERVERS = ORBITS + ("site:34.26,-116.92,2067", "site:-24.63,-70.40,2635")


def dates(every_hours: int, nights: int, start=dt.datetime(2026, 1, 3, 5), first_night=dt.date(2026, 1, 5),
          night_step: int = 9, hours=("03", "08"), observers=OBSERVERS) -> list[tuple[str, str]]:
    """(observer, UTC label) pairs: for each orbit (``orbit:`` observers) dates every
    ``every_hours`` hours of a year from ``start``, and for each site ``nights`` nights every
    ``night_step`` days from ``first_night`` at ``hours`` UTC (defaults: this model's dates)."""
    out = []
    for obs in observers:
        if obs.startswith("orbit:"):
            out += [(obs, (start + dt.timedelta(hours=h)).strftime("%Y-%m-%dT%H:%M:00Z"))
                    for h in range(0, 8760, every_hours)]
            continue
        for k in range(nights):
            day = first_night + dt.timedelta(days=night_step * k)
            out += [(obs, f"{day.isoformat()}T{hh}:00:00Z") for hh in hours]
    return out


#: the orbit places where the zero-phase point lies on the Earth's lit limb seen from the Moon: the
#: detector this many Earth radii off the Earth's centre toward the Sun (across the Moon's
#: direction), where the rule converges slowest; random orbit dates rarely come this close (on
#: them the table at order 11 was exceeded 1.7x here)
LIMB_OFFSETS = (0.995, 0.998)
#: the dates of those places: θ ≈ 20-60° (the worst) over May 2026, and θ ≈ 35° in three other months
LIMB_DATES = ("2026-05-03T11:00:00Z", "2026-05-04T10:00:00Z", "2026-05-05T08:00:00Z", "2026-05-06T06:00:00Z",
              "2026-05-07T05:00:00Z", "2026-01-06T00:00:00Z", "2026-07-03T03:00:00Z", "2026-09-29T09:00:00Z")


#: held-out places on the lit limb's zero-phase family (other dates and offsets than the model's)
HELD_OUT_LIMB_DATES = ("2026-02-28T17:00:00Z", "2026-04-05T03:00:00Z", "2026-05-05T20:00:00Z",
                       "2026-08-25T03:00:00Z", "2026-11-22T01:00:00Z")
HELD_OUT_LIMB_OFFSETS = (0.993, 0.997, 1.0005)


def limb_observers(labels=LIMB_DATES, offsets=LIMB_OFFSETS, alt_km=550.0, inc_deg=97.6) -> list[tuple[str, str]]:
    """(observer, UTC label) pairs: at each date, a circular orbit of the benchmark's altitude and
    inclination through the point ``offset`` Earth radii from the Earth's centre, perpendicular to
    the Moon's direction toward the Sun, on the Moon's side (its node and argument of latitude at
    that date, the date its epoch)."""
    import math

    from lunarviz.scene import ResolvedScene
    from lunarviz.sky.observers import WGS84_A_M
    inc = math.radians(inc_deg)
    out = []
    for label in labels:
        sc = ResolvedScene(method="raytrace", observer="geocentre", times=(label,)).geometry(label)
        u_moon = (sc.moon - sc.earth) / np.linalg.norm(sc.moon - sc.earth)
        toward_sun = (sc.sun - sc.earth) - ((sc.sun - sc.earth) @ u_moon) * u_moon
        toward_sun /= np.linalg.norm(toward_sun)
        r = WGS84_A_M + alt_km * 1e3
        for rho in offsets:
            b = rho * sc.radii["earth"]
            p = math.sqrt(r * r - b * b) * u_moon + b * toward_sun
            arg = math.asin(max(-1.0, min(1.0, p[2] / (r * math.sin(inc)))))
            node = math.atan2(p[1], p[0]) - math.atan2(math.cos(inc) * math.sin(arg), math.cos(arg))
            out.append((f"orbit:{alt_km:g},{inc_deg:g},{math.degrees(node):.9f},{math.degrees(arg):.9f},{label}",
                        label))
    return out


def measure(args) -> dict | None:
    """Errors (and seconds) of one (observer, date, lunar model[, variants]) at each Earth order
    of each variant of the rule (those named, else every one), or None (left out)."""
    obs, label, moon = args[:3]
    variants = args[3] if len(args) > 3 else tuple(VARIANTS)
    from lunarviz.methods import accuracy
    from lunarviz.methods.tracer.estimators import TraceScene, trace_path
    from lunarviz.scene import ResolvedScene
    from lunarviz.workflows.skips import skip_reason
    s = ResolvedScene(method="raytrace", brdfs=BRDFS, moon_model=moon, observer=obs, times=(label,), rtol=1e-4)
    sc = s.geometry(label)
    if skip_reason(s, sc) or not accuracy.in_model_range(sc):
        return None
    base = s.trace_settings(1, s.trace_plan(sc.theta_deg))
    brdfs = s.brdf_models()

    def trace(order, pole, horizon_order=None):
        pair = None if base.lune_source_orders is None else (base.lune_source_orders[0], order)
        st = replace(base, earth_pole=pole, earth_order=order, lune_source_orders=pair,
                     earth_horizon_order=horizon_order)
        ts = TraceScene(sc, st)
        t = time.perf_counter()
        r = trace_path(ts, "earthshine", brdfs)
        return r.mean, ts, time.perf_counter() - t
    t = time.perf_counter()
    ref, ts, _ = trace(REFERENCE_ORDER, "detector-cut", REFERENCE_ORDER)
    lune = ts.sampling.lune_rule_applies("earth")
    unbounded = ts.sampling.eclipse_possible() or ts.sampling.moon_shadow_on_earth_possible() or \
        (not lune and ts.sampling.edges_found("earth"))
    if unbounded:  # rows without a bound whatever the Earth's rule (accuracy.traced_bound): not measured
        return None
    if not all(v > 0 for v in ref.values()):
        return None
    out = {"observer": obs, "time_utc": label, "moon_model": moon, "theta_deg": sc.theta_deg, "lune_rule": bool(lune)}
    for variant, (pole, orders) in ((v, VARIANTS[v]) for v in variants):
        errs, secs = {}, {}
        for o in orders:
            got, _, dt_ = trace(o, pole)
            errs[str(o)] = {k: abs(got[k] / ref[k] - 1.0) for k in brdfs}
            secs[str(o)] = dt_
        out[variant] = {"errors": errs, "seconds": secs}
    out["seconds"] = time.perf_counter() - t
    return out


def table(results: list[dict], variant: str) -> tuple[dict, dict]:
    """({moon model: {order: largest error}}, {moon model: {order: mean seconds}}) of one variant
    over dates and BRDFs; the errors non-increasing in the order."""
    orders = VARIANTS[variant][1]
    err, sec = {}, {}
    for moon in MOONS:
        rs = [r[variant] for r in results if r["moon_model"] == moon]
        worst = [max(max(r["errors"][str(o)].values()) for r in rs) for o in orders]
        nested = [max(worst[i:]) for i in range(len(worst))]  # never less error allowed at a lower order
        err[moon] = {str(o): float(e) for o, e in zip(orders, nested)}
        sec[moon] = {str(o): float(np.mean([r["seconds"][str(o)] for r in rs])) for o in orders}
    return err, sec


def remeasure(results: list[dict], variant: str, workers: int) -> None:
    """Measure ``variant`` of the rule again on every case of ``results`` (in place: each keeps
    the other variants' errors), after a change to that rule."""
    with ProcessPoolExecutor(workers) as ex:
        again = list(ex.map(measure, [(r["observer"], r["time_utc"], r["moon_model"], (variant,)) for r in results]))
    kept = []
    for r, new in zip(results, again):
        if new is not None:  # (a case now left out goes: its variant's errors would be stale)
            r[variant] = new[variant]
            r["seconds"] = r.get("seconds", 0.0) + new["seconds"]
            kept.append(r)
    if len(kept) < len(results):
        print(f"{len(results) - len(kept)} cases now left out (a hidden Moon, an eclipse, θ outside 5-175°): dropped")
    results[:] = kept


def held_out(a, argv) -> int:
    """Each rule's error at each order on dates the model was not built from, against the table
    stored in ``lunarviz/data/error_models.json`` (the bound a row takes is SAFETY times it): the
    largest over the dates and BRDFs, and its ratio to the table's."""
    from lunarviz.methods import accuracy
    t0 = time.perf_counter()
    picks = dates(a.every_hours, a.nights, start=dt.datetime(2026, 1, 1, 7), first_night=dt.date(2026, 1, 7),
                  hours=("05", "10")) + limb_observers(HELD_OUT_LIMB_DATES, HELD_OUT_LIMB_OFFSETS) \
        if not a.dates else [(orbit, d.strip()) for d in a.dates.split(",") for orbit in ORBITS]
    name = "off_centre_earth_held_out_dates" if a.dates else "off_centre_earth_held_out"
    old = {}
    if a.from_json:  # an earlier held-out run's cases (with --remeasure, one variant measured again)
        old = json.loads(Path(a.from_json).read_text())
        results = old["dates"]
        if a.remeasure:
            remeasure(results, a.remeasure, a.workers)
    else:
        with ProcessPoolExecutor(a.workers) as ex:
            results = [r for r in ex.map(measure, [(obs, t, moon) for obs, t in picks for moon in MOONS])
                       if r is not None]
    this = "python scripts/off_centre_earth_model.py " + " ".join(argv or sys.argv[1:])
    command = " && ".join(c for c in (old.get("command"), this) if c)  # (a rerun's after the run it starts from)
    wall = old.get("wall_seconds", 0.0) + time.perf_counter() - t0
    lines = ["# The Earth's beam rules about the zero-phase point, on held-out dates", "",
             f"`{command}`: {len(results)} (date, "
             f"lunar model) cases the model was not built from ({wall:.0f} s); the largest "
             f"error over them and the BRDFs, and its ratio to the stored table's (rows report "
             f"{accuracy.SAFETY:g} times the table's).", ""]
    for variant, (pole, orders) in VARIANTS.items():
        stored = accuracy.error_models()[TABLE_KEYS[variant]]["max_rel_error"]
        lines += [f"## {variant}", "", "| lunar model | " + " | ".join(f"order {o}" for o in orders) + " |",
                  "|---|" + "---|" * len(orders)]
        for moon in MOONS:
            rs = [r[variant]["errors"] for r in results if r["moon_model"] == moon]
            cells = []
            for o in orders:
                worst = max(max(e[str(o)].values()) for e in rs)
                cells.append(f"{worst:.1e} ({worst / stored[moon][str(o)]:.2f})")
            lines.append(f"| {moon} | " + " | ".join(cells) + " |")
        lines.append("")
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / f"{name}.json").write_text(json.dumps({"dates": results, "command": command, "wall_seconds": wall},
                                                 indent=1) + "\n")
    (out / f"{name}.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--every-hours", type=int, default=61, help="orbit dates every this many hours (default 61)")
    ap.add_argument("--nights", type=int, default=8, help="nights per site (default 8)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--write", action="store_true", help="store the table in lunarviz/data/error_models.json")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "error_models"))
    ap.add_argument("--from-json", default=None, help="the cases of an earlier run's off_centre_earth.json, not "
                    "measured again (only the cases it lacks are); with --held-out, of an earlier held-out run")
    ap.add_argument("--remeasure", default=None, choices=tuple(VARIANTS),
                    help="with --from-json: measure this variant of the rule again on every stored case (the "
                         "others' errors kept), after a change to it (with --held-out: the held-out cases)")
    ap.add_argument("--held-out", action="store_true",
                    help="measure dates the model was not built from (orbit hours from Jan 1 07:00, site nights "
                         "from Jan 7 at 05:00 and 10:00 UTC, the lit limb's places at HELD_OUT_LIMB_DATES and "
                         "_OFFSETS) against the stored table: off_centre_earth_held_out.md")
    ap.add_argument("--dates", default=None,
                    help="with --held-out: these orbit dates (UTC, comma-separated) instead, reported in "
                         "off_centre_earth_held_out_dates.md")
    a = ap.parse_args(argv)
    if a.remeasure and not a.from_json:
        ap.error("--remeasure takes the cases of --from-json")
    if a.held_out:
        return held_out(a, argv)
    jobs = [(obs, t, moon) for obs, t in dates(a.every_hours, a.nights) + limb_observers() for moon in MOONS]
    t0 = time.perf_counter()
    results = json.loads(Path(a.from_json).read_text())["dates"] if a.from_json else []
    stored = {(r["observer"], r["time_utc"], r["moon_model"]) for r in results}
    if a.remeasure:  # the stored cases (those it lacks are measured whole below)
        remeasure(results, a.remeasure, a.workers)
    todo = [j for j in jobs if j not in stored]  # (with --from-json: the cases it lacks, e.g. new places;
    new = []  # those left out, e.g. a hidden Moon, are looked at again: a fraction of a second each)
    if todo:
        with ProcessPoolExecutor(a.workers) as ex:
            new = [r for r in ex.map(measure, todo) if r is not None]
    results += new
    measured = bool(new or a.remeasure)  # (this run measured something: its command and time count)
    tabs = {v: table(results, v) for v in VARIANTS}
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    old = json.loads(Path(a.from_json).read_text()) if a.from_json else {}
    report = {"variants": {v: {"earth_pole": p, "orders": list(o)} for v, (p, o) in VARIANTS.items()},
              "reference": {"earth_pole": "detector-cut", "order": REFERENCE_ORDER},
              "table": {v: t[0] for v, t in tabs.items()}, "seconds": {v: t[1] for v, t in tabs.items()},
              "dates": results,
              "wall_seconds": old.get("wall_seconds", 0.0) + (time.perf_counter() - t0 if measured else 0.0),
              "command": " && ".join(c for c in (old.get("command"), "python scripts/off_centre_earth_model.py "
                                                 + " ".join(argv or sys.argv[1:]) if measured else None) if c)}
    (out / "off_centre_earth.json").write_text(json.dumps(report, indent=1) + "\n")
    lines = ["# The Earth's beam rules about the zero-phase point, off the Earth's centre", "",
             f"`{report['command']}`: {len(results)} (date, lunar model) cases, earthshine of "
             f"{', '.join(BRDFS)} at each Earth order of each rule against order {REFERENCE_ORDER} of the rule "
             f"cut along the roughness's kinks ({report['wall_seconds']:.0f} s).", "",
             "Rules: `plain` (`earth_pole=\"detector\"`: the visible disc, the lit cap and the horizon as caps), "
             "`cut` (`earth_pole=\"detector-cut\"`: also cut along the plane of the normal and the detector, "
             "ψ = 0, and the circle tangent to i = e at the pole). Largest error over dates and BRDFs "
             "(non-increasing in the order), then the mean seconds of a date's earthshine trace.", ""]
    for v, (pole, orders) in VARIANTS.items():
        err, sec = tabs[v]
        lines += [f"## {v}", "", "| lunar model | " + " | ".join(f"order {o}" for o in orders) + " |",
                  "|---|" + "---|" * len(orders)]
        for moon in MOONS:
            lines.append(f"| {moon} | " + " | ".join(f"{err[moon][str(o)]:.1e}" for o in orders) + " |")
        for moon in MOONS:
            lines.append(f"| {moon}, seconds | " + " | ".join(f"{sec[moon][str(o)]:.2f}" for o in orders) + " |")
        lines += ["", "Largest error per observer:", ""]
        groups = [(f"`{obs}`", lambda r, obs=obs: r["observer"] == obs) for obs in OBSERVERS]
        groups.append(("the orbit through the Earth's lit limb's zero-phase places (LIMB_OFFSETS)",
                       lambda r: r["observer"] not in OBSERVERS))
        for name, member in groups:
            for moon in MOONS:
                rs = [r[v] for r in results if member(r) and r["moon_model"] == moon]
                if rs:
                    cells = " | ".join(f"{max(max(r['errors'][str(o)].values()) for r in rs):.1e}" for o in orders)
                    lines.append(f"- {name}, {moon} ({len(rs)} dates): {cells}")
        lines.append("")
    (out / "off_centre_earth.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    if a.write:
        path = ROOT / "lunarviz" / "data" / "error_models.json"
        m = json.loads(path.read_text())
        for v, key in TABLE_KEYS.items():
            m[key] = {"earth_pole": VARIANTS[v][0], "orders": list(VARIANTS[v][1]),
                      "reference": report["reference"], "max_rel_error": tabs[v][0], "seconds": tabs[v][1],
                      "source": "scripts/off_centre_earth_model.py (benchmarks/error_models/off_centre_earth.md)"}
        path.write_text(json.dumps(m, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
