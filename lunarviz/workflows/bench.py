"""Run time against error for every method, throughput against raw Embree, and the skips.

``run_bench(out)`` writes ``out`` (.json), a CSV table of the Pareto data beside it and a
log-log plot of error against run time. Errors are against the exact reference
(:mod:`lunarviz.methods.reference`, order (32, 12)); the analytic method is also measured against its
own converged limit (its quadrature error), since its physics (point sources) differs from the
reference's. Speeds are reported as ratios measured in the same run (the machine is shared):
end-to-end rays/s over raw ``embreex`` rays/s on the very same float32 rays, and the speed-up of
two threads over one.
"""

from __future__ import annotations

import json
import os
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from lunarviz.geometry.scene_geometry import SceneGeometry
from lunarviz.methods.analytic import AnalyticSettings, analytic_irradiance
from lunarviz.methods.reference import ReferenceSettings, reference_irradiance
from lunarviz.outputs.writers import json_safe, save_figure, write_bytes_atomic, write_results
from lunarviz.photometry.brdf import make_brdf
from lunarviz.scene import ResolvedScene
from lunarviz.workflows.sweeps import run_sweep

BRDFS = ("lambert", "shg", "dhg")


def _timed(fn, repeat=1):
    best = np.inf
    out = None
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t)
    return out, best


def _err(values: dict, ref: dict, path: str) -> float:
    return max(abs(values[b] / getattr(ref[b], f"{path}_W_m2") - 1) for b in values)


def run_bench(out, quick: bool = False, progress: bool = False) -> dict:
    """Run time against error for every method (rows), throughput against raw Embree, the
    skips with their savings, the speed targets and the picture timings; writes ``out`` (.json)
    with a .csv table and a .png Pareto plot beside it."""
    out = Path(out)
    models = {b: make_brdf(b) for b in BRDFS}
    phases = (60.0, 150.0) if quick else (30.0, 90.0, 150.0)
    t_all = time.perf_counter()
    refs = {th: reference_irradiance(SceneGeometry(th), models, ReferenceSettings(32, 12)) for th in phases}
    limit = {th: analytic_irradiance(SceneGeometry(th), models, AnalyticSettings(order=96)) for th in phases}
    rows = _bench_analytic(models, phases, refs, limit, quick) + _bench_deterministic(models, phases, refs, quick) \
        + _bench_montecarlo(models, phases, refs, quick)
    throughput = _bench_throughput(models)
    skips = _bench_skips(models)
    targets = _bench_targets(models, quick)
    render = _bench_render()
    res = {"quick": quick, "phases_deg": list(phases), "rows": rows, "throughput": throughput, "render": render,
           "skips": skips, "targets": targets, "seconds_total": time.perf_counter() - t_all,
           "machine": {"cpus": os.cpu_count()}}
    write_bytes_atomic(out, json.dumps(json_safe(res), indent=1, allow_nan=False).encode())
    write_results(out.with_suffix(".csv"), {"rows": rows})
    plot_pareto(res, out.with_suffix(".png"))
    return res




def _bench_analytic(models, phases, refs, limit, quick) -> list[dict]:
    """Analytic method: error against the Gauss order."""
    rows = []
    for order in ((4, 8, 16, 24) if quick else (4, 6, 8, 12, 16, 24, 32)):
        for th in phases:
            res, dt = _timed(lambda: analytic_irradiance(SceneGeometry(th), models, AnalyticSettings(order=order)), 3)
            for path in ("moonshine", "earthshine"):
                v = {b: getattr(res[b], f"{path}_W_m2") for b in BRDFS}
                rows.append({"method": "analytic", "setting": f"order {order}", "theta_deg": th, "path": path,
                             "seconds": dt, "rays": 0, "error_vs_reference": _err(v, refs[th], path),
                             "error_vs_own_limit": _err(v, limit[th], path)})

    return rows


def _bench_deterministic(models, phases, refs, quick) -> list[dict]:
    """Deterministic ray tracing: error against the mesh level and the source orders."""
    from lunarviz.methods.tracer.estimators import TraceScene, TraceSettings, trace_path
    rows = []
    det_cases = [(3, 4, 1), (4, 4, 2), (5, 6, 2), (6, 6, 2)] if quick else \
        [(3, 4, 1), (4, 4, 2), (4, 6, 2), (5, 4, 2), (5, 6, 2), (6, 6, 2), (6, 8, 3)]
    for lv, eo, so in det_cases:
        for th in phases:
            ts = TraceScene(SceneGeometry(th),
                            TraceSettings(moon_level=lv, earth_order=eo, sun_order=so, occlusion=False))
            for path in ("moonshine", "earthshine"):
                r = trace_path(ts, path, models)
                rows.append({"method": "deterministic", "setting": f"moon L{lv}, earth order {eo}, sun order {so}",
                             "theta_deg": th, "path": path, "seconds": r.seconds, "rays": r.rays,
                             "error_vs_reference": _err(r.mean, refs[th], path)})

    return rows


def _bench_montecarlo(models, phases, refs, quick) -> list[dict]:
    """Monte Carlo: error and spread against the ray count."""
    from lunarviz.methods.tracer.estimators import TraceScene, TraceSettings, trace_path
    rows = []
    for n in ((1000, 10_000, 50_000) if quick else (1000, 10_000, 50_000, 200_000)):
        for th in phases:
            ts = TraceScene(SceneGeometry(th),
                            TraceSettings(estimator="montecarlo", rays=n, runs=1, occlusion=False, seed=11))
            for path in ("moonshine", "earthshine"):
                r = trace_path(ts, path, models)
                rel_std = max(r.std[b] / r.mean[b] for b in BRDFS if r.mean[b] > 0)
                rows.append({"method": "montecarlo", "setting": f"{n} rays", "theta_deg": th, "path": path,
                             "seconds": r.seconds, "rays": r.rays, "error_vs_reference": _err(r.mean, refs[th], path),
                             "relative_std_one_run": rel_std})

    return rows


def _bench_throughput(models) -> dict:
    """End-to-end rays per second against raw Embree on the same rays, one and two threads."""
    from lunarviz.methods.tracer.estimators import TraceScene, TraceSettings, trace_path
    # warm-up (first traces pay one-time costs: allocation, mesh loading, Embree builds)
    trace_path(TraceScene(SceneGeometry(90.0), TraceSettings(occlusion=True, threads=1)), "earthshine", models)
    ts = TraceScene(SceneGeometry(90.0), TraceSettings(occlusion=True, threads=1))
    for body in (ts.moon, ts.earth, ts.sun):
        body.recorder = []
    r_es = trace_path(ts, "earthshine", models)
    r_ms = trace_path(ts, "moonshine", models)
    batches = [(b, rec) for b in (ts.moon, ts.earth, ts.sun) for rec in b.recorder]
    for b in (ts.moon, ts.earth, ts.sun):
        b.recorder = None
    n_raw = sum(len(rec[2]) for _, rec in batches)  # rec = (scene, query, o32, d32, dists)

    def replay(threads):
        t = time.perf_counter()
        for b, (scene, query, o, d, dists) in batches:
            b.threads = threads
            b.run_rays(o, d, query, dists, scene=scene)
        return time.perf_counter() - t

    raw1 = min(replay(1) for _ in range(3))
    raw2 = min(replay(2) for _ in range(3))

    def end_to_end(threads):
        t = TraceScene(SceneGeometry(90.0), TraceSettings(occlusion=True, threads=threads))
        return trace_path(t, "earthshine", models).seconds + trace_path(t, "moonshine", models).seconds

    e2e = {1: [], 2: []}
    for th in (1, 2, 1, 2):
        e2e[th].append(end_to_end(th))
    e2e1, e2e2 = min(e2e[1]), min(e2e[2])
    n_rays = r_es.rays + r_ms.rays
    throughput = {
        "rays_end_to_end": n_rays, "rays_sent_to_embree": n_raw,
        "end_to_end_seconds_1_thread": e2e1, "end_to_end_seconds_2_threads": e2e2,
        "raw_embree_seconds_1_thread": raw1, "raw_embree_seconds_2_threads": raw2,
        # both rates over the same rays, those sent to Embree (counting every
        # end-to-end ray, culled ones included, on one side only inflated the ratio 4-fold)
        "end_to_end_rays_per_s": n_raw / e2e1,
        "raw_embree_rays_per_s": n_raw / raw1,
        "ratio_end_to_end_over_raw": raw1 / e2e1,
        "embree_share_of_end_to_end": raw1 / e2e1,
        "raw_speedup_2_threads": raw1 / raw2,
        "end_to_end_speedup_2_threads": e2e1 / e2e2,
        "note": "rates count the rays sent to Embree on both sides (rays_end_to_end also counts those the "
                "bounding-sphere test answers); the rest of the time is numpy: quadrature rules, geometry, "
                "shading. Sweeps parallelise over phases in processes instead (see sweep_speedup).",
    }
    six = ResolvedScene(method="raytrace", phases_deg=(20.0, 50.0, 80.0, 110.0, 140.0, 170.0))
    _, t_w1 = _timed(lambda: run_sweep(six, workers=1))
    _, t_w2 = _timed(lambda: run_sweep(six, workers=2))
    throughput["sweep_speedup_2_processes"] = {"seconds_1_worker": t_w1, "seconds_2_workers": t_w2,
                                               "speedup": t_w1 / t_w2, "phases": 6}

    return throughput


def _bench_skips(models) -> dict:
    """Work the tracer skips, each with its saving."""
    from lunarviz.methods.tracer.estimators import TraceScene, TraceSettings, trace_path
    skips = {}
    one = {"dhg": models["dhg"]}
    ts = TraceScene(SceneGeometry(90.0), TraceSettings(occlusion=False))
    t3 = trace_path(ts, "earthshine", models).seconds
    t1 = sum(trace_path(TraceScene(SceneGeometry(90.0), TraceSettings(occlusion=False)), "earthshine",
                        {b: models[b]}).seconds for b in BRDFS)
    skips["transport_reused_across_3_brdfs"] = {"seconds_one_trace": t3, "seconds_three_traces": t1,
                                                "saving": 1 - t3 / t1}
    cand = ts.sampling.candidates("sun").size
    skips["facets_culled_moonshine_theta90"] = {"facets": ts.moon.n_faces, "traced": int(cand),
                                                "saving": 1 - cand / ts.moon.n_faces}
    on = TraceScene(SceneGeometry(90.0), TraceSettings(occlusion=True))
    off = TraceScene(SceneGeometry(90.0), TraceSettings(occlusion=False))
    r_on, r_off = trace_path(on, "moonshine", one), trace_path(off, "moonshine", one)
    skips["earth_not_traced_for_moonshine_without_occlusion"] = {
        "rays_with_occlusion": r_on.rays, "rays_without": r_off.rays,
        "seconds_with": r_on.seconds, "seconds_without": r_off.seconds, "saving": 1 - r_off.seconds / r_on.seconds}
    dets = TraceScene(SceneGeometry(90.0), TraceSettings())
    skips["detector_inside_earth_no_sightline_rays"] = {
        "detector_inside_earth": True, "sight_line_rays_skipped": int(dets.sampling.candidates("sun").size)}
    rf_on = trace_path(TraceScene(SceneGeometry(170.0), TraceSettings(occlusion=False)), "moonshine", one)
    rf_off = trace_path(TraceScene(SceneGeometry(170.0), TraceSettings(occlusion=False, refine=False)), "moonshine",
                        one)
    ref170 = reference_irradiance(SceneGeometry(170.0), one, ReferenceSettings(32, 12),
                                  paths=("moonshine",))["dhg"].moonshine_W_m2
    skips["refinement_only_where_needed_theta170"] = {
        "rays_refined": rf_on.rays, "rays_unrefined": rf_off.rays,
        "error_refined": rf_on.mean["dhg"] / ref170 - 1, "error_unrefined": rf_off.mean["dhg"] / ref170 - 1}

    return skips


def _bench_targets(models, quick) -> dict:
    """The speed targets: the paper sweep, the analytic sweep, Monte Carlo at 0.2 %."""
    from lunarviz.methods.tracer.estimators import TraceScene, TraceSettings, trace_path
    targets = {}
    if not quick:
        sw = ResolvedScene(method="raytrace", occlusion=False)
        t = time.perf_counter()
        traced = run_sweep(sw)
        t_trace = time.perf_counter() - t
        ref = run_sweep(replace(sw, method="reference"))
        ib = {(r["theta_deg"], r["brdf"]): r for r in ref["rows"]}
        errs = [abs(r[k] / ib[(r["theta_deg"], r["brdf"])][k] - 1) for r in traced["rows"]
                for k in ("moonshine_W_m2", "earthshine_W_m2") if ib[(r["theta_deg"], r["brdf"])][k] > 0
                and 0 < r["theta_deg"] < 180]
        targets["paper_sweep_raytrace"] = {"seconds": t_trace, "max_relative_error_5_175": float(max(errs)),
                                           "phases": 37, "brdfs": 3, "workers": os.cpu_count(),
                                           "target": "<= 60 s at <= 0.1 %"}
    _, t_an = _timed(lambda: run_sweep(ResolvedScene()), 3)
    targets["analytic_sweep_seconds"] = {"seconds": t_an, "target": "<= 1 s"}
    mc = {}
    for path, n in (("moonshine", 50_000), ("earthshine", 50_000), ("earthshine", 120_000)):
        ts = TraceScene(SceneGeometry(90.0),
                        TraceSettings(estimator="montecarlo", rays=n, runs=1, occlusion=False, seed=5))
        r = trace_path(ts, path, models)
        mc[f"{path}_{n}_rays"] = {"seconds": r.seconds,
                                  "relative_std": max(r.std[b] / r.mean[b] for b in BRDFS)}
    mc["target"] = "0.2 % std in < 1 s per phase (moonshine + earthshine)"
    mc["seconds_per_phase_at_0.2pct"] = mc["moonshine_50000_rays"]["seconds"] + mc["earthshine_120000_rays"]["seconds"]
    targets["montecarlo_one_phase_theta90"] = mc

    return targets


def _bench_render() -> dict:
    """Pictures: a frame once the data is computed, and a cold-start render."""
    render = {}
    try:
        import subprocess
        import sys
        import tempfile

        from lunarviz.scene import ResolvedScene
        from lunarviz.viz import views
        from lunarviz.workflows.tasks import view_data
        data, t_data = _timed(lambda: view_data(ResolvedScene(method="raytrace"), 90.0, "dhg"))

        def frame():
            pl = views.build_plotter(data, "composite", (1024, 768))
            pl.render()
            img = pl.screenshot(return_img=True)
            pl.close()
            return img
        frame()  # the first frame pays the OpenGL context set-up
        _, t_frame = _timed(frame, 3)
        with tempfile.TemporaryDirectory() as tmp:
            t = time.perf_counter()
            subprocess.run([sys.executable, "-m", "lunarviz.cli", "render", "--phase", "90", "--size", "1024x768",
                            "--out", os.path.join(tmp, "p.png"), "--quiet"], check=True, capture_output=True)
            t_cold = time.perf_counter() - t
        render = {"data_seconds": t_data, "frame_1024x768_seconds": t_frame, "cold_start_render_seconds": t_cold,
                  "targets": "frame < 1 s once data is computed; cold start < 60 s"}
    except ImportError as exc:  # pictures are optional extras
        render = {"skipped": f"{exc}"}

    return render


def plot_pareto(res: dict, path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.6))
    style = {"analytic": ("tab:green", "o"), "deterministic": ("tab:blue", "s"), "montecarlo": ("tab:red", "x")}
    for ax, path_name in zip(axes, ("moonshine", "earthshine")):
        for method, (c, m) in style.items():
            rs = [r for r in res["rows"] if r["method"] == method and r["path"] == path_name]
            settings = list(dict.fromkeys(r["setting"] for r in rs))
            x = np.array([np.mean([r["seconds"] for r in rs if r["setting"] == s]) for s in settings])
            key = "error_vs_own_limit" if method == "analytic" else "error_vs_reference"
            y = np.array([max(r[key] for r in rs if r["setting"] == s) for s in settings], dtype=float)
            y = np.where(y > 0, y, np.nan)  # (an exact 0 has no place on a log axis: a gap, not a made-up floor)
            label = {"analytic": "analytic (vs its converged limit)", "deterministic": "ray traced, deterministic",
                     "montecarlo": "ray traced, Monte Carlo (one run)"}[method]
            ax.loglog(x, y, m + "-", color=c, label=label)
            if method == "analytic":
                yr = [max(r["error_vs_reference"] for r in rs if r["setting"] == s) for s in settings]
                ax.loglog(x, yr, m + ":", color=c, alpha=0.6, label="analytic vs extended-source reference (physics)")
        ax.axhline(1e-3, color="k", ls="--", lw=0.8, label="0.1 %")
        ax.set_xlabel("run time per phase, 3 BRDFs [s]")
        ax.set_ylabel("max relative error (phases × BRDFs)")
        ax.set_title(path_name)
        ax.grid(alpha=0.3, which="both")
    axes[0].legend(fontsize=7)
    fig.suptitle("Error against run time (Pareto front of the methods)")
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)
