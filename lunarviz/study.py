"""Mesh-resolution studies: facets, run time, error against the exact reference, observed order.

``mesh_study([2, 3, 4, 5, 6], phases, brdfs, out)`` traces every phase at every Moon level
(deterministic estimator, no occlusion, so the exact reference applies) and writes a table
(.json or .csv) and a log-log plot beside it. The observed order of convergence between two
levels is ``p = log2(e_{L-1} / e_L)`` (the facet size halves per level).
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from .brdf import make_brdf
from .geometry import Scene
from .reference import ReferenceSettings, reference_irradiance


def mesh_study(levels, phases, brdfs, out=None, shading: str = "smooth", refine: bool = True,
               progress: bool = False) -> dict:
    from .trace.estimators import TraceScene, TraceSettings, trace_path
    models = {b: make_brdf(b) for b in brdfs}
    refs = {th: reference_irradiance(Scene(th), models, ReferenceSettings(32, 12)) for th in phases}
    rows = []
    it = [(lv, th) for lv in levels for th in phases]
    if progress:
        from tqdm import tqdm
        it = tqdm(it, desc="mesh study", unit="run", leave=False)
    for lv, th in it:
        t0 = time.perf_counter()
        ts = TraceScene(Scene(th), TraceSettings(moon_level=int(lv), occlusion=False, shading=shading,
                                                  refine=refine))
        ms = trace_path(ts, "moonshine", models)
        es = trace_path(ts, "earthshine", models)
        dt = time.perf_counter() - t0
        for b in brdfs:
            for path, res in (("moonshine", ms), ("earthshine", es)):
                ref = getattr(refs[th][b], f"{path}_W_m2")
                rows.append({"level": int(lv), "facets": int(ts.moon.n_faces), "theta_deg": float(th),
                             "brdf": b, "path": path, "value_W_m2": res.mean[b], "reference_W_m2": ref,
                             "relative_error": res.mean[b] / ref - 1, "seconds": dt,
                             "rays": ms.rays + es.rays, "shading": shading, "refine": refine})
    # observed order between successive levels, on the worst case over phases and BRDFs
    summary = []
    for path in ("moonshine", "earthshine"):
        prev = None
        for lv in levels:
            errs = [abs(r["relative_error"]) for r in rows if r["level"] == lv and r["path"] == path]
            secs = np.mean([r["seconds"] for r in rows if r["level"] == lv])
            e = float(max(errs))
            order = float(np.log2(prev / e)) if prev and e > 0 else None
            summary.append({"path": path, "level": int(lv), "max_abs_relative_error": e,
                            "observed_order": order, "mean_seconds_per_phase": float(secs)})
            prev = e
    res = {"settings": {"levels": list(levels), "phases_deg": list(phases), "brdfs": list(brdfs),
                        "shading": shading, "refine": refine, "reference": "ReferenceSettings(32, 12)"},
           "rows": rows, "summary": summary}
    if out is not None:
        from .io import write_results
        out = Path(out)
        write_results(out, res)
        plot_study(res, out.with_suffix(".png"))
    return res


def plot_study(res: dict, path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for path_name, ax in zip(("moonshine", "earthshine"), axes):
        s = [r for r in res["summary"] if r["path"] == path_name]
        facets = sorted({r["facets"] for r in res["rows"]})
        ax.loglog(facets, [max(r["max_abs_relative_error"], 1e-12) for r in s], "o-",
                  label="max |error| over phases, BRDFs")
        for x, r in zip(facets, s):
            if r["observed_order"] is not None:
                ax.annotate(f"p={r['observed_order']:.1f}", (x, r["max_abs_relative_error"]), fontsize=7,
                            textcoords="offset points", xytext=(4, 4))
        ax.axhline(1e-3, color="k", ls="--", lw=0.8, label="0.1 % target")
        ax.set_xlabel("lunar facets")
        ax.set_ylabel("relative error vs exact reference")
        ax.set_title(f"{path_name} ({res['settings']['shading']} shading)")
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
