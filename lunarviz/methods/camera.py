"""Synthetic images: what an earthshine camera at the detector records, in radiance units.

A pinhole camera at the detector looks at the Moon (or an RA/Dec). Its image plane is a
gnomonic (TAN) projection with north up and east left (FITS convention, CDELT1 < 0): pixel
(i, j) (0-based column, row; row 0 at the bottom) has intermediate coordinates
ξ = -s (i - c_x), η = s (j - c_y) [rad of the projection plane, s the pixel scale], looks along
d ∝ f + ξ e + η n (f the boresight, e east, n north) and covers the solid angle
Ω = s² / (1 + ξ² + η²)^{3/2}. Each pixel is sampled by K × K stratified sub-pixels.

Every sub-pixel ray is traced with Embree into the Moon mesh (the exact sphere for the
packaged icospheres; facets or smoothed normals for a user's mesh), and also:

* hidden by the Earth (Embree; a site's horizon plane) or by the Moon's own relief, exactly
  as the detector's sight lines of the transport
  (:meth:`~lunarviz.methods.tracer.lunar_sampling.LunarSampling.detector_view`);
* **moonshine**: shaded at the hit with the extended Sun's beams (the transport's Sun rule,
  eclipse and self-shadowing included) for each BRDF — the terminator is smooth;
* **earthshine**: the transport's earthlight (extended Earth, its lit part, shadows) evaluated
  at the mesh's vertices as radiance toward the detector for each BRDF, and interpolated
  linearly to the hit: the earthlit field is smooth, so a few thousand transport points stand
  for the whole image. The camera sits at the detector, so that radiance is the one it records.

The image integrated over the Moon, Σ L Ω cos δ (δ off the boresight), is the detector
irradiance of ``sweep --method raytrace`` (docs: synthetic images, checked at three phases).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lunarviz.errors import LunarvizError
from lunarviz.geometry.scene_geometry import SceneGeometry, unit
from lunarviz.methods.camera_shading import GreyShading, SpectralImageShading
from lunarviz.methods.tracer.settings import TraceSettings
from lunarviz.methods.tracer.trace_scene import TraceScene
from lunarviz.sky.dated_scene import moon_direction_radec
from lunarviz.spectral.shading_inputs import SpectralInputs

MAX_PIXELS = 4096
MAX_SUPERSAMPLE = 16
#: rays per image (the ray arrays take ~150 B per ray: 2^24 rays ≈ 2.5 GB)
MAX_RAYS = 2**24


@dataclass(frozen=True)
class Camera:
    """A pinhole camera at the detector.

    Parameters
    ----------
    fov_deg : float
        Full field of view across the image width [deg], in (0, 180).
    width, height : int
        Pixels (1..4096 each).
    supersample : int
        K: K × K stratified rays per pixel (1..16).
    pointing : str
        ``moon`` (the Moon's centre) or ``RA,DEC`` [deg] in the scene frame (ICRF for dates).
    """

    fov_deg: float = 0.75
    width: int = 256
    height: int = 256
    supersample: int = 4
    pointing: str = "moon"

    def __post_init__(self):
        if not (np.isfinite(self.fov_deg) and 0 < self.fov_deg < 180):
            raise LunarvizError(f"--fov-deg {self.fov_deg!r} must be in (0, 180) degrees")
        for name in ("width", "height"):
            v = getattr(self, name)
            if not (isinstance(v, (int, np.integer)) and 1 <= v <= MAX_PIXELS):
                raise LunarvizError(f"image {name} {v!r} must be an integer from 1 to {MAX_PIXELS} pixels")
        if not (isinstance(self.supersample, (int, np.integer)) and 1 <= self.supersample <= MAX_SUPERSAMPLE):
            raise LunarvizError(f"--supersample {self.supersample!r} must be an integer from 1 to {MAX_SUPERSAMPLE}")
        rays = int(self.width) * int(self.height) * int(self.supersample) ** 2
        if rays > MAX_RAYS:
            raise LunarvizError(f"{self.width}x{self.height} pixels with supersample {self.supersample} make {rays:,} "
                                f"rays (more than {MAX_RAYS:,}): fewer pixels or a smaller --supersample")
        if self.pointing != "moon":
            self.radec()

    def radec(self) -> tuple[float, float]:
        try:
            ra, dec = (float(x) for x in str(self.pointing).split(","))
        except ValueError:
            raise LunarvizError(f"--pointing {self.pointing!r} is not moon or RA,DEC in degrees") from None
        if not (np.isfinite(ra) and -90 <= dec <= 90):
            raise LunarvizError(f"--pointing {self.pointing!r}: declination must be in [-90, 90] degrees")
        return ra % 360.0, dec

    @property
    def scale_rad(self) -> float:
        """Pixel scale on the projection plane [rad]: the full width spans 2 tan(fov/2)."""
        return 2.0 * np.tan(np.radians(self.fov_deg) / 2.0) / self.width


def parse_pixels(text: str) -> tuple[int, int]:
    """``N`` or ``WxH``."""
    t = str(text).lower().replace(" ", "")
    try:
        w, h = (int(x) for x in t.split("x")) if "x" in t else (int(t), int(t))
    except ValueError:
        raise LunarvizError(f"--pixels {text!r} is not N or WxH") from None
    if not (1 <= w <= MAX_PIXELS and 1 <= h <= MAX_PIXELS):
        raise LunarvizError(f"--pixels {text!r}: each side must be 1 to {MAX_PIXELS} pixels")
    return w, h


def camera_axes(scene, camera: Camera):
    """Boresight f, east e and north n (unit vectors, scene frame) and the boresight's RA/Dec [deg]."""
    if camera.pointing == "moon":
        f = unit(scene.moon - scene.det)
    else:
        ra, dec = np.radians(camera.radec())
        f = np.array([np.cos(dec) * np.cos(ra), np.cos(dec) * np.sin(ra), np.sin(dec)])
    # the sky's pole (SceneGeometry.sky_north): ICRF z on dates; +x in the θ scene, whose RA/Dec
    # are then about that pole, RA 0 toward +y (the cyclic frame y, z, x)
    axes = (0, 1, 2) if scene.general else (1, 2, 0)
    z = scene.sky_north
    e = np.cross(z, f)
    if np.linalg.norm(e) < 1e-12:  # boresight at a pole: any east will do
        e = np.cross(np.eye(3)[axes[0]], f)
    e = unit(e)
    n = np.cross(f, e)
    fx, fy, fz = f[list(axes)]
    ra = float(np.degrees(np.arctan2(fy, fx)) % 360.0)
    dec = float(np.degrees(np.arcsin(np.clip(fz, -1, 1))))
    return f, e, n, ra, dec


def _subpixel_rays(camera: Camera, f, e, n):
    """Unit directions, sub-pixel solid angles and (row, col) of every sub-pixel ray."""
    K, W, H, s = camera.supersample, camera.width, camera.height, camera.scale_rad
    off = (np.arange(K) + 0.5) / K - 0.5  # stratified sub-pixel centres
    cx, cy = (W - 1) / 2.0, (H - 1) / 2.0
    cols = (np.arange(W)[None, :, None] + off[None, None, :]).repeat(H, 0)  # (H, W, K)
    rows = (np.arange(H)[:, None, None] + off[None, None, :]).repeat(W, 1)
    xi = -s * (cols[:, :, :, None] - cx)  # (H, W, K, 1): east to the left
    eta = s * (rows[:, :, None, :] - cy)   # (H, W, 1, K)
    xi, eta = np.broadcast_arrays(xi, eta)
    xi, eta = xi.reshape(-1), eta.reshape(-1)
    d = f[None, :] + xi[:, None] * e[None, :] + eta[:, None] * n[None, :]
    norm = np.linalg.norm(d, axis=1)
    omega = (s / K) ** 2 / (1.0 + xi * xi + eta * eta) ** 1.5
    rr = np.repeat(np.arange(H), W * K * K)
    cc = np.tile(np.repeat(np.arange(W), K * K), H)
    return d / norm[:, None], omega, rr, cc


def _lagrange(nodes: np.ndarray, values: list, x: np.ndarray) -> np.ndarray:
    """Interpolate ``values`` (one array per node) at ``x``: quadratic through three nodes."""
    if len(nodes) == 1:
        return values[0]
    out = np.zeros_like(values[0])
    for j, (nj, vj) in enumerate(zip(nodes, values)):
        w = np.ones_like(x)
        for k, nk in enumerate(nodes):
            if k != j:
                w = w * (x - nk) / (nj - nk)
        out = out + w * vj
    return out


def _vertex_transports(ts, which: np.ndarray):
    """The Moon's vertices ``which`` (indices) as Earth transports toward the detector:
    ``(indices, Transport)`` chunks.

    The transport's own earthlight (the Earth's beams, its lit part, the Moon's and the
    Earth's shadows) evaluated at the vertices, on the exact sphere for the packaged icospheres
    (else at the vertex with its crease-limited normal). μ toward the detector is clipped at 0
    so that vertices just behind the limb carry the grazing value: whether a pixel sees the
    Moon is decided by its own ray. Linear interpolation of these point values between
    vertices is second-order accurate. Each vertex's value depends on that vertex alone, so the
    camera asks only for the corners of the facets its rays meet (:func:`_facets_seen`)."""
    M = ts.moon
    v = M.vertices
    if M.mode(ts.settings.shading) == "exact":
        nrm = v / np.linalg.norm(v, axis=1, keepdims=True)
        x = M.centre + M.radius * nrm
    else:
        x = v + M.centre
        acc = np.zeros_like(v)
        cn = M.corner_normals if M.mode(ts.settings.shading) == "interp" else np.repeat(M.normals[:, None], 3, 1)
        for k in range(3):
            np.add.at(acc, M.faces[:, k], cn[:, k] * M.areas[:, None])
        nrm = acc / np.linalg.norm(acc, axis=1, keepdims=True)
    order = ts.settings.earth_order
    det = ts.scene.det
    for a in range(0, len(which), CHUNK // 8):
        sl = which[a:a + CHUNK // 8]
        xs, ns = x[sl], nrm[sl]
        o = unit(det - xs)
        mu = np.clip(np.einsum("ij,ij->i", ns, o), 0.0, 1.0)
        yield sl, ts.deterministic.beam_transport(xs, ns, o, mu, np.ones(len(mu)), "earth", order)


def _facets_seen(ts, origin: np.ndarray, dirs: np.ndarray) -> np.ndarray:
    """The facets of the Moon's mesh that the camera's rays ``dirs`` meet (indices, sorted): the
    earthshine is needed only at their corners (the far side and the Moon outside the field of
    view take none). A superset of what the image shades: the sight-line test against the Earth
    and the relief comes later."""
    M = ts.moon
    exact = M.mode(ts.settings.shading) == "exact"
    seen = np.zeros(len(M.faces), dtype=bool)
    for a in range(0, len(dirs), CHUNK):
        d = dirs[a:a + CHUNK]
        o = np.broadcast_to(origin, d.shape)
        hits = M.sphere_hits(o, d) if exact else M.intersect(o, d)
        seen[hits.prim[hits.prim >= 0]] = True
    return np.flatnonzero(seen)


def _barycentric(tri, p):
    """Barycentric coordinates of points p (n,3) in triangles tri (n,3,3) (projected)."""
    v0, v1, v2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0], p - tri[:, 0]
    d00 = np.einsum("ij,ij->i", v0, v0)
    d01 = np.einsum("ij,ij->i", v0, v1)
    d11 = np.einsum("ij,ij->i", v1, v1)
    d20 = np.einsum("ij,ij->i", v2, v0)
    d21 = np.einsum("ij,ij->i", v2, v1)
    den = d00 * d11 - d01 * d01
    b1 = (d11 * d20 - d01 * d21) / den
    b2 = (d00 * d21 - d01 * d20) / den
    return np.clip(np.stack([1 - b1 - b2, b1, b2], axis=1), 0.0, 1.0)


@dataclass
class ImageResult:
    """Radiance planes [W m⁻² sr⁻¹], (height, width), row 0 at the bottom (north up)."""

    planes: dict  # {"moonshine": {brdf: array}, "earthshine": {brdf: array}}
    camera: Camera
    info: dict
    pixel_solid_angle: np.ndarray  # (H, W) [sr]
    lit_fraction: float  # sunlit share of the Moon's disc (sub-pixel count)
    disc_fraction: float  # share of sub-pixels that see the Moon

    def integrated(self, component: str, brdf: str) -> float:
        """Σ L Ω cos δ [W m⁻²]: the irradiance the image stands for (cos δ folded into Ω)."""
        return float(np.sum(self.planes[component][brdf] * self.pixel_solid_angle))


CHUNK = 20_000


def synthesize(geometry: SceneGeometry, fields: dict, trace: TraceSettings, brdfs: dict, camera: Camera,
               spectral: SpectralInputs | None = None, trace_scene: TraceScene | None = None) -> ImageResult:
    """The image of one task for every BRDF model.

    Parameters
    ----------
    geometry : SceneGeometry
        The task's bodies and detector (positions [m]).
    fields : dict
        The task's row fields (time, distances, flags), copied into ``info``.
    trace : TraceSettings
        The tracer's settings (meshes, shading, source orders, surfaces).
    brdfs : dict
        ``{name: BRDF}``: one plane per model (and per band or wavelength with ``spectral``).
    camera : Camera
        The pinhole camera at the detector.
    spectral : SpectralInputs, optional
        Spectral planes (a band, a wavelength, an instrument's photon-counting response); grey
        without.
    trace_scene : TraceScene, optional
        The traced scene of ``geometry`` and ``trace``, when the caller has it.

    Returns
    -------
    ImageResult
        Radiance planes [W m⁻² sr⁻¹, or per nm], pixel solid angles [sr], ``info``.
    """
    from lunarviz.methods.tracer.trace_scene import TraceScene  # Embree: loaded to trace
    sc = geometry
    ts = trace_scene or TraceScene(sc, trace)
    models = brdfs
    M = ts.moon
    f, e, n, ra, dec = camera_axes(sc, camera)
    dirs, omega, rr, cc = _subpixel_rays(camera, f, e, n)
    cosd = np.clip(dirs @ f, 0.0, 1.0)  # off-boresight cosine (flat detector facing f)
    W, H = camera.width, camera.height
    req = None if spectral is None else spectral.request
    shading = GreyShading(ts, models) if spectral is None else SpectralImageShading(ts, models, spectral)
    ms = {k: np.zeros(H * W) for k in shading.keys}
    es = {k: np.zeros(H * W) for k in shading.keys}
    pix_omega = np.zeros(H * W)
    np.add.at(pix_omega, rr * W + cc, omega * cosd)
    params = shading.factors
    corners = np.unique(M.faces[_facets_seen(ts, sc.det, dirs)])
    vfield = shading.earth_vertex_fields(_vertex_transports(ts, corners), len(M.vertices))
    order = trace.sun_order
    n_disc = n_lit = 0
    origin = sc.det
    for a in range(0, len(dirs), CHUNK):
        sl = slice(a, a + CHUNK)
        d = dirs[sl]
        o = np.broadcast_to(origin, d.shape)
        hits = M.sphere_hits(o, d) if M.mode(ts.settings.shading) == "exact" else M.intersect(o, d)
        h, x, nrm = M.shade_hits(hits, ts.settings.shading)
        if h.size == 0:
            continue
        # hidden by the Earth or by the Moon's relief: the transport's own sight-line test
        mu, geom, o_dir = ts.sampling.detector_view(x, nrm, np.ones(len(h)))
        vis = geom > 0
        h, x, nrm, mu, o_dir = h[vis], x[vis], nrm[vis], mu[vis], o_dir[vis]
        if h.size == 0:  # all hidden (the Moon below a site's horizon, behind the Earth)
            continue
        n_disc += h.size
        idx = a + h
        pix = rr[idx] * W + cc[idx]
        w_sub = omega[idx] * cosd[idx]
        # moonshine: the extended Sun's beams at the hit (eclipses, self-shadowing)
        prim = hits.prim[h]
        beams = ts.deterministic.beam_transport(x, nrm, o_dir, mu, np.ones(len(mu)), "sun", order)
        tr = ts.surfaces.with_moon_albedo(beams, prim)
        n_lit += int(np.count_nonzero(tr.e_beam.sum(1) > 0))
        bary = _barycentric(M.vertices[M.faces[prim]] + M.centre, x)
        for b, rad in shading.moon_radiances(tr).items():
            np.add.at(ms[b], pix, rad * w_sub)
        for b in shading.keys:
            nodes, node_fields = vfield[b]
            at_hit = [np.einsum("ij,ij->i", bary, f[M.faces[prim]]) for f in node_fields]
            val = at_hit[0] if params is None else _lagrange(nodes, at_hit, params[b][prim])
            np.add.at(es[b], pix, val * w_sub)
    with np.errstate(invalid="ignore", divide="ignore"):
        to_radiance = np.where(pix_omega > 0, 1.0 / np.where(pix_omega > 0, pix_omega, 1.0), 0.0)
    planes = {"moonshine": {b: (ms[b] * to_radiance).reshape(H, W) for b in shading.keys},
              "earthshine": {b: (es[b] * to_radiance).reshape(H, W) for b in shading.keys}}
    moon_radec = moon_direction_radec(sc)
    info = {**{k: v for k, v in fields.items()}, "theta_deg": sc.theta_deg, "alpha_deg": sc.alpha_deg,
            "beta_deg": sc.beta_deg, "boresight_ra_deg": ra, "boresight_dec_deg": dec,
            "moon_ra_deg": moon_radec[0], "moon_dec_deg": moon_radec[1],
            "frame": "ICRF (geocentric axes)" if sc.general else "scene axes of the paper's theta scene",
            "bunit": shading.bunit}
    if req is not None:
        info.update(spectral=req.kind, spectral_labels=list(req.labels),
                    spectral_solar_1au=[float(x) for x in req.solar_1au], spectral_centres_nm=list(req.centres_nm))
    total = len(dirs)
    return ImageResult(planes, camera, info, pix_omega.reshape(H, W), n_lit / max(n_disc, 1), n_disc / total)
