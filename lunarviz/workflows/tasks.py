"""One task of a resolved scene (a phase θ or a date), computed by the methods it needs: per-facet
arrays, a camera image, what a view shows.

Each function takes a :class:`~lunarviz.scene.resolved.ResolvedScene` and hands the methods their
own typed inputs (the task's geometry, the tracer's settings, the BRDF models, the spectral inputs).
"""

from __future__ import annotations

from dataclasses import replace

from lunarviz.methods.analytic import analytic_irradiance
from lunarviz.methods.camera import Camera, ImageResult, synthesize
from lunarviz.methods.tracer.facet_result import FacetResult
from lunarviz.methods.tracer.facets import sample_ray_paths, trace_facets
from lunarviz.methods.tracer.settings import PICTURE_TRACE, QUICK_TRACE
from lunarviz.photometry import albedo_inversion as alb
from lunarviz.viz.view_data import ViewData


def facets(scene, key, brdf: str | None = None, trace_scene=None, quick: bool | str = False) -> FacetResult:
    """Per-facet arrays of task ``key`` (θ [deg] or a UTC time) for every BRDF of ``scene``
    (:func:`lunarviz.methods.tracer.facets.trace_facets`); the unsuffixed ones for ``brdf``;
    ``quick``: with :data:`QUICK_TRACE` (True) or :data:`PICTURE_TRACE` (``"picture"``)."""
    geometry, fields = scene.task(key)
    settings = scene.trace_settings()
    if quick:
        settings = replace(settings, **(PICTURE_TRACE if quick == "picture" else QUICK_TRACE))
    return trace_facets(geometry, fields, settings, scene.brdf_models(), brdf, trace_scene)


def image(scene, key, camera: Camera, request=None, trace_scene=None) -> ImageResult:
    """The camera image of task ``key`` for every BRDF of ``scene`` (and its bands or wavelengths;
    ``request``: a :class:`~lunarviz.spectral.request.SpectralRequest` in their place)."""
    geometry, fields = scene.task(key)
    return synthesize(geometry, fields, scene.trace_settings(), scene.brdf_models(), camera,
                      scene.spectral_inputs(request), trace_scene)


def view_data(scene, key, brdf: str, quick: bool | str = False) -> ViewData:
    """Trace task ``key`` with ``brdf`` and collect everything a view shows (``quick``: as for
    :func:`facets`)."""
    scene = replace(scene, brdfs=(brdf,))
    fr = facets(scene, key, brdf, quick=quick)
    sc, fields = scene.task(key)
    ms, es = fr.totals["moonshine_W_m2"], fr.totals["earthshine_W_m2"]
    model = scene.brdf_models()
    pt = analytic_irradiance(sc, model, scene.point_calibration_settings())[brdf]
    # inversions assume the uniform model Earth of earth_albedo (as the sweep's rows): a mapped
    # Earth never calibrates its own inversion; both terms come from unit-albedo transports
    a0 = scene.earth_albedo
    uniform = scene.earth_uniform
    pt_model = pt.earthshine_W_m2 if uniform else a0 * pt.earthshine_unit_W_m2
    es_model = es if uniform else a0 * fr.totals["earthshine_unit_W_m2"]
    terms_pt = alb.lunar_terms(sc, pt_model, pt.moonshine_W_m2, a0)
    terms = alb.lunar_terms(sc, es_model, ms, a0)
    numbers = {
        **fields, "theta_deg": sc.theta_deg, "alpha_deg": sc.alpha_deg, "beta_deg": sc.beta_deg, "brdf": brdf,
        "method": f"raytrace ({fr.info['estimator']}, occlusion {'on' if fr.info['occlusion'] else 'off'})",
        "moonshine_W_m2": ms, "earthshine_W_m2": es,
        "ratio": es / ms if ms > 0 else float("nan"),
        "apparent_albedo": alb.apparent_albedo(sc.beta_deg, alb.geometric_albedo_term(sc, es, ms, terms)),
        "apparent_albedo_point_inversion": alb.apparent_albedo(
            sc.beta_deg, alb.geometric_albedo_term(sc, es, ms, terms_pt)),
        "point_source_earthshine_W_m2": pt.earthshine_W_m2,
        "rays": fr.totals["rays"],
        "earth_visible_lit_albedo": fr.totals.get("earth_visible_lit_albedo", float("nan")),
        "error_note": "deterministic, at the tolerance's settings: a sweep's rtol gives the bound (docs: accuracy)"
        if fr.info["estimator"] == "deterministic" else "Monte Carlo: see std in sweep",
    }
    return ViewData(fr, sample_ray_paths(sc, scene.trace_settings(), n=10), numbers)
