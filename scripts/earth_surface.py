"""What an earthshine measurement sees of a real Earth.

    python scripts/earth_surface.py [--out benchmarks/earth_surface] [--quick]

A land/ocean Earth (global-land-mask; land 0.25, ocean 0.06) under zonal-mean clouds (cloud
albedo 0.40; lunarviz/data/zonal_clouds.csv), DHG Moon, ray traced (occlusion on):

* ``diurnal.{json,csv}``: the paper's θ scene at θ = 120° (crescent Moon, gibbous Earth: where
  earthshine is measured) while the Earth turns, sub-solar longitude −180° … 165° every 15°;
  with clouds and without.
* ``lunation.{json,csv}``: June 2026 every 8 h from the geocentre, the Earth turning with the date.
* ``earth_surface.png``: for both, the albedo of the Earth's lit face as the earthshine weights
  it (``earth_visible_lit_albedo``), the apparent albedo p* that the paper's point-source
  inversion recovers from the ray-traced earthshine/moonshine ratio, and the Earth's global
  mean albedo.

The consistent inversion (lunar terms from the same transport with a uniform model Earth) is
not plotted: for a Lambert Earth, earthshine is linear in the albedo and that inversion returns
``earth_visible_lit_albedo`` exactly (to 1e-15). ``--quick`` runs a few points analytically.
"""

from __future__ import annotations

import argparse
import os
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from lunarviz.outputs.writers import write_results
from lunarviz.sky.ephemeris import time_list
from lunarviz.scene import ResolvedScene
from lunarviz.workflows.sweeps import run_phase, run_sweep

SURFACE = dict(earth_surface="landocean", clouds="zonal")


def global_mean(clouds: str) -> float:
    """Area-weighted mean albedo of the Earth's facets (level-6 mesh)."""
    from lunarviz.geometry.scene_geometry import SceneGeometry
    from lunarviz.methods.tracer.estimators import TraceScene, TraceSettings
    ts = TraceScene(SceneGeometry(90.0), TraceSettings(earth_surface="landocean", clouds=clouds))
    a = ts.surfaces.earth_facet_albedo()
    return float((a * ts.earth.areas).sum() / ts.earth.areas.sum())


def diurnal(out: Path, quick: bool) -> dict:
    lons = np.arange(-180.0, 180.0, 90.0 if quick else 15.0)
    method = "analytic" if quick else "raytrace"
    payload = {"theta_deg": 120.0, "method": method, "runs": []}
    rows = []
    jobs = [(clouds, float(lam)) for clouds in ("zonal", "none") for lam in lons]
    settings = [ResolvedScene(phases_deg=(120.0,), brdfs=("dhg",), method=method, earth_surface="landocean",
                              clouds=clouds, earth_rotation_deg=lam) for clouds, lam in jobs]
    with ProcessPoolExecutor(os.cpu_count() or 1) as ex:
        results = list(ex.map(run_phase, settings, [120.0] * len(jobs)))
    for (clouds, lam), res in zip(jobs, results):
        for r in res:
            r["earth_rotation_deg"] = lam
            r["clouds"] = clouds
        rows += res
    for clouds in ("zonal", "none"):
        payload["runs"].append({"clouds": clouds, "global_mean_albedo": global_mean(clouds)})
    payload["rows"] = rows
    write_results(out / "diurnal.json", payload)
    write_results(out / "diurnal.csv", {"rows": rows})
    return payload


def lunation(out: Path, quick: bool) -> dict:
    times = time_list(time_range="2026-06-01,2026-06-13,4d" if quick else "2026-06-01,2026-06-30,8h")
    method = "analytic" if quick else "raytrace"
    res = run_sweep(ResolvedScene(times=times, brdfs=("dhg",), method=method, **SURFACE))
    payload = {"method": method, "settings": res["settings"], "wall_seconds": res["wall_seconds"], "rows": res["rows"],
               "global_mean_albedo": global_mean("zonal")}
    write_results(out / "lunation.json", payload)
    write_results(out / "lunation.csv", {"rows": res["rows"]})
    return payload


def _p_point(r):
    """The point-source inversion's p* (the analytic method's own p* is one)."""
    v = r.get("apparent_albedo_point_source_inversion", r["apparent_albedo"])
    return np.nan if v is None else v


def plot(out: Path, di: dict, lu: dict):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(1, 2, figsize=(13, 4.8))
    for clouds, style in (("zonal", "-"), ("none", "--")):
        rs = [r for r in di["rows"] if r["clouds"] == clouds]
        lam = np.array([r["earth_rotation_deg"] for r in rs])
        gm = next(p["global_mean_albedo"] for p in di["runs"] if p["clouds"] == clouds)
        lab = "zonal clouds" if clouds == "zonal" else "no clouds"
        ax[0].plot(lam, [r["earth_visible_lit_albedo"] for r in rs], "C0" + style, marker="o", ms=3,
                   label=f"lit face, earthshine-weighted ({lab})")
        ax[0].plot(lam, [_p_point(r) for r in rs], "C3" + style, marker="s", ms=3,
                   label=f"p* from the paper's point-source inversion ({lab})")
        ax[0].axhline(gm, color="gray", ls=style, lw=1, label=f"global mean ({lab}) {gm:.3f}")
    ax[0].set_xlabel("sub-solar longitude [deg]")
    ax[0].set_ylabel("albedo")
    ax[0].set_title(f"one day at θ = {di['theta_deg']:.0f}° (Earth phase β = 60°), DHG Moon, {di['method']}")
    ax[0].legend(fontsize=7)
    rs = lu["rows"]
    t = np.arange(len(rs)) * 8 / 24.0
    p = np.array([_p_point(r) for r in rs], dtype=float)
    ok = np.isfinite(p)
    ax[1].plot(t, [r["earth_visible_lit_albedo"] for r in rs], "C0-", lw=1, label="lit face, earthshine-weighted")
    ax[1].plot(t[ok], p[ok], "C3.", ms=3,
               label="p* (paper's point-source inversion)")
    ax[1].axhline(lu["global_mean_albedo"], color="gray", lw=1, label=f"global mean {lu['global_mean_albedo']:.3f}")
    ax2 = ax[1].twinx()
    ax2.plot(t, [r["phase_angle_deg"] for r in rs], color="0.7", lw=0.8)
    ax2.set_ylabel("lunar phase angle [deg]", color="0.5")
    ax[1].set_xlabel("days from 2026-06-01T00Z")
    ax[1].set_ylabel("albedo")
    ax[1].set_ylim(0, 0.6)
    ax[1].set_title(f"June 2026 from the geocentre, every 8 h, {lu['method']}")
    ax[1].legend(fontsize=7, loc="upper left")
    fig.suptitle("land/ocean Earth (global-land-mask) with zonal clouds: what the earthshine inversion recovers")
    fig.tight_layout()
    fig.savefig(out / "earth_surface.png", dpi=110)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="benchmarks/earth_surface")
    ap.add_argument("--quick", action="store_true")
    a = ap.parse_args(argv)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    di = diurnal(out, a.quick)
    lu = lunation(out, a.quick)
    plot(out, di, lu)
    print(f"wrote {out}/diurnal.*, lunation.*, earth_surface.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
