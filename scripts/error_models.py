"""Measure the error models behind ``--rtol`` and write them where lunarviz reads them.

    python scripts/error_models.py [--quick]

For every deterministic setting a tolerance can choose, the largest relative error of the
moonshine and of the earthshine over the paper's scene (θ = 5-175° every 2.5°, lambert, shg and
dhg, no occlusion) against the exact extended-source reference at a high order, with the rays
it cast and its time (one thread):

* the ray tracer's lune rule (the packaged exact-sphere Moon: lune Gauss order × Sun or Earth
  beam order);
* the ray tracer's facet samples (icosphere level × beam order): Moons the lune rule does not
  take (a lunar map, an eclipse's penumbra, an outside detector's Earth limb);
* the ray tracer's facet samples on a mapped Moon (``rolo-fit-map``'s lunar map), against the
  finest level (self-convergence: a map's exact integral is not known in closed form);
* the analytic method's Gauss order, against its own converged value (the analytic method is
  the paper's point-source model: its distance from the extended reference is a model error,
  reported in its rows as ``extended_over_point_earthshine``, not a quadrature error);
* the reference's own orders, against a higher order;
* Monte Carlo: the relative standard deviation of one ray (each path's largest over phases), from
  which a tolerance gives the ray count.

Writes ``lunarviz/data/error_models.json`` (read by :mod:`lunarviz.methods.accuracy`) and
``benchmarks/error_models/`` (``report.md``, ``error_vs_time.png``). ``--quick``: fewer phases
and settings, into a temporary folder only (a smoke run).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
BRDFS = ("lambert", "shg", "dhg")
PATHS = ("moonshine", "earthshine")
SOURCE = {"moonshine": "sun_order", "earthshine": "earth_order"}


def _settings(phases, **kw):
    from lunarviz.scene import ResolvedScene
    return ResolvedScene(phases_deg=tuple(phases), brdfs=BRDFS, occlusion=False, **kw)


def reference_values(phases, outer: int, inner: int) -> dict:
    """{(θ, brdf): (moonshine, earthshine)} from the exact reference at (outer, inner)."""
    from lunarviz.methods.reference import ReferenceSettings, reference_irradiance
    s = _settings(phases)
    out = {}
    for th in phases:
        res = reference_irradiance(s.geometry(th), s.brdf_models(), ReferenceSettings(outer, inner))
        for k, v in res.items():
            out[(th, k)] = (v.moonshine_W_m2, v.earthshine_W_m2)
    return out


def trace_values(args) -> dict:
    """One ray-tracer setting over every phase, one thread: errors need the reference after."""
    phases, path, kw, map_model = args
    from lunarviz.methods.tracer.estimators import TraceScene, trace_path
    s = _settings(phases, method="raytrace", **({"moon_model": map_model} if map_model else {}))
    lune = kw.pop("lune_order", None)
    ts_set = replace(s.trace_settings(threads=1), lune_order=lune, **kw)
    models = s.brdf_models()
    vals, rays, t0 = {}, 0, time.perf_counter()
    for th in phases:
        ts = TraceScene(s.geometry(th), ts_set)
        res = trace_path(ts, path, models)
        rays += res.rays
        for k in models:
            vals[(th, k)] = res.mean[k]
    kw["lune_order"] = lune
    return {"path": path, "setting": kw, "values": vals, "rays": rays,
            "seconds_per_phase": (time.perf_counter() - t0) / len(phases)}


def max_error(values: dict, ref: dict, index: int | None) -> float:
    return max(abs(v / (ref[key] if index is None else ref[key][index]) - 1.0) for key, v in values.items())


def montecarlo_sigma(phases) -> dict:
    """Each path's largest relative standard deviation of one ray over the phases (×√N of a run)."""
    from lunarviz.methods.tracer.estimators import TraceScene, trace_path
    s = _settings(phases, method="raytrace", estimator="montecarlo", rays=20_000, seed=7)
    models = s.brdf_models()
    out = {p: 0.0 for p in PATHS}
    for th in phases:
        ts = TraceScene(s.geometry(th), s.trace_settings(threads=1))
        for p in PATHS:
            r = trace_path(ts, p, models)
            for k in models:
                if r.mean[k] > 0:
                    out[p] = max(out[p], r.std[k] / r.mean[k] * np.sqrt(s.rays))
    return out


def analytic_errors(phases, orders) -> list:
    from lunarviz.methods.analytic import analytic_irradiance
    s = _settings(phases)
    conv = {}
    rows = []
    for order in (*orders, 192):
        a = replace(s.analytic_settings(), order=order)
        t0 = time.perf_counter()
        vals = {}
        for th in phases:
            for k, v in analytic_irradiance(s.geometry(th), s.brdf_models(), a).items():
                vals[(th, k)] = (v.moonshine_W_m2, v.earthshine_W_m2)
        dt = (time.perf_counter() - t0) / len(phases)
        if order == 192:
            conv = vals
        else:
            rows.append((order, vals, dt))
    return [{"order": o, "seconds_per_phase": dt, **{p: max_error({k: v[i] for k, v in vals.items()}, conv, i)
                                                      for i, p in enumerate(PATHS)}} for o, vals, dt in rows]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--out", default=None, help="results folder (default benchmarks/error_models)")
    a = ap.parse_args(argv)
    t_start = time.perf_counter()
    phases = [float(p) for p in (np.arange(30, 151, 60) if a.quick else np.arange(5, 175.1, 2.5))]
    lune_orders = (8, 16) if a.quick else (6, 8, 10, 12, 14, 16, 20, 24)
    levels = (2, 3) if a.quick else (2, 3, 4, 5)
    source = {"moonshine": (1, 2) if a.quick else (1, 2, 3),
              "earthshine": (4, 6) if a.quick else (5, 6, 7, 8, 10)}
    ref_orders = ((24, 8), (32, 12)) if a.quick else ((24, 8), (32, 12), (48, 16))
    print("reference ...", flush=True)
    refs = {o: reference_values(phases, *o) for o in ref_orders}
    best = refs[ref_orders[-1]]
    reference = [{"outer": o, "inner": i, **{p: max_error({k: v[j] for k, v in refs[(o, i)].items()}, best, j)
                                              for j, p in enumerate(PATHS)}} for o, i in ref_orders[:-1]]
    jobs = [(phases, p, {"lune_order": L, SOURCE[p]: o}, None) for p in PATHS for L in lune_orders for o in source[p]]
    jobs += [(phases, p, {"moon_level": lv, SOURCE[p]: o}, None) for p in PATHS for lv in levels for o in source[p]]
    map_levels = (2, 3, 4) if a.quick else (2, 3, 4, 5, 6)
    map_phases = phases[::4] if not a.quick else phases
    jobs += [(map_phases, p, {"moon_level": lv, SOURCE[p]: o}, "rolo-fit-map") for p in PATHS for lv in map_levels
             for o in ((2,) if p == "moonshine" else (8,))]
    print(f"{len(jobs)} ray-tracer settings ...", flush=True)
    with ProcessPoolExecutor(2) as ex:
        traced = list(ex.map(trace_values, jobs))
    tables = {"raytrace_lune": {p: [] for p in PATHS}, "raytrace_facets": {p: [] for p in PATHS},
              "raytrace_facets_mapped": {p: [] for p in PATHS}}
    finest = {p: next(t["values"] for t in traced[::-1] if t["path"] == p) for p in PATHS}  # last mapped job
    for job, t in zip(jobs, traced):
        p, mapped = t["path"], job[3] is not None
        idx = PATHS.index(p)
        err = max_error(t["values"], finest[p], None) if mapped else max_error(t["values"], best, idx)
        name = "raytrace_facets_mapped" if mapped else "raytrace_lune" if t["setting"]["lune_order"] else \
            "raytrace_facets"
        row = {k: v for k, v in t["setting"].items() if v is not None}
        row.update(max_rel_error=err, rays_per_phase=t["rays"] / len(job[0]), seconds_per_phase=t["seconds_per_phase"])
        tables[name][p].append(row)
    for p in PATHS:  # the finest mapped level is the reference of the others: not a model row
        tables["raytrace_facets_mapped"][p] = tables["raytrace_facets_mapped"][p][:-1]
    print("Monte Carlo and analytic ...", flush=True)
    mc = montecarlo_sigma(phases[::3])
    analytic = analytic_errors(phases, (4, 6, 8, 12, 16, 24, 32, 48, 64, 96))
    model = {
        "about": "largest relative errors over the paper's scene (θ = 5-175°, lambert/shg/dhg, no occlusion) "
                 "against the exact reference at outer/inner order "
                 f"{ref_orders[-1][0]}/{ref_orders[-1][1]}; mapped Moon (rolo-fit-map) against its finest level; "
                 "analytic against its order 192; written by scripts/error_models.py",
        "phases_deg": phases, "reference_orders": list(ref_orders[-1]),
        "mapped_finest_level": map_levels[-1],
        **tables, "analytic": analytic, "reference": reference, "montecarlo_sigma_one_ray": mc,
    }
    out = Path(a.out) if a.out else (Path(tempfile.mkdtemp(prefix="lunarviz_error_models_quick_")) if a.quick
                                      else ROOT / "benchmarks" / "error_models")
    out.mkdir(parents=True, exist_ok=True)
    text = json.dumps(model, indent=1)
    (out / "error_models.json").write_text(text)
    if not a.quick:
        (ROOT / "lunarviz" / "data" / "error_models.json").write_text(text)
    _report(model, out, time.perf_counter() - t_start)
    print(f"wrote {out} in {time.perf_counter() - t_start:.0f} s")
    return 0


def plot_error_vs_time(model: dict, out: Path) -> None:
    """Each setting's largest error against its time (``error_vs_time.png``); the analytic
    method's own errors drawn as they are (no floor: they reach 1e-14)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2), sharey=True)
    for ax, p in zip(axes, PATHS):
        for name, key, mark in (("raytrace_lune", "lune_order", "o"), ("raytrace_facets", "moon_level", "s")):
            for row in (r for r in model[name][p] if r["max_rel_error"] > 0):
                ax.loglog(row["seconds_per_phase"], row["max_rel_error"], mark, ms=4,
                          color="tab:blue" if mark == "o" else "tab:orange")
        an = model["analytic"]
        ax.loglog([r["seconds_per_phase"] for r in an if r[p] > 0], [r[p] for r in an if r[p] > 0], "k^-", ms=4)
        ax.set_title(p)
        ax.set_xlabel("seconds per phase (one thread, 3 BRDFs)")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_ylabel("max relative error, θ = 5-175°")
    axes[0].legend(loc="lower right", handles=[
        plt.Line2D([], [], ls="", marker="o", color="tab:blue", label="ray traced, lune rule"),
        plt.Line2D([], [], ls="", marker="s", color="tab:orange", label="ray traced, facets"),
        plt.Line2D([], [], marker="^", color="k", label="analytic (its own model)")])
    fig.tight_layout()
    fig.savefig(out / "error_vs_time.png", dpi=110)
    plt.close(fig)


def _report(model: dict, out: Path, seconds: float) -> None:
    plot_error_vs_time(model, out)
    lines = ["# Error models behind `--rtol`", "",
             f"`python scripts/error_models.py` ({seconds:.0f} s). {model['about']}.", ""]
    for name, key in (("raytrace_lune", "lune_order"), ("raytrace_facets", "moon_level"),
                      ("raytrace_facets_mapped", "moon_level")):
        for p in PATHS:
            lines += [f"## {name}, {p}", "", f"| {key} | {SOURCE[p]} | max rel. error | rays/phase | s/phase |",
                      "| --- | --- | --- | --- | --- |"]
            lines += [f"| {r[key]} | {r[SOURCE[p]]} | {r['max_rel_error']:.2e} | {r['rays_per_phase']:,.0f} | "
                      f"{r['seconds_per_phase']:.3f} |" for r in model[name][p]]
            lines.append("")
    lines += ["## analytic (against its order 192)", "", "| order | moonshine | earthshine | s/phase |",
              "| --- | --- | --- | --- |"]
    lines += [f"| {r['order']} | {r['moonshine']:.1e} | {r['earthshine']:.1e} | {r['seconds_per_phase']:.4f} |"
              for r in model["analytic"]]
    lines += ["", "## reference (against its highest order)", "", "| outer | inner | moonshine | earthshine |",
              "| --- | --- | --- | --- |"]
    lines += [f"| {r['outer']} | {r['inner']} | {r['moonshine']:.1e} | {r['earthshine']:.1e} |"
              for r in model["reference"]]
    mc = model["montecarlo_sigma_one_ray"]
    lines += ["", f"Monte Carlo, relative σ of one ray (largest over phases): moonshine {mc['moonshine']:.3f}, "
              f"earthshine {mc['earthshine']:.3f}.", ""]
    (out / "report.md").write_text("\n".join(lines))


if __name__ == "__main__":
    sys.exit(main())
