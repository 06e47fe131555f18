"""Embree's time per ray against the coarse scene that stands for an exact sphere, by icosphere level.

    python scripts/hit_scene_speed.py [--rays N] [--repeats R] [--out DIR]

The deterministic tracer traces each beam toward a uniform exact-sphere source (the Earth, the
Sun) against a polyhedron circumscribing the sphere
(:meth:`lunarviz.methods.tracer.embree_bodies.EmbreeBody.hit_scene`): only whether a ray meets it
counts, and the hit is then found on the exact sphere, so the rows do not depend on the level,
only the time does. Here: ``--rays`` rays from the Moon's mean distance
toward points spread uniformly over the Earth's disc seen from there (as a lunar sample's Earth
beams are), started at the polyhedron's bounding sphere as the tracer starts them, traced
against the icosahedron (level 0) and the icosphere levels 2-6 in turn, one thread, best of
``--repeats``; every ray must hit. Writes ``hit_scene.json`` and ``hit_scene.md`` to
``benchmarks/speed`` (or ``--out``).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from lunarviz.methods.tracer.embree_bodies import ENTRY_MARGIN, _circumscribing_scene, _unit_icosphere

ROOT = Path(__file__).resolve().parents[1]
EARTH_RADIUS_M = 6.371e6
MOON_DISTANCE_M = 3.844e8


def rays(n: int, bound: float, seed: int = 5):
    """float32 origins and directions of n rays from (-d, 0, 0) toward uniform points of the
    Earth's disc seen from there, each started at ``bound`` (1 + ENTRY_MARGIN) from the centre."""
    rng = np.random.default_rng(seed)
    r = EARTH_RADIUS_M * 0.999 * np.sqrt(rng.random(n))
    a = 2 * np.pi * rng.random(n)
    target = np.stack([np.zeros(n), r * np.cos(a), r * np.sin(a)], axis=1)
    start = np.array([-MOON_DISTANCE_M, 0.0, 0.0])
    d = target - start
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    b = -d @ start  # the ray's point nearest the centre, then back to the bounding sphere
    near = start + b[:, None] * d
    back = np.sqrt(np.maximum((bound * (1 + ENTRY_MARGIN)) ** 2 - (near ** 2).sum(axis=1), 0.0))
    o = near - back[:, None] * d
    return o.astype(np.float32), d.astype(np.float32)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rays", type=int, default=167_000, help="rays a level (default: an orbit date's Earth beams)")
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "speed"))
    a = ap.parse_args(argv)
    rows = []
    for level in (0, 2, 3, 4, 5, 6):
        unit = _unit_icosphere(level)
        if unit is None:
            continue
        scene, bound, faces = _circumscribing_scene(*unit, EARTH_RADIUS_M)[:3]
        o, d = rays(a.rays, bound)
        hit = scene.run(o, d, query="INTERSECT")
        if not (hit >= 0).all():
            raise SystemExit(f"level {level}: {(hit < 0).sum()} rays missed the circumscribing polyhedron")
        best = min(_timed(scene, o, d) for _ in range(a.repeats))
        rows.append({"level": level, "facets": faces, "seconds": best, "ns_per_ray": best / a.rays * 1e9})
        print(f"level {level} ({faces} facets): {best * 1e3:.1f} ms, {best / a.rays * 1e9:.0f} ns a ray", flush=True)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    res = {"command": "python scripts/hit_scene_speed.py", "rays": a.rays, "repeats": a.repeats, "levels": rows}
    (out / "hit_scene.json").write_text(json.dumps(res, indent=1) + "\n")
    lines = ["# Embree's time per ray against the coarse hit scene", "",
             f"`{res['command']}`: {a.rays:,} rays toward the Earth's disc from the Moon's distance, one thread, "
             f"best of {a.repeats}; every ray hits.", "",
             "| level | facets | time [ms] | ns a ray |", "| --- | --- | --- | --- |"]
    lines += [f"| {r['level']} | {r['facets']} | {r['seconds'] * 1e3:.1f} | {r['ns_per_ray']:.0f} |" for r in rows]
    (out / "hit_scene.md").write_text("\n".join(lines) + "\n")
    print(f"wrote {out}")
    return 0


def _timed(scene, o, d) -> float:
    t = time.perf_counter()
    scene.run(o, d, query="INTERSECT")
    return time.perf_counter() - t


if __name__ == "__main__":
    raise SystemExit(main())
