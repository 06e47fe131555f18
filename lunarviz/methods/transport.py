"""BRDF-independent transport: what reaches each lunar surface sample, and what the detector sees.

Every method (analytic, exact reference, deterministic and Monte Carlo ray tracing) reduces a
scene to a :class:`Transport`: for N lunar surface samples and K incident beams per sample,

* ``e_beam`` (N, K) — irradiance carried by each beam, measured normal to the beam [W m⁻²]
  (radiance × solid angle of the beam); zero for blocked or missing beams;
* ``mu0`` (N, K), ``sin_hg``/``cos_hg`` (N, K) — cos incidence and the half phase angle;
* ``mu`` (N,) — cos emission toward the detector;
* ``geom`` (N,) — ``μ · cos(detector tilt) · dA / d²`` [sr m⁻²·m²], zero where the detector
  cannot see the sample.

Then the radiance toward the detector is ``L = Σ_k BRDF·μ0·e_beam`` (paper Eq. 10, summed over
beams) and the detector irradiance ``E = Σ_n L · geom`` (paper Eq. 11). Shading three BRDFs
costs three cheap evaluations of one transport (the docs' architecture page: data flows one way).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from lunarviz.photometry import rough_kernels, shading_kernels
from lunarviz.photometry.brdf import Lambert
from lunarviz.surfaces.moon_map import map_scale


@dataclass
class Transport:
    mu0: np.ndarray
    sin_hg: np.ndarray
    cos_hg: np.ndarray
    e_beam: np.ndarray
    mu: np.ndarray
    geom: np.ndarray
    #: ``e_beam`` before shadowing by other bodies and by the Moon itself (ray tracing only)
    e_beam_free: np.ndarray | None = None
    #: earthshine only: ``e_beam`` for an Earth of albedo 1 everywhere (the Earth is Lambert,
    #: so earthshine is linear in its albedo: the weights of ``earth_visible_lit_albedo``)
    e_beam_unit: np.ndarray | None = None
    #: earthshine of a spectral run (:mod:`lunarviz.surfaces.earth_spectra`): ``e_beam`` for each surface
    #: component's weight as the Earth's albedo, ``{name: (N, K)}``; ``None``: one uniform component
    e_beam_parts: dict | None = None
    #: per-sample values of a lunar albedo map (:mod:`lunarviz.surfaces.maps`): the BRDF's albedo
    #: parameter itself (``albedo_absolute``) or a factor on it; ``None``: the scalar
    albedo: np.ndarray | None = None
    albedo_absolute: bool = False
    #: the map's standard deviation over each sample's area (same units as ``albedo``): a BRDF
    #: that is not linear in its albedo (Hapke's H-functions) is averaged over it (below)
    albedo_std: np.ndarray | None = None
    #: the mapped lune rule's map (:mod:`lunarviz.geometry.mapped_lune`): ``(values (Q,), factors
    #: (N, Q))``: each sample shaded at every map value, weighted by its factor (``albedo_absolute``
    #: as above); ``None``: ``albedo`` per sample or none
    albedo_nodes: tuple | None = None
    #: the rough Hapke geometry of these beams (effective cosines and shadowing), computed once per
    #: model's roughness by the spectral shading (:mod:`lunarviz.spectral.shading`) and kept for
    #: the transport's other shadings (an image shades each chunk at several lunar albedo values)
    rough_geometry: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def _node_radiances(self, brdf):
        """:meth:`radiances` with :attr:`albedo_nodes`: the BRDF at every map value (the geometry's
        part of a rough Hapke computed once, broadcast over the values), each sample's radiance
        the factor-weighted sum over them."""
        values, factors = self.albedo_nodes
        w = np.asarray(values, dtype=float) * map_scale(self.albedo_absolute, brdf)
        N = len(self.mu)
        if rough_kernels.handles(brdf):  # compiled: each beam's geometry once, the H-functions per value
            return rough_kernels.rough_node_radiances(brdf, self.mu0, self.mu, self.sin_hg, self.cos_hg,
                                                      self.e_beam, self.e_beam_unit, w, factors)
        compiled = shading_kernels.available() and (shading_kernels.hapke_codes(brdf) is not None
                                                    or type(brdf) is Lambert)
        if compiled:
            L, U = np.zeros(N), None if self.e_beam_unit is None else np.zeros(N)
            for q, wq in enumerate(w):
                lq, uq = Transport(mu0=self.mu0, sin_hg=self.sin_hg, cos_hg=self.cos_hg, e_beam=self.e_beam,
                                   mu=self.mu, geom=self.geom, e_beam_unit=self.e_beam_unit,
                                   albedo=np.full(N, wq), albedo_absolute=True).radiances(brdf)
                L += lq * factors[:, q]
                if U is not None:
                    U += uq * factors[:, q]
            return L, U
        rf = brdf.radiance_factor(self.mu0[:, None, :], self.mu[:, None, None], self.sin_hg[:, None, :],
                                  self.cos_hg[:, None, :], albedo=w[None, :, None])  # (N, Q, K)
        L = np.einsum("nqk,nk,nq->n", rf, self.e_beam, factors)
        return L, None if self.e_beam_unit is None else np.einsum("nqk,nk,nq->n", rf, self.e_beam_unit, factors)

    def sample_albedo(self, brdf):
        """The BRDF's albedo parameter per sample ((N, 1), for ``albedo=``), or ``None``."""
        if self.albedo is None:
            return None
        return (self.albedo * map_scale(self.albedo_absolute, brdf))[:, None]

    def _albedo_pair(self, brdf):
        """``(w - σ, w + σ)`` per sample ((N, 1) each) where the map varies within the samples'
        areas and the BRDF is not linear in w, else ``None``: the mean of the BRDF at the two
        is exact to second order in the variation (the mean of f(w) over an area is
        f(w̄) + f''(w̄) σ²/2 + …), where f(w̄) alone is first order (Hapke reflectance grows
        faster than linearly with w)."""
        if self.albedo is None or self.albedo_std is None or getattr(brdf, "linear_in_albedo", False):
            return None
        if not np.any(self.albedo_std > 0):
            return None
        k = map_scale(self.albedo_absolute, brdf)
        a, s = self.albedo * k, self.albedo_std * k
        return np.clip(a - s, 0.0, 1.0)[:, None], np.clip(a + s, 0.0, 1.0)[:, None]

    def radiance(self, brdf) -> np.ndarray:
        """Radiance toward the detector at each sample [W m⁻² sr⁻¹], paper Eq. 10."""
        return self.radiances(brdf)[0]

    def radiances(self, brdf) -> tuple[np.ndarray, np.ndarray | None]:
        """Radiance toward the detector [W m⁻² sr⁻¹] and, for earthshine, the same for an
        Earth of albedo 1 (``None`` without ``e_beam_unit``); one BRDF evaluation for both."""
        if self.albedo_nodes is not None:
            return self._node_radiances(brdf)
        if shading_kernels.available() and shading_kernels.hapke_codes(brdf) is not None:
            # compiled: one pass over the beams, no (N, K) temporaries (lunarviz.photometry.shading_kernels)
            args = (brdf, self.mu0, self.mu, self.sin_hg, self.cos_hg, self.e_beam, self.e_beam_unit)
            pair = self._albedo_pair(brdf)
            if pair is None:
                a = self.sample_albedo(brdf)
                return shading_kernels.hapke_radiances(*args, None if a is None else a[:, 0])
            (lo, lo_u), (hi, hi_u) = (shading_kernels.hapke_radiances(*args, w[:, 0]) for w in pair)
            return 0.5 * (lo + hi), None if lo_u is None else 0.5 * (lo_u + hi_u)
        if rough_kernels.handles(brdf):  # compiled rough Hapke: each beam's geometry once, its w (or two)
            pair, n = self._albedo_pair(brdf), len(self.mu)
            if pair is not None:
                w, f = np.concatenate(pair, axis=1), np.full((n, 2), 0.5)
            else:
                a = self.sample_albedo(brdf)
                w, f = (np.array([[brdf.albedo_parameter]]) if a is None else a), np.ones((n, 1))
            return rough_kernels.rough_node_radiances(brdf, self.mu0, self.mu, self.sin_hg, self.cos_hg, self.e_beam,
                                                      self.e_beam_unit, w, f)
        if shading_kernels.available() and type(brdf) is Lambert:  # linear in albedo: no pair
            a = self.sample_albedo(brdf)
            return shading_kernels.lambert_radiances(brdf, self.mu0, self.e_beam, self.e_beam_unit,
                                             None if a is None else a[:, 0])
        pair = self._albedo_pair(brdf)
        if pair is not None:
            rf = 0.5 * sum(brdf.radiance_factor(self.mu0, self.mu[:, None], self.sin_hg, self.cos_hg, albedo=w)
                           for w in pair)
        else:
            rf = brdf.radiance_factor(self.mu0, self.mu[:, None], self.sin_hg, self.cos_hg,
                                      albedo=self.sample_albedo(brdf))
        unit = None if self.e_beam_unit is None else np.sum(rf * self.e_beam_unit, axis=1)
        return np.sum(rf * self.e_beam, axis=1), unit

    def irradiance_on_sample(self) -> np.ndarray:
        """Irradiance on the surface at each sample [W m⁻²]: Σ_k μ0 e_beam."""
        return np.sum(np.clip(self.mu0, 0.0, None) * self.e_beam, axis=1)

    def lit_fraction_parts(self) -> tuple[np.ndarray, np.ndarray]:
        """Per sample: irradiance with shadows and without (Σ_k μ0 e_beam, same unshadowed);
        their ratio is the lit (unshadowed) fraction."""
        free = self.e_beam if self.e_beam_free is None else self.e_beam_free
        mu0 = np.clip(self.mu0, 0.0, None)
        return np.sum(mu0 * self.e_beam, axis=1), np.sum(mu0 * free, axis=1)

    def detector_irradiance(self, brdf) -> float:
        """Irradiance at the detector [W m⁻²], paper Eq. 11."""
        return float(np.dot(self.radiance(brdf), self.geom))

    def detector_irradiances(self, brdf) -> tuple[float, float | None]:
        """Detector irradiance [W m⁻²] and the same for an Earth of albedo 1 (or ``None``)."""
        L, L1 = self.radiances(brdf)
        return float(np.dot(L, self.geom)), None if L1 is None else float(np.dot(L1, self.geom))


def detector_geometry(points, normals, areas, det, det_normal):
    """``mu`` and ``geom`` for samples at ``points`` with ``normals`` and ``areas`` [m²].

    ``geom = μ · cosδ · dA / d²`` where μ is the cosine of emission toward the detector and δ
    the angle off the detector's normal; both clipped at 0 (back faces, detector's back side).
    """
    v = det[None, :] - points
    d2 = np.einsum("ij,ij->i", v, v)
    d = np.sqrt(d2)
    mu = np.einsum("ij,ij->i", normals, v) / d
    cos_det = -np.einsum("ij,j->i", v, det_normal) / d
    geom = np.clip(mu, 0.0, None) * np.clip(cos_det, 0.0, None) * areas / d2
    return np.clip(mu, 0.0, 1.0), geom, v / d[:, None]
