"""Synthetic images in colour: a radiance plane per band, or per wavelength (a cube).

:func:`lunarviz.methods.camera.synthesize` shades each pixel's hit with the Sun's beams and reads
the earthlight from fields at the Moon's vertices. In a spectral run both are shaded at the
request's node wavelengths in one compiled pass (:func:`lunarviz.spectral.shading.shade`,
per sample) and turned into the outputs (:class:`~lunarviz.spectral.request.SpectralRequest`):
``L_o = (4π au²/Φ) Σ_j W_oj L(λ_j)``, radiance per nm [W m⁻² sr⁻¹ nm⁻¹] at a wavelength, or
band-integrated ``∫ L S dλ`` [W m⁻² sr⁻¹]. A plane's key is ``BRDF|LABEL`` (``dhg|V``,
``dhg|550``). With a lunar albedo map the earthlit fields are interpolated in the map's factor
on w(λ), as the grey image interpolates in the albedo.
"""

from __future__ import annotations

import numpy as np

from lunarviz.spectral.earth import spectral_components
from lunarviz.spectral.shading import shade, spectral_brdfs


def plane_key(brdf: str, label) -> str:
    """``BRDF|LABEL``: a band's name, or a wavelength to 12 significant digits."""
    from lunarviz.spectral.request import wavelength_label
    return f"{brdf}|{wavelength_label(label)}" if isinstance(label, float) else f"{brdf}|{label}"


class SpectralImageShading:
    """The spectral counterpart of the camera's grey shading (same three calls)."""

    def __init__(self, settings, ts, models: dict, request=None):
        self.req = request if request is not None else settings.spectral_request()
        self.ts = ts
        self.sbs = spectral_brdfs(settings, models, self.req.nodes)
        surface = settings.surfaces().earth if settings.surfaces() is not None else None
        self.mapped = surface is not None and not surface.uniform
        if self.mapped:
            ts.earth_parts, self.albedo = spectral_components(surface, self.req.nodes, settings.earth_spectra)
            ts.earth_part_wavelengths = self.req.nodes if surface.physical else None
        self.phi = ts.scene.phi_sun
        self.keys = [plane_key(b, lab) for b in models for lab in self.req.labels]
        self.factors = None
        fa = ts.moon_facet_albedo()
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
                es = self.ts.earth_albedo_value() * node[:, -1, :]
            res.update(self._outputs(b, es))
        return res

    def earth_vertex_fields(self, chunks, n: int) -> dict:
        """``{key: (factor nodes, [field (n,) per node])}`` from the camera's vertex transports
        ``chunks`` (``(slice, Transport)``): with a lunar map, at three values of its factor
        spanning the facets' (:func:`lunarviz.methods.image_shading.albedo_nodes`)."""
        from lunarviz.methods.image_shading import albedo_nodes
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
