"""One task of a spectral sweep: trace once, shade every node wavelength, write a row per wavelength
or band and BRDF.

The transports are the grey run's (analytic, or ray traced with either estimator); the rows'
values are :class:`~lunarviz.spectral.request.SpectralRequest` outputs of the node irradiances of
:class:`~lunarviz.spectral.shading.SpectralShader`. Each row's apparent albedo is Eq. 15-16 with
lunar terms at its own wavelength (or band: solar-weighted over it), from a calibration transport
of the model Earth (uniform, ``earth_albedo``) as in the grey run. The Earth's spectral albedo
enters through its components (:mod:`lunarviz.surfaces.earth_spectra`). Monte Carlo rows carry the mean
over runs, without the per-wavelength standard deviations of the grey rows.
"""

from __future__ import annotations

import math
import time
import warnings

import numpy as np

from lunarviz.errors import UnpolarisedRowsWarning
from lunarviz.methods import accuracy
from lunarviz.methods.analytic import earthshine_transport, moonshine_transport
from lunarviz.photometry import albedo_inversion as alb
from lunarviz.photometry import moon_polarisation
from lunarviz.spectral.shading import SpectralShader, spectral_brdfs
from lunarviz.surfaces.earth_spectra import spectral_components, weights_toward
from lunarviz.surfaces.physical_earth import albedo_toward_moon


def _earthshine_nodes(parts: np.ndarray, albedo: np.ndarray | None, uniform_albedo: float):
    """(earthshine, unit-albedo earthshine) at the nodes from a shader's (P + 1, L) sums:
    ``Σ_c A_c(λ) E_c`` with the component albedos ``albedo`` (P, L), or the uniform Earth's
    albedo times the unit sums where the transport has no components."""
    unit = parts[-1]
    if albedo is None or parts.shape[0] == 1:
        return uniform_albedo * unit, unit
    return np.sum(albedo * parts[:-1], axis=0), unit


def spectral_rows(settings, sc, base: dict, threads=None) -> list[dict]:
    """All rows of one task (a phase θ or a time, its scene ``sc``) of a spectral run."""
    t0 = time.perf_counter()
    rows = _task_rows(settings, sc, base, threads)
    for r in rows:
        r["seconds"] = (time.perf_counter() - t0) / len(rows)
    return rows


def _task_rows(settings, sc, base: dict, threads) -> list[dict]:
    mapped_bound = None
    req = settings.spectral_request()
    brdfs = settings.brdf_models()
    shader = SpectralShader(spectral_brdfs(settings.spectral_inputs(req), brdfs))
    surface = settings.earth_model()
    mapped = not surface.uniform
    names, albedo = spectral_components(surface, req.nodes, settings.earth_spectra) if mapped else (("uniform",), None)
    a0 = settings.earth_albedo
    extra: dict = {}
    if settings.method == "analytic":
        st = settings.analytic_settings()
        ms = shader.moonshine(moonshine_transport(sc, st))
        es_tr = earthshine_transport(sc, st)
        unit = shader.earthshine(es_tr)  # (1, L): a point Earth of albedo 1
        if mapped:  # the point Earth's components, weighted toward the Moon as its albedo is
            if surface.physical:  # one component per node: the disc's reflectance toward the Moon there
                w = albedo_toward_moon(st.surfaces, sc, req.nodes)
            else:
                w = weights_toward(st.surfaces, sc, sc.moon)
            es = {k: np.concatenate([w[:, None] * u[-1][None, :], u[-1:]]) for k, u in unit.items()}
        else:
            es = unit
        cal_st = settings.point_calibration_settings()
        if cal_st == st:
            cal_ms, cal_es = ms, es
        else:
            cal_ms = shader.moonshine(moonshine_transport(sc, cal_st))
            cal_es = shader.earthshine(earthshine_transport(sc, cal_st))
        uniform_albedo = a0
        method_fields = {"method": "analytic"}
        extra["rtol"], extra["no_bound_reason"] = settings.analytic_row_bound()
    else:
        from lunarviz.methods.tracer.estimators import TraceScene, trace_path
        # once per task: the settings and the bounds both come from it (beside a mapped Earth, its
        # part expected on this date, output by output, sets the earthshine's lunar-side tolerance)
        level, part = settings.expected_mapped_level(sc, dict(zip(names, albedo)), [
            lambda v, o=o: req.averages(v)[o] for o in range(len(req.labels))]) \
            if mapped and settings.traced_earth_mapped() else (None, None)
        plan = settings.trace_plan(sc.theta_deg, part, level)
        ts_set = settings.trace_settings(threads, plan)
        ts = TraceScene(sc, ts_set)
        ts.surfaces.earth_parts = names if mapped else None
        ts.surfaces.earth_part_wavelengths = req.nodes if mapped and surface.physical else None
        ms_r = trace_path(ts, "moonshine", brdfs, spectral=shader)
        es_r = trace_path(ts, "earthshine", brdfs, spectral=shader)
        zeros = np.zeros(len(req.nodes))
        ms = {k: ms_r.spectral.get(k, zeros) for k in brdfs}
        es = {k: es_r.spectral.get(k, np.zeros((len(names) + 1 if mapped else 1, len(req.nodes)))) for k in brdfs}
        uniform_albedo = ts.surfaces.earth_albedo_value()
        if ts_set.estimator == "deterministic" and ts_set.earth_mesh is None:
            cal_ms, cal_es = ms, es
        else:  # the model Earth (the nominal sphere, uniform): as the grey run's calibration
            dts = TraceScene(sc, accuracy.calibration_settings(ts_set, settings.moon_level is not None,
                                                               settings.mapped_moon()))
            cal_m = trace_path(dts, "moonshine", brdfs, spectral=shader).spectral  # one trace each, all BRDFs
            cal_e = trace_path(dts, "earthshine", brdfs, spectral=shader).spectral
            cal_ms = {k: cal_m.get(k, zeros) for k in brdfs}
            cal_es = {k: cal_e.get(k, zeros[None]) for k in brdfs}  # (1, L): the uniform Earth's unit sums
        method_fields = {"method": "raytrace", "estimator": ts_set.estimator}
        extra["rays"] = ms_r.rays + es_r.rays
        extra["rtol"], extra["no_bound_reason"] = accuracy.traced_bound(plan["bounds"], ts, ms_r, es_r,
                                                                        settings.unmodelled_reason())
        paths = accuracy.traced_path_bounds(plan["bounds"], ts)[0] if mapped and settings.traced_earth_mapped() \
            and ts_set.estimator == "deterministic" and math.isfinite(extra["rtol"]) else {}
        if paths:
            mapped_bound = (plan, paths, names)
        if ts_set.estimator == "montecarlo":
            extra.update(runs=ts_set.runs, rays_per_run=ts_set.rays)
    return _rows(settings, sc, base, req, brdfs, ms, es, cal_ms, cal_es, albedo, uniform_albedo, method_fields,
                 extra, mapped_bound)


def solar_at_moon(req, sc) -> np.ndarray:
    """Each output's solar irradiance at the Moon's distance from the Sun (``req.solar_1au`` scaled
    as the grey Sun's irradiance, :attr:`SceneGeometry.phi` over 4π d², is) [W m⁻² nm⁻¹ or W m⁻²]."""
    e_sun_moon = sc.phi / (4.0 * np.pi * sc.d_sm**2)  # the grey Sun at the Moon [W m-2]
    e_sun_1au = sc.phi_sun / (4.0 * np.pi * 1.495978707e11**2)
    return req.solar_1au * (e_sun_moon / e_sun_1au)


def _rows(settings, sc, base, req, brdfs, ms, es, cal_ms, cal_es, albedo, uniform_albedo, method_fields, extra,
          mapped_bound=None):
    """The rows of one task. ``mapped_bound``: ``(plan, path bounds, component names)`` where a traced
    row's earthshine bound takes its mapped Earth's part, output by output
    (:meth:`~lunarviz.scene.resolved.ResolvedScene.mapped_earth_row_bound`: each component's
    albedo-1 earthshine times its albedo, averaged over the output as the earthshine is)."""
    a0 = settings.earth_albedo
    solar_moon = solar_at_moon(req, sc)
    suffix = req.value_suffix
    label_field = "wavelength_nm" if req.kind == "wavelength" else "band"
    pole = settings.earth_pole_at_zero_phase()
    polarised = moon_polarisation_nodes(req, base, sc) if settings.stokes else None
    rows = []
    for k in brdfs:
        bound, why = accuracy.row_bound(extra["rtol"], sc, method_fields["method"], method_fields.get("estimator"),
                                        brdfs[k], extra["no_bound_reason"], pole)
        es_T, esu_T = _earthshine_nodes(es[k], albedo, uniform_albedo)
        ms_o, es_o = req.outputs(ms[k], sc.phi_sun), req.outputs(es_T, sc.phi_sun)
        ms_a, es_a, esu_a = req.averages(ms[k]), req.averages(es_T), req.averages(esu_T)
        cms_a, cesu_a = req.averages(cal_ms[k]), req.averages(cal_es[k][-1])
        row_bounds = [(bound, why)] * len(req.labels)
        if mapped_bound is not None and math.isfinite(bound):
            plan, paths, names = mapped_bound
            albedos = dict(zip(names, albedo))
            row_bounds = [settings.mapped_earth_row_bound(plan, paths, brdfs[k], albedos, es[k][-1], es_a[o],
                                                          sc.theta_deg, average=lambda v, o=o: req.averages(v)[o])
                          for o in range(len(req.labels))]
        stokes = {} if polarised is None else moonshine_stokes(req, polarised, ms[k], ms_o, sc)
        for o, label in enumerate(req.labels):
            bound, why = row_bounds[o]
            terms = alb.lunar_terms(sc, a0 * cesu_a[o], cms_a[o], a0)
            pe = alb.geometric_albedo_term(sc, es_a[o], ms_a[o], terms)
            measurable = ms_o[o] > 0 and alb.lunar_terms(sc, 0.0, ms_a[o], a0).pb_fb > alb.MIN_LUNAR_TERM
            rows.append({**base, "brdf": k, **method_fields, label_field: label,
                         f"moonshine{suffix}": float(ms_o[o]), f"earthshine{suffix}": float(es_o[o]),
                         f"solar_irradiance{suffix}": float(solar_moon[o]),
                         "ratio_earthshine_moonshine": float(es_o[o] / ms_o[o]) if measurable else float("nan"),
                         "earth_visible_lit_albedo": float(es_a[o] / esu_a[o]) if esu_a[o] > 0 else float("nan"),
                         "geometric_albedo_term": pe, "apparent_albedo": alb.apparent_albedo(sc.beta_deg, pe),
                         **{f: v if np.ndim(v) == 0 else float(v[o]) for f, v in stokes.items()},
                         **extra, "rtol": bound, "no_bound_reason": why, "skip_reason": ""})
    return rows


def moon_polarisation_nodes(req, base: dict, sc) -> np.ndarray:
    """The Moon's disc polarisation P at the request's node wavelengths (:mod:`lunarviz.photometry.
    moon_polarisation`: the task's phase angle and branch; NaN outside the model)."""
    return moon_polarisation.disc_polarisation(base["alpha_deg"], req.nodes, moon_polarisation.scene_branch(base))


def moonshine_stokes(req, p_nodes: np.ndarray, ms_nodes: np.ndarray, ms_out: np.ndarray, sc) -> dict:
    """The moonshine's Stokes fields of each output (``--stokes``): Q = −P I node by node, summed over
    a band as I is (so a band's P is its moonshine-weighted mean); NaN for an output that weighs a
    node outside the model. Dated scenes add the scattering plane's position angle on the sky."""
    outside = np.isnan(p_nodes)
    q_out = req.outputs(-np.where(outside, 0.0, p_nodes) * ms_nodes, sc.phi_sun)
    bad = (req.weights[:, outside] > 0).any(axis=1)
    return moon_polarisation.stokes_fields(np.where(bad, np.nan, q_out), ms_out, req.value_suffix, sc)


def warn_unpolarised_rows(rows: list[dict]) -> None:
    """One warning for the computed rows whose Stokes fields are NaN (``--stokes`` outside the
    Moon's polarisation model), with the model's ranges."""
    n = sum(1 for r in rows if "moonshine_dolp" in r and not r.get("skip_reason")
            and not np.isfinite(r["moonshine_dolp"]))
    if n:
        lo, hi = moon_polarisation.PHASE_RANGE_DEG
        wl, wh = moon_polarisation.WAVELENGTH_RANGE_NM
        warnings.warn(f"{n} of {len(rows)} rows carry no polarisation (moonshine_Q, _U, _dolp, _aolp NaN): the Moon's "
                      f"polarisation model covers phase angles {lo:g}-{hi:g} deg and {wl:g}-{wh:g} nm",
                      UnpolarisedRowsWarning, stacklevel=2)
