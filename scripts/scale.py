"""Run time and peak memory against the Moon's facet count.

    python scripts/scale.py [--levels 5,6,7,8] [--out benchmarks/scale]

For each level a cratered Moon (``shapes.craters``: 400 craters of 20-300 km, seed 1; facets =
20·4^level, 20 k at level 5 to 1.3 M at level 8, 5.2 M at level 9) is traced at θ = 90°, both
paths, DHG, occlusion and self-shadowing on, deterministic, in a fresh process (``--threads``,
default 2: chunks of lunar samples traced on both cores), and
the process's wall time and peak RSS are recorded (the mesh is built and written beforehand, in
another process: the run starts from the mesh file, as a user's would). Writes ``scale.json``
and ``scale.png``.
Level 9 (5.2 M facets) builds the same craters on trimesh's icosphere (the packaged ones stop at 8).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

BUILD = """
import sys, time, json, resource
from lunarviz.bodies import shapes
from lunarviz.constants import R_MOON_M
level = int(sys.argv[1]); path = sys.argv[2]
t0 = time.perf_counter()
if level <= 8:
    shapes.write_mesh(shapes.craters(R_MOON_M, level, 400, 20e3, 300e3, seed=1), path)
else:  # beyond the packaged icospheres' level 8: the same craters on trimesh's icosphere
    import numpy as np, trimesh
    m = trimesh.creation.icosphere(subdivisions=level)
    u = np.asarray(m.vertices)
    cen, D = shapes.crater_population(400, 20e3, 300e3, 1, None)
    h = shapes.crater_heights(u, cen, D, R_MOON_M)
    shapes.write_mesh(trimesh.Trimesh(u * (R_MOON_M + h)[:, None], m.faces, process=False), path)
print(json.dumps({"mesh_seconds": time.perf_counter() - t0,
                  "mesh_peak_rss_GB": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024**2}))
"""

#: The measured run, in a fresh process: read and check the mesh file, then one phase, both paths.
TRACE = """
import sys, time, json, resource
from lunarviz.bodies import meshes
from lunarviz.photometry.brdf import make_brdf
from lunarviz.geometry.scene_geometry import SceneGeometry
from lunarviz.methods.tracer.estimators import TraceScene, TraceSettings, trace_path
path, threads = sys.argv[1], int(sys.argv[2])
load = []
_load = meshes.load_user_mesh
def timed_load(*a, **k):
    t = time.perf_counter()
    try:
        return _load(*a, **k)
    finally:
        load.append(time.perf_counter() - t)
meshes.load_user_mesh = timed_load  # (the tracer imports it at call time)
t1 = time.perf_counter()
ts = TraceScene(SceneGeometry(90.0), TraceSettings(moon_mesh=path, threads=threads))
ms, es = (trace_path(ts, p, {"dhg": make_brdf("dhg")}) for p in ("moonshine", "earthshine"))
t2 = time.perf_counter()
print(json.dumps({"load_seconds": sum(load), "trace_seconds": t2 - t1, "moonshine_W_m2": ms.mean["dhg"],
                  "earthshine_W_m2": es.mean["dhg"], "rays": ts.rays_cast, "threads": threads,
                  "peak_rss_GB": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024**2}))
"""


def _child(code: str, *args) -> dict:
    p = subprocess.run([sys.executable, "-c", code, *map(str, args)], capture_output=True, text=True)
    if p.returncode != 0:
        return {"returncode": p.returncode,
                "error": p.stderr.strip().splitlines()[-1] if p.stderr.strip() else "killed"}
    return {"returncode": 0, **json.loads(p.stdout.strip().splitlines()[-1])}


def plot(res: dict, out: Path, threads: int) -> None:
    """Run time and peak memory against the Moon's facets, each on its own axis with its target."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    ok = [r for r in res["rows"] if r["returncode"] == 0]
    f = [r["facets"] for r in ok]
    fig, (ax_t, ax_m) = plt.subplots(1, 2, figsize=(9, 3.8), sharex=True)
    ax_t.loglog(f, [r["trace_seconds"] for r in ok], "o-", label="trace")
    ax_t.axhline(res["targets"]["seconds"], color="C3", ls=":", lw=1, label=f"target {res['targets']['seconds']} s")
    ax_t.set_ylabel("run time of one phase [s]")
    ax_m.loglog(f, [r["peak_rss_GB"] or float("nan") for r in ok], "s-", color="C1", label="peak RSS")
    ax_m.axhline(res["targets"]["peak_rss_GB"], color="C3", ls=":", lw=1,
                 label=f"target {res['targets']['peak_rss_GB']} GiB")
    ax_m.set_ylabel("peak memory of the run [GiB]")
    for ax in (ax_t, ax_m):
        ax.axvline(res["targets"]["facets"], color="gray", ls="--", lw=0.8, label="5 M facets")
        ax.set_xlabel("Moon facets")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle(f"cratered Moon, θ = 90°, both paths, {threads} thread(s)")
    fig.tight_layout()
    fig.savefig(out / "scale.png", dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--levels", default="5,6,7")
    ap.add_argument("--out", default="benchmarks/scale")
    ap.add_argument("--append", action="store_true", help="add the rows to an existing scale.json")
    ap.add_argument("--threads", type=int, default=2, help="threads of the trace (default 2: this machine's cores)")
    a = ap.parse_args(argv)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for level in (int(x) for x in a.levels.split(",")):
        mesh = Path("/tmp") / f"lunarviz_scale_L{level}.ply"
        built = _child(BUILD, level, mesh)
        row = {"level": level, "facets": 20 * 4**level}
        if built["returncode"] == 0:
            row["mesh_seconds"], row["mesh_peak_rss_GB"] = built["mesh_seconds"], built["mesh_peak_rss_GB"]
            t0 = time.perf_counter()
            row.update(_child(TRACE, mesh, a.threads))
            row["wall_seconds"] = time.perf_counter() - t0
        else:
            row.update(built)
        rows.append(row)
        print(json.dumps(row))
        mesh.unlink(missing_ok=True)
    if a.append and (out / "scale.json").exists():
        rows = json.loads((out / "scale.json").read_text())["rows"] + rows
    command = f"python scripts/scale.py --levels {a.levels} --threads {a.threads}" + (" --append" if a.append else "")
    res = {"command": command, "theta_deg": 90.0, "brdf": "dhg",
           "targets": {"facets": 5_000_000, "seconds": 60, "peak_rss_GB": 4}, "rows": rows,
           "note": "the mesh is built (and written) in one process; a fresh process then reads and checks it "
                   "and traces one phase: peak_rss_GB (in GiB, 2**30 bytes) and wall_seconds are that run's own "
                   "(ru_maxrss of the process), load_seconds the reading and checking of the mesh within it"}
    (out / "scale.json").write_text(json.dumps(res, indent=1) + "\n")
    plot(res, out, a.threads)
    return 0


if __name__ == "__main__":
    sys.exit(main())
