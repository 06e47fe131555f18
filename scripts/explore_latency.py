"""The explorer's latency: time from a control change to its first picture and to its converged one.

    python scripts/explore_latency.py [--quick] [--out benchmarks/explore]

Drives :class:`lunarviz.explore.controls.Explorer` (what the desktop window and the browser app
drive; the background pass on, as in them) on this machine, one change every ``--pause`` seconds,
each to a state not seen before:

* θ: the θ scene (default mesh and tolerance), θ from 60° in steps of 5°;
* a date step: one date a night from Big Bear (site:34.26,-116.92,2067m), the slider moved one night;
* a band: at θ = 120°, the band cycled through B, V, R, Sentinel-2A B4 and MODIS Terra B1.

For each kind: the median and the largest time to the first picture and to the converged one
[s]. Each converged row is also compared with the one ``lunarviz sweep --state`` computes for the
same state (the API's ``run`` on the state's scene): the largest relative difference of
moonshine, earthshine and p* is reported (0: the same numbers). Writes ``latency.json`` and
``README.md`` in ``--out``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _drive(explorer, changes, pause: float) -> list[dict]:
    """Apply each change (a callable) once the previous state has converged; the times its frames
    came after the change [s]."""
    out = []
    for change in changes:
        explorer.engine.wait_idle(600)
        time.sleep(pause)
        seen: dict = {}
        explorer._on_frame = lambda f, seen=seen: seen.setdefault(f.quality, time.perf_counter())
        t0 = time.perf_counter()
        change()
        explorer.engine.wait_idle(600)
        frame = explorer.frame
        out.append({"key": str(frame.state.key), "band": frame.state.band, "error": frame.error,
                    "first_s": seen.get("first", seen.get("converged", float("nan"))) - t0,
                    "converged_s": seen.get("converged", float("nan")) - t0, "row": frame.row})
    return out


def _sweep_difference(state) -> float:
    """Largest relative difference between the explorer's row and ``sweep --state``'s for ``state``."""
    import lunarviz
    from lunarviz.explore.engine import pick_row, state_row
    mine = state_row(state)
    res = lunarviz.run(state.scene(), "raytrace")
    theirs = pick_row(res["rows"], state)
    worst = 0.0
    for k in ("moonshine_W_m2", "earthshine_W_m2", "apparent_albedo"):
        a, b = mine[k], theirs[k]
        if a or b:
            worst = max(worst, abs(a / b - 1.0))
    return worst


def measure(quick: bool, pause: float) -> dict:
    import lunarviz
    from lunarviz.explore.controls import Explorer
    from lunarviz.explore.state import ExploreState, state_from_scene
    n = 3 if quick else 8
    res = {}
    # θ
    ex = Explorer(ExploreState(key=60.0))
    res["theta"] = _drive(ex, [lambda: ex.step(1) for _ in range(n)], pause)
    res["theta_vs_sweep"] = _sweep_difference(ex.state)
    ex.close()
    # a date step, one night at a time, from Big Bear
    times = [f"2026-03-{d:02d}T04:00Z" for d in range(20, 20 + n + 1)]
    scene = lunarviz.Scene(time=times, observer="site:34.26,-116.92,2067m", brdfs=("dhg",))
    ex = Explorer(state_from_scene(scene, brdf="dhg"))
    res["date_step"] = _drive(ex, [lambda: ex.step(1) for _ in range(n)], pause)
    res["date_vs_sweep"] = _sweep_difference(ex.state)
    ex.close()
    # a band
    bands = ["B", "V", "R", "S2A-B4", "MODIS-TERRA-B1"][: 2 if quick else 5]
    ex = Explorer(ExploreState(key=120.0))
    res["band"] = _drive(ex, [lambda b=b: ex.set("band", b) for b in bands], pause)
    res["band_vs_sweep"] = _sweep_difference(ex.state)
    ex.close()
    summary = {}
    for kind in ("theta", "date_step", "band"):
        first = [r["first_s"] for r in res[kind]]
        conv = [r["converged_s"] for r in res[kind]]
        summary[kind] = {"changes": len(first), "first_median_s": statistics.median(first), "first_max_s": max(first),
                         "converged_median_s": statistics.median(conv), "converged_max_s": max(conv),
                         "errors": [r["error"] for r in res[kind] if r["error"]],
                         "max_rel_difference_vs_sweep_state": res[f"{kind.split('_')[0]}_vs_sweep"]}
    return {"quick": quick, "pause_s": pause, "summary": summary,
            "changes": {k: [{x: v for x, v in r.items() if x != "row"} for r in res[k]]
                        for k in ("theta", "date_step", "band")}}


def report(res: dict, out: Path) -> None:
    cmd = "python scripts/explore_latency.py" + (" --quick" if res["quick"] else "")
    lines = ["# The explorer's latency", "",
             f"`{cmd}` on this 2-core machine (no GPU): a control change every {res['pause_s']:g} s after the "
             "previous state converged, each to a state not seen before, the background pass on (as in the "
             "windows). Targets: the first picture ≤ 0.3 s and the converged one ≤ 3 s (medians). Times run to the "
             "engine's callback: the browser app adds its PNG encoding (~25 ms at 1280×800) and up to one 30 ms poll, "
             "the desktop window one 30 ms poll. Steps go to a neighbouring value, whose row the background pass may "
             "have computed already (its picture never: pictures are traced when asked for).", "",
             "| change | changes | first picture, median [s] | max [s] | converged, median [s] | max [s] | "
             "largest difference from `sweep --state` |", "| --- | --- | --- | --- | --- | --- | --- |"]
    for kind, s in res["summary"].items():
        lines.append(f"| {kind.replace('_', ' ')} | {s['changes']} | {s['first_median_s']:.3f} "
                     f"| {s['first_max_s']:.3f} | {s['converged_median_s']:.3f} | {s['converged_max_s']:.3f} | "
                     f"{s['max_rel_difference_vs_sweep_state']:.1e} |")
    (out / "README.md").write_text("\n".join(lines) + "\n")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="three changes of each kind (two bands)")
    ap.add_argument("--pause", type=float, default=1.0, help="seconds between a converged picture and the next change")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "explore"))
    a = ap.parse_args(argv)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    res = measure(a.quick, a.pause)
    (out / "latency.json").write_text(json.dumps(res, indent=1) + "\n")
    report(res, out)
    print((out / "README.md").read_text())


if __name__ == "__main__":
    main()
