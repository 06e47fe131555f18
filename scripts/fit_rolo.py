"""Fit every lunar BRDF to ROLO, store the ``rolo-fit`` preset, and check it on real dates.

    python scripts/fit_rolo.py            # ~1 min; needs the optional rimopy package

Writes
* ``lunarviz/data/moon_models.json``: the ``rolo-fit`` preset (``--moon-model rolo-fit``) and
  ``rolo-fit-map`` (the same fit on a Moon carrying the synthetic albedo map, which makes
  the waxing and waning branches differ), with the fits' provenance;
* ``benchmarks/rolo_fit/fit_{dhg,shg,lambert}[_map].{json,png}``: parameters, 1σ, correlations,
  which parameters the data constrain, residuals against phase (both branches);
* ``benchmarks/rolo_fit/phase_curves.png``: every preset and BRDF against ROLO, 2-120°,
  waxing and waning;
* ``benchmarks/rolo_fit/real_dates.{json,csv}``: lunarviz's moonshine with each preset at real
  dates and the geocentre (DE421 geometry with libration, analytic method) against ROLO
  evaluated for the same geometry (rimopy with lunarviz's selenographic coordinates), none of
  them in the fit (the fit uses zero libration);
* ``benchmarks/rolo_fit/summary.md``: the README's table.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from lunarviz.outputs.writers import write_bytes_atomic, write_results
from lunarviz.workflows.fit import DEFAULT_FREE, DiskModel, plot_fit, rolo_irradiance, rolo_reflectance, run_fit

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "benchmarks" / "rolo_fit"
BAND = "400-750"
FIT_PHASES = "2:96:2"  # ROLO's validity range is about 1.5-97° (Kieffer & Stone 2005)
#: real dates (geocentre), 2026-2030, phase angles about 5-90°, waxing and waning
DATES = ("2026-06-01T00:00Z", "2026-06-03T00:00Z", "2026-06-05T12:00Z", "2026-06-08T12:00Z",
         "2026-06-25T00:00Z", "2026-06-27T12:00Z", "2027-03-20T06:00Z", "2027-03-26T18:00Z",
         "2028-09-07T00:00Z", "2028-09-12T00:00Z", "2029-11-25T00:00Z", "2030-05-13T12:00Z")
#: presets: name -> lunar albedo map they are fitted with
PRESETS = {"rolo-fit": None, "rolo-fit-map": "synthetic"}
#: analytic Gauss order of the fits and the real-date checks: 48 resolves the synthetic map's
#: maria (1° edges) where it is read at the nodes (24 and 48 differ by 0.5 % with the map)
ORDER = 48


def real_dates(models: list[str]) -> list[dict]:
    from lunarviz.scene import ResolvedScene
    from lunarviz.workflows.sweeps import run_phase
    rows = []
    for iso in DATES:
        for model in models:
            rs = run_phase(ResolvedScene(times=(iso,), brdfs=("lambert", "shg", "dhg"), method="analytic",
                                         moon_model=model, order=ORDER), iso)
            for r in rs:
                g = r["phase_angle_deg"]
                waxing = r["sub_solar_lon_deg"] > r["sub_observer_lon_deg"]
                e_rolo = rolo_irradiance(r)
                rows.append({"time_utc": r["time_utc"], "phase_angle_deg": g, "waxing": waxing,
                             "sub_observer_lat_deg": r["sub_observer_lat_deg"],
                             "sub_observer_lon_deg": r["sub_observer_lon_deg"], "moon_model": model,
                             "brdf": r["brdf"], "moonshine_W_m2": r["moonshine_W_m2"], "rolo_W_m2": e_rolo,
                             "ratio": r["moonshine_W_m2"] / e_rolo})
    return rows


OBSERVERS = ("geocentre", "site:34.26,-116.92,2067", "orbit:550,97.6,0,0")


def observers_check() -> list[dict]:
    """``rolo-fit-map`` DHG against ROLO at the real dates for three observers (geocentre, a
    ground site, a 550 km orbit), analytic (default order) and ray traced: rows where the
    Earth hides the Moon are skipped."""
    from lunarviz.scene import ResolvedScene
    from lunarviz.workflows.sweeps import run_phase
    rows = []
    for obs in OBSERVERS:
        for method in ("analytic", "raytrace"):
            for iso in DATES:
                r = run_phase(ResolvedScene(times=(iso,), brdfs=("dhg",), method=method, observer=obs,
                                            moon_model="rolo-fit-map"), iso)[0]
                if r["moonshine_W_m2"] <= 0:
                    continue
                e = rolo_irradiance(r)
                rows.append({"observer": obs, "method": method, "time_utc": iso, "phase_angle_deg": r["phase_angle_deg"],
                             "moonshine_W_m2": r["moonshine_W_m2"], "rolo_W_m2": e, "ratio": r["moonshine_W_m2"] / e})
    return rows


def phase_curves(fitted: dict, path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from lunarviz.photometry.brdf import make_brdf
    g = np.arange(2.0, 120.1, 2.0)
    fig, ax = plt.subplots(1, 2, figsize=(12, 4.6))
    for wax, style in ((True, "-"), (False, "--")):
        a = rolo_reflectance(g, wax, band=(400.0, 750.0))
        ax[0].semilogy(g, a, "k" + style, lw=2, label=f"ROLO {'waxing' if wax else 'waning'}")
        for model in ("paper", *PRESETS):
            mp = PRESETS.get(model)
            dm = DiskModel(g, order=ORDER, waxing=np.full(len(g), wax), moon_map=mp)
            for b, col in (("lambert", "C0"), ("shg", "C1"), ("dhg", "C2")):
                if model == "rolo-fit-map" and b != "dhg":
                    continue  # one map curve keeps the figure legible
                m = dm.reflectance(make_brdf(b, params=fitted[model][b] if model != "paper" else None))
                lw = 1.2 if model != "paper" else 0.8
                ls = style if model != "paper" else ":"
                col = "C3" if model == "rolo-fit-map" else col
                if wax:
                    ax[0].semilogy(g, m, color=col, ls=ls, lw=lw, label=f"{b} ({model})")
                ax[1].plot(g, 100 * (m / a - 1), color=col, ls=ls, lw=lw,
                           label=f"{b} ({model}) / ROLO {'waxing' if wax else 'waning'}" if model != "paper" or wax
                           else None)
    ax[0].set_xlabel("phase angle [deg]")
    ax[0].set_ylabel("disk reflectance (400-750 nm)")
    ax[0].legend(fontsize=7)
    ax[0].set_title("phase curves: presets and BRDFs against ROLO (zero libration)", fontsize=9)
    ax[1].axhline(0, color="k", lw=0.5)
    for y in (-5, 5):
        ax[1].axhline(y, color="k", lw=0.5, ls=":")
    ax[1].set_ylim(-60, 60)
    ax[1].set_xlabel("phase angle [deg]")
    ax[1].set_ylabel("model / ROLO - 1 [%]  (solid waxing, dashed waning)")
    ax[1].legend(fontsize=6, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def replot() -> int:
    """Redraw every fit_*.png from its kept fit_*.json (``--plot-only``)."""
    from lunarviz.workflows.fit import FitResult
    for f in sorted(OUT.glob("fit_*.json")):
        d = json.loads(f.read_text())
        rows = d["rows"]
        res = FitResult(d["brdf"], d["params"], tuple(d["free"]), d["sigma"], np.eye(len(d["free"])), d["constrained"],
                        np.array([r["phase_deg"] for r in rows]), np.array([r["waxing"] for r in rows]),
                        np.array([r["target_reflectance"] for r in rows]),
                        np.array([r["model_reflectance"] for r in rows]), d["rms_log_residual"])
        mp = d["settings"].get("moon_albedo_map")
        plot_fit(res, f.with_suffix(".png"),
                 title=f"{res.brdf} fitted to ROLO (400-750 nm){' on the synthetic albedo map' if mp else ''}, rms log "
                       f"residual {res.rms_log_residual:.3f}; free: {', '.join(res.free)}")
    return 0


def main() -> int:
    if "--plot-only" in sys.argv:
        return replot()
    OUT.mkdir(parents=True, exist_ok=True)
    fitted, report = {}, {}
    for preset_name, mp in PRESETS.items():
        fitted[preset_name], report[preset_name] = {}, {}
        suffix = "" if mp is None else "_map"
        for b in ("dhg", "shg", "lambert"):
            res = run_fit(b, "rolo", BAND, FIT_PHASES, DEFAULT_FREE[b], moon_map=mp, order=ORDER)
            d = res.to_dict()
            d["settings"] = {"source": "rolo (rimopy, Apollo-adjusted, no RCF)", "band_nm": BAND,
                             "phases_deg": FIT_PHASES, "libration": "zero", "free": list(res.free),
                             "moon_albedo_map": mp, "order": ORDER}
            write_results(OUT / f"fit_{b}{suffix}.json", d)
            plot_fit(res, OUT / f"fit_{b}{suffix}.png",
                     title=f"{b} fitted to ROLO (400-750 nm){' on the synthetic albedo map' if mp else ''}, rms log "
                           f"residual {res.rms_log_residual:.3f}; free: {', '.join(res.free)}")
            keep = set(res.free) | {"w", "h", "B0", "b", "c", "xi", "theta_bar", "Bc0", "hc", "albedo"}
            fitted[preset_name][b] = {k: v for k, v in res.params.items() if k in keep}
            report[preset_name][b] = res
            print(f"{preset_name} {b}: rms {res.rms_log_residual:.4f} "
                  + ", ".join(f"{k}={res.params[k]:.4g}±{res.sigma[k]:.2g}" for k in res.free))
    models = {}
    for preset_name, mp in PRESETS.items():
        models[preset_name] = {b: {"params": fitted[preset_name][b],
                                   "rms_log_residual": report[preset_name][b].rms_log_residual}
                               for b in fitted[preset_name]}
        if mp is not None:
            models[preset_name]["moon_albedo_map"] = mp
    preset = {"models": models,
              "provenance": "scripts/fit_rolo.py: ROLO (Kieffer & Stone 2005, rimopy) disk reflectance, "
                            f"{BAND} nm weighted by the Wehrli spectrum, phase {FIT_PHASES} deg both branches, "
                            f"zero libration; analytic disk integration (lunarviz.workflows.fit, order {ORDER}); "
                            "rolo-fit-map on the synthetic lunar albedo map"}
    write_bytes_atomic(ROOT / "lunarviz" / "data" / "moon_models.json", (json.dumps(preset, indent=2) + "\n").encode())
    from lunarviz.photometry.presets import _fitted
    _fitted.cache_clear()
    phase_curves(fitted, OUT / "phase_curves.png")
    rows = real_dates(["paper", *PRESETS])
    write_results(OUT / "real_dates.json", {"rows": rows})
    write_results(OUT / "real_dates.csv", {"rows": rows})
    lines = ["| preset | BRDF | max \\|lunarviz/ROLO − 1\\|, 5–90°, real dates | at phase < 60° | rms log residual of the fit |",
             "| --- | --- | --- | --- | --- |"]
    for model in ("paper", *PRESETS):
        for b in ("lambert", "shg", "dhg"):
            sel = [r for r in rows if r["moon_model"] == model and r["brdf"] == b and 5 <= r["phase_angle_deg"] <= 90]
            lo = [r for r in sel if r["phase_angle_deg"] < 60]
            e = max(abs(r["ratio"] - 1) for r in sel)
            e60 = max(abs(r["ratio"] - 1) for r in lo) if lo else float("nan")
            rms = f"{report[model][b].rms_log_residual:.3f}" if model != "paper" else "—"
            lines.append(f"| {model} | {b} | {100 * e:.1f} % | {100 * e60:.1f} % | {rms} |")
    lines.append("")
    lines.append("| parameter (dhg) | rolo-fit | 1σ | constrained | rolo-fit-map | 1σ | constrained |")
    lines.append("| --- | --- | --- | --- | --- | --- | --- |")
    r, rm = report["rolo-fit"]["dhg"], report["rolo-fit-map"]["dhg"]
    for k in r.free:
        lines.append(f"| {k} | {r.params[k]:.4g} | {r.sigma[k]:.2g} | {'yes' if r.constrained[k] else 'no'} "
                     f"| {rm.params[k]:.4g} | {rm.sigma[k]:.2g} | {'yes' if rm.constrained[k] else 'no'} |")
    obs_rows = observers_check()
    write_results(OUT / "real_dates_observers.json", {"rows": obs_rows})
    lines.append("")
    lines.append("| rolo-fit-map, dhg: observer | method | dates (Moon above the horizon) | max \\|lunarviz/ROLO − 1\\|, 5–90° |")
    lines.append("| --- | --- | --- | --- |")
    for obs in OBSERVERS:
        for method in ("analytic", "raytrace"):
            sel = [r for r in obs_rows if r["observer"] == obs and r["method"] == method and 5 <= r["phase_angle_deg"] <= 90]
            e = max((abs(r["ratio"] - 1) for r in sel), default=float("nan"))
            lines.append(f"| {obs} | {method} | {len(sel)} | {100 * e:.1f} % |")
    (OUT / "summary.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
