#!/usr/bin/env python3
"""The bars on non-spherical Moons, end to end, against independent references.

The references were written apart from the tracer (scripts/validation/, numpy and raw embreex
only, plus lunarviz's BRDF formulas):

* ``ref_shapes.py``: parametric Gauss quadrature over the exact triaxial ellipsoid
  (1.15/1.00/0.85 R) and over each face of a rotated 2 R cube, extended Sun and Earth,
  converged to < 1e-5; it also writes the meshes (icosphere L7 scaled per axis: 327,680
  facets; the cube), in metres, body frame;
* ``make_crater_moon.py`` + ``ref_crater.py``: 40 paraboloid bowls near the terminator at
  θ = 120° on an L7 icosphere, and a ray cast of every sub-facet sample to the detector and to
  a sampled solar disc (converged to 3e-6).

Usage (about 10 minutes on 2 cores)::

    export LUNARVIZ_VALIDATION_DIR=validation_out
    python3 scripts/validation/ref_shapes.py
    python3 scripts/validation/make_crater_moon.py
    python3 scripts/validation/ref_crater.py --configs 32:1x4
    python3 scripts/validate_shapes.py      # runs lunarviz, writes benchmarks/validation_shapes.json
"""

from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path

from lunarviz.scene import ResolvedScene
from lunarviz.workflows.sweeps import run_sweep

OUT = Path(os.environ.get("LUNARVIZ_VALIDATION_DIR", "validation_out"))


def sweep(mesh, phases, **kw):
    t0 = time.perf_counter()
    res = run_sweep(ResolvedScene(method="raytrace", brdfs=("lambert", "dhg"), phases_deg=tuple(phases),
                                  moon_mesh=str(mesh), **kw))
    return res["rows"], time.perf_counter() - t0


def main():
    ref = json.loads((OUT / "ref_shapes.json").read_text())
    table = []
    for shape, mesh in (("ellipsoid", OUT / "ellipsoid_L7.ply"), ("cube", OUT / "cube_rot.ply")):
        rows, secs = sweep(mesh, (30.0, 90.0, 150.0))
        for r in rows:
            R = ref[shape][str(int(r["theta_deg"]))][r["brdf"]]
            table.append({"mesh": shape, "theta_deg": r["theta_deg"], "brdf": r["brdf"], "settings": "default",
                          "moonshine_rel": r["moonshine_W_m2"] / R["moonshine_W_m2"] - 1,
                          "earthshine_rel": r["earthshine_W_m2"] / R["earthshine_W_m2"] - 1, "sweep_seconds": secs})
    crater_ref = OUT / "ref_crater.json"
    if crater_ref.exists():
        cref = json.loads(crater_ref.read_text())
        best = cref[-1] if isinstance(cref, list) else cref
        rows, secs = sweep(OUT / "crater_moon.ply", (120.0,), shading="flat")
        for r in rows:
            want = best["E"][r["brdf"]]["full"]
            table.append({"mesh": "craters", "theta_deg": 120.0, "brdf": r["brdf"], "settings": "--shading flat",
                          "moonshine_rel": r["moonshine_W_m2"] / want - 1, "rays": r["rays"], "sweep_seconds": secs})
    out = Path("benchmarks/validation_shapes.json")
    out.write_text(json.dumps({"reference_dir": str(OUT), "rows": table}, indent=1) + "\n")
    for t in table:
        print(t)
    print(f"wrote {out}")


if __name__ == "__main__":
    sys.exit(main())
