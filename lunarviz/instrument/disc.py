"""Where the Moon lies in an instrument's frame: its centre, radius and the Sun's direction in
pixels, and the bright-side neutral-density mask placed from them.

Pixel coordinates are (column x, row y) as in :func:`lunarviz.methods.camera.synthesize`: the
camera points at the Moon's centre, east is to the left (−x) and north up (+y). The sunlit limb
lies along the unit vector ``u`` (the Sun's direction from the Moon projected on the image); a
sphere's terminator crosses that axis at ``x' = −R cos α`` from the centre (α the phase angle,
orthographic projection: the Moon's 0.26° radius makes perspective a 1e-5 effect) and ends at
the horns, on the perpendicular through the centre.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lunarviz.errors import LunarvizError
from lunarviz.geometry.scene_geometry import unit


@dataclass(frozen=True)
class DiscGeometry:
    """The lunar disc in pixels."""

    x0: float  # centre column
    y0: float  # centre row
    radius_px: float
    ux: float  # the Sun's direction in the image (unit)
    uy: float
    phase_deg: float  # Sun-Moon-observer angle α

    def coordinates(self, shape) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(r, along, angle)`` per pixel: distance from the centre in radii, the coordinate along
        the Sun's direction in radii, and the angle from the Sun's direction [deg, 0-180]."""
        h, w = shape
        y, x = np.mgrid[0:h, 0:w].astype(float)
        dx, dy = (x - self.x0) / self.radius_px, (y - self.y0) / self.radius_px
        r = np.hypot(dx, dy)
        along = dx * self.ux + dy * self.uy
        with np.errstate(invalid="ignore", divide="ignore"):
            ang = np.degrees(np.arccos(np.clip(np.where(r > 0, along / np.where(r > 0, r, 1), 1.0), -1, 1)))
        return r, along, ang

    @property
    def terminator_along(self) -> float:
        """Where the terminator crosses the Sun's axis, in radii from the centre (−cos α)."""
        return float(-np.cos(np.radians(self.phase_deg)))


def disc_geometry(sc, camera) -> DiscGeometry:
    """The disc of scene ``sc`` in ``camera`` (pointed at the Moon)."""
    from lunarviz.methods.camera import camera_axes
    f, e, n, _, _ = camera_axes(sc, camera)
    d = float(np.linalg.norm(sc.moon - sc.det))
    r_m = float(sc.radii["moon"])
    radius = float(np.tan(np.arcsin(min(r_m / d, 1.0))) / camera.scale_rad)
    s = unit(sc.sun - sc.moon)
    u = np.array([-(s @ e), s @ n])  # east (+e) is toward −x
    norm = float(np.hypot(*u))
    ux, uy = (u / norm) if norm > 0 else (1.0, 0.0)
    alpha = float(np.degrees(np.arccos(np.clip(unit(sc.sun - sc.moon) @ unit(sc.det - sc.moon), -1, 1))))
    return DiscGeometry((camera.width - 1) / 2.0, (camera.height - 1) / 2.0, radius, float(ux), float(uy), alpha)


@dataclass(frozen=True)
class BrightSideMask:
    """A focal-plane neutral-density half-plane over the sunlit side: pixels whose coordinate along
    the Sun's direction exceeds ``edge_along`` [radii] see ``transmission`` of their light."""

    transmission: float
    edge_along: float

    def pixels(self, geom: DiscGeometry, shape) -> np.ndarray:
        _, along, _ = geom.coordinates(shape)
        return along > self.edge_along


def place_mask(geom: DiscGeometry, transmission: float, margin_px: float) -> BrightSideMask | None:
    """The mask's edge ``margin_px`` short of the sunlit region on the dark side (None: no mask).

    The terminator is a half-ellipse from horn to horn: its horns lie on the line through the
    centre perpendicular to the Sun's direction, and its middle at ``−cos α``; the sunlit region
    reaches ``min(−cos α, 0)`` along the Sun's direction (a half-plane through the centre past
    quarter Moon)."""
    if transmission >= 1.0:
        return None
    return BrightSideMask(float(transmission), min(geom.terminator_along, 0.0) - margin_px / geom.radius_px)


def masked_pixels(sc, camera, transmission: float, margin_px: float):
    """The disc, the mask placed on it (None: no mask) and the (H, W) pixels behind it."""
    geom = disc_geometry(sc, camera)
    mask = place_mask(geom, transmission, margin_px)
    shape = (camera.height, camera.width)
    return geom, mask, mask.pixels(geom, shape) if mask is not None else np.zeros(shape, bool)


def surface_points(sc, camera, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points [m] (n, 3) and outward normals where the central rays of pixels (x, y) meet the
    Moon's sphere."""
    from lunarviz.methods.camera import camera_axes
    f, e, n, _, _ = camera_axes(sc, camera)
    s = camera.scale_rad
    x, y = np.atleast_1d(np.asarray(x, dtype=float)), np.atleast_1d(np.asarray(y, dtype=float))
    xi, eta = -s * (x - (camera.width - 1) / 2.0), s * (y - (camera.height - 1) / 2.0)  # as the camera's rays
    d = f[None, :] + xi[:, None] * e[None, :] + eta[:, None] * n[None, :]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    oc = sc.det - sc.moon
    r = float(sc.radii["moon"])
    bq = d @ oc
    disc = bq * bq - (float(oc @ oc) - r * r)
    if np.any(disc < 0):
        raise LunarvizError(f"{int(np.count_nonzero(disc < 0))} pixels of a patch miss the Moon")
    p = sc.det + (-bq - np.sqrt(disc))[:, None] * d
    nrm = p - sc.moon
    return p, nrm / np.linalg.norm(nrm, axis=1, keepdims=True)
