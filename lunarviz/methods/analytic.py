"""The paper's finite-element analytic method (Sec. 2.2, Eqs. 4-11), with point sources.

The Sun is a point of power Φ (Eq. 6-7), the Earth a point source with the Lambert-sphere
intensity of :mod:`lunarviz.photometry.earth_phase` (Eq. 8 corrected, paper notes item 1), the Moon a sphere whose
surface elements see both at their true finite distances. The detector irradiance is the sum
over surface elements of BRDF · μ0 · E · μ · cosδ · dA / d² (Eqs. 10-11).

Two surface rules:

* ``grid="converged"`` (default): product Gauss rules over the part of the lunar sphere seen by
  the detector, cut at the lit boundary (:mod:`lunarviz.geometry.sphere_quadrature`); converged to
  < 1e-6 relative at ``order=24`` (the documentation's validation page shows the convergence).
* ``grid="paper"``: the paper's grid of Eq. 4, latitude φ and longitude δ in
  [-85°, 85°] about the sub-Earth point at ``paper_step_deg`` spacing; it misses the limb
  zones beyond 85°, which is its truncation error (shown by ``lunarviz sweep --grid paper``).

Neglected physics: occlusion between bodies (the paper ignores it; see the ray tracer),
the Sun's and Earth's angular extent (see :mod:`lunarviz.methods.reference`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lunarviz.errors import LunarvizError
from lunarviz.geometry.scene_geometry import SceneGeometry, angle_between, half_angle_sin_cos, unit
from lunarviz.geometry.sphere_quadrature import cap_rule, compact
from lunarviz.methods.transport import Transport, detector_geometry
from lunarviz.options import BY_NAME, compose, group, validate
from lunarviz.photometry.earth_phase import earth_intensity
from lunarviz.surfaces.physical_earth import albedo_toward_moon


@dataclass(frozen=True)
@compose("analytic", names=("earth_albedo",))
class AnalyticSettings:
    """The analytic method's settings: the options of the schema's ``analytic`` group
    (:mod:`lunarviz.options`: ``grid``, ``order``, ``earth_law``) and ``earth_albedo``, with the
    order resolved, and:"""

    #: the Gauss order of the lunar surface rule (resolved: the schema's ``None`` is the tolerance's choice)
    order: int = 24
    #: the paper grid's step [deg] (``grid="paper"``)
    paper_step_deg: float = 1.0
    #: lunar albedo map and Earth surface (:class:`lunarviz.surfaces.point_values.Surfaces`), read at the
    #: lunar nodes; the point Earth takes the albedo its lit face shows the Moon's centre
    surfaces: object = None

    def __post_init__(self):
        validate(self, group("analytic") + (BY_NAME["earth_albedo"],))
        if self.order is None:
            raise LunarvizError("analytic order=None: give an integer in [2, 512]")
        if not (0 < self.paper_step_deg <= 85):
            raise LunarvizError(f"paper grid step {self.paper_step_deg!r} deg must be in (0, 85]")


def lunar_surface_rule(scene: SceneGeometry, source: np.ndarray, source_radius: float = 0.0,
                       order: int = 24, view_cut: bool = True):
    """Points, normals and areas [m²] on the lunar sphere: seen by the detector, lit by a source.

    For ``source_radius = 0`` the region is cut at ``n·(S - M) > R_M`` (lit by a point); for an
    extended source the rule extends to ``R_M - ρ`` and is split at ``R_M + ρ`` (the edges of
    the band where the source is partly below the horizon). Where the detector's view of the
    Moon is cut (a site's horizon plane, or the Earth's limb seen from outside the Earth), the
    rule is cut there too (:func:`hidden_view_cut`; unless ``view_cut`` is False): every node is
    in sight of the detector.
    """
    M, R = scene.moon, scene.radii["moon"]
    to_det = scene.det - M
    d_det = np.linalg.norm(to_det)
    if d_det <= R:
        raise LunarvizError("the detector is inside the Moon")
    to_src = source - M
    d_src = np.linalg.norm(to_src)
    u = to_src / d_src
    if source_radius > 0:
        caps_u = np.array([[u, u]])
        caps_c = np.array([[(R - source_radius) / d_src, (R + source_radius) / d_src]])
        split = np.array([[False, True]])
    else:
        caps_u, caps_c, split = np.array([[u]]), np.array([[R / d_src]]), None
    static, ring = hidden_view_cut(scene) if view_cut else (None, None)
    if static is not None:
        caps_u = np.concatenate([caps_u, static[0].reshape(1, 1, 3)], axis=1)
        caps_c = np.concatenate([caps_c, [[static[1]]]], axis=1)
        split = None if split is None else np.concatenate([split, [[False]]], axis=1)
    # (a horizon's cap crosses the source's: the rule is cut at the rings through the crossings)
    nodes, w = cap_rule(unit(to_det)[None, :], [R / d_det], caps_u, caps_c, split, order, order,
                        crossings=static is not None, ring_cap=ring, near_pole=ring is not None or static is not None)
    n, w = compact(nodes[0], w[0])
    return M + R * n, n, w * R * R


def hidden_view_cut(scene: SceneGeometry):
    """The cut of the lunar sphere where the detector's sight lines end: ``(static, ring)``.

    A site sees what lies above its horizon plane: ``(x - D)·h > 0`` with x = M + R_M n is the
    cap ``n·h > (D - M)·h / R_M`` (``static``: ``(h, c)``). From outside the Earth, x is hidden
    where the sight line enters the Earth's model sphere, ``(x - D)·ê > |x - D| cos α`` (ê toward
    the Earth's centre, ``sin α = R_E / |E - D|``): no circle on the lunar sphere, but on each ring
    at polar angle t about the sub-detector point ``|x - D|² = d² - 2 R_M d cos t + R_M²`` is fixed,
    so the visible part of the ring is ``n·(-ê) > -(|x - D| cos α + (D - M)·ê) / R_M``: a cap whose
    threshold depends on t (``ring``: ``(-ê, c(t))``, :func:`~lunarviz.geometry.sphere_quadrature.cap_rule`'s
    ``ring_cap``). Either is ``None`` where it does not cut the Moon's disc: the detector at or
    in the Earth, the Earth's disc clear of the Moon's, or covering it whole (the sight-line tests
    then hide every point, as they hide every point of a Moon set)."""
    M, R = scene.moon, scene.radii["moon"]
    to_det = scene.det - M
    d = float(np.linalg.norm(to_det))
    if scene.horizon_normal is not None:
        h = unit(np.asarray(scene.horizon_normal, dtype=float))
        c = float(np.dot(to_det, h)) / R
        return ((h, c) if -1.0 < c < 1.0 else None), None
    if scene.detector_inside("earth"):
        return None, None
    w = scene.earth - scene.det
    dw, Re = float(np.linalg.norm(w)), scene.radii["earth"]
    rho, alpha = np.arcsin(min(1.0, R / d)), np.arcsin(min(1.0, Re / dw))
    gap = angle_between(M - scene.det, w)
    if gap >= rho + alpha or gap <= alpha - rho:
        return None, None
    e = w / dw
    cos_a = np.sqrt(max(0.0, 1.0 - (Re / dw) ** 2))
    de = float(np.dot(to_det, e))

    def threshold(t):
        return -(np.sqrt(d * d - 2.0 * R * d * np.cos(t) + R * R) * cos_a + de) / R
    return None, (-e, threshold)


def paper_grid(scene: SceneGeometry, step_deg: float = 1.0):
    """The paper's surface elements, Eq. 4: φ, δ ∈ [-85°, 85°] about the sub-Earth point.

    Element area R² cos φ Δφ Δδ (a full-weight rectangle rule; the paper does not say more).
    """
    R = scene.radii["moon"]
    th = np.radians(scene.theta_deg)
    ang = np.radians(np.arange(-85.0, 85.0 + 1e-9, step_deg))
    phi, delta = np.meshgrid(ang, ang, indexing="ij")
    phi, delta = phi.ravel(), delta.ravel()
    if scene.general:
        # the same grid about the sub-Earth point: φ across and δ along the Sun-Earth-Moon plane
        u = unit(scene.moon - scene.earth)
        x = np.cross(scene.sun - scene.earth, u)
        x = unit(x) if np.linalg.norm(x) > 0 else unit(np.cross(u, [0.0, 0.0, 1.0]))
        v = np.cross(u, x)
        c = np.cos(phi)[:, None]
        n = -(np.sin(phi)[:, None] * x + c * (np.cos(delta)[:, None] * u + np.sin(delta)[:, None] * v))
    else:
        n = -np.stack([np.sin(phi), np.cos(phi) * np.sin(th + delta), np.cos(phi) * np.cos(th + delta)], axis=1)
    dA = R * R * np.cos(phi) * np.radians(step_deg) ** 2
    return scene.moon + R * n, n, dA


def _point_source_transport(scene: SceneGeometry, x, n, dA, source, e_normal) -> Transport:
    v = source[None, :] - x
    s = unit(v)
    mu0 = np.einsum("ij,ij->i", n, s)
    mu, geom, o = detector_geometry(x, n, dA, scene.det, scene.det_normal)
    geom = np.where(scene.sight_lines_clear(x), geom, 0.0)  # the Earth occulting the Moon (real sky)
    sh, ch = half_angle_sin_cos(s, o)
    lit = mu0 > 0
    return Transport(mu0=np.clip(mu0, 0, 1)[:, None], sin_hg=sh[:, None], cos_hg=ch[:, None],
                     e_beam=np.where(lit, e_normal, 0.0)[:, None], mu=mu, geom=geom)


def moonshine_transport(scene: SceneGeometry, settings: AnalyticSettings = AnalyticSettings(),
                        rule: tuple | None = None) -> Transport:
    """Sun → Moon → detector with a point Sun (paper Eq. 6, 10, 11); on ``rule`` (see
    :func:`analytic_irradiance`) where given."""
    if rule is not None:
        x, n, dA = rule[:3]
    elif settings.grid == "paper":
        x, n, dA = paper_grid(scene, settings.paper_step_deg)
    else:
        x, n, dA = lunar_surface_rule(scene, scene.sun, 0.0, settings.order)
    tr = _point_source_transport(scene, x, n, dA, scene.sun, scene.solar_irradiance_at(x))
    return _with_moon_map(tr, scene, x, settings, rule)


def _with_moon_map(tr: Transport, scene: SceneGeometry, x, settings: AnalyticSettings,
                   rule: tuple | None = None) -> Transport:
    """The lunar map on ``tr``: read at the nodes x, or ``rule``'s map weights (its AlbedoNodes)."""
    sf = settings.surfaces
    if sf is not None and sf.moon_map is not None:
        if rule is not None:
            tr.albedo_nodes = (rule[3].values, rule[3].factors)
        else:
            tr.albedo = sf.moon_values_at(scene, x)
        tr.albedo_absolute = sf.moon_map.absolute
    return tr


def earthshine_transport(scene: SceneGeometry, settings: AnalyticSettings = AnalyticSettings(),
                         rule: tuple | None = None) -> Transport:
    """Sun → Earth → Moon → detector with a point Earth of Lambert-sphere intensity (Eq. 7-9); on
    ``rule`` (see :func:`analytic_irradiance`) where given."""
    if rule is not None:
        x, n, dA = rule[:3]
    elif settings.grid == "paper":
        x, n, dA = paper_grid(scene, settings.paper_step_deg)
    else:
        x, n, dA = lunar_surface_rule(scene, scene.earth, 0.0, settings.order)
    E = scene.earth
    d2 = np.sum((x - E) ** 2, axis=1)
    beta = angle_between(x - E, np.broadcast_to(scene.sun - E, x.shape))  # Kahan: exact near π
    e_in = scene.phi / (4 * np.pi * scene.d_se_actual**2)  # Eq. 7
    unit_intensity = earth_intensity(beta, 1.0, scene.radii["earth"], e_in, settings.earth_law)
    sf = settings.surfaces
    if sf is None:
        albedo = settings.earth_albedo
    elif sf.earth.physical:  # the disc integral of the classes' reflectance toward the Moon
        albedo = float(albedo_toward_moon(sf, scene, [sf.earth.wavelength_nm])[0])
    else:
        albedo = sf.earth_albedo_toward(scene, scene.moon)
    tr = _point_source_transport(scene, x, n, dA, E, albedo * unit_intensity / d2)
    tr.e_beam_unit = np.where(tr.mu0 > 0, (unit_intensity / d2)[:, None], 0.0)  # lit: μ0 > 0, as e_beam
    return _with_moon_map(tr, scene, x, settings, rule)


@dataclass(frozen=True)
class DetectorIrradiance:
    """Moonshine and earthshine irradiance at the detector [W m⁻²]."""

    moonshine_W_m2: float
    earthshine_W_m2: float
    #: earthshine for an Earth of albedo 1 [W m⁻²] (the weights of ``earth_visible_lit_albedo``)
    earthshine_unit_W_m2: float | None = None

    @property
    def earth_visible_lit_albedo(self) -> float:
        """The Earth's albedo as the earthshine weights it: earthshine over its unit-albedo value."""
        u = self.earthshine_unit_W_m2
        return self.earthshine_W_m2 / u if u else float("nan")


def analytic_irradiance(scene: SceneGeometry, brdfs: dict, settings: AnalyticSettings = AnalyticSettings(),
                        rules: dict | None = None) -> dict[str, DetectorIrradiance]:
    """Moonshine and earthshine at the detector for each named BRDF (one transport each).

    ``rules`` ({"sun": rule, "earth": rule}, optional): each path's lunar rule, ``(x, n, dA,
    AlbedoNodes)`` of :func:`lunarviz.geometry.mapped_lune.mapped_lune_rule`, in place of the
    settings' grid: the mapped lune rule of the ray tracer's extended source, whose region holds
    the point source's (its lit cap reaches past the point's terminator by the source's
    angular radius; the point-source integrand is 0 there) and whose weights hold the map's cells
    exactly, where the nodes of ``order`` read the map at points (3e-3 at order 96)."""
    rules = rules or {}
    ms = moonshine_transport(scene, settings, rules.get("sun"))
    es = earthshine_transport(scene, settings, rules.get("earth"))
    return {k: DetectorIrradiance(ms.detector_irradiance(b), *es.detector_irradiances(b))
            for k, b in brdfs.items()}
