"""Run time of real observers' dates, measured end to end through the command line (wall time of a
fresh process, imports included; this machine, nothing else running).

    python scripts/observer_speed.py [--repeats N] [--out DIR]

1. A lunation of nightly dates from Big Bear Solar Observatory (``site:34.26,-116.92,2067``), V
   band, ``--moon-model rolo-fit-map``, DHG, a land-ocean Earth with zonal clouds, one date a night
   at 03:00 UTC: 30 nights from 2026-02-17 by ``--time-range`` (the nights whose Moon is below the
   horizon are skipped in the run), and the same lunation by ``--lunation 2026-02-25,03:00Z``
   (those nights dropped before it). Best and median of ``--repeats`` runs; each skipped row's own
   time (``seconds``); ``--dry-run``'s estimate beside the measured time.
2. The paper sweep at ``--rtol 1e-5`` (37 phases, three BRDFs, the deterministic tracer, no occlusion:
   the paper's assumption, as the speed targets measure it).

Writes ``results.json`` and ``report.md`` to ``benchmarks/observers`` (or ``--out``).
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SITE = "site:34.26,-116.92,2067"
SCENE = ["--method", "raytrace", "--observer", SITE, "--band", "V", "--moon-model", "rolo-fit-map", "--brdf", "dhg",
         "--earth-surface", "landocean", "--clouds", "zonal"]
NIGHTS = ["--time-range", "2026-02-17T03:00Z,2026-03-18T03:00Z,1d"]
LUNATION = ["--lunation", "2026-02-25,03:00Z"]
PAPER = ["--method", "raytrace", "--no-occlusion", "--phases", "0:180:5", "--brdf", "lambert,shg,dhg", "--rtol", "1e-5"]


def lunarviz(*args) -> tuple[float, str]:
    """Run ``lunarviz ARGS`` in a fresh process: (wall time [s], its standard output)."""
    t = time.perf_counter()
    r = subprocess.run([sys.executable, "-m", "lunarviz", *args], check=True, cwd=ROOT, capture_output=True,
                       text=True)
    return time.perf_counter() - t, r.stdout


def timed(args: list, repeats: int, tmp: Path, name: str) -> dict:
    out = tmp / f"{name}.json"
    walls = [lunarviz("sweep", *args, "--quiet", "--out", str(out))[0] for _ in range(repeats)]
    rows = json.loads(out.read_text())["rows"]
    skipped = [r for r in rows if r.get("skip_reason")]
    return {"command": "lunarviz sweep " + " ".join(args) + " --out FILE", "wall_s": walls,
            "best_s": min(walls), "median_s": statistics.median(walls), "rows": len(rows),
            "skipped_rows": len(skipped), "skip_reasons": sorted({r["skip_reason"] for r in skipped}),
            "max_skipped_row_seconds": max((r["seconds"] for r in skipped), default=None),
            "computed_row_seconds_sum": sum(r["seconds"] for r in rows if not r.get("skip_reason")),
            "bounded_rows": sum(1 for r in rows if r["rtol"] is not None and r["rtol"] == r["rtol"]),
            "computed_rows_bounded": len(bounds := [r["rtol"] for r in rows if not r.get("skip_reason")
                                                    and r["rtol"] is not None and r["rtol"] == r["rtol"]]),
            "bounds": [min(bounds), max(bounds)] if bounds else None,
            "no_bound_reasons": sorted({r["no_bound_reason"] for r in rows if r.get("no_bound_reason")})}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "observers"))
    a = ap.parse_args(argv)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    res = {"machine": {"platform": platform.platform(), "cpus": __import__("os").cpu_count()}}
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        dry_wall, dry = lunarviz("sweep", *SCENE, *NIGHTS, "--dry-run")
        res["dry_run"] = {"command": "lunarviz sweep " + " ".join(SCENE + NIGHTS) + " --dry-run",
                          "wall_s": dry_wall, "printed": dry.strip().splitlines()}
        res["bbso_nights"] = timed(SCENE + NIGHTS, a.repeats, tmp, "nights")
        res["bbso_lunation"] = timed(SCENE + LUNATION, a.repeats, tmp, "lunation")
        res["paper_rtol_1e-5"] = timed(PAPER, a.repeats, tmp, "paper")
    (out / "results.json").write_text(json.dumps(res, indent=2) + "\n")
    lines = ["# Real observers' dates: run time", "",
             f"`python scripts/observer_speed.py --repeats {a.repeats}` on {res['machine']['platform']}, "
             f"{res['machine']['cpus']} CPUs (wall time of a fresh process each, imports included).", "",
             "| run | rows | skipped | best [s] | median [s] | slowest skipped row [s] "
             "| computed rows bounded: bounds |",
             "|---|---|---|---|---|---|---|"]
    for key in ("bbso_nights", "bbso_lunation", "paper_rtol_1e-5"):
        r = res[key]
        slow = "" if r["max_skipped_row_seconds"] is None else f"{r['max_skipped_row_seconds']:.3f}"
        b = r["bounds"]
        bounds = f"{r['computed_rows_bounded']} of {r['rows'] - r['skipped_rows']}: {b[0]:.2e}-{b[1]:.2e}" if b else ""
        lines.append(f"| `{r['command']}` | {r['rows']} | {r['skipped_rows']} | {r['best_s']:.1f} | "
                     f"{r['median_s']:.1f} | {slow} | {bounds} |")
    lines += ["", "`--dry-run` of the nightly run printed (in "
              f"{res['dry_run']['wall_s']:.1f} s):", "", "```", *res["dry_run"]["printed"], "```", "",
              "Rows without a bound, and why: " + "; ".join(
                  f"{k}: {', '.join(res[k]['no_bound_reasons']) or 'none'}"
                  for k in ("bbso_nights", "paper_rtol_1e-5")),
              ""]
    (out / "report.md").write_text("\n".join(lines))
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
