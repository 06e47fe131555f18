"""Per-facet results of one task, ray traced: the arrays of
:class:`~lunarviz.methods.tracer.facet_result.FacetResult` (its module lists them), and a few
sample light paths for the views."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from lunarviz.geometry.scene_geometry import SceneGeometry, angle_between, half_angle_sin_cos, unit
from lunarviz.methods.sources import earth_radiance
from lunarviz.methods.tracer import settings as tuning
from lunarviz.methods.tracer.facet_result import FacetResult
from lunarviz.methods.tracer.settings import TraceSettings
from lunarviz.surfaces.moon_map import map_scale

if TYPE_CHECKING:
    from lunarviz.methods.tracer.trace_scene import TraceScene


def trace_facets(geometry: SceneGeometry, fields: dict, trace: TraceSettings, brdfs: dict,
                 brdf_name: str | None = None, trace_scene: TraceScene | None = None) -> FacetResult:
    """Ray trace one task and return per-facet arrays.

    Parameters
    ----------
    geometry : SceneGeometry
        The task's bodies and detector (positions [m]).
    fields : dict
        The task's row fields (time, distances, flags), copied into ``info``.
    trace : TraceSettings
        The tracer's settings.
    brdfs : dict
        ``{name: BRDF}``: ``<path>_radiance_W_m2_sr_<brdf>`` for each.
    brdf_name : str, optional
        The BRDF of the unsuffixed radiance/contribution arrays (default: the first).
    trace_scene : TraceScene, optional
        The traced scene of ``geometry`` and ``trace``, when the caller has it.

    Returns
    -------
    FacetResult
        Moon facets also carry ``solar_lit_fraction`` and ``earth_lit_fraction``: the share of
        the incident irradiance that survives shadowing by the Moon itself and by the other
        bodies (1 on a facet no shadow touches; 0 where the facet is not lit at all). Earth
        facets carry ``radiance_toward_moon_W_m2_sr`` (Lambertian: the same in every direction),
        ``sun_visibility`` (the Moon's shadow) and ``earthshine_beam_hits``; Sun facets
        ``moonshine_beam_hits``.
    """
    from lunarviz.methods.tracer.estimators import TraceScene, trace_path  # Embree: loaded to trace
    models = brdfs
    brdf_name = brdf_name or next(iter(models))
    sc = geometry
    ts = trace_scene or TraceScene(sc, trace)
    M = ts.moon
    ms = trace_path(ts, "moonshine", models, keep_facets=True)
    es = trace_path(ts, "earthshine", models, keep_facets=True)
    cd = {}
    f = {**ms.facets, **es.facets}
    for path in ("moonshine", "earthshine"):
        geom = f[f"{path}_geom"]
        for k in models:
            contrib = f[f"{path}_contribution_{k}"]
            cd[f"{path}_radiance_W_m2_sr_{k}"] = np.where(geom > 0, contrib / np.where(geom > 0, geom, 1), 0.0)
        cd[f"{path}_contribution_W_m2"] = f[f"{path}_contribution_{brdf_name}"]
        cd[f"{path}_radiance_W_m2_sr"] = cd[f"{path}_radiance_W_m2_sr_{brdf_name}"]
        cd[f"{path}_rays"] = f[f"{path}_rays"]
    cd["solar_irradiance_W_m2"] = f["moonshine_irradiance"]
    cd["earth_irradiance_W_m2"] = f["earthshine_irradiance"]
    for path, name in (("moonshine", "solar_lit_fraction"), ("earthshine", "earth_lit_fraction")):
        lit, free = f[f"{path}_lit_sum"], f[f"{path}_free_sum"]
        cd[name] = np.where(free > 0, lit / np.where(free > 0, free, 1), 0.0)
    model = models[brdf_name]
    amap, values = ts.settings.moon_map(), ts.surfaces.moon_facet_albedo()
    if values is None:
        alb = None
        cd["albedo_parameter"] = np.full(M.n_faces, model.albedo_parameter)
    else:
        alb = values * map_scale(amap.absolute, model)
        cd["albedo_parameter"] = alb
    cd.update(_facet_angles_and_brdf(ts, sc, model, alb))
    cd["reflectance_factor"] = np.pi * cd["brdf_per_sr"]
    totals = {"moonshine_W_m2": ms.mean[brdf_name], "earthshine_W_m2": es.mean[brdf_name],
              "rays": ms.rays + es.rays, "seconds": ms.seconds + es.seconds}
    for k in models:
        totals[f"moonshine_W_m2_{k}"] = ms.mean[k]
        totals[f"earthshine_W_m2_{k}"] = es.mean[k]
    u = es.mean_unit.get(brdf_name, 0.0)
    totals["earthshine_unit_W_m2"] = u  # the same transport for an Earth of albedo 1
    totals["earth_visible_lit_albedo"] = es.mean[brdf_name] / u if u else float("nan")
    info = {**fields, "theta_deg": sc.theta_deg, "alpha_deg": sc.alpha_deg, "beta_deg": sc.beta_deg,
            "brdf": brdf_name, "brdfs": list(models), "moon_centre_m": sc.moon.tolist(),
            "detector_m": sc.det.tolist(), "sun_m": sc.sun.tolist(), "earth_m": sc.earth.tolist(),
            "estimator": ts.settings.estimator, "occlusion": ts.settings.occlusion,
            "self_shadow": ts.settings.self_shadow, "shading": ts.settings.shading,
            "moon_shading_mode": M.mode(ts.settings.shading),
            "moon_albedo_map": ts.settings.moon_albedo_map, "earth_surface": ts.settings.earth_surface,
            "clouds": ts.settings.clouds}
    bodies = _other_bodies(ts, sc)
    # the Moon's mesh is returned in its own body frame (MOON_ME on dates; the scene axes in
    # the θ scene), so it lines up with the user's mesh and maps; the rotation to the scene
    # is kept in ``info`` (the .vtm multiblock applies it)
    rot = sc.rotation("moon")
    verts = M.vertices.copy() if rot is None else M.vertices @ rot
    if rot is not None:
        info["moon_rotation_body_to_scene"] = rot.tolist()
    return FacetResult(verts, M.faces.copy(), cd, totals, info, bodies)


def _facet_angles_and_brdf(ts, sc, model, alb) -> dict:
    """Per-facet angles at the centroid [deg] and the BRDF there [sr⁻¹] for sunlight and
    earthlight, computed in blocks of facets (a few dozen (F, 3) temporaries would take 1 GB at 5 M
    facets)."""
    M = ts.moon
    cd = {}
    names = ("incidence_deg", "emission_deg", "phase_deg", "earth_incidence_deg", "earth_phase_deg",
             "brdf_per_sr", "earth_brdf_per_sr")
    for name in names:
        cd[name] = np.empty(M.n_faces)
    normals = M.normals_for(ts.settings.shading)
    for a in range(0, M.n_faces, tuning.FACET_BLOCK):
        b = slice(a, min(M.n_faces, a + tuning.FACET_BLOCK))
        x = M.centroids_local[b] + M.centre
        n = normals[b]
        s_dir, e_dir, o_dir = unit(sc.sun - x), unit(sc.earth - x), unit(sc.det - x)
        cd["incidence_deg"][b] = np.degrees(angle_between(n, s_dir))
        cd["emission_deg"][b] = np.degrees(angle_between(n, o_dir))
        cd["phase_deg"][b] = np.degrees(angle_between(s_dir, o_dir))
        cd["earth_incidence_deg"][b] = np.degrees(angle_between(n, e_dir))
        cd["earth_phase_deg"][b] = np.degrees(angle_between(e_dir, o_dir))
        ab = None if alb is None else alb[b]
        mu0 = np.clip(np.einsum("ij,ij->i", n, s_dir), 0, 1)
        mu = np.clip(np.einsum("ij,ij->i", n, o_dir), 0, 1)
        sh, ch = half_angle_sin_cos(s_dir, o_dir)
        cd["brdf_per_sr"][b] = np.where((mu0 > 0) & (mu > 0), model.brdf(mu0, mu, sh, ch, albedo=ab), 0.0)
        mu0e = np.clip(np.einsum("ij,ij->i", n, e_dir), 0, 1)
        she, che = half_angle_sin_cos(e_dir, o_dir)
        cd["earth_brdf_per_sr"][b] = np.where((mu0e > 0) & (mu > 0), model.brdf(mu0e, mu, she, che, albedo=ab), 0.0)
    return cd


def _other_bodies(ts, sc) -> dict:
    """The Earth's and the Sun's meshes with their per-facet arrays."""
    E, S = ts.earth, ts.sun
    xe, ne = E.facet_points(ts.settings.shading)
    vis = ts.sources.sun_visibility_of_earth()
    fa = ts.surfaces.earth_facet_albedo()
    fa = np.full(E.n_faces, ts.surfaces.earth_albedo_value()) if fa is None else fa
    earth_cd = {"radiance_toward_moon_W_m2_sr": earth_radiance(sc, xe, ne, 1.0) * fa * vis,
                "albedo": fa, "sun_visibility": vis, "earthshine_beam_hits": ts.source_hits["earth"].copy()}
    L_sun = ts.sources.sun_surface_radiance()
    sun_cd = {"radiance_W_m2_sr": np.full(S.n_faces, L_sun),
              "moonshine_beam_hits": ts.source_hits["sun"].copy()}
    bodies = {"earth": (E.vertices.copy(), E.faces.copy(), earth_cd),
              "sun": (S.vertices.copy(), S.faces.copy(), sun_cd)}
    return bodies


def sample_ray_paths(geometry: SceneGeometry, trace: TraceSettings, n: int = 12, seed: int = 0) -> dict:
    """A few representative light paths as polylines (world coordinates [m]).

    ``moonshine``: Sun surface → lunar point → detector; ``earthshine``: Sun → Earth surface
    → lunar point → detector. Lunar points are drawn among lit, visible facets ∝ area.
    """
    from lunarviz.methods.tracer.trace_scene import TraceScene  # Embree: loaded to trace
    rng = np.random.default_rng(seed)
    sc = geometry
    ts = TraceScene(sc, trace)
    M = ts.moon
    out = {}
    for path, body in (("moonshine", "sun"), ("earthshine", "earth")):
        cand = ts.sampling.candidates(body)
        c = {"sun": sc.sun, "earth": sc.earth}[body]
        x = M.centroids[cand]
        lit = np.einsum("ij,ij->i", M.normals_for(trace.shading)[cand], unit(c - x)) > 0
        cand = cand[lit]
        if cand.size == 0:
            out[path] = []
            continue
        pick = rng.choice(cand, size=min(n, cand.size), replace=False, p=M.areas[cand] / M.areas[cand].sum())
        lines = []
        for fidx in pick:
            xm = M.centroids[fidx]
            if body == "sun":
                src = sc.sun + sc.radii["sun"] * unit(xm - sc.sun + rng.normal(size=3) * sc.radii["sun"] * 0.3)
                lines.append(np.array([src, xm, sc.det]))
            else:
                # a point on the Earth's lit, visible side, then the Sun behind it
                for _ in range(50):
                    m = unit(xm - sc.earth + rng.normal(size=3) * sc.radii["earth"] * 1.5)
                    y = sc.earth + sc.radii["earth"] * m
                    if np.dot(m, unit(sc.sun - y)) > 0 and np.dot(m, unit(xm - y)) > 0:
                        break
                src = sc.sun + sc.radii["sun"] * unit(y - sc.sun)
                lines.append(np.array([src, y, xm, sc.det]))
        out[path] = lines
    return out
