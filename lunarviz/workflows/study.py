"""Mesh-resolution studies: facets, run time, error, observed order of convergence.

``mesh_study(levels, phases, brdfs, out, body="moon")`` traces every phase with ``body`` at
every level (deterministic estimator, no occlusion, source beams converged: Earth order 12,
Sun order 4) and writes a table (.json or .csv) and a
log-log plot beside it. The body's mesh at each level is

* ``shape="sphere"``: the packaged icosphere (the exact-sphere fast path with ``auto`` or
  ``smooth`` shading, the facets with ``flat``); error against the exact reference;
* ``shape="ellipsoid"`` (semi-axes ``axes`` in body radii) or ``"craters"`` (a seeded cratered
  body, :mod:`lunarviz.bodies.shapes`): generated at each level and traced on its facets;
* ``meshes=[f1, f2, ...]``: the user's meshes, coarse to fine (``levels`` is then their index).

Without an exact reference (every shape but the sphere) the error is measured against the
finest mesh of the study and the observed order from successive differences,
``p = log2(|v_{L-1} - v_{L-2}| / |v_L - v_{L-1}|)``; the table says which. With the exact
reference, ``p = log2(e_{L-1} / e_L)`` (the facet size halves per level).
"""

from __future__ import annotations

import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from lunarviz.errors import LunarvizError, unknown_choice
from lunarviz.options import BY_NAME
from lunarviz.geometry.scene_geometry import SceneGeometry
from lunarviz.methods.reference import ReferenceSettings, reference_irradiance
from lunarviz.outputs.writers import check_output_path, save_figure, write_results
from lunarviz.photometry.brdf import BRDF_NAMES, make_brdf
from lunarviz.workflows.sweeps import dask_client

STUDY_SHAPES = ("sphere", "ellipsoid", "craters")


def _study_meshes(body, shape, levels, axes, meshes, tmp):
    """Mesh path (or None for the packaged sphere) per level."""
    from lunarviz.bodies import shapes
    from lunarviz.bodies.meshes import NOMINAL_RADII
    if meshes:
        return {i: str(m) for i, m in enumerate(meshes)}
    if shape == "sphere":
        return {lv: None for lv in levels}
    R = NOMINAL_RADII[body]
    out = {}
    for lv in levels:
        if shape == "ellipsoid":
            m = shapes.ellipsoid(*(a * R for a in axes), level=int(lv))
        else:  # same craters at every level (seeded), so only the resolution changes
            m = shapes.craters(R, int(lv), 20, 0.06 * R, 0.2 * R, seed=0)
        p = Path(tmp) / f"{body}_{shape}_L{lv}.ply"
        shapes.write_mesh(m, p)
        out[lv] = str(p)
    return out


class _Means:
    def __init__(self, mean, rays):
        self.mean, self.rays = mean, rays


def _study_task(task):
    """One (mesh, phase) of a study: ``(seconds, facets, moonshine means, earthshine means, rays)``.
    Module-level and fed only settings, so a Dask worker can run it (meshes must be readable
    there: generated shapes live in a local temporary folder, so remote clusters need ``meshes``
    on a shared file system)."""
    from lunarviz.methods.tracer.estimators import TraceScene, trace_path
    st, th, body, brdfs = task
    models = {b: make_brdf(b) for b in brdfs}
    t0 = time.perf_counter()
    ts = TraceScene(SceneGeometry(th), st)
    ms = trace_path(ts, "moonshine", models)
    es = trace_path(ts, "earthshine", models)
    return time.perf_counter() - t0, int(getattr(ts, body).n_faces), ms.mean, es.mean, (ms.rays, es.rays)


def mesh_study(levels, phases, brdfs, out=None, shading: str = BY_NAME["shading"].default, refine: bool = True,
               progress: bool = False, body: str = "moon", shape: str = "sphere",
               axes=(1.15, 1.0, 0.85), meshes=None, mesh_units: str = BY_NAME["mesh_units"].default,
               executor: str = "local",
               scheduler: str | None = None, workers: int | None = None) -> dict:
    from lunarviz.methods.tracer.estimators import TraceSettings
    if body not in ("moon", "earth", "sun"):
        raise unknown_choice("body", body, ("moon", "earth", "sun"))
    if shape not in STUDY_SHAPES:
        raise unknown_choice("study shape", shape, STUDY_SHAPES)
    if meshes:
        levels = list(range(len(meshes)))
    if body != "moon" and shape == "sphere" and not meshes and shading == "auto":
        # the packaged Earth and Sun are shaded on the exact sphere, where their level only picks
        # the facet a beam meets: a resolution study of them is a study of their facets
        shading = "flat"
    models = {b: make_brdf(b) for b in brdfs}
    exact = shape == "sphere" and not meshes
    refs = {th: reference_irradiance(SceneGeometry(th), models, ReferenceSettings(32, 12)) for th in phases} \
        if exact else {}
    _refuse_dark_phases(refs, brdfs)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        paths = _study_meshes(body, shape, levels, axes, meshes, tmp)
        it = [(lv, th) for lv in levels for th in phases]
        # ``shading`` applies to the studied body only; the others keep their defaults
        # the source beams are converged (Earth order 12, Sun order 4) so the study sees the
        # mesh's error, not the beams' (~8e-6 at the default Earth order 6)
        base = TraceSettings(occlusion=False, refine=refine, body_shading=((body, shading),),
                             mesh_units=mesh_units if meshes else "m", earth_order=12, sun_order=4)
        tasks = [(replace(base, **{f"{body}_mesh": paths[lv]}) if paths[lv] else
                  replace(base, **{f"{body}_level": int(lv)}), float(th), body, tuple(brdfs)) for lv, th in it]
        if executor == "dask":
            client, cluster = dask_client(scheduler, workers)
            try:
                outs = client.gather(client.map(_study_task, tasks, pure=False))
            finally:
                client.close()
                if cluster is not None:
                    cluster.close()
        else:
            run_list = tasks
            if progress:
                from tqdm import tqdm
                run_list = tqdm(tasks, desc="mesh study", unit="run", leave=False)
            outs = [_study_task(t) for t in run_list]
        for (lv, th), (dt, facets, ms_mean, es_mean, n_rays) in zip([(lv, th) for lv in levels for th in phases],
                                                                   outs):
            ms = _Means(ms_mean, n_rays[0])
            es = _Means(es_mean, n_rays[1])
            for b in brdfs:
                for path, res in (("moonshine", ms), ("earthshine", es)):
                    ref = getattr(refs[th][b], f"{path}_W_m2") if exact else None
                    rows.append({"level": int(lv), "facets": facets, "theta_deg": float(th),
                                 "brdf": b, "path": path, "value_W_m2": res.mean[b], "reference_W_m2": ref,
                                 "relative_error": res.mean[b] / ref - 1 if exact else None, "seconds": dt,
                                 "rays": ms.rays + es.rays, "shading": shading, "refine": refine})
    if not exact:  # error against the finest mesh; order from successive differences
        _against_finest(rows, max(levels))
    summary = []
    for path in ("moonshine", "earthshine"):
        prev = None
        vals = []
        for lv in levels:
            sel = [r for r in rows if r["level"] == lv and r["path"] == path]
            secs = np.mean([r["seconds"] for r in rows if r["level"] == lv])
            e = float(max(abs(r["relative_error"]) for r in sel))
            v = np.array([r["value_W_m2"] for r in sel])
            if exact:
                order = float(np.log2(prev / e)) if prev and e > 0 else None
            else:
                order = None
                if len(vals) >= 2:
                    d1 = np.max(np.abs(vals[-1] / vals[-2] - 1))
                    d2 = np.max(np.abs(v / vals[-1] - 1))
                    order = float(np.log2(d1 / d2)) if d1 > 0 and d2 > 0 else None
            vals.append(v)
            summary.append({"path": path, "level": int(lv), "facets": sel[0]["facets"],
                            "max_abs_relative_error": e, "observed_order": order,
                            "mean_seconds_per_phase": float(secs)})
            prev = e
    res = {"settings": {"levels": list(levels), "phases_deg": list(phases), "brdfs": list(brdfs),
                        "body": body, "shape": shape if not meshes else "user meshes",
                        "meshes": [str(m) for m in meshes] if meshes else None,
                        "shading": shading, "refine": refine, "earth_order": 12, "sun_order": 4,
                        "reference": "exact reference ReferenceSettings(32, 12)" if exact else
                        "finest mesh of the study; order from successive differences"},
           "rows": rows, "summary": summary}
    if out is not None:
        out = Path(out)
        write_results(out, res)
        plot_study(res, out.with_suffix(".png"))
    return res


def mesh(levels=(2, 3, 4, 5), phases=(30.0, 90.0, 150.0), brdfs=("lambert", "shg", "dhg"), *, body: str = "moon",
         shape: str = "sphere", axes=(1.15, 1.0, 0.85), meshes=None, mesh_units: str = BY_NAME["mesh_units"].default,
         shading: str = BY_NAME["shading"].default,
         refine: bool = True, out=None, plot=None, progress: bool = False, executor: str = "local",
         scheduler: str | None = None, workers: int | None = None) -> dict:
    """Mesh-resolution study (the Python face of ``lunarviz study mesh``).

    Parameters
    ----------
    levels : sequence of int
        Icosphere levels of ``body``'s mesh, increasing (ignored with ``meshes``).
    phases : sequence of float
        Phases θ [deg] in [0, 180].
    brdfs : sequence of str
        Lunar BRDFs.
    body : {"moon", "earth", "sun"}
        The body whose mesh varies; ``shape`` sphere, ellipsoid (semi-axes ``axes`` in body
        radii) or craters; ``meshes`` the user's meshes coarse to fine (in ``mesh_units``).
    shading, refine
        Ray-tracing options (see :class:`lunarviz.methods.tracer.estimators.TraceSettings`).
    executor, scheduler, workers
        ``"local"`` (this process) or ``"dask"`` (each level and phase a task; see
        :func:`lunarviz.run`).
    out : path, optional
        Write the table (.json or .csv).
    plot : path, optional
        Draw the convergence plot (.png).

    Returns
    -------
    dict
        ``{"settings", "rows", "summary"}``: per level the facets, the relative error (against
        the exact reference for the sphere, else the finest mesh), the observed order and the
        run time [s]. Nothing is written or drawn unless asked.
    """
    from lunarviz.bodies.meshes import MAX_LEVEL
    levels = list(levels)
    if meshes is None:
        if not levels or not all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) and 0 <= v <= MAX_LEVEL
                                 for v in levels):
            raise LunarvizError(f"levels {tuple(levels)!r} must be integers in [0, {MAX_LEVEL}]")
        if any(b <= a for a, b in zip(levels, levels[1:])):
            raise LunarvizError(f"levels {tuple(levels)!r} must increase (coarse to fine)")
    elif len(meshes) < 2:
        raise LunarvizError("meshes needs at least two meshes, coarse to fine")
    if isinstance(phases, str):
        from lunarviz.parsing import parse_float_list
        phases = parse_float_list(phases, "phase", 0.0, 180.0)
    if isinstance(brdfs, str):
        brdfs = [b.strip().lower() for b in brdfs.split(",") if b.strip()]
    try:
        phases = [float(p) for p in phases]
    except (TypeError, ValueError):
        raise LunarvizError(f"phases {phases!r} must be numbers θ [deg]") from None
    if not phases or not all(np.isfinite(p) and 0 < p < 180 for p in phases):
        raise LunarvizError(f"phases {tuple(phases)!r} must be angles θ in (0, 180) deg (at 0 the earthshine, at 180 "
                            f"the moonshine vanishes: a relative error has no meaning there)")
    for b in brdfs:
        if b not in BRDF_NAMES:
            raise unknown_choice("BRDF", b, BRDF_NAMES)
    if body not in ("moon", "earth", "sun"):
        raise LunarvizError(f"body {body!r} is not moon, earth or sun")
    if shape not in STUDY_SHAPES:
        raise unknown_choice("study shape", shape, STUDY_SHAPES)
    if out is not None:
        out = check_output_path(out)
    if plot is not None:
        plot = check_output_path(plot, (".png",))
    if executor not in ("local", "dask"):
        raise unknown_choice("executor", executor, ("local", "dask"))
    res = mesh_study(list(levels), list(phases), list(brdfs), None, shading=shading, refine=refine,
                     progress=progress, body=body, shape=shape, axes=tuple(axes), meshes=meshes,
                     mesh_units=mesh_units, executor=executor, scheduler=scheduler, workers=workers)
    if out is not None:
        write_results(out, res)
    if plot is not None:
        plot_study(res, plot)
    return res


def _against_finest(rows: list[dict], finest: int) -> None:
    """Each row's relative error against the finest mesh's row of its phase, BRDF and path."""
    for r in rows:
        ref = next(q["value_W_m2"] for q in rows if q["level"] == finest and q["theta_deg"] == r["theta_deg"]
                   and q["brdf"] == r["brdf"] and q["path"] == r["path"])
        if not ref > 0:
            raise LunarvizError(f"phase θ = {r['theta_deg']:g} deg: the finest mesh's {r['path']} is 0 there: a "
                                f"mesh study needs light on both paths")
        r["reference_W_m2"] = ref
        r["relative_error"] = r["value_W_m2"] / ref - 1


def _refuse_dark_phases(refs: dict, brdfs) -> None:
    """Before any tracing: a phase whose exact moonshine or earthshine is 0 (no lit side to see)
    has no relative error, and the study refuses it in one line."""
    for th, by in refs.items():
        dark = [f"{p} ({b})" for b in brdfs for p in ("moonshine", "earthshine") if not getattr(by[b], f"{p}_W_m2") > 0]
        if dark:
            raise LunarvizError(f"phase θ = {th:g} deg: the exact {dark[0]} is 0 there (the Earth or the Moon shows "
                                f"no lit side): a mesh study needs light on both paths")


def plot_study(res: dict, path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.2))
    for path_name, mark in (("moonshine", "o-"), ("earthshine", "s--")):  # what a study is for: error against time
        s = [r for r in res["summary"] if r["path"] == path_name and r["max_abs_relative_error"] > 0]
        axes[2].loglog([r["mean_seconds_per_phase"] for r in s], [r["max_abs_relative_error"] for r in s], mark,
                       label=path_name)
        for r in s:  # (the two paths' labels on either side of their points)
            axes[2].annotate(f"{r['facets']:,}", (r["mean_seconds_per_phase"], r["max_abs_relative_error"]),
                             fontsize=6, textcoords="offset points", xytext=(-34, 4) if mark[0] == "o" else (4, -9))
    axes[2].axhline(1e-3, color="k", ls="--", lw=0.8)
    axes[2].set_xlabel("run time per phase [s] (labels: facets)")
    axes[2].set_ylabel("max |relative error|")
    axes[2].set_title("error against run time")
    axes[2].grid(alpha=0.3, which="both")
    axes[2].legend(fontsize=7)
    for path_name, ax in zip(("moonshine", "earthshine"), axes):
        # (the finest mesh, when it is the reference, has no error of its own: not drawn)
        s = [r for r in res["summary"] if r["path"] == path_name and r["max_abs_relative_error"] > 0]
        facets = [r["facets"] for r in s]
        ax.loglog(facets, [r["max_abs_relative_error"] for r in s], "o-",
                  label="max |error| over phases, BRDFs")
        for x, r in zip(facets, s):
            if r["observed_order"] is not None and r["observed_order"] > 0:  # (a negative one: not yet asymptotic)
                ax.annotate(f"p={r['observed_order']:.1f}", (x, r["max_abs_relative_error"]), fontsize=7,
                            textcoords="offset points", xytext=(4, 4))
        ax.axhline(1e-3, color="k", ls="--", lw=0.8, label="0.1 % target")
        ax.set_xlabel(f"{res['settings'].get('body', 'moon')} facets")
        ax.set_ylabel("relative error vs " + ("exact reference" if "exact" in res["settings"]["reference"]
                                              else "finest mesh"))
        ax.set_title(f"{path_name}: {res['settings'].get('body', 'moon')} {res['settings'].get('shape', 'sphere')}, "
                     f"{res['settings']['shading']} shading")
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7)
    from matplotlib.ticker import NullFormatter
    for ax in axes:  # (decades only: the minor labels of a short log axis overlap)
        ax.xaxis.set_minor_formatter(NullFormatter())
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)
