"""The paper's small-scale BRDF ray-tracing test (Sec. 3.1; paper notes, item 9), with embreex.

A collimated "grid source" of radius 0.5 m at incidence i = 75° lights a circular target plane
of radius 2.5 m (the target's centre is 10 m from the source); a detector disk of radius 0.5 m
at 200 m from the target's centre, facing it, moves in 5° zenith steps through the plane of
incidence on both sides (azimuth 0: the source's side; 180: the far side). Rays from a square
grid over the source disk are traced against the triangulated target with Embree; every hit
sends next-event beams to a Gauss rule over the detector disk. The BRDF is recovered as

    BRDF_rec = P_det / (E_target · A_lit · cos e · Ω_det)        (E_target · A_lit = Φ_beam)

and compared with Eq. 12 averaged over the lit footprint and the detector aperture
(``brdf_expected_per_sr``, an independent product-Gauss quadrature that shares no code with the
tracer) and with Eq. 12 at the nominal angles (``brdf_eq12_per_sr``): near exact backscatter
the opposition surge is narrower than the aperture, so a finite detector does not see the
nominal value. Neglected: the source disk's shadow on the detector near backscatter (the
paper's set-up ignores it too), diffraction.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lunarviz.geometry.scene_geometry import half_angle_sin_cos, unit
from lunarviz.photometry.brdf import brdf_from_angles

INCIDENCE_DEG = 75.0
SOURCE_RADIUS_M = 0.5
TARGET_RADIUS_M = 2.5
SOURCE_DISTANCE_M = 10.0
DETECTOR_RADIUS_M = 0.5
DETECTOR_DISTANCE_M = 200.0


@dataclass(frozen=True)
class BrdfTestSettings:
    grid: int = 160  # source grid points across the beam diameter
    detector_order: int = 8  # Gauss order (radial × 2·order azimuthal) on the detector disk
    reference_order: int = 24
    emissions_deg: tuple = tuple(float(e) for e in range(0, 90, 5))
    azimuths_deg: tuple = (0.0, 180.0)


def _disk_mesh(radius: float, segments: int = 256):
    import trimesh
    ang = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    v = np.vstack([[0.0, 0.0, 0.0], np.c_[radius * np.cos(ang), radius * np.sin(ang), np.zeros(segments)]])
    f = np.array([[0, 1 + k, 1 + (k + 1) % segments] for k in range(segments)])
    return trimesh.Trimesh(v, f, process=False)


def _disk_rule(order: int):
    """Gauss rule on the unit disk: points (n, 2), weights summing to π."""
    x, w = np.polynomial.legendre.leggauss(order)
    r2 = 0.5 * (x + 1.0)  # uniform in r² (area)
    wr = 0.5 * w
    nphi = 2 * order
    phi = (np.arange(nphi) + 0.5) * 2 * np.pi / nphi
    R, P = np.meshgrid(np.sqrt(r2), phi, indexing="ij")
    W = np.repeat(wr[:, None], nphi, axis=1) * (2 * np.pi / nphi) * 0.5  # dA = ½ d(r²) dφ
    return np.c_[(R * np.cos(P)).ravel(), (R * np.sin(P)).ravel()], W.ravel()


def _geometry(e_deg, az_deg):
    i = np.radians(INCIDENCE_DEG)
    d_in = -np.array([np.sin(i), 0.0, np.cos(i)])  # travelling toward the target; source at +x
    e, a = np.radians(e_deg), np.radians(az_deg)
    # azimuth 0 = the source's side (+x), 180 = the far side
    det_dir = np.array([np.sin(e) * np.cos(a), np.sin(e) * np.sin(a), np.cos(e)])
    return d_in, det_dir


def _detector_points(det_dir, order):
    pts, w = _disk_rule(order)
    c = det_dir * DETECTOR_DISTANCE_M
    helper = np.array([0.0, 1.0, 0.0]) if abs(det_dir[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    e1 = unit(np.cross(det_dir, helper))
    e2 = np.cross(det_dir, e1)
    P = c + DETECTOR_RADIUS_M * (pts[:, :1] * e1 + pts[:, 1:] * e2)
    return P, w * DETECTOR_RADIUS_M**2, -det_dir  # detector normal faces the target centre


def _detector_power(model, hits, hit_w, d_in, det_dir, order):
    """Power [W per W of beam] reaching the detector from hit points (n,3) with beam weights."""
    P, dA, n_det = _detector_points(det_dir, order)
    n_t = np.array([0.0, 0.0, 1.0])
    s = -d_in  # toward the source
    mu0 = float(np.dot(n_t, s))
    total = 0.0
    for a in range(0, len(hits), 4096):
        h = hits[a:a + 4096]
        v = P[None, :, :] - h[:, None, :]
        r2 = np.einsum("ijk,ijk->ij", v, v)
        o = v / np.sqrt(r2)[..., None]
        mu = o[..., 2]
        cos_det = -np.einsum("ijk,k->ij", o, n_det)
        sh, ch = half_angle_sin_cos(np.broadcast_to(s, o.shape), o)
        f = model.brdf(np.full(mu.shape, mu0), mu, sh, ch)
        # irradiance on the target per unit beam power is 1/A_lit; a hit of weight w carries
        # w·A_lit of area, so E·dA = w (beam power fraction)
        total += float(np.sum(hit_w[a:a + 4096, None] * f * mu * cos_det * dA[None, :] / r2))
    return total


def _omega_det():
    return 2 * np.pi * (1 - np.cos(np.arctan(DETECTOR_RADIUS_M / DETECTOR_DISTANCE_M)))


def trace_beam(settings: BrdfTestSettings):
    """Trace the grid source against the target with Embree; hit points and beam weights."""
    from lunarviz.methods.tracer.embree_bodies import EmbreeBody
    i = np.radians(INCIDENCE_DEG)
    d_in = _geometry(0.0, 0.0)[0]
    target = EmbreeBody(_disk_mesh(TARGET_RADIUS_M), [0.0, 0.0, 0.0], threads=1)
    # square grid of ray origins over the source disk (the paper's "grid source")
    g = (np.arange(settings.grid) + 0.5) / settings.grid * 2 - 1
    X, Y = np.meshgrid(g, g)
    inside = X**2 + Y**2 <= 1.0
    X, Y = X[inside] * SOURCE_RADIUS_M, Y[inside] * SOURCE_RADIUS_M
    e1 = np.array([np.cos(i), 0.0, -np.sin(i)])  # ⟂ beam, in the plane of incidence
    e2 = np.array([0.0, 1.0, 0.0])
    centre = -d_in * SOURCE_DISTANCE_M
    origins = centre + X[:, None] * e1 + Y[:, None] * e2
    dirs = np.broadcast_to(d_in, origins.shape)
    hits = target.intersect(origins, dirs)
    w = np.full(int(hits.hit.sum()), 1.0 / inside.sum())  # equal share of the beam power
    return hits.point[hits.hit], w, int(len(origins))


def expected_brdf(model, e_deg, az_deg, order=24):
    """Eq. 12 averaged over the lit footprint and the detector aperture, without ray tracing.

    Written apart from the tracer's path (:func:`_detector_power`): a product Gauss rule over
    the footprint ellipse and over the detector disk, each pair's incidence, emission and
    relative azimuth computed as angles and the BRDF evaluated by :func:`brdf_from_angles`
    (Eq. 12 in its angle form). Shared with the recovered value: only the BRDF formula itself,
    checked against a textbook implementation (docs: the notes on the paper).
    """
    i = np.radians(INCIDENCE_DEG)
    e0, a0 = np.radians(e_deg), np.radians(az_deg)
    det_c = DETECTOR_DISTANCE_M * np.array([np.sin(e0) * np.cos(a0), np.sin(e0) * np.sin(a0), np.cos(e0)])
    # detector disk: centre det_c, normal toward the target's centre, radius DETECTOR_RADIUS_M
    x, w = np.polynomial.legendre.leggauss(order)
    rr = np.sqrt(0.5 * (x + 1))  # Gauss in r² (area)
    ang = (np.arange(2 * order) + 0.5) * np.pi / order
    RR, AA = np.meshgrid(rr, ang, indexing="ij")
    WW = np.repeat(0.5 * w[:, None], 2 * order, axis=1) * (np.pi / order) * 0.5
    up = np.array([0.0, 0.0, 1.0]) if abs(np.cos(e0)) < 0.99 else np.array([1.0, 0.0, 0.0])
    f1 = np.cross(det_c, up)
    f1 /= np.linalg.norm(f1)
    f2 = np.cross(det_c / DETECTOR_DISTANCE_M, f1)
    P = det_c + DETECTOR_RADIUS_M * ((RR * np.cos(AA)).reshape(-1, 1) * f1 + (RR * np.sin(AA)).reshape(-1, 1) * f2)
    dA = (WW * DETECTOR_RADIUS_M**2).reshape(-1)
    # footprint of the uniform circular beam on z = 0: (x / cos i, y), equal power per area
    Fx = (RR * np.cos(AA)).reshape(-1) * SOURCE_RADIUS_M / np.cos(i)
    Fy = (RR * np.sin(AA)).reshape(-1) * SOURCE_RADIUS_M
    fw = (WW.reshape(-1) / np.pi)  # fraction of the beam power
    v = P[None, :, :] - np.stack([Fx, Fy, np.zeros_like(Fx)], axis=1)[:, None, :]  # (foot, det, 3)
    r = np.linalg.norm(v, axis=2)
    cos_e = v[..., 2] / r
    emission = np.arccos(np.clip(cos_e, -1, 1))
    azimuth = np.arctan2(v[..., 1], v[..., 0])  # source on +x: azimuth 0 is the source's side
    f = brdf_from_angles(model, np.full(r.shape, i), emission, azimuth)
    cos_det = np.einsum("fdj,j->fd", v, det_c) / (r * DETECTOR_DISTANCE_M)
    power = float(np.sum(fw[:, None] * f * cos_e * cos_det * dA[None, :] / r**2))
    return power / (np.cos(e0) * _omega_det())


def run_brdf_test(models: dict, settings: BrdfTestSettings = BrdfTestSettings()) -> dict:
    """``{name: {"max_relative_error", "rows": [...]}}`` (rows: one per detector position)."""
    hits, hw, n_rays = trace_beam(settings)
    out = {}

    def row(model, az, e):
        d_in, det_dir = _geometry(e, az)
        p = _detector_power(model, hits, hw, d_in, det_dir, settings.detector_order)
        rec = p / (np.cos(np.radians(e)) * _omega_det())
        exp = expected_brdf(model, e, az, settings.reference_order)
        nominal = float(brdf_from_angles(model, np.radians(INCIDENCE_DEG), np.radians(e), np.radians(az)))
        return {"emission_deg": e, "azimuth_deg": az, "brdf_recovered_per_sr": rec,
                "brdf_expected_per_sr": exp, "brdf_eq12_per_sr": nominal,
                "relative_error": rec / exp - 1, "relative_error_vs_nominal": rec / nominal - 1}
    from concurrent.futures import ThreadPoolExecutor

    from lunarviz.methods.tracer.embree_bodies import default_threads
    # the detector positions on the machine's cores (numpy's array work releases the GIL); rows in order
    with ThreadPoolExecutor(default_threads()) as ex:
        for name, model in models.items():
            rows = list(ex.map(lambda a: row(model, *a), [(az, e) for az in settings.azimuths_deg
                                                           for e in settings.emissions_deg]))
            out[name] = {"max_relative_error": max(abs(r["relative_error"]) for r in rows),
                         "max_relative_error_vs_nominal": max(abs(r["relative_error_vs_nominal"]) for r in rows),
                         "rays": n_rays, "rows": rows}
    return out
