"""Shading one transport at every wavelength: the spectral dimension costs no tracing.

A :class:`~lunarviz.methods.transport.Transport` does not depend on wavelength (geometry,
visibility, the Sun's and the Earth's beams for unit albedo), so a spectral run traces once and
shades here: for each BRDF, its parameters at every node wavelength
(:mod:`lunarviz.spectral.moon`) and, for earthshine, each surface component's beams
(:mod:`lunarviz.surfaces.earth_spectra`). :class:`SpectralShader` returns detector irradiances at the
grey Sun per node (W m⁻², as the grey run's); :mod:`lunarviz.spectral.request` turns them into
spectral [W m⁻² nm⁻¹] or band values with the Sun's spectrum.

The compiled path (:mod:`lunarviz.spectral.kernels`) reads each beam once for all wavelengths;
where it does not apply (numba off, the exact H-function, a roughness that changes with
wavelength) every wavelength is shaded through :meth:`Transport.radiances`' numpy formulas.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lunarviz.photometry import rough_kernels
from lunarviz.photometry import shading_kernels as sk
from lunarviz.photometry.brdf import Hapke, Lambert
from lunarviz.photometry.roughness import azimuth_from_half_angle, coherent_backscatter, shadowing
from lunarviz.spectral import kernels
from lunarviz.spectral.moon import models_at, parameters_at
from lunarviz.spectral.shading_inputs import SpectralInputs
from lunarviz.surfaces.moon_map import map_scale

#: parameters that must be grey for the compiled path (they shape the effective geometry)
GREY_GEOMETRY = ("theta_bar", "Bc0", "hc")


@dataclass
class SpectralBRDF:
    """One BRDF across the node wavelengths: the grey model (its structure) and ``params``
    ``{name: (L,) array}`` (:func:`lunarviz.spectral.moon.parameters_at`)."""

    grey: object
    params: dict

    @property
    def n(self) -> int:
        return len(next(iter(self.params.values())))

    @property
    def contrast(self) -> np.ndarray:
        """The lunar map's contrast at each node (:mod:`lunarviz.spectral.moon`; 1: as it is)."""
        return self.params.get("map_contrast", np.ones(self.n))

    def model(self, index: int):
        return models_at(self.grey, self.params, index)

    def distinct(self) -> tuple["SpectralBRDF", np.ndarray]:
        """The distinct parameter sets among the nodes and, per node, which one it is: a grey
        Moon (the paper's) has one, so its spectral run shades once, not once per wavelength."""
        names = sorted(self.params)
        table = np.stack([np.asarray(self.params[k], dtype=float) for k in names])
        uniq, inverse = np.unique(table, axis=1, return_inverse=True)
        return SpectralBRDF(self.grey, {k: uniq[i] for i, k in enumerate(names)}), np.asarray(inverse).reshape(-1)


def spectral_brdfs(inputs: SpectralInputs, brdfs: dict) -> dict:
    """``{name: SpectralBRDF}`` for a run's grey BRDF models ``brdfs`` at the request's node
    wavelengths (the preset and overrides of ``inputs``)."""
    return {k: SpectralBRDF(b, parameters_at(inputs.moon_model, k, inputs.request.nodes, inputs.params.get(k),
                                             grey_model=b))
            for k, b in brdfs.items()}


def _compiled_codes(sb: SpectralBRDF):
    """(pcode, hcode, p1, p2) for the compiled path, or ``None`` where it does not apply."""
    if not kernels.available():
        return None
    g = sb.grey
    if type(g) is Lambert:
        return sk.LAMBERT, sk.H1981, np.zeros(sb.n), np.zeros(sb.n)
    if not isinstance(g, Hapke) or g.h_function not in ("hapke1981", "hapke2002"):
        return None
    for k in GREY_GEOMETRY:
        if k in sb.params and np.ptp(sb.params[k]) > 0:
            return None
    hcode = sk.H1981 if g.h_function == "hapke1981" else sk.H2002
    if "xi" in sb.params:
        xi = sb.params["xi"]
        return sk.SHG, hcode, np.abs(xi), (xi < 0).astype(float)
    pcode = sk.DHG_PAPER if g.phase.convention == "paper" else sk.DHG_HAPKE2012
    return pcode, hcode, sb.params["b"], sb.params["c"]


def _effective_geometry(sb: SpectralBRDF, tr):
    """μ0e (N, K), μe (N, 1 or K) and F (N, 1 or K) of :mod:`lunarviz.spectral.kernels`."""
    mu0 = np.clip(tr.mu0, 0.0, 1.0)
    mu = np.clip(tr.mu, 0.0, 1.0)[:, None]
    if not isinstance(sb.grey, Hapke):
        return mu0, mu, np.ones((len(mu), 1))
    g = sb.model(0)  # θ̄, B_C0 and h_C: the nodes' own (one value for all of them on this path)
    if not g.rough:
        return mu0, mu, np.ones((len(mu), 1))
    key = (g.theta_bar, g.Bc0, g.hc)  # (the transport's beams do not change: computed once per roughness)
    if key not in tr.rough_geometry:
        if rough_kernels.available():  # one compiled pass over the beams
            mu0e, mue, S = rough_kernels.rough_geometry(mu0, mu[:, 0], tr.sin_hg, tr.cos_hg,
                                                        np.radians(g.theta_bar), g.Bc0, g.hc)
        else:
            psi = azimuth_from_half_angle(mu0, mu, tr.sin_hg)
            mu0e, mue, S = shadowing(mu0, mu, psi, np.radians(g.theta_bar))
            if g.Bc0 > 0.0:
                S = S * (1.0 + g.Bc0 * coherent_backscatter(tr.sin_hg, tr.cos_hg, g.hc))
            mue, S = np.broadcast_to(mue, mu0.shape), np.broadcast_to(S, mu0.shape)
        mu0e.setflags(write=False)  # (the compiled arrays are the transport's own; broadcasts are read-only)
        for a in (mue, S):
            if a.flags.writeable:
                a.setflags(write=False)
        tr.rough_geometry[key] = (mu0e, mue, S)
    return tr.rough_geometry[key]


def _albedo_factors(tr, sb: SpectralBRDF):
    """Per-sample factors on w(λ) for a lunar map: ``[(factor, weight), ...]`` (the pair w ± σ of
    :meth:`Transport._albedo_pair` where the BRDF is not linear in w, weights 1/2; a mapped lune
    rule's map values (:attr:`Transport.albedo_nodes`), each at every sample, weighted per sample
    by its factor (N,)), and whether the map gives the parameter itself (then w(λ) is replaced,
    not scaled)."""
    if tr.albedo_nodes is not None:
        values, weights = tr.albedo_nodes
        n = len(tr.mu)
        return [(np.full(n, float(v)), weights[:, q]) for q, v in enumerate(values)], tr.albedo_absolute
    if tr.albedo is None:
        return [(None, 1.0)], False
    a = tr.albedo
    linear = getattr(sb.grey, "linear_in_albedo", False) or type(sb.grey) is Lambert
    if tr.albedo_std is not None and not linear and np.any(tr.albedo_std > 0):
        return [(a - tr.albedo_std, 0.5), (a + tr.albedo_std, 0.5)], tr.albedo_absolute
    return [(a, 1.0)], tr.albedo_absolute


def _weighted(weight, sums, per_sample: bool):
    """A factor's share of :func:`shade`'s output: its ``sums`` (from geom times ``weight``) as
    they are, or each sample's radiances (``per_sample``) times its weight (a scalar or (N,))."""
    if np.ndim(weight) == 0:
        return weight * sums
    return np.asarray(weight)[:, None, None] * sums if per_sample else sums


def shade(tr, sb: SpectralBRDF, parts: np.ndarray, per_sample: bool = False) -> np.ndarray:
    """``out[p, l] = Σ_n geom_n Σ_k rf_l E_p`` for beam arrays ``parts`` (P, N, K) of transport
    ``tr`` [W m⁻², at the grey Sun]; ``per_sample``: each sample's radiance ``Σ_k rf_l E_p``
    (N, P, L) [W m⁻² sr⁻¹] where its ``geom`` is not zero (images pass geom = 1)."""
    out = np.zeros((parts.shape[1], parts.shape[0], sb.n) if per_sample else (parts.shape[0], sb.n))
    if parts.shape[1] == 0:
        return out
    uniq, inverse = sb.distinct()
    if uniq.n < sb.n:  # nodes sharing every parameter share their shading
        return shade(tr, uniq, parts, per_sample)[..., inverse]
    codes = _compiled_codes(sb)
    factors, absolute = _albedo_factors(tr, sb)
    if codes is not None:
        pcode, hcode, p1, p2 = codes
        mu0e, mue, fac = _effective_geometry(sb, tr)
        pr = sb.params
        w = pr["albedo"] if type(sb.grey) is Lambert else pr["w"]
        if absolute:
            w = np.ones_like(w)
        zeros = np.zeros(sb.n)
        h, B0 = (zeros, zeros) if type(sb.grey) is Lambert else (pr["h"], pr["B0"])
        kc = np.ones(sb.n) if absolute else sb.contrast
        for alb, weight in factors:  # (a per-sample weight rides on geom: the sums are linear in it)
            geom = tr.geom * weight if np.ndim(weight) else tr.geom
            out += _weighted(weight, kernels.spectral_sums(mu0e, mue, tr.sin_hg, tr.cos_hg, fac, parts, geom, alb,
                                                           w, kc, h, B0, p1, p2, pcode, hcode, per_sample), per_sample)
        return out
    for ll in range(sb.n):  # numpy: one wavelength at a time, Transport's own formulas
        m = sb.model(ll)
        for alb, weight in factors:
            a = None
            if alb is not None:
                k = 1.0 if absolute else sb.contrast[ll]
                a = np.clip((k * alb + (1.0 - k)) * map_scale(absolute, m), 0.0, 1.0)[:, None]
            rf = m.radiance_factor(tr.mu0, tr.mu[:, None], tr.sin_hg, tr.cos_hg, albedo=a)
            for p in range(parts.shape[0]):
                L = np.sum(rf * parts[p], axis=1)
                if per_sample:
                    out[:, p, ll] += weight * np.where(tr.geom != 0, L, 0.0)
                else:
                    out[p, ll] += float(np.dot(L, tr.geom * weight))
    return out


class SpectralShader:
    """Detector irradiances of one run's BRDFs at its node wavelengths, from transports.

    ``earth_parts``: the surface components' names in the order of a transport's
    ``e_beam_parts`` (:mod:`lunarviz.surfaces.earth_spectra`)."""

    def __init__(self, brdfs: dict):
        self.brdfs = brdfs  # {name: SpectralBRDF}

    def moonshine(self, tr) -> dict:
        """``{brdf: (L,)}`` moonshine at the grey Sun [W m⁻²] per node."""
        parts = tr.e_beam[None]
        return {k: shade(tr, sb, parts)[0] for k, sb in self.brdfs.items()}

    def earthshine(self, tr) -> dict:
        """``{brdf: (P + 1, L)}``: per surface component (``tr.e_beam_parts``, in order) and last
        for an Earth of albedo 1 [W m⁻², at the grey Sun, for unit albedo of each component]."""
        parts = np.stack([*tr.e_beam_parts.values(), tr.e_beam_unit]) if tr.e_beam_parts \
            else tr.e_beam_unit[None]
        return {k: shade(tr, sb, parts) for k, sb in self.brdfs.items()}
