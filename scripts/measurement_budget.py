"""The error budget of an earthshine measurement against lunar phase, for both packaged instruments.

For each phase (salex: the paper's θ scene from the geocentre, θ = 30-170°; bbso: one night-time
date a day over the lunation of March-April 2026 from Big Bear, the hour of the Moon's highest
altitude with the Sun below -12° and the Moon above 25°):

1. ``lunarviz plan``: the exposure reaching SNR 100 on the earthlit patch unsaturated, or the
   longest safe exposure and the frames that reach SNR 100 with it (at most 100);
2. the noise-free frame measured by the pipeline with that many frames: the predicted random
   terms (photon, read + dark, halo fit) and p*;
3. the systematic terms (lunar model, halo shape, ND filter, ephemeris, band).

Then 200 simulated salex measurements at θ = 120° (``lunarviz measure --simulate``) check that
the stated σ covers the truth. Writes ``benchmarks/measurement/budget.json``, ``budget.md``,
``budget.png`` and ``simulate_salex_120.json``. About 10 minutes on 2 cores (``--quick``: a
smoke run of one phase and one date into ``--out``).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from lunarviz.api import Scene
from lunarviz.errors import LunarvizError
from lunarviz.instrument.budget import halo_shape_sigma, with_budget
from lunarviz.instrument.pipeline import measure
from lunarviz.instrument.spec import load_instrument
from lunarviz.scene import ResolvedScene
from lunarviz.workflows.measurement import instrument_scene, observation, observation_calibration, plan, systematics

BBSO_SITE = "site:34.26,-116.92,2067"
TARGET_SNR = 100.0
MAX_FRAMES = 100
TERMS = ("sigma_photon", "sigma_read_dark", "sigma_halo_fit", "sigma_lunar_model", "sigma_halo_shape",
         "sigma_nd_filter", "sigma_ephemeris", "sigma_band")


def budget_row(settings, key, inst) -> dict:
    try:
        return _budget_row(settings, key, inst)
    except LunarvizError as exc:  # a phase without patches (a crescent too thin): said in the table
        sc, _ = settings.task(key)
        return {"key": str(key), "phase_angle_deg": float(sc.alpha_deg), "error": str(exc)}


def _budget_row(settings, key, inst) -> dict:
    obs = observation(settings, key, inst, 1.0)
    cal = observation_calibration(settings, key, inst, obs)
    p = plan(settings, key, inst, TARGET_SNR, obs, cal)
    if p["feasible"]:
        t, n = p["exposure_s"], 1
    else:
        t, n = p["saturation_exposure_s"], min(p["frames_needed_at_saturation_exposure"], MAX_FRAMES)
    obs, cal = replace(obs, exposure_s=t), replace(cal, exposure_s=t)  # rates do not depend on the exposure
    row = measure(obs.expected_counts, n, cal)
    rel = systematics(instrument_scene(settings, inst), key, cal)
    row = with_budget(row, rel, halo_shape_sigma(obs.expected_counts, n, cal, row["p_star"]))
    sc, fields = settings.task(key)
    return {"key": str(key), "phase_angle_deg": float(sc.alpha_deg), "exposure_s": t, "frames": n,
            "plan_feasible": p["feasible"], "snr_planned": p.get("snr_at_exposure", p["snr_at_saturation_exposure"]),
            "moon_altitude_deg": fields.get("moon_altitude_deg"), "sky_model": obs.sky_note,
            **{k: row[k] for k in ("p_star", "p_star_sigma", *TERMS, "p_star_sigma_systematic",
                                   "p_star_sigma_total", "p_star_U_k2")}}


def bbso_dates(start: str, days: int) -> list[str]:
    """One date a day: the hour of the Moon's highest altitude at night (Sun below -12°, Moon above 25°)."""
    from datetime import datetime, timedelta

    from lunarviz.geometry.scene_geometry import angle_between
    t0 = datetime.fromisoformat(start.replace("Z", "+00:00"))
    out = []
    for d in range(days):
        best = None
        for h in range(24):
            label = (t0 + timedelta(days=d, hours=h)).strftime("%Y-%m-%dT%H:%M:%SZ")
            s = ResolvedScene(times=(label,), observer=BBSO_SITE, brdfs=("dhg",))
            sc, f = s.task(label)
            sun_alt = 90.0 - float(np.degrees(angle_between(np.asarray(sc.horizon_normal), sc.sun - sc.det)))
            if sun_alt < -12.0 and f["moon_altitude_deg"] > 25.0 and 30.0 < f["phase_angle_deg"] < 165.0:
                if best is None or f["moon_altitude_deg"] > best[0]:
                    best = (f["moon_altitude_deg"], label)
        if best is not None:
            out.append(best[1])
    return out


def plot(rows: dict, path: Path) -> None:
    """The budget's figure: ``lunarviz plot budget.json`` draws the same (lunarviz.workflows.plot_file)."""
    from lunarviz.workflows.plot_file import plot_budget
    plot_budget({"rows": rows}, path)


def markdown(rows: dict, sim: dict | None) -> str:
    lines = ["# Error budget of p* (1σ, relative to p*; `python scripts/measurement_budget.py`)", ""]
    head = ["phase", "exposure s", "frames", "p*", "random", *[k.replace("sigma_", "") for k in TERMS], "total",
            "U (k=2)"]
    for name, rs in rows.items():
        lines += [f"## {name}", "", "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        for r in sorted(rs, key=lambda r: r["phase_angle_deg"]):
            if "error" in r:
                lines.append(f"| {r['phase_angle_deg']:.1f} | {r['error']} |")
                continue
            p = r["p_star"]
            lines.append("| " + " | ".join([f"{r['phase_angle_deg']:.1f}", f"{r['exposure_s']:.4g}", str(r["frames"]),
                                            f"{p:.4f}", f"{r['p_star_sigma'] / p:.2e}",
                                            *[f"{r[k] / p:.2e}" for k in TERMS], f"{r['p_star_sigma_total'] / p:.2e}",
                                            f"{r['p_star_U_k2'] / p:.2e}"]) + " |")
        lines.append("")
    if sim is not None:
        s = sim["summary"]
        lines += ["## Coverage: 200 simulated salex measurements at θ = 120°", "",
                  f"`{sim['command']}`", "",
                  f"sweep p* {s['p_star_sweep']:.6f}, noiseless measurement {s['p_star_noiseless']:.6f} "
                  f"(relative {s['noiseless_relative_error']:.1e}); standardised errors (p* − sweep)/p_star_sigma: "
                  f"mean {s['standardised_error_mean']:+.3f}, variance {s['standardised_error_variance']:.3f}, "
                  f"|z| ≤ 1 in {100 * s['coverage_1sigma']:.1f} %, "
                  f"|z| ≤ 2 in {100 * s['coverage_k2_random']:.1f} %.", ""]
    return "\n".join(lines)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true",
                    help="a smoke run: one phase, one date, 128² detectors, no simulation")
    ap.add_argument("--out", default="benchmarks/measurement", help="output folder")
    ap.add_argument("--plot-only", action="store_true", help="redraw budget.png from the kept budget.json")
    a = ap.parse_args(argv)
    out = Path(a.out)
    if a.plot_only:
        plot(json.loads((out / "budget.json").read_text())["rows"], out / "budget.png")
        return
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.time()
    phases = [120.0] if a.quick else [float(p) for p in range(30, 171, 10)]
    salex = load_instrument("salex")
    bbso = load_instrument("bbso")
    if a.quick:  # smoke size: the presets on 128² detectors of 4× larger pixels, one ray per pixel
        salex = replace(salex, width=128, height=128, pixel_size_um=4 * salex.pixel_size_um, supersample=1)
        bbso = replace(bbso, width=128, height=128, pixel_size_um=4 * bbso.pixel_size_um, supersample=1)
    rows = {"salex (geocentre, θ scene)": [budget_row(Scene([th], brdfs="dhg").settings("raytrace"), th, salex)
                                          for th in phases]}
    # quick: one night the full run also picks (the Moon 61° up, phase 99°)
    dates = ["2026-03-25T03:30:00Z"] if a.quick else bbso_dates("2026-03-21T00:00Z", 26)
    settings = Scene(time=dates, observer=BBSO_SITE, brdfs="dhg").settings("raytrace")
    rows["bbso (Big Bear, March-April 2026)"] = [budget_row(settings, d, bbso) for d in dates]
    sim = None
    if not a.quick:
        t120 = plan(Scene([120.0], brdfs="dhg").settings("raytrace"), 120.0, salex, TARGET_SNR)["exposure_s"]
        cmd = ["lunarviz", "measure", "--simulate", "200", "--instrument", "salex", "--phase", "120", "--exposure",
               f"{t120:.6g}", "--seed", "1", "--out", str(out / "simulate_salex_120.json"), "--quiet"]
        subprocess.run(cmd, check=True)
        sim = json.loads((out / "simulate_salex_120.json").read_text())
        sim["command"] = " ".join(cmd[:-1]).replace(str(out) + "/", "")
    (out / "budget.json").write_text(json.dumps({"target_snr": TARGET_SNR, "max_frames": MAX_FRAMES, "rows": rows,
                                                 "seconds": time.time() - t0}, indent=1))
    (out / "budget.md").write_text(markdown(rows, sim))
    plot(rows, out / "budget.png")
    print(f"wrote {out}/budget.json, budget.md, budget.png in {time.time() - t0:.0f} s", file=sys.stderr)


if __name__ == "__main__":
    main()
