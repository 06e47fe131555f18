"""Write benchmarks/README.md from the kept results (bench.json, mesh_study_*.json).

    python scripts/bench_summary.py
"""

import json
from pathlib import Path

B = Path(__file__).resolve().parent.parent / "benchmarks"


def main():
    b = json.loads((B / "bench.json").read_text())
    t, tg, sk, rd = b["throughput"], b["targets"], b["skips"], b.get("render", {})
    L = ["# Benchmarks (kept results)", "",
         "Regenerate everything with `bash scripts/run_benchmarks.sh` (about 20 minutes on this",
         "2-core machine), then `python scripts/bench_summary.py` for this page. Timings are on a shared",
         "machine: compare ratios measured in one run, not absolute seconds across runs.", "",
         "Files: `bench.json` (everything), `bench.csv` (Pareto rows), `bench.png` (error against run",
         "time), `mesh_study_{auto,flat,ellipsoid,craters}.*` (mesh-resolution studies).", "",
         "## Targets (issue 5)", "",
         "| target | measured | met |", "| --- | --- | --- |"]
    if "paper_sweep_raytrace" in tg:
        p = tg["paper_sweep_raytrace"]
        L.append(f"| paper sweep by ray tracing (37 phases × 3 BRDFs × 2 paths) ≤ 60 s at ≤ 0.1 % | "
                 f"{p['seconds']:.1f} s, max error {p['max_relative_error_5_175']:.1e} (θ = 5…175°) | "
                 f"{'yes' if p['seconds'] <= 60 and p['max_relative_error_5_175'] <= 1e-3 else 'no'} |")
    a = tg["analytic_sweep_seconds"]["seconds"]
    L.append(f"| analytic sweep ≤ 1 s | {a:.2f} s | {'yes' if a <= 1 else 'no'} |")
    r = t["ratio_end_to_end_over_raw"]
    L.append(f"| end-to-end ray throughput ≥ 60 % of raw embreex | {100 * r:.0f} % | {'yes' if r >= 0.6 else 'no'} |")
    mc = tg["montecarlo_one_phase_theta90"]
    L.append(f"| Monte Carlo 0.2 % std in < 1 s per phase | moonshine 50k rays "
             f"{100 * mc['moonshine_50000_rays']['relative_std']:.3f} %, earthshine 120k rays "
             f"{100 * mc['earthshine_120000_rays']['relative_std']:.3f} %: {mc['seconds_per_phase_at_0.2pct']:.2f} s | "
             f"{'yes' if mc['seconds_per_phase_at_0.2pct'] < 1 and mc['earthshine_120000_rays']['relative_std'] <= 0.0021 else 'no'} |")
    if rd and "frame_1024x768_seconds" in rd:
        L.append(f"| 1024×768 frame < 1 s once data is computed | {rd['frame_1024x768_seconds']:.2f} s | "
                 f"{'yes' if rd['frame_1024x768_seconds'] < 1 else 'no'} |")
        L.append(f"| `lunarviz render` from a cold start < 60 s | {rd['cold_start_render_seconds']:.1f} s | "
                 f"{'yes' if rd['cold_start_render_seconds'] < 60 else 'no'} |")
    L += ["", "## Throughput (θ = 90°, occlusion on, 3 BRDFs, same rays)", "",
          f"* end-to-end: {t['end_to_end_rays_per_s']:.3g} rays/s; raw embreex on the very same float32 rays: "
          f"{t['raw_embree_rays_per_s']:.3g} rays/s; ratio {t['ratio_end_to_end_over_raw']:.2f}.",
          f"* Embree's share of the end-to-end time: {100 * t['embree_share_of_end_to_end']:.0f} %; the rest is numpy:",
          "  three BRDF evaluations per beam, the product Gauss rules, half-angle geometry.",
          f"* two threads: raw Embree ×{t['raw_speedup_2_threads']:.2f}, end-to-end ×{t['end_to_end_speedup_2_threads']:.2f};"
          f" a sweep over phases in two processes ×{t['sweep_speedup_2_processes']['speedup']:.2f}"
          " (this is how sweeps use both cores).", "",
          "## Skips and their savings", ""]
    s = sk["transport_reused_across_3_brdfs"]
    L.append(f"* transport traced once for three BRDFs: {s['seconds_one_trace']:.2f} s instead of "
             f"{s['seconds_three_traces']:.2f} s ({100 * s['saving']:.0f} % saved).")
    s = sk["facets_culled_moonshine_theta90"]
    L.append(f"* facets neither lit nor visible are not shaded: {s['traced']} of {s['facets']} traced at θ = 90° "
             f"({100 * s['saving']:.0f} % skipped).")
    s = sk["earth_not_traced_for_moonshine_without_occlusion"]
    L.append(f"* no Earth rays for moonshine without occlusion: {s['rays_without']} rays instead of "
             f"{s['rays_with_occlusion']} ({100 * s['saving']:.0f} % of the time: the occlusion rays are mostly"
             " answered by the bounding-sphere test, never by Embree).")
    s = sk["detector_inside_earth_no_sightline_rays"]
    L.append(f"* detector inside the Earth: {s['sight_line_rays_skipped']} sight-line shadow rays skipped.")
    s = sk["refinement_only_where_needed_theta170"]
    L.append(f"* thin crescent (θ = 170°): refining the lune costs {s['rays_refined']:,} rays instead of "
             f"{s['rays_unrefined']:,} and takes the error from {s['error_unrefined']:.1e} to {s['error_refined']:.1e};"
             " elsewhere the lune is wide and nothing is refined.")
    L += ["", "## Error against run time (bench.png)", "",
          "Per method, max relative error over phases × BRDFs against the exact reference, and mean time per phase:", "",
          "| method | setting | path | seconds | error |", "| --- | --- | --- | --- | --- |"]
    seen = {}
    for row in b["rows"]:
        k = (row["method"], row["setting"], row["path"])
        e = row["error_vs_own_limit"] if row["method"] == "analytic" else row["error_vs_reference"]
        s0, e0, n0 = seen.get(k, (0.0, 0.0, 0))
        seen[k] = (s0 + row["seconds"], max(e0, e), n0 + 1)
    for (m, st, p), (sec, err, n) in seen.items():
        L.append(f"| {m} | {st} | {p} | {sec / n:.3f} | {err:.1e} |")
    L += ["", "(analytic: error against its own converged limit; its physics — point Sun, point Earth — differs",
          "from the reference's by up to tens of percent for Hapke earthshine, which is the point of the",
          "extended-source model.)", ""]
    for name in ("auto", "flat", "ellipsoid", "craters"):
        f = B / f"mesh_study_{name}.json"
        if not f.exists():
            continue
        m = json.loads(f.read_text())
        st = m["settings"]
        L += [f"## Mesh-resolution study: {st.get('body', 'moon')} {st.get('shape', 'sphere')}, {st['shading']} shading "
              f"(mesh_study_{name}.png)", "",
              f"Phases {st['phases_deg']}, BRDFs {st['brdfs']}, deterministic, no occlusion; error against the "
              f"{st['reference']}.", "",
              "| path | level | facets | max error | observed order | s/phase |", "| --- | --- | --- | --- | --- | --- |"]
        for r in m["summary"]:
            o = "" if r["observed_order"] is None else f"{r['observed_order']:.1f}"
            L.append(f"| {r['path']} | {r['level']} | {r.get('facets', '')} | {r['max_abs_relative_error']:.1e} | {o} | "
                     f"{r['mean_seconds_per_phase']:.2f} |")
        L.append("")
    (B / "README.md").write_text("\n".join(L) + "\n")
    print(B / "README.md")


if __name__ == "__main__":
    main()
