"""Honest throughput: end-to-end against raw Embree on the very same rays, and where the time goes.

    python scripts/throughput.py [--out benchmarks/throughput] [--quick]

Rays are counted the same way on both sides: the rays *submitted to Embree*
(every float32 batch :meth:`EmbreeBody.run_rays` sends, recorded). The end-to-end time is one
deterministic trace of both paths (three BRDFs), one thread; the raw time replays the recorded
batches through ``embreex`` alone (``scene.run``), one thread, best of three. Then

* ``ratio = (N / T_end_to_end) / (N / T_raw) = T_raw / T_end_to_end`` (the same N on both
  sides), which is also Embree's share of the time;
* the exclusive time of each stage, measured by wrapping the tracer's functions:
  ray generation (lunar samples, candidates, source beams and their angles, detector
  geometry, the compiled passes that write Embree's rays: ``cap_beam_rays``, ``beam_rays``,
  ``occluder_rays``), beam assembly (gathering live beams, building each Transport,
  ``scatter_beams``), Embree (inside ``run_rays``), source look-ups (hit refinement, source
  radiance: ``source_hits``), shading (BRDF evaluation) and accumulation (``trace_path``'s own
  loop: sums and per-facet bincounts).

Both cores: the same trace with ``threads=2`` (chunks of lunar samples traced on two threads,
``TraceScene.deterministic.transport``) against raw Embree on one thread and on two
(``replay_threads``).

Two scenes: the paper's (θ = 90°, packaged spheres, occlusion on) and a cratered Moon (level 6,
400 craters of 20-300 km, self-shadowing on), where Embree has real work. ``rays_<scene>.npz``
holds the counted rays (origins, directions, tmax, query per batch, and the mesh) so anyone can
replay them through embreex and recount the ratio (:func:`replay_npz`).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from lunarviz.geometry.scene_geometry import SceneGeometry
from lunarviz.methods import transport as T
from lunarviz.methods.tracer import deterministic as DT
from lunarviz.methods.tracer import embree_bodies as B
from lunarviz.methods.tracer import estimators as E
from lunarviz.methods.tracer import lunar_sampling as LS
from lunarviz.methods.tracer import mapped_earth as ME
from lunarviz.methods.tracer import ray_kernels as K
from lunarviz.methods.tracer import source_rules as SR
from lunarviz.photometry.brdf import make_brdf

MODELS = {b: make_brdf(b) for b in ("lambert", "shg", "dhg")}


class StageTimer:
    """Exclusive time per stage: wrapped functions push onto a stack; a call's time is charged
    to its stage minus the time of wrapped calls inside it."""

    def __init__(self):
        self.total: dict = {}
        self.stack: list = []
        self.saved: list = []

    def wrap(self, owner, name: str, stage: str):
        fn = getattr(owner, name)
        self.saved.append((owner, name, fn))
        timer = self

        def wrapped(*a, **kw):
            t0 = time.perf_counter()
            timer.stack.append(0.0)
            try:
                return fn(*a, **kw)
            finally:
                el = time.perf_counter() - t0
                inner = timer.stack.pop()
                timer.total[stage] = timer.total.get(stage, 0.0) + el - inner
                if timer.stack:
                    timer.stack[-1] += el
        setattr(owner, name, wrapped)

    def restore(self):
        for owner, name, fn in reversed(self.saved):
            setattr(owner, name, fn)
        self.saved.clear()


def instrument(timer: StageTimer):
    for owner, name in ((LS.LunarSampling, "lunar_samples"), (LS.LunarSampling, "candidates"),
                        (SR.SourceRules, "source_nodes"), (LS.LunarSampling, "detector_view"),
                        (ME.MappedEarthTransport, "earth_elements"), (SR.SourceRules, "sun_visibility_of_earth")):
        timer.wrap(owner, name, "ray generation")
    for owner, name in ((SR.SourceRules, "source_radiance"), (ME.MappedEarthTransport, "transport")):
        timer.wrap(owner, name, "source look-ups")
    for name in ("beam_angles", "cap_beam_rays", "beam_rays", "occluder_rays"):
        timer.wrap(K, name, "ray generation")
    timer.wrap(K, "source_hits", "source look-ups")
    timer.wrap(K, "scatter_beams", "beam assembly")
    timer.wrap(DT.DeterministicTransport, "beam_transport", "beam assembly")
    timer.wrap(B.EmbreeBody, "run_rays", "embree")
    timer.wrap(T.Transport, "radiances", "shading")
    timer.wrap(E, "trace_path", "accumulation")


def make_scene(name: str, quick: bool):
    if name == "paper":
        return SceneGeometry(90.0), E.TraceSettings(occlusion=True, threads=1), None
    from lunarviz.bodies import shapes
    from lunarviz.constants import R_MOON_M
    level = 4 if quick else 6  # quick: a smoke run (tests), 5,120 facets
    mesh = shapes.craters(R_MOON_M, level, 400, 20e3, 300e3, seed=1)
    path = Path("/tmp") / f"lunarviz_craters_L{level}.ply"
    shapes.write_mesh(mesh, path)
    return SceneGeometry(90.0), E.TraceSettings(occlusion=True, threads=1, moon_mesh=str(path)), path


def trace_once(scene, settings):
    ts = E.TraceScene(scene, settings)
    t0 = time.perf_counter()
    E.trace_path(ts, "moonshine", MODELS)
    E.trace_path(ts, "earthshine", MODELS)
    return ts, time.perf_counter() - t0


def record(scene, settings):
    """The batches one trace sends to Embree: (body, scene, query, o32, d32, dists)."""
    ts = E.TraceScene(scene, settings)
    for b in (ts.moon, ts.earth, ts.sun):
        b.recorder = []
    E.trace_path(ts, "moonshine", MODELS)
    E.trace_path(ts, "earthshine", MODELS)
    out = [(b, *rec) for b in (ts.moon, ts.earth, ts.sun) for rec in b.recorder]
    for b in (ts.moon, ts.earth, ts.sun):
        b.recorder = None
    return ts, out


def replay(batches) -> float:
    """Raw embreex time for the recorded batches, one thread, no Python around the calls."""
    t0 = time.perf_counter()
    for _, scene, query, o, d, dists in batches:
        kw = {} if dists is None else {"dists": dists}
        scene.run(o, d, query=query, **kw)
    return time.perf_counter() - t0


def replay_threads(batches, threads: int = 2) -> float:
    """Raw embreex time for the same batches on ``threads`` threads (embreex releases the
    GIL): the batches shared out, large ones halved, as fast as Embree alone uses the cores."""
    from concurrent.futures import ThreadPoolExecutor
    jobs = []
    for _, scene, query, o, d, dists in batches:
        cut = [0, len(o) // 2, len(o)] if len(o) > 4096 else [0, len(o)]
        for a, b in zip(cut[:-1], cut[1:]):
            jobs.append((scene, query, o[a:b], d[a:b], None if dists is None else dists[a:b]))

    def one(job):
        scene, query, o, d, dists = job
        kw = {} if dists is None else {"dists": dists}
        scene.run(o, d, query=query, **kw)
    t0 = time.perf_counter()
    with ThreadPoolExecutor(threads) as ex:
        list(ex.map(one, jobs))
    return time.perf_counter() - t0


def save_npz(path: Path, ts, batches):
    """Rays and meshes for an independent replay (``replay_npz``)."""
    arrays = {}
    names = {id(ts.moon._scene): "moon", id(ts.earth._scene): "earth", id(ts.sun._scene): "sun"}
    for body in (ts.moon, ts.earth, ts.sun):
        geo = body.geometry
        label = 'moon' if body is ts.moon else 'earth' if body is ts.earth else 'sun'
        if geo.get("outer") is not None:
            names[id(geo["outer"])] = f"{label}_outer"
        if geo.get("hit_scene") is not None:  # the coarse hit scene of a uniform source (EmbreeBody.hit_scene)
            names[id(geo["hit_scene"][0])] = f"{label}_hit"
            arrays[f"{label}_hit_vertices"], arrays[f"{label}_hit_faces"] = geo["hit_mesh"]
    meshes = {"moon": ts.moon, "earth": ts.earth, "sun": ts.sun}
    for n, b in meshes.items():
        arrays[f"{n}_vertices"] = b.vertices.astype(np.float32)
        arrays[f"{n}_faces"] = b.faces.astype(np.int32)
        if b.geometry.get("outer") is not None:
            plane = np.einsum("ij,ij->i", b.normals, b.vertices[b.faces[:, 0]])
            k = b.radius / float(plane.min()) * (1.0 + 1e-9)
            arrays[f"{n}_outer_vertices"] = (b.vertices * k).astype(np.float32)
    for i, (_, scene, query, o, d, dists) in enumerate(batches):
        arrays[f"b{i}_mesh"] = np.array(names[id(scene)])
        arrays[f"b{i}_query"] = np.array(query)
        arrays[f"b{i}_o"] = o
        arrays[f"b{i}_d"] = d
        if dists is not None:
            arrays[f"b{i}_dists"] = dists
    arrays["n_batches"] = np.array(len(batches))
    np.savez_compressed(path, **arrays)


def replay_npz(path) -> tuple[int, float]:
    """Replay a saved ``.npz`` through embreex alone: (rays, seconds)."""
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh
    z = np.load(path)
    scenes = {}
    for n in ("moon", "earth", "sun"):
        for suffix in ("", "_outer", "_hit"):
            key = f"{n}{suffix}_vertices"
            if key in z:
                sc = rtcore_scene.EmbreeScene()
                faces = z[f"{n}_hit_faces" if suffix == "_hit" else f"{n}_faces"]
                TriangleMesh(scene=sc, vertices=z[key], indices=faces)
                scenes[n + suffix] = sc
    n_rays, t = 0, 0.0
    for i in range(int(z["n_batches"])):
        sc = scenes[str(z[f"b{i}_mesh"])]
        kw = {"dists": z[f"b{i}_dists"]} if f"b{i}_dists" in z else {}
        o, d = z[f"b{i}_o"], z[f"b{i}_d"]
        t0 = time.perf_counter()
        sc.run(o, d, query=str(z[f"b{i}_query"]), **kw)
        t += time.perf_counter() - t0
        n_rays += len(o)
    return n_rays, t


def measure(name: str, out: Path, quick: bool) -> dict:
    scene, settings, mesh_path = make_scene(name, quick)
    trace_once(scene, settings)  # warm-up: mesh loading, Embree builds, caches
    ts, batches = record(scene, settings)
    n = sum(len(b[3]) for b in batches)
    repeats = 1 if quick else 3  # (best of three; a smoke run once)
    raw = min(replay(batches) for _ in range(repeats))
    e2e = min(trace_once(scene, settings)[1] for _ in range(repeats))
    # both cores: chunks traced on two threads (TraceScene.deterministic.transport), against
    # raw Embree on one thread and on two
    from dataclasses import replace as _replace
    settings2 = _replace(settings, threads=2)
    trace_once(scene, settings2)
    e2e2 = min(trace_once(scene, settings2)[1] for _ in range(repeats))
    raw2 = min(replay_threads(batches) for _ in range(repeats))
    timer = StageTimer()
    instrument(timer)
    try:
        _, t_inst = trace_once(scene, settings)
    finally:
        timer.restore()
    npz = out / f"rays_{name}.npz"
    save_npz(npz, ts, batches)
    n_re, t_re = replay_npz(npz)
    stages = {k: v for k, v in sorted(timer.total.items(), key=lambda kv: -kv[1])}
    return {"scene": name, "moon_mesh": None if mesh_path is None else str(mesh_path),
            "moon_faces": int(ts.moon.n_faces), "rays_sent_to_embree": n, "batches": len(batches),
            "end_to_end_seconds": e2e, "raw_embree_seconds": raw,
            "end_to_end_rays_per_s": n / e2e, "raw_embree_rays_per_s": n / raw,
            "ratio_end_to_end_over_raw": raw / e2e, "target_ratio": 0.8, "met": raw / e2e >= 0.8,
            "two_threads": {"end_to_end_seconds": e2e2, "raw_embree_seconds_2_threads": raw2,
                            "ratio_over_raw_1_thread": raw / e2e2, "ratio_over_raw_2_threads": raw2 / e2e2,
                            "end_to_end_speedup": e2e / e2e2, "raw_speedup": raw / raw2},
            "stage_seconds_instrumented_run": stages, "instrumented_run_seconds": t_inst,
            "stage_shares": {k: v / sum(stages.values()) for k, v in stages.items()},
            "npz": npz.name, "npz_replay_rays": n_re, "npz_replay_seconds": t_re}


def _reference(theta: float) -> dict:
    from lunarviz.methods.reference import ReferenceSettings, reference_irradiance
    r = reference_irradiance(SceneGeometry(theta), MODELS, ReferenceSettings(32, 12))
    return {k: (v.moonshine_W_m2, v.earthshine_W_m2) for k, v in r.items()}


def paper_sweep(out: Path, quick: bool) -> dict:
    """The paper sweep from the command line (wall time, numba on and off in the same
    run) and its largest error against the exact reference (order 32, 12) at θ = 5-175°."""
    import os
    import subprocess
    from concurrent.futures import ProcessPoolExecutor
    phases = "0:180:45" if quick else "0:180:5"
    cmd = [sys.executable, "-m", "lunarviz", "sweep", "--method", "raytrace", "--no-occlusion", "--phases", phases,
           "--brdf", "lambert,shg,dhg", "--quiet"]
    walls, rows = {}, None
    for flag in ("1", "0", "1"):  # numba, numpy, numba again (the first call may compile)
        target = out / f"paper_sweep_numba{flag}.json"
        t0 = time.perf_counter()
        subprocess.run([*cmd, "--out", str(target)], check=True, env={**os.environ, "LUNARVIZ_NUMBA": flag})
        walls[flag] = time.perf_counter() - t0
        if flag == "1":
            rows = json.loads(target.read_text())["rows"]
        target.unlink()
    thetas = sorted({r["theta_deg"] for r in rows if 5 <= r["theta_deg"] <= 175})
    with ProcessPoolExecutor(os.cpu_count() or 1) as ex:
        refs = dict(zip(thetas, ex.map(_reference, thetas)))
    err = max(abs(r[f"{p}_W_m2"] / refs[r["theta_deg"]][r["brdf"]][i] - 1)
              for r in rows if r["theta_deg"] in refs for i, p in enumerate(("moonshine", "earthshine")))
    return {"command": " ".join(["lunarviz", *cmd[3:]]), "phases": phases, "wall_seconds_numba": walls["1"],
            "wall_seconds_numpy": walls["0"], "speedup_numba": walls["0"] / walls["1"],
            "max_rel_error_vs_reference_5_175": err, "target_seconds": 10.0, "target_error": 1e-4,
            "met_time": walls["1"] <= 10.0, "met_error": err <= 1e-4}


def montecarlo_phase(target: float = 0.002, quick: bool = False) -> dict:
    """The Monte Carlo target: the seconds one phase (θ = 90°, no occlusion, both paths,
    three BRDFs, one run each, default threads) takes at the paper's 0.2 % standard deviation per
    path. N per path from a pilot run (σ ∝ N^-1/2), then the best of three timed runs at that N
    with fresh seeds; the σ reported is the pooled within-run estimate of the last one."""
    import math

    from lunarviz.methods.tracer.estimators import TraceScene, TraceSettings, trace_path
    out = {"target_seconds": 0.2, "target_relative_std": target}
    total = 0.0
    for path, pilot in (("moonshine", 2_000), ("earthshine", 5_000)) if quick else \
            (("moonshine", 10_000), ("earthshine", 100_000)):
        def run(n, seed):
            ts = TraceScene(SceneGeometry(90.0),
                            TraceSettings(estimator="montecarlo", rays=n, occlusion=False, seed=seed))
            r = trace_path(ts, path, MODELS)
            return r.seconds, max(r.std[b] / r.mean[b] for b in MODELS)
        _, rel = run(pilot, 1)
        n = int(math.ceil(pilot * (rel / target) ** 2 * 1.02))
        runs = [run(n, seed) for seed in (2, 3, 4)]
        sec = min(t for t, _ in runs)
        out[path] = {"rays": n, "seconds": sec, "relative_std": runs[-1][1]}
        total += sec
    out["seconds_per_phase"] = total
    out["met"] = total <= 0.2
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="benchmarks/throughput")
    ap.add_argument("--quick", action="store_true")
    a = ap.parse_args(argv)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    res = {"command": "python scripts/throughput.py", "threads": 1, "brdfs": list(MODELS),
           "scenes": [measure(s, out, a.quick) for s in ("paper", "craters")],
           "paper_sweep": paper_sweep(out, a.quick),
           "montecarlo_phase": montecarlo_phase(0.01 if a.quick else 0.002, a.quick)}
    (out / "throughput.json").write_text(json.dumps(res, indent=1) + "\n")
    for r in res["scenes"]:
        print(f"{r['scene']}: {r['rays_sent_to_embree']:,} rays to Embree; end-to-end {r['end_to_end_rays_per_s']:.3g}"
              f" rays/s, raw {r['raw_embree_rays_per_s']:.3g} rays/s, ratio {r['ratio_end_to_end_over_raw']:.3f}")
        t2 = r["two_threads"]
        print(f"   two threads: end-to-end x{t2['end_to_end_speedup']:.2f}, raw x{t2['raw_speedup']:.2f}; ratio over "
              f"raw on one thread {t2['ratio_over_raw_1_thread']:.3f}, on two {t2['ratio_over_raw_2_threads']:.3f}")
        print("   stages: " + ", ".join(f"{k} {100 * v:.0f} %" for k, v in r["stage_shares"].items()))
    mc = res["montecarlo_phase"]
    print(f"Monte Carlo at 0.2 %: {mc['seconds_per_phase']:.3f} s per phase (moonshine "
          f"{mc['moonshine']['rays']:,} rays, earthshine {mc['earthshine']['rays']:,} rays)")
    ps = res["paper_sweep"]
    print(f"paper sweep: {ps['wall_seconds_numba']:.1f} s (numpy {ps['wall_seconds_numpy']:.1f} s), max error "
          f"{ps['max_rel_error_vs_reference_5_175']:.1e}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
