"""The exact reference for the ray tracer: extended Sun, extended Earth, finite distances.

Same physics as the ray tracer on perfect spheres, integrated by nested product Gauss rules
(:mod:`lunarviz.geometry.sphere_quadrature`):

* outer: the lunar sphere seen by the detector, cut at the edges of the band where the source
  is partly below the horizon (``n·(S - M) = R_M ± ρ``, exact plane conditions);
* inner: for every lunar node x, the source sphere's surface seen from x and above x's horizon
  (and, for the Earth, lit by the Sun), in polar coordinates about the sub-x point — where the
  opposition-surge cusp sits when the detector is at the Earth's centre, so the integrand is
  smooth in those coordinates — or, for a detector off the centre (``earth_pole="detector"``),
  about the zero-phase point itself.

The Sun is a Lambertian emitting sphere of radiance ``L = Φ/(4π² R_S²)``; the Earth a Lambertian
reflector of albedo A lit by a point Sun (the Sun's 0.27° extent moves the Earth's terminator by a
penumbra whose effect on the Earth's light is O(ρ²) ≈ 2e-5; neglected here and in the ray
tracer). No occlusion between bodies (compare with the ray tracer's ``--no-occlusion``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lunarviz.geometry.scene_geometry import SceneGeometry, half_angle_sin_cos
from lunarviz.methods.analytic import DetectorIrradiance, lunar_surface_rule
from lunarviz.methods.sources import (  # noqa: F401 (re-export)
    earth_radiance,
    source_beams,
    source_sphere_rule,
    sun_radiance,
    zero_phase_points,
)
from lunarviz.methods.transport import Transport, detector_geometry
from lunarviz.options import BY_NAME, validate


@dataclass(frozen=True)
class ReferenceSettings:
    """The exact reference's settings (``earth_albedo``: the schema's option, :mod:`lunarviz.options`)."""

    #: the Gauss orders of the lunar surface (outer) and of each source sphere (inner)
    outer_order: int = 24
    inner_order: int = 8
    earth_albedo: float = BY_NAME["earth_albedo"].default
    #: lunar nodes per batch (bounds memory)
    chunk: int = 256
    #: lunar albedo map and Earth surface (:class:`lunarviz.surfaces.point_values.Surfaces`), read at the nodes
    surfaces: object = None
    #: the pole of the Earth's rule: ``centre`` (the sub-x point), ``detector`` (the zero-phase
    #: point, :func:`~lunarviz.methods.sources.zero_phase_points`: a detector off the Earth's centre)
    #: or ``detector-cut`` (that pole, the rule cut along the roughness's kinks too)
    earth_pole: str = "centre"

    def __post_init__(self):
        validate(self, (BY_NAME["earth_albedo"],))


def reference_transports(scene: SceneGeometry, path: str, settings: ReferenceSettings = ReferenceSettings()):
    """Yield :class:`Transport` chunks for ``path`` in {"moonshine", "earthshine"}."""
    body = {"moonshine": "sun", "earthshine": "earth"}[path]
    src = {"sun": scene.sun, "earth": scene.earth}[body]
    x, n, dA = lunar_surface_rule(scene, src, scene.radii[body], settings.outer_order)
    mu, geom, o = detector_geometry(x, n, dA, scene.det, scene.det_normal)
    geom = np.where(scene.sight_lines_clear(x), geom, 0.0)  # the Earth occulting the Moon (real sky)
    pole_rule = body == "earth" and settings.earth_pole != "centre"
    # (the zero-phase rule holds up to ~18·order² nodes a row: batches that bound its memory)
    chunk = max(4, min(settings.chunk, (1 << 15) // settings.inner_order**2)) if pole_rule else settings.chunk
    for a in range(0, len(x), chunk):
        sl = slice(a, a + chunk)
        xs, ns = x[sl], n[sl]
        pole = zero_phase_points(scene, xs) if pole_rule else None
        m, w = source_sphere_rule(scene, xs, ns, body, settings.inner_order, pole=pole,
                                  roughness_cuts=pole_rule and settings.earth_pole == "detector-cut")
        y, om, omega = source_beams(scene, xs, body, m, w)
        sf = settings.surfaces
        L_unit = None
        if body == "sun":
            L = sun_radiance(scene)
        else:
            L_unit = earth_radiance(scene, y, m, 1.0)
            L = L_unit * (settings.earth_albedo if sf is None else sf.earth_albedo_at(scene, y))
        mu0 = np.clip(np.einsum("bmj,bj->bm", om, ns), 0.0, 1.0)
        sh, ch = half_angle_sin_cos(om, o[sl][:, None, :])
        tr = Transport(mu0=mu0, sin_hg=sh, cos_hg=ch, e_beam=L * omega, mu=mu[sl], geom=geom[sl],
                       e_beam_unit=None if L_unit is None else L_unit * omega)
        if sf is not None and sf.moon_map is not None:
            tr.albedo = sf.moon_values_at(scene, xs)
            tr.albedo_absolute = sf.moon_map.absolute
        yield tr


def reference_irradiance(scene: SceneGeometry, brdfs: dict, settings: ReferenceSettings = ReferenceSettings(),
                         paths=("moonshine", "earthshine")) -> dict[str, DetectorIrradiance]:
    """Converged detector irradiance [W m⁻²] with extended Sun and Earth, for each BRDF."""
    tot = {k: {"moonshine": 0.0, "earthshine": 0.0, "unit": 0.0} for k in brdfs}
    for path in paths:
        for tr in reference_transports(scene, path, settings):
            for k, b in brdfs.items():
                e, e1 = tr.detector_irradiances(b)
                tot[k][path] += e
                tot[k]["unit"] += e1 or 0.0
    return {k: DetectorIrradiance(v["moonshine"], v["earthshine"], v["unit"]) for k, v in tot.items()}
