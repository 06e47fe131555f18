"""Rows seen from observers off the Earth's centre against high-order references: is every error
below the bound its row reports, and every bound within the tolerance?

    python scripts/off_centre_validation.py [--rtol 1e-4] [--every-hours H] [--nights N] [--reference-order N]
                                            [--view-cut N | --lit-limb] [--out DIR]

Dates that the error models were not built from (:mod:`scripts.off_centre_earth_model` takes
2026 hours from 05:00 on Jan 3 in steps of 61 h, and site nights every 9 days from Jan 5): a
550 km orbit every 700 hours from 2026-01-08T11:00 and Big Bear (``site:34.26,-116.92,2067``)
and Mauna Kea (``site:19.82,-155.47,4205``) nights every 11 days from 2026-01-10 at 04:00
and 09:00 UTC. Each row of ``lunarviz sweep --method raytrace --rtol R`` (Lambert, SHG, DHG;
the paper's Moon and rolo-fit-map; grey and at 550 nm) is compared with

* the paper's Moon: the exact reference (``--method reference``) at outer/inner orders 48/12
  (its rule about the zero-phase point cut along the roughness's kinks);
* rolo-fit-map, and every spectral row: the tracer's own lune rule at a high order
  (``--reference-order``: by default 64 at tolerances of 1e-4 and above, 128 below) with Sun
  order 12 and Earth order 10 of the rule cut along the kinks (2.1e-7 on rolo-fit-map, its
  model), the mapped rule with the finer sums of its error model's reference
  (``mapped_lune_models.REFERENCE_RULE``; a map's cells are exact in the mapped rule's weights;
  the reference reads the map per node and would not converge). Order 128 is above every order
  the models hold, and 64 above every order a tolerance of 1e-4 takes (at most 32), so the lune
  rule's own error is in what is checked; the reference's own error on rolo-fit-map over
  θ = 5-175° (``benchmarks/error_models/mapped_lune.md``): order 64 ≤ 9.8e-6, a tenth of 1e-4;
  orders 96 and 128 differ by ≤ 1.9e-6. The 550 nm rows on one computed date in
  ``--spectral-every``.

Writes ``off_centre_validation.md`` and ``.json`` to ``benchmarks/error_models`` (or ``--out``).
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import math
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "scripts"))
import mapped_lune_models  # noqa: E402 (a script beside this one)
import off_centre_earth_model  # noqa: E402

#: the high-order reference's lune order (both paths) by default: above every order the models hold,
#: or, at tolerances of 1e-4 and above, above every order they take there (at a quarter of the cost)
REFERENCE_LUNE_ORDER, LOOSE_REFERENCE_LUNE_ORDER = 128, 64


def reference_lune_order(rtol: float) -> int:
    """The high-order reference's lune order at ``rtol`` when none is given (module docstring)."""
    return LOOSE_REFERENCE_LUNE_ORDER if rtol >= 1e-4 else REFERENCE_LUNE_ORDER

BRDFS = ("lambert", "shg", "dhg")
OBSERVERS = ("orbit:550,97.6,0,0", "site:34.26,-116.92,2067", "site:19.82,-155.47,4205")
PATHS = {"moonshine_W_m2": "moonshine", "earthshine_W_m2": "earthshine"}


def dates(every_hours: int, nights: int) -> list[tuple[str, str]]:
    """The held-out dates (the module docstring's): the error model's date list with other starts,
    steps, hours and a second site."""
    return off_centre_earth_model.dates(every_hours, nights, start=dt.datetime(2026, 1, 8, 11),
                                        first_night=dt.date(2026, 1, 10), night_step=11, hours=("04", "09"),
                                        observers=OBSERVERS)


#: held-out places where the zero-phase point lies on or beside the Earth's lit limb, where the Earth's
#: rule about it converges slowest (the error model's LIMB_DATES and its held-out places are other
#: dates): ``limb_observers`` at these dates (θ ≈ 31-170°) and offsets [Earth radii] (just inside
#: the limb, and 0.015 and 0.05 beyond it)
LIT_LIMB_DATES = ("2026-06-19T14:00:00Z", "2026-06-24T16:00:00Z", "2026-06-27T05:00:00Z", "2026-07-04T20:00:00Z",
                  "2026-10-11T09:00:00Z", "2026-10-14T22:00:00Z")
LIT_LIMB_OFFSETS = (0.996, 1.015, 1.05)

#: the orbit of the view-cut dates, its epoch fixed (so a date's place on it does not depend on the run)
CUT_ORBIT = "orbit:550,97.6,0,0,2026-01-01T00:00Z"
#: hidden shares of the Moon's disc the view-cut dates aim at (the Earth's limb or a horizon across it)
CUT_SHARES = (0.1, 0.5, 0.9)


def _hidden_share(obs: str, when: dt.datetime) -> float:
    """The share of the Moon's disc hidden from ``obs`` at ``when``: behind a site's horizon (the disc's
    segment below the plane) or the Earth's disc (two caps' overlap on the sky, closed form)."""
    import numpy as np

    from lunarviz.geometry.scene_geometry import angle_between
    from lunarviz.scene import ResolvedScene
    label = when.strftime("%Y-%m-%dT%H:%M:%SZ")
    sc = ResolvedScene(method="raytrace", observer=obs, times=(label,)).geometry(label)
    v = sc.moon - sc.det
    rho = float(np.arcsin(sc.radii["moon"] / np.linalg.norm(v)))
    if sc.horizon_normal is not None:  # the disc's share below the plane (a flat segment: small disc)
        h = -float(np.dot(v, sc.horizon_normal)) / np.linalg.norm(v) / np.sin(rho)
        h = min(1.0, max(-1.0, h))
        return float((np.arccos(-h) - (-h) * np.sqrt(1 - h * h)) / np.pi)
    w = sc.earth - sc.det
    alpha = float(np.arcsin(sc.radii["earth"] / np.linalg.norm(w)))
    g = float(angle_between(v, w))
    if g >= rho + alpha:
        return 0.0
    if g <= alpha - rho:
        return 1.0
    c1, c2, cg, s1, s2, sg = np.cos(rho), np.cos(alpha), np.cos(g), np.sin(rho), np.sin(alpha), np.sin(g)
    lens = 2 * (np.pi - np.arccos((cg - c1 * c2) / (s1 * s2)) - c1 * np.arccos((c2 - cg * c1) / (sg * s1))
                - c2 * np.arccos((c1 - cg * c2) / (sg * s2)))
    return float(lens / (2 * np.pi * (1 - c1)))


def view_cut_dates(count: int) -> list[tuple[str, str]]:
    """Dates with the Earth's limb (:data:`CUT_ORBIT`) or a site's horizon across the Moon's disc,
    hiding :data:`CUT_SHARES` of it: from ``count`` starts (every 613 h from 2026-01-04T02:00 for the
    orbit, every 17 days from 2026-01-06 for each site) the first minute the share changes, then the
    second where it passes each aim (bisection on whole seconds)."""
    out = []
    orbit = [dt.datetime(2026, 1, 4, 2) + dt.timedelta(hours=613 * k) for k in range(count)]
    nights = [dt.datetime(2026, 1, 6) + dt.timedelta(days=17 * k) for k in range(count)]
    # (observer, starts, minutes scanned, step [min]): an orbit's limb crosses the Moon within its period
    scans = [(CUT_ORBIT, orbit, 100, 1), *[(site, nights, 1440, 2) for site in OBSERVERS[1:]]]
    for obs, starts, span, step in scans:
        for t0 in starts:
            prev = _hidden_share(obs, t0)
            for m in range(step, span, step):
                t1 = t0 + dt.timedelta(minutes=m)
                cur = _hidden_share(obs, t1)
                if cur != prev:
                    break
                prev = cur
            else:
                continue
            for aim in CUT_SHARES:  # bisect the minute for the second the share passes the aim
                lo, hi = t1 - dt.timedelta(minutes=step), t1
                rising = cur > prev
                if not (min(prev, cur) < aim < max(prev, cur)):
                    lo, hi = t1 - dt.timedelta(minutes=step), t1 + dt.timedelta(minutes=step)
                for _ in range(12):
                    mid = lo + (hi - lo) / 2
                    if (_hidden_share(obs, mid) < aim) == rising:
                        lo = mid
                    else:
                        hi = mid
                when = lo.replace(microsecond=0)
                if 0.0 < _hidden_share(obs, when) < 1.0:
                    out.append((obs, when.strftime("%Y-%m-%dT%H:%M:%SZ")))
    return out


def reference(s, label: str, moon: str, spectral: bool, lune_order: int) -> dict:
    """{(brdf, path): value} of the high-order reference for one date: the exact reference at
    48/12 (the paper's Moon, grey), else the tracer at high orders (its plan replaced: lune rule
    at ``lune_order`` for both paths, Sun order 12, Earth order 10 of the Earth's rule about the
    zero-phase point cut along the roughness's kinks)."""
    from lunarviz.scene import ResolvedScene
    from lunarviz.workflows.sweeps import run_phase
    if moon == "paper" and not spectral:
        ref = s.replace(method="reference", rtol=None, reference_outer=48, reference_inner=12)
        return {(r["brdf"], p): r[k] for r in run_phase(ref, label, threads=1) for k, p in PATHS.items()}
    sc = s.geometry(label)
    plan = s.trace_plan(sc.theta_deg)
    hi = {"settings": {**plan["settings"], "lune_order": (lune_order, lune_order), "sun_order": 12, "earth_order": 10,
                       "lune_source_orders": (12, 10), "earth_pole": "detector-cut", "earth_horizon_order": 10},
            "bounds": {}}
    real = ResolvedScene.trace_plan
    ResolvedScene.trace_plan = lambda self, *args, **kwargs: hi  # (whatever the plan is asked)
    try:
        rows = mapped_lune_models.with_rule(mapped_lune_models.REFERENCE_RULE, lambda: run_phase(s, label, threads=1))
    finally:
        ResolvedScene.trace_plan = real
    suffix = "_W_m2_nm" if spectral else "_W_m2"
    return {(r["brdf"], p): r[k.replace("_W_m2", suffix)] for r in rows for k, p in PATHS.items()}


def computed(obs: str, label: str) -> bool:
    """Whether a date is computed and inside the models' phases (not skipped, θ within 5-175°)."""
    from lunarviz.methods import accuracy
    from lunarviz.scene import ResolvedScene
    from lunarviz.workflows.skips import skip_reason
    s = ResolvedScene(method="raytrace", observer=obs, times=(label,))
    sc = s.geometry(label)
    return not skip_reason(s, sc) and accuracy.in_model_range(sc)


def check(args) -> list[dict]:
    obs, label, moon, spectral, rtol, lune_order = args
    from lunarviz.methods import accuracy
    from lunarviz.scene import ResolvedScene
    from lunarviz.workflows.skips import skip_reason
    from lunarviz.workflows.sweeps import run_phase
    kw = {"wavelengths": "550"} if spectral else {}
    s = ResolvedScene(method="raytrace", brdfs=BRDFS, moon_model=moon, observer=obs, times=(label,), rtol=rtol, **kw)
    sc = s.geometry(label)
    if skip_reason(s, sc) or not accuracy.in_model_range(sc):
        return []
    t = time.perf_counter()
    rows = run_phase(s, label, threads=1)
    if not all(r["rtol"] is not None and math.isfinite(r["rtol"]) for r in rows):
        return [{"observer": obs, "time_utc": label, "moon_model": moon, "spectral": spectral, "brdf": r["brdf"],
                 "bound": r["rtol"], "no_bound_reason": r["no_bound_reason"]} for r in rows]
    ref = reference(s, label, moon, spectral, lune_order)
    out = []
    for r in rows:
        for key, path in PATHS.items():
            k = key if not spectral else key.replace("_W_m2", "_W_m2_nm")
            v, want = r[k], ref[(r["brdf"], path)]
            err = abs(v / want - 1.0) if want > 0 else (0.0 if v == 0 else math.inf)
            out.append({"observer": obs, "time_utc": label, "moon_model": moon, "spectral": spectral,
                        "brdf": r["brdf"], "path": path, "theta_deg": sc.theta_deg, "error": err, "bound": r["rtol"],
                        "ratio": err / r["rtol"] if r["rtol"] > 0 else (0.0 if err == 0 else math.inf),
                        "seconds": time.perf_counter() - t})
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rtol", type=float, default=1e-4)
    ap.add_argument("--every-hours", type=int, default=700)
    ap.add_argument("--nights", type=int, default=5)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--reference-order", type=int, default=None,
                    help="the reference's lune order (default: 64 at --rtol 1e-4 and above, else 128)")
    ap.add_argument("--spectral-every", type=int, default=4, help="the 550 nm rows on one computed date in this many")
    places = ap.add_mutually_exclusive_group()
    places.add_argument("--view-cut", type=int, default=None, metavar="N",
                    help="instead: dates with the Earth's limb or a horizon across the Moon's disc, from N starts "
                         "per observer (view_cut_dates); writes off_centre_validation_view_cut_RTOL.*")
    places.add_argument("--lit-limb", action="store_true",
                    help="instead: orbit places with the zero-phase point on or beside the Earth's lit limb "
                         "(LIT_LIMB_DATES, LIT_LIMB_OFFSETS); writes off_centre_validation_lit_limb_RTOL.*")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "error_models"))
    a = ap.parse_args(argv)
    if a.lit_limb:
        chosen = off_centre_earth_model.limb_observers(LIT_LIMB_DATES, LIT_LIMB_OFFSETS)
    else:
        chosen = view_cut_dates(a.view_cut) if a.view_cut else dates(a.every_hours, a.nights)
    live = [d for d in chosen if computed(*d)]
    lights = [(False, True) if i % a.spectral_every == 0 else (False,) for i in range(len(live))]
    order = a.reference_order or reference_lune_order(a.rtol)
    jobs = [(obs, t, moon, spec, a.rtol, order) for (obs, t), specs in zip(live, lights)
            for moon in ("paper", "rolo-fit-map") for spec in specs]
    t0 = time.perf_counter()
    with ProcessPoolExecutor(a.workers) as ex:
        rows = [r for res in ex.map(check, jobs) for r in res]
    checked = [r for r in rows if "error" in r]
    unbounded = [r for r in rows if "error" not in r]
    worst = max(checked, key=lambda r: r["ratio"]) if checked else None
    tag = ("view_cut_" if a.view_cut else "lit_limb_" if a.lit_limb else "") + f"{a.rtol:g}"
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    cmd = "python scripts/off_centre_validation.py " + " ".join(argv or sys.argv[1:])
    (out / f"off_centre_validation_{tag}.json").write_text(json.dumps({"command": cmd, "rows": rows}, indent=1) + "\n")
    places = " (views cut by a limb or a horizon)" if a.view_cut else " (the lit limb's places)" if a.lit_limb else ""
    lines = [f"# Rows off the Earth's centre against high-order references{places} (rtol {a.rtol:g})", "",
             f"`{cmd}` ({time.perf_counter() - t0:.0f} s): {len(checked)} values checked, "
             f"{len(unbounded)} rows without a bound; the tracer's reference at lune order {order}.", ""]
    if worst is not None:
        lines += [f"- largest error / bound: {worst['ratio']:.2f} ({worst['observer']}, {worst['time_utc']}, "
                  f"{worst['moon_model']}, {'550 nm' if worst['spectral'] else 'grey'}, {worst['brdf']} "
                  f"{worst['path']}: error {worst['error']:.1e}, bound {worst['bound']:.1e})",
                  f"- largest bound: {max(r['bound'] for r in checked):.1e} (the tolerance: {a.rtol:g})",
                  f"- errors above their bound: {sum(r['ratio'] > 1 for r in checked)}", ""]
        lines += ["| observer | lunar model | light | BRDF | largest error | largest bound | largest ratio |",
                  "|---|---|---|---|---|---|---|"]
        groups: dict = {}
        for r in checked:
            groups.setdefault((r["observer"], r["moon_model"], r["spectral"], r["brdf"]), []).append(r)
        for (obs, moon, spec, b), rs in sorted(groups.items()):
            lines.append(f"| `{obs}` | {moon} | {'550 nm' if spec else 'grey'} | {b} | "
                         f"{max(r['error'] for r in rs):.1e} | {max(r['bound'] for r in rs):.1e} | "
                         f"{max(r['ratio'] for r in rs):.2f} |")
    if unbounded:
        lines += ["", "Rows without a bound: " + "; ".join(sorted({r["no_bound_reason"] for r in unbounded}))]
    (out / f"off_centre_validation_{tag}.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
