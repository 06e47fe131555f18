"""How the synthetic camera shades a grey run: one radiance plane per BRDF.

:func:`lunarviz.methods.camera.synthesize` takes a shading object with three things: ``keys``
(the planes), ``moon_radiances(transport)`` (moonshine radiance of each plane at the hits) and
``earth_vertex_fields(chunks, n)`` (earthshine radiance at the Moon's vertices, interpolated to
the hits), and ``factors`` (a lunar map's values per facet, or ``None``). This is the grey one;
:mod:`lunarviz.spectral.image_shading` is the spectral one.
"""

from __future__ import annotations

import numpy as np


def facet_params(ts, models) -> dict | None:
    """Each BRDF's albedo parameter per Moon facet under a lunar albedo map, or ``None``."""
    v = ts.moon_facet_albedo()
    if v is None:
        return None
    from lunarviz.bodies.surfaces import map_scale
    absolute = ts.settings.moon_map().absolute
    return {b: v * map_scale(absolute, m) for b, m in models.items()}


def albedo_nodes(p: np.ndarray) -> np.ndarray:
    """Three albedo values spanning ``p`` (Chebyshev points; one where p is uniform)."""
    lo, hi = float(p.min()), float(p.max())
    if hi - lo <= 1e-12 * max(hi, 1e-300):
        return np.array([lo])
    return 0.5 * (lo + hi) + 0.5 * (hi - lo) * np.cos(np.pi * (np.arange(3) + 0.5) / 3)


class GreyShading:
    """The camera's shading of a grey run: one plane per BRDF (keys: the BRDF names).

    Earthshine radiance toward the detector [W m⁻² sr⁻¹] at every Moon vertex, per BRDF
    (:func:`lunarviz.methods.camera._vertex_transports`). With a lunar albedo map (``factors``, per facet), per BRDF a
    list of fields at three albedo values spanning the map's (:func:`albedo_nodes`): each hit
    interpolates them quadratically at its facet's albedo (exact for Lambert, whose radiance is
    linear in the albedo; Hapke's radiance is smooth in w)."""

    bunit = "W m-2 sr-1"

    def __init__(self, ts, models: dict):
        self.models = models
        self.keys = list(models)
        self.factors = facet_params(ts, models)

    def moon_radiances(self, tr) -> dict:
        return {b: tr.radiance(m) for b, m in self.models.items()}

    def earth_vertex_fields(self, chunks, n: int) -> dict:
        nodes = {b: np.array([np.nan]) if self.factors is None else albedo_nodes(self.factors[b])
                 for b in self.models}
        out = {b: [np.zeros(n) for _ in nodes[b]] for b in self.models}
        for sl, tr in chunks:
            for b, model in self.models.items():
                for j, wj in enumerate(nodes[b]):
                    if self.factors is not None:
                        tr.albedo, tr.albedo_absolute = np.full(len(tr.mu), wj), True
                    out[b][j][sl] = tr.radiance(model)
        return {b: (nodes[b], out[b]) for b in self.models}
