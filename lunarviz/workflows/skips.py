"""Tasks that need no computing: a date whose Moon sends nothing to the detector, and its rows.

A date is skipped, in every method, when no lunar point can reach the detector or be lit:

* the whole Moon is below a site's horizon plane, or behind the Earth from a detector outside it
  (:meth:`~lunarviz.geometry.scene_geometry.SceneGeometry.moon_wholly_hidden`, with margins that
  cover the packaged Earth icosphere's facets, level 3 and finer). Every method hides a lunar
  point the Earth or the horizon hides, with or without ``occlusion``;
* the whole Moon is in the Earth's umbra
  (:meth:`~lunarviz.geometry.scene_geometry.SceneGeometry.moon_wholly_in_umbra`): the ray tracer
  with ``occlusion`` (the analytic and reference methods have no cast shadows, and their eclipsed
  Moon is lit).

Such a task's rows are exact zeros (bound 0): moonshine and earthshine 0, the ratio and the
albedos undefined (NaN), and ``skip_reason`` says why. A user's Earth mesh is not the sphere the
tests assume: its dates are computed (a site's horizon still skips them); so are a user's Moon
mesh's (it may reach beyond the nominal sphere), and a user's Sun mesh's eclipses.
"""

from __future__ import annotations

import math

from lunarviz.geometry.scene_geometry import SceneGeometry
from lunarviz.photometry.moon_polarisation import stokes_fields
from lunarviz.workflows.spectral_phase import solar_at_moon

#: the ``skip_reason`` values
BELOW_HORIZON = "the Moon is below the horizon"
BEHIND_EARTH = "the Earth hides the Moon"
ECLIPSED = "the Moon is wholly in the Earth's umbra"


def skip_reason(scene, sc: SceneGeometry) -> str:
    """Why task ``sc`` of ``scene`` (a :class:`~lunarviz.scene.resolved.ResolvedScene`) needs no
    computing, or ``""``: only dates (the θ scene's rows are the paper's, computed whatever they
    are)."""
    if scene.times is None or scene.moon_mesh is not None:  # (a user's Moon may reach beyond the sphere)
        return ""
    if sc.horizon_normal is not None and sc.moon_wholly_hidden():
        return BELOW_HORIZON
    packaged_earth = scene.earth_mesh is None and (scene.earth_level is None or scene.earth_level >= 3)
    if not packaged_earth:
        return ""
    if sc.horizon_normal is None and sc.moon_wholly_hidden():
        return BEHIND_EARTH
    if scene.method == "raytrace" and scene.occlusion and scene.sun_mesh is None and sc.moon_wholly_in_umbra():
        return ECLIPSED
    return ""


def skipped_rows(scene, sc: SceneGeometry, base: dict, reason: str) -> list[dict]:
    """The rows of a skipped task: one per BRDF (and wavelength or band), zeros with bound 0."""
    req = scene.spectral_request()
    suffix = "_W_m2" if req is None else req.value_suffix
    labels = [None] if req is None else list(req.labels)
    label_field = None if req is None else ("wavelength_nm" if req.kind == "wavelength" else "band")
    solar = None if req is None else solar_at_moon(req, sc)
    method = {"method": scene.method}
    if scene.method == "raytrace":
        method["estimator"] = scene.estimator
    rows = []
    for brdf in scene.brdfs:
        for label in labels:
            row = {**base, "brdf": brdf, **method}
            if label_field is not None:
                row[label_field] = label
                row[f"solar_irradiance{suffix}"] = float(solar[labels.index(label)])
            row.update({f"moonshine{suffix}": 0.0, f"earthshine{suffix}": 0.0,
                        "ratio_earthshine_moonshine": math.nan, "earth_visible_lit_albedo": math.nan,
                        "geometric_albedo_term": math.nan, "apparent_albedo": math.nan,
                        "seconds": 0.0, "rtol": 0.0, "no_bound_reason": "", "skip_reason": reason})
            if scene.stokes and req is not None:  # no light: Q = U = 0, no degree or angle of polarisation
                row.update({k: float(v) for k, v in stokes_fields(0.0, 0.0, suffix, sc).items()})
            rows.append(row)
    return rows
