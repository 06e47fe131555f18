"""The surfaces of a scene read at points, for the quadrature methods without facets (analytic,
reference): the lunar map at lunar nodes, the Earth's albedo at Earth points and toward the Moon.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lunarviz.surfaces.earth_surface import EarthSurface
from lunarviz.surfaces.maps import map_frame, sample_map
from lunarviz.surfaces.moon_map import MoonAlbedoMap


@dataclass(frozen=True)
class Surfaces:
    """The surfaces of a scene for methods without facets: the lunar map and the Earth's
    surface read at points (nearest cell; see the module docstring)."""

    moon_map: MoonAlbedoMap | None = None
    earth: EarthSurface = EarthSurface()
    earth_rotation_deg: float = 0.0

    def moon_values_at(self, scene, points: np.ndarray):
        """Lunar map values at lunar surface points (n, 3) [m] (scene frame), or ``None``."""
        if self.moon_map is None:
            return None
        d = (np.asarray(points) - scene.moon) @ map_frame(scene, "moon")
        return sample_map(self.moon_map.values(), d)

    def earth_albedo_at(self, scene, points: np.ndarray) -> np.ndarray | float:
        """Earth albedo at Earth surface points (..., 3) [m] (scene frame); the scalar if uniform."""
        if self.earth.uniform:
            return float(self.earth.earth_albedo)
        p = np.asarray(points) - scene.earth
        d = p.reshape(-1, 3) @ map_frame(scene, "earth", self.earth_rotation_deg)
        return self.earth.albedo_at(d).reshape(p.shape[:-1])

    def earth_albedo_toward(self, scene, target: np.ndarray, rows: int | None = None, values=None):
        """The Earth's albedo as a Lambert Earth lit by a point Sun weights it toward a distant
        ``target`` (the Moon's centre): ``∫A μ_s μ_t dA / ∫μ_s μ_t dA`` over the sphere, on a
        grid of cells at least as fine as the surface's maps (the map's value per cell; ``rows``:
        that many rows of latitude instead). ``values``: a function of map-frame directions (n, 3)
        giving (n,) or (n, C) values to weight instead of the albedo
        (:mod:`lunarviz.surfaces.earth_spectra`'s components)."""
        if self.earth.uniform and values is None:
            return float(self.earth.earth_albedo)
        if self.earth.physical:
            raise AssertionError("a physical Earth: use lunarviz.surfaces.physical_earth.albedo_toward")  # a caller bug
        values = values or self.earth.albedo_at
        clear = self.earth.clear_map()
        n = rows if rows is not None else max(360, min(1800, 0 if clear is None else clear.shape[0]))
        lat = np.radians(90.0 - (np.arange(n) + 0.5) * 180.0 / n)
        lon = np.radians(-180.0 + (np.arange(2 * n) + 0.5) * 180.0 / n)
        frame = map_frame(scene, "earth", self.earth_rotation_deg)
        us = (scene.sun - scene.earth) / np.linalg.norm(scene.sun - scene.earth)
        ut = (target - scene.earth) / np.linalg.norm(target - scene.earth)
        num = den = 0.0
        cl = np.cos(lon)
        sl = np.sin(lon)
        for a in range(0, n, 90):
            la = lat[a:a + 90, None]
            d = np.stack([np.cos(la) * cl, np.cos(la) * sl, np.broadcast_to(np.sin(la), (len(la), 2 * n))], -1)
            ds = d @ frame.T  # scene frame
            w = np.clip(ds @ us, 0, None) * np.clip(ds @ ut, 0, None) * np.cos(la)
            if not w.any():
                continue
            # the map is read only where the cell is lit and faces the target (w > 0): the others
            # add exact zeros to the same sums
            seen = w.reshape(-1) > 0
            got = values(d.reshape(-1, 3)[seen])
            A = np.zeros((seen.size,) + got.shape[1:])
            A[seen] = got
            A = A.reshape(w.shape + A.shape[1:])
            if A.ndim == 2:
                num += float((A * w).sum())
            else:
                num = num + (A * w[..., None]).sum(axis=(0, 1))
            den += float(w.sum())
        if np.ndim(num) == 0:
            return float(num) / den if den > 0 else float("nan")
        return num / den if den > 0 else np.full(np.shape(num), np.nan)
