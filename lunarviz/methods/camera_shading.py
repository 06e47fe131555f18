"""How the synthetic camera shades its hits: one radiance plane per BRDF (grey), or per BRDF and
band or wavelength (spectral).

:func:`lunarviz.methods.camera.synthesize` takes a shading object with ``keys`` (the planes),
``moon_radiances(transport)`` (moonshine radiance of each plane at the hits),
``earth_vertex_fields(chunks, n)`` (earthshine radiance at the Moon's vertices, interpolated to
the hits), ``factors`` (a lunar map's values per facet, or ``None``) and ``bunit``.

In a spectral run both lights are shaded at the request's node wavelengths in one compiled pass
(:func:`lunarviz.spectral.shading.shade`, per sample) and turned into the outputs
(:class:`~lunarviz.spectral.request.SpectralRequest`): ``L_o = (4π au²/Φ) Σ_j W_oj L(λ_j)``,
radiance per nm [W m⁻² sr⁻¹ nm⁻¹] at a wavelength, or band-integrated ``∫ L S dλ``
[W m⁻² sr⁻¹]. A plane's key is ``BRDF|LABEL`` (``dhg|V``, ``dhg|550``). With a lunar albedo map
the earthlit fields are interpolated in the map's factor on w(λ), as the grey image interpolates
in the albedo.
"""

from __future__ import annotations

import numpy as np

from lunarviz.outputs.images import plane_key
from lunarviz.spectral.shading import shade, spectral_brdfs
from lunarviz.spectral.shading_inputs import SpectralInputs
from lunarviz.surfaces.earth_spectra import spectral_components
from lunarviz.surfaces.moon_map import map_scale


def facet_params(ts, models) -> dict | None:
    """Each BRDF's albedo parameter per Moon facet under a lunar albedo map, or ``None``."""
    v = ts.surfaces.moon_facet_albedo()
    if v is None:
        return None
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


class SpectralImageShading:
    """The spectral counterpart of the camera's grey shading (same three calls)."""

    def __init__(self, ts, models: dict, inputs: SpectralInputs):
        self.req = inputs.request
        self.ts = ts
        self.sbs = spectral_brdfs(inputs, models)
        surface = ts.settings.surface()
        self.mapped = not surface.uniform
        if self.mapped:
            ts.surfaces.earth_parts, self.albedo = spectral_components(surface, self.req.nodes, inputs.earth_spectra)
            ts.surfaces.earth_part_wavelengths = self.req.nodes if surface.physical else None
        self.phi = ts.scene.phi_sun
        self.keys = [plane_key(b, lab) for b in models for lab in self.req.labels]
        self.factors = None
        fa = ts.surfaces.moon_facet_albedo()
        if fa is not None:
            self.factors = {k: fa for k in self.keys}

    @property
    def bunit(self) -> str:
        return "W m-2 sr-1 nm-1" if self.req.kind == "wavelength" else "W m-2 sr-1"

    def _outputs(self, b: str, node_radiance: np.ndarray) -> dict:
        out = self.req.outputs(node_radiance, self.phi)  # (N, O)
        return {plane_key(b, lab): out[:, o] for o, lab in enumerate(self.req.labels)}

    def moon_radiances(self, tr) -> dict:
        """``{key: (N,)}`` moonshine radiance of each plane at the hits of transport ``tr``."""
        res = {}
        for b, sb in self.sbs.items():
            res.update(self._outputs(b, shade(tr, sb, tr.e_beam[None], per_sample=True)[:, 0, :]))
        return res

    def earth_radiances(self, tr) -> dict:
        """``{key: (N,)}`` earthshine radiance of each plane from an Earth transport."""
        res = {}
        for b, sb in self.sbs.items():
            parts = np.stack([*tr.e_beam_parts.values(), tr.e_beam_unit]) if tr.e_beam_parts \
                else tr.e_beam_unit[None]
            node = shade(tr, sb, parts, per_sample=True)  # (N, P + 1, L)
            if self.mapped and tr.e_beam_parts:
                es = np.einsum("npl,pl->nl", node[:, :-1, :], self.albedo)
            else:
                es = self.ts.surfaces.earth_albedo_value() * node[:, -1, :]
            res.update(self._outputs(b, es))
        return res

    def earth_vertex_fields(self, chunks, n: int) -> dict:
        """``{key: (factor nodes, [field (n,) per node])}`` from the camera's vertex transports
        ``chunks`` (``(slice, Transport)``): with a lunar map, at three values of its factor
        spanning the facets' (:func:`albedo_nodes`)."""
        nodes = np.array([np.nan]) if self.factors is None else albedo_nodes(next(iter(self.factors.values())))
        absolute = self.factors is not None and self.ts.settings.moon_map().absolute
        out = {k: [np.zeros(n) for _ in nodes] for k in self.keys}
        for sl, tr in chunks:
            for j, wj in enumerate(nodes):
                if self.factors is not None:
                    tr.albedo, tr.albedo_absolute, tr.albedo_std = np.full(len(tr.mu), wj), absolute, None
                for k, v in self.earth_radiances(tr).items():
                    out[k][j][sl] = v
        return {k: (nodes, out[k]) for k in self.keys}
