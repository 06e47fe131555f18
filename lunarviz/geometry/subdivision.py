"""Subdivision of a triangle into k×k similar sub-triangles, in barycentric coordinates.

Used by the lune refinement of the tracer (facets that a terminator, limb or shadow edge
crosses are split) and by the per-facet reading of surface maps.
"""

from __future__ import annotations

import numpy as np

from lunarviz.caches import memoize


@memoize(maxsize=32)
def sub_barycentric(k: int) -> tuple[np.ndarray, np.ndarray]:
    """Barycentric centroids (k², 3) and corners (k², 3, 3) of a triangle split k×k.

    The arrays are shared between callers: treat them as read-only.
    """
    cor = []
    for i in range(k):
        for j in range(k - i):
            cor.append([(i, j), (i + 1, j), (i, j + 1)])
            if i + j <= k - 2:
                cor.append([(i + 1, j), (i + 1, j + 1), (i, j + 1)])
    corners = np.array([[[1 - (a + b) / k, a / k, b / k] for a, b in t] for t in cor])
    cen = corners.mean(axis=1)
    cen.flags.writeable = False
    corners.flags.writeable = False
    return cen, corners
