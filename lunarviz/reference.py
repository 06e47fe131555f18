"""The exact reference for the ray tracer: extended Sun, extended Earth, finite distances.

Same physics as the ray tracer on perfect spheres, integrated by nested product Gauss rules
(:mod:`lunarviz.sphere_quadrature`):

* outer: the lunar sphere seen by the detector, cut at the edges of the band where the source
  is partly below the horizon (``n·(S - M) = R_M ± ρ``, exact plane conditions);
* inner: for every lunar node x, the source sphere's surface seen from x and above x's horizon
  (and, for the Earth, lit by the Sun), in polar coordinates about the sub-x point — where the
  opposition-surge cusp sits when the detector is at the Earth's centre, so the integrand is
  smooth in those coordinates.

The Sun is a Lambertian emitting sphere of radiance ``L = Φ/(4π² R_S²)``; the Earth a Lambertian
reflector of albedo A lit by a point Sun (the Sun's 0.27° extent moves the Earth's terminator by a
penumbra whose effect on the Earth's light is O(ρ²) ≈ 2e-5; neglected here and in the ray
tracer). No occlusion between bodies (compare with the ray tracer's ``--no-occlusion``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .analytic import DetectorIrradiance, lunar_surface_rule
from .geometry import Scene, half_angle_sin_cos, unit
from .sphere_quadrature import cap_rule
from .transport import Transport, detector_geometry


@dataclass(frozen=True)
class ReferenceSettings:
    outer_order: int = 24
    inner_order: int = 8
    earth_albedo: float = 0.3
    chunk: int = 256


def sun_radiance(scene: Scene) -> float:
    """Radiance of the Sun's surface [W m⁻² sr⁻¹]: exitance Φ/(4πR²) = πL."""
    return scene.phi / (4 * np.pi**2 * scene.radii["sun"] ** 2)


def reference_transports(scene: Scene, path: str, settings: ReferenceSettings = ReferenceSettings()):
    """Yield :class:`Transport` chunks for ``path`` in {"moonshine", "earthshine"}."""
    body = {"moonshine": "sun", "earthshine": "earth"}[path]
    src = {"sun": scene.sun, "earth": scene.earth}[body]
    x, n, dA = lunar_surface_rule(scene, src, scene.radii[body], settings.outer_order)
    mu, geom, o = detector_geometry(x, n, dA, scene.det, scene.det_normal)
    for a in range(0, len(x), settings.chunk):
        sl = slice(a, a + settings.chunk)
        xs, ns = x[sl], n[sl]
        c = src
        R = scene.radii[body]
        xc = xs - c
        dxc = np.linalg.norm(xc, axis=1)
        caps_u = [ns]
        caps_c = [np.einsum("ij,ij->i", xc, ns) / R]
        if body == "earth":
            caps_u.append(np.broadcast_to(unit(scene.sun - c), ns.shape))
            caps_c.append(np.full(len(ns), R / np.linalg.norm(scene.sun - c)))
        m, w = cap_rule(xc / dxc[:, None], R / dxc, np.stack(caps_u, 1), np.stack(caps_c, 1),
                        n_t=settings.inner_order, n_phi=settings.inner_order)
        y = c + R * m
        v = y - xs[:, None, :]
        r = np.linalg.norm(v, axis=2)
        om = v / r[..., None]
        cos_y = np.clip(-np.einsum("bmj,bmj->bm", m, om), 0.0, None)
        if body == "sun":
            L = sun_radiance(scene)
        else:
            vs = scene.sun - y
            ds = np.linalg.norm(vs, axis=2)
            mu_s = np.clip(np.einsum("bmj,bmj->bm", m, vs) / ds, 0.0, None)
            L = settings.earth_albedo / np.pi * scene.phi / (4 * np.pi * ds**2) * mu_s
        e_beam = L * cos_y * R * R * w / r**2
        mu0 = np.clip(np.einsum("bmj,bj->bm", om, ns), 0.0, 1.0)
        sh, ch = half_angle_sin_cos(om, o[sl][:, None, :])
        yield Transport(mu0=mu0, sin_hg=sh, cos_hg=ch, e_beam=e_beam, mu=mu[sl], geom=geom[sl])


def reference_irradiance(scene: Scene, brdfs: dict, settings: ReferenceSettings = ReferenceSettings(),
                         paths=("moonshine", "earthshine")) -> dict[str, DetectorIrradiance]:
    """Converged detector irradiance [W m⁻²] with extended Sun and Earth, for each BRDF."""
    tot = {k: {"moonshine": 0.0, "earthshine": 0.0} for k in brdfs}
    for path in paths:
        for tr in reference_transports(scene, path, settings):
            for k, b in brdfs.items():
                tot[k][path] += tr.detector_irradiance(b)
    return {k: DetectorIrradiance(v["moonshine"], v["earthshine"]) for k, v in tot.items()}
