"""Phase sweeps: one independent, picklable task per phase, mapped through an executor.

Every task computes the BRDF-independent transport once and shades every requested BRDF,
so a sweep over three BRDFs costs one trace per phase. Tasks run in local worker processes
(``workers``) so a distributed executor (e.g. Dask's ``Client.map``) can take the same
:func:`run_phase` calls when a study outgrows one machine.
"""

from __future__ import annotations

import math
import multiprocessing
import os
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from lunarviz.errors import LunarvizError, unknown_choice
from lunarviz.methods import accuracy
from lunarviz.methods.analytic import analytic_irradiance
from lunarviz.methods.reference import reference_irradiance
from lunarviz.options import EXECUTORS
from lunarviz.parsing import wavelength_label
from lunarviz.photometry import albedo_inversion as alb
from lunarviz.scene import ResolvedScene
from lunarviz.scene.tolerance import warn_loose_rows, warn_unbounded_rows
from lunarviz.workflows.earth_own_albedos import run_earth_albedos
from lunarviz.surfaces.earth_spectra import components, grey_albedos
from lunarviz.workflows.skips import skip_reason, skipped_rows
from lunarviz.workflows.spectral_phase import spectral_rows, warn_unpolarised_rows


def run_phase(settings: ResolvedScene, key, threads: int | None = None) -> list[dict]:
    """All rows (one per BRDF) for one task: a phase θ [deg], or a UTC time with ``times``.
    Pure function of its arguments (``threads``, the trace's threads, changes no number)."""
    t0 = time.perf_counter()
    sc, fields = settings.task(key)
    base = {**fields, "alpha_deg": sc.alpha_deg, "beta_deg": sc.beta_deg}
    reason = skip_reason(settings, sc)
    if reason:  # nothing of the Moon reaches the detector, or nothing of it is lit: nothing to compute
        rows = skipped_rows(settings, sc, base, reason)
        for r in rows:
            r["seconds"] = (time.perf_counter() - t0) / len(rows)
        return rows
    if settings.spectral_request() is not None:
        return spectral_rows(settings, sc, base, threads)
    brdfs = settings.brdf_models()
    rows = []
    # point-source calibration (lunar terms of Eq. 15, and the point-vs-extended comparison):
    # converged grid, correct Lambert-sphere Earth law
    # (an inversion assumes a uniform Earth of earth_albedo: a mapped Earth never calibrates its
    # own inversion; the lunar map, which an observer knows, stays)
    a0 = settings.earth_albedo
    uniform = settings.earth_uniform

    def model_es(es, es_unit):
        """Earthshine of the model Earth (uniform albedo a0) on the same transport."""
        return es if uniform else a0 * es_unit
    cal_settings = settings.point_calibration_settings()
    point = None if settings.method == "raytrace" else analytic_irradiance(sc, brdfs, cal_settings)
    if settings.method == "analytic":
        res = point if settings.analytic_settings() == cal_settings else \
            analytic_irradiance(sc, brdfs, settings.analytic_settings())
        bound, why = settings.analytic_row_bound()
        for k, v in res.items():
            cal = point[k]
            rows.append({**base, "brdf": k, "method": "analytic",
                         "moonshine_W_m2": v.moonshine_W_m2, "earthshine_W_m2": v.earthshine_W_m2,
                         "earth_visible_lit_albedo": v.earth_visible_lit_albedo,
                         "_terms": alb.lunar_terms(sc, model_es(cal.earthshine_W_m2, cal.earthshine_unit_W_m2),
                                                   cal.moonshine_W_m2, a0)})
    elif settings.method == "reference":
        why = settings.unmodelled_reason()
        bound = math.nan if why else settings.reference_orders()[2]
        why = why or ("" if math.isfinite(bound) else "no error model row for these reference orders")
        res = reference_irradiance(sc, brdfs, settings.reference_settings())
        for k, v in res.items():
            pt = point[k]
            rows.append({**base, "brdf": k, "method": "reference",
                         "moonshine_W_m2": v.moonshine_W_m2, "earthshine_W_m2": v.earthshine_W_m2,
                         "earth_visible_lit_albedo": v.earth_visible_lit_albedo,
                         "earthshine_point_source_W_m2": pt.earthshine_W_m2,
                         "_terms": alb.lunar_terms(sc, model_es(v.earthshine_W_m2, v.earthshine_unit_W_m2),
                                                   v.moonshine_W_m2, a0),
                         "_terms_point": alb.lunar_terms(sc, model_es(pt.earthshine_W_m2, pt.earthshine_unit_W_m2),
                                                         pt.moonshine_W_m2, a0)})
    else:
        rows, (bound, why) = _traced_rows(settings, sc, base, brdfs, cal_settings, model_es, threads)
    dt = time.perf_counter() - t0
    pole = settings.earth_pole_at_zero_phase()
    for r in rows:
        es_, ms_ = r["earthshine_W_m2"], r["moonshine_W_m2"]
        # a ratio of round-off (no measurable sunlit Moon: new Moon, eclipse, occultation) is no ratio
        measurable = ms_ > 0 and alb.lunar_terms(sc, 0.0, ms_, settings.earth_albedo).pb_fb > alb.MIN_LUNAR_TERM
        r["ratio_earthshine_moonshine"] = es_ / ms_ if measurable else float("nan")
        pe = alb.geometric_albedo_term(sc, es_, ms_, r.pop("_terms"))
        r["geometric_albedo_term"] = pe
        r["apparent_albedo"] = alb.apparent_albedo(sc.beta_deg, pe)
        if "_terms_point" in r:
            pp = alb.geometric_albedo_term(sc, es_, ms_, r.pop("_terms_point"))
            r["apparent_albedo_point_source_inversion"] = alb.apparent_albedo(sc.beta_deg, pp)
            pt_es = r["earthshine_point_source_W_m2"]
            pt_terms = alb.lunar_terms(sc, pt_es, ms_, settings.earth_albedo)
            r["extended_over_point_earthshine"] = es_ / pt_es \
                if pt_es > 0 and pt_terms.pa_fa > alb.MIN_LUNAR_TERM else float("nan")
        r["seconds"] = dt / len(rows)
        r["rtol"], r["no_bound_reason"] = accuracy.row_bound(r.pop("_bound", bound), sc, settings.method,
                                                             settings.estimator, brdfs[r["brdf"]],
                                                             r.pop("_why", why), pole)
        r["skip_reason"] = ""
    return rows


def _traced_rows(settings: ResolvedScene, sc, base: dict, brdfs: dict, cal_settings, model_es, threads):
    """The ray tracer's rows of one task (before the inversion's fields) and their bound. The
    point-source calibration (``cal_settings``) runs on the mapped lune rule the trace used where it
    used one (:meth:`~lunarviz.methods.tracer.lunar_sampling.LunarSampling.mapped_rule_used`: the
    map's cells exact in its weights), else on the analytic grid."""
    from lunarviz.methods.tracer.estimators import TraceScene, trace_path
    a0 = settings.earth_albedo
    rows = []
    grey = None
    if settings.traced_earth_mapped():  # a mapped Earth's components and their grey albedos
        earth = settings.earth_model()
        grey = {c: grey_albedos(earth)[c] for c in components(earth)}
    # once per task: the settings and the bounds both come from it (beside a mapped Earth, its
    # part expected on this date sets the earthshine's lunar-side tolerance)
    expect = grey is not None and settings.estimator == "deterministic"  # (Monte Carlo's plan takes its rays alone)
    level, part = settings.expected_mapped_level(sc, grey) if expect else (None, None)
    plan = settings.trace_plan(sc.theta_deg, part, level)
    ts_set = settings.trace_settings(threads, plan)
    ts = TraceScene(sc, ts_set)
    ms = trace_path(ts, "moonshine", brdfs)
    es = trace_path(ts, "earthshine", brdfs)
    bound = accuracy.traced_bound(plan["bounds"], ts, ms, es, settings.unmodelled_reason())
    paths = accuracy.traced_path_bounds(plan["bounds"], ts)[0] \
        if grey is not None and ts_set.estimator == "deterministic" and math.isfinite(bound[0]) else {}
    mapped = bool(paths)  # (then the mapped Earth's part of the earthshine's bound, row by row)
    rules = {b: r for b in ("sun", "earth") if (r := ts.sampling.mapped_rule_used(b)) is not None}
    point = analytic_irradiance(sc, brdfs, cal_settings, rules=rules)
    if ts_set.estimator == "deterministic" and ts_set.earth_mesh is None:
        cal_ms = ms.mean
        cal_es = {k: model_es(es.mean[k], es.mean_unit[k]) for k in brdfs}
    else:
        # lunar terms from a deterministic transport of the same scene with the *model*
        # Earth (the nominal Lambert sphere): the Earth is what the inversion measures, so a
        # user's Earth mesh must not calibrate its own inversion (that is an identity)
        dts = TraceScene(sc, accuracy.calibration_settings(ts_set, settings.moon_level is not None,
                                                           settings.mapped_moon()))
        cal_ms = trace_path(dts, "moonshine", brdfs).mean
        cal_es = trace_path(dts, "earthshine", brdfs).mean
    for k in brdfs:
        row = {**base, "brdf": k, "method": "raytrace", "estimator": ts_set.estimator,
               "moonshine_W_m2": ms.mean[k], "earthshine_W_m2": es.mean[k],
               "earth_visible_lit_albedo": es.mean[k] / es.mean_unit[k] if es.mean_unit[k] else float("nan"),
               "earthshine_point_source_W_m2": point[k].earthshine_W_m2,
               "_terms": alb.lunar_terms(sc, cal_es[k], cal_ms[k], settings.earth_albedo),
               "_terms_point": alb.lunar_terms(sc, model_es(point[k].earthshine_W_m2,
                                                            point[k].earthshine_unit_W_m2),
                                               point[k].moonshine_W_m2, a0),
               "rays": ms.rays + es.rays}
        if mapped:
            row["_bound"], row["_why"] = settings.mapped_earth_row_bound(
                plan, paths, brdfs[k], grey, es.mean_unit[k], es.mean[k], sc.theta_deg)
        if ts_set.estimator == "montecarlo":
            row["moonshine_std_W_m2"] = ms.std[k]
            row["earthshine_std_W_m2"] = es.std[k]
            row["moonshine_sem_W_m2"] = ms.sem[k]
            row["earthshine_sem_W_m2"] = es.sem[k]
            row["runs"] = ts_set.runs
            row["rays_per_run"] = ts_set.rays
        rows.append(row)
    return rows, bound


def _run_phase_star(args):
    return run_phase(*args, threads=1)  # one of several worker processes: one thread each


def bond_table(rows: list[dict], key: str = "apparent_albedo") -> dict:
    """``{brdf: {method: Bond albedo}}`` from rows' apparent albedo (corrected Eq. 17)."""
    out: dict = {}
    groups: dict = {}
    for r in rows:
        if key in r:
            groups.setdefault((r["brdf"], r["method"], spectral_label(r)), []).append(r)
    for (b, m, lab), rs in groups.items():
        beta = np.array([r["beta_deg"] for r in rs])
        ps = np.array([np.nan if r[key] is None else r[key] for r in rs], dtype=float)
        if lab is None:
            out.setdefault(b, {})[m] = alb.bond_albedo(beta, ps)
        else:  # a spectral run: one per wavelength or band
            out.setdefault(b, {}).setdefault(m, {})[lab] = alb.bond_albedo(beta, ps)
    return out


def spectral_label(row: dict) -> str | None:
    """A spectral row's wavelength (as text, e.g. ``"550"``, 12 significant digits) or band name;
    ``None`` for a grey row."""
    if "wavelength_nm" in row:
        return wavelength_label(row["wavelength_nm"])
    return row.get("band")


def worker_count(requested: int | None, tasks: int, method: str = "raytrace") -> int:
    """Worker processes actually started: at most one per task and one per core (``requested``
    is an upper bound, never a count to fork blindly; ``None``: one per core, or one for the
    analytic method, whose tasks take milliseconds)."""
    cores = os.cpu_count() or 1
    if requested is None:
        return 1 if method == "analytic" else max(1, min(tasks, cores))
    return max(1, min(int(requested), tasks, cores))


def dask_client(scheduler: str | None, workers: int | None):
    """A Dask client: to ``scheduler`` (an address such as tcp://host:8786), or to a new local
    cluster of ``workers`` single-threaded processes (closed with the client)."""
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise LunarvizError("--executor dask needs the optional packages dask and distributed: "
                            "pip install 'lunarviz[dask]'") from None
    if scheduler:
        try:
            _refused_at_once(scheduler)
            return Client(scheduler, timeout="10s"), None
        except (OSError, TimeoutError) as exc:
            raise LunarvizError(f"cannot reach the Dask scheduler at {scheduler!r}: {exc}") from None
    cluster = LocalCluster(n_workers=min(workers or os.cpu_count() or 1, os.cpu_count() or 1), threads_per_worker=1,
                           processes=True, dashboard_address=None)
    return Client(cluster), cluster


def _refused_at_once(address: str) -> None:
    """Raise ``OSError`` where a ``tcp://HOST:PORT`` scheduler address refuses a connection: a
    closed port answers at once, where Dask's client would retry until its timeout."""
    import socket
    from urllib.parse import urlsplit
    if not address.startswith("tcp://"):
        return
    try:
        parts = urlsplit(address)
        host, port = parts.hostname, parts.port
    except ValueError:  # not HOST:PORT: Dask's client says what is wrong with it
        return
    if host is None or port is None:
        return
    with socket.create_connection((host, port), timeout=10):
        pass


def run_sweep(settings: ResolvedScene, workers: int | None = None, progress: bool = False,
              executor: str = "local", scheduler: str | None = None) -> dict:
    """Run every phase or time; returns ``{"settings", "rows", "bond_albedo", ...}``.

    ``executor="local"``: worker processes of this machine (``workers``). ``"dask"``: the same
    :func:`run_phase` tasks on a Dask distributed cluster (``scheduler`` address, or a local
    cluster of ``workers``). Tasks carry only the settings and the key; each worker builds its
    Embree scenes itself and caches them (``tracer.bodies``), nothing Embree is pickled. The
    rows are identical whichever executor runs them.
    """
    if executor not in EXECUTORS:
        raise unknown_choice("executor", executor, EXECUTORS)
    if scheduler is not None and executor != "dask":
        raise LunarvizError("--scheduler goes with --executor dask")
    phases = settings.tasks()
    settings.warn_unmet_tolerance()
    t0 = time.perf_counter()
    if executor == "dask":
        client, cluster = dask_client(scheduler, None if workers is None else min(workers, len(phases)))
        try:
            futures = client.map(run_phase, [settings] * len(phases), phases, threads=1, pure=False)
            results = client.gather(futures)
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
        return _assemble(settings, results, t0)
    workers = worker_count(workers, len(phases), settings.method)
    bar = None
    if progress:
        from tqdm import tqdm
        bar = tqdm(total=len(phases), desc=f"{settings.method} sweep", unit="time" if settings.times else "phase",
                   leave=False)
    results = []
    if workers <= 1:
        for th in phases:
            results.append(run_phase(settings, th))
            if bar:
                bar.update()
    else:
        _warm_before_fork(settings)
        # the costliest phases first (thin crescents, θ near 180°, refine their lune) so that no
        # worker is left with one at the end; rows come back in the sweep's order
        order = list(range(len(phases)))
        if not settings.times:
            order.sort(key=lambda i: abs(float(phases[i]) - 180.0))  # (θ in [0, 360]: both crescents)
        results = [None] * len(phases)
        ex = ProcessPoolExecutor(workers, initializer=_worker_init)
        # dates go to the workers in runs of consecutive times (one message per run, and each
        # worker's caches serve neighbouring dates); phases one by one, costliest first
        chunk = 1 if not settings.times else max(1, min(32, len(phases) // (workers * 8)))
        try:
            for i, res in zip(order, ex.map(_run_phase_star, [(settings, phases[i]) for i in order], chunksize=chunk)):
                results[i] = res
                if bar:
                    bar.update()
        except BaseException:  # an error, Ctrl-C or SIGTERM: end the workers now, not after their tasks
            _quiet_pool_teardown()
            ex.shutdown(wait=False, cancel_futures=True)
            for proc in multiprocessing.active_children():
                proc.terminate()
            raise
        ex.shutdown(wait=True)
    if bar:
        bar.close()
    return _assemble(settings, results, t0)


def _quiet_pool_teardown() -> None:
    """Ending a pool whose futures were just cancelled races the pool's manager thread, which
    may then set an exception on a cancelled future and print InvalidStateError's traceback
    (CPython's concurrent.futures, fixed in later versions): that thread's report is dropped, so
    an interrupted run still ends in one line."""
    import threading
    from concurrent.futures import InvalidStateError
    previous = threading.excepthook

    def hook(args):
        if not issubclass(args.exc_type, InvalidStateError):
            previous(args)
    threading.excepthook = hook


def _worker_init() -> None:
    """In a worker: SIGTERM ends it at once, silently (the parent ends its workers that way), and
    BLAS runs on one thread: each worker is one of ``cpu_count`` single-threaded processes, and
    OpenBLAS's own threads (one per core by default) fought the other workers for the cores (a
    mapped Moon's dates, whose weights are GEMMs: 1.47 s a date on 2 workers, 0.94 s with one
    BLAS thread each; docs: accuracy, "Dates in bulk")."""
    import signal
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    from threadpoolctl import threadpool_limits
    threadpool_limits(1)


def _warm_before_fork(settings: ResolvedScene) -> None:
    """Import the tracer and load the compiled kernels in this process before the worker
    pool starts: forked workers inherit both instead of each paying ~1.5 s for them (a third
    of a 2-worker paper sweep's start-up; no Embree object is made here, so nothing
    thread-bound crosses the fork). Harmless where workers are spawned instead. Dates: the
    ephemeris kernels and the observer too (the first date's geometry), so a worker's first
    skipped date costs milliseconds like the others (~0.06-0.1 s cold)."""
    if settings.times is not None:
        settings.task(settings.times[0])
        settings.spectral_request()
    if settings.method != "raytrace":
        return
    from lunarviz.methods.tracer import estimators, ray_kernels  # noqa: F401 (the import is the warm-up)
    ray_kernels.warm_up()


def _assemble(settings: ResolvedScene, results: list, t0: float) -> dict:
    rows = [r for res in results for r in res]
    warn_unbounded_rows(rows)
    warn_loose_rows(settings, rows)
    warn_unpolarised_rows(rows)
    alb.warn_non_lambert_apparent_albedo(rows)
    out = {"settings": settings.to_dict(), "rows": rows, "bond_albedo": bond_table(rows),
           **run_earth_albedos(settings), "wall_seconds": time.perf_counter() - t0}
    if any("apparent_albedo_point_source_inversion" in r for r in rows):
        out["bond_albedo_point_source_inversion"] = bond_table(rows, "apparent_albedo_point_source_inversion")
    return out
