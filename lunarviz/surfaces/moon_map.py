"""The lunar albedo map (``--moon-albedo-map FILE[:MEAN]``) and its values on the Moon's facets.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lunarviz.caches import file_key, memoize
from lunarviz.errors import LunarvizError
from lunarviz.resources import DATA_DIR
from lunarviz.surfaces.maps import check_range, facet_average, facet_sub_count, map_mean, read_map, sample_map

#: the synthetic lunar albedo map shipped for tests and demos (docs: surfaces)
SYNTHETIC_MOON_MAP = DATA_DIR / "synthetic_moon_albedo.npy"


def map_scale(absolute: bool, brdf) -> float:
    """Factor from a lunar map's values to ``brdf``'s albedo parameter: 1 for a ``FILE:MEAN``
    map (its values are the parameter), the BRDF's own parameter for a pattern (``FILE``)."""
    return 1.0 if absolute else brdf.albedo_parameter


@dataclass(frozen=True)
class MoonAlbedoMap:
    """``--moon-albedo-map FILE[:MEAN]`` (``FILE`` may be ``synthetic``, the shipped demo map).

    ``FILE``: a pattern. Each BRDF's albedo parameter (Lambert albedo, Hapke w) is multiplied per
    facet by ``map / ⟨map⟩`` (⟨⟩ the area-weighted mean over the sphere): every BRDF keeps its
    own mean, and a uniform map changes nothing. ``FILE:MEAN``: the map is normalised to the
    area-weighted mean MEAN and its values *are* the albedo parameter of every BRDF.
    """

    path: str
    mean: float | None = None

    @classmethod
    def parse(cls, text: str) -> "MoonAlbedoMap":
        text = str(text).strip()
        if not text:
            raise LunarvizError("--moon-albedo-map is empty: give FILE[:MEAN] or synthetic[:MEAN]")
        path, mean = text, None
        head, sep, tail = text.rpartition(":")
        if sep and head and not tail.startswith(("\\", "/")) and not Path(text).is_file():
            try:
                mean = float(tail)
            except ValueError:
                raise LunarvizError(f"--moon-albedo-map {text!r}: the mean after ':' must be a number, "
                                    f"not {tail!r}") from None
            path = head
            if not (np.isfinite(mean) and 0.0 < mean <= 1.0):
                raise LunarvizError(f"--moon-albedo-map mean {tail!r} must be in (0, 1]")
        out = cls(path, mean)
        out.values()  # read and check now, before any work
        return out

    @property
    def absolute(self) -> bool:
        return self.mean is not None

    def source(self) -> Path:
        return SYNTHETIC_MOON_MAP if self.path == "synthetic" else Path(self.path)

    def values(self) -> np.ndarray:
        """The map, normalised: mean 1 (a pattern) or mean MEAN (albedo values)."""
        return _moon_map_values(file_key(self.source()), self.mean)

    def check_brdfs(self, brdfs: dict) -> None:
        """Every BRDF's per-facet albedo parameter stays within [0, 1]."""
        v = self.values()
        for name, b in brdfs.items():
            top = float(v.max()) * map_scale(self.absolute, b)
            if top > 1.0:
                pname = "albedo" if name == "lambert" else "w"
                raise LunarvizError(f"--moon-albedo-map {self.path!r} gives {name} {pname} up to {top:.3g} > 1: "
                                    f"give a smaller :MEAN or a smaller {pname}")


@memoize(maxsize=8)
def _moon_map_values(key: tuple, mean: float | None) -> np.ndarray:
    """The lunar map at ``key`` (:func:`lunarviz.caches.file_key`), scaled to ``mean``."""
    path = key[0]
    m = read_map(path, "Moon albedo map")
    mu = map_mean(m)
    if mu <= 0.0:
        raise LunarvizError(f"Moon albedo map {path!r} has mean {mu:g}: it must be positive")
    check_range(m, f"Moon albedo map {path!r}", 0.0, np.inf)
    out = m / mu * (1.0 if mean is None else mean)
    if mean is not None:
        check_range(out, f"Moon albedo map {path!r} normalised to mean {mean:g}")
    out.setflags(write=False)
    return out


def moon_facet_values(amap: MoonAlbedoMap, body, frame: np.ndarray, faces=None):
    """Per-facet map values on an Embree body (vertices in scene axes, body-centred), for a map
    frame ``frame`` (:func:`map_frame`): ``(mean, std)`` over each facet (or over each triangle
    of ``faces`` into ``body.vertices``-like ``(vertices, faces)``)."""
    m = amap.values()
    verts, tris = (body.vertices, body.faces) if faces is None else faces
    k = facet_sub_count(verts, tris, m.shape)
    return facet_average(lambda d: sample_map(m, d @ frame), verts, tris, k, spread=True)


