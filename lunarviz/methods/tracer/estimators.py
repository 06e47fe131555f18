"""Moonshine and earthshine by Embree ray tracing: deterministic and Monte Carlo estimators.

Both estimators build the same BRDF-independent :class:`~lunarviz.methods.transport.Transport` as the
analytic method and the exact reference, so one trace per phase serves every BRDF.

Paths (paper Table 1, Sec. 2.1): moonshine Sun → Moon → detector, earthshine
Sun → Earth → Moon → detector. The detector is reached by next-event estimation (Eq. 2):
from every lunar sample a beam toward the detector, weighted by μ cosδ dA / d².

* Lunar samples. ``deterministic`` on the packaged exact-sphere Moon in a sweep: the lune rule,
  product Gauss rules over the lit, visible part of the sphere (``lune_order``, chosen by a
  tolerance: :mod:`lunarviz.methods.accuracy`), a lunar map's cells moved into its weights
  (:mod:`lunarviz.geometry.mapped_lune`); elsewhere (a user's mesh, a lunar map without a
  tolerance, an eclipse, per-facet arrays): one sample per facet (centroid), 16 per facet on the
  facets that straddle the terminator, its penumbra or the detector's limb (where the
  integrand has a kink), and up to 256 per facet across a thin crescent so that ≥ 64 samples
  span the lit and visible lune (adaptive refinement, ``lunar_refinement``). ``montecarlo``: N
  uniform points on facets drawn with probability ∝ a proxy of each facet's contribution,
  defensively mixed with 10 % ∝ area so the estimator stays unbiased.
* Source beams, restricted to the source's solid angle (Table 1). ``deterministic``: for the
  Sun, a Gauss rule over its 0.27° cone where the whole disc is above the horizon, and the
  sphere-surface rule of :mod:`lunarviz.geometry.sphere_quadrature` cut at the horizon elsewhere; for
  the Earth, the sphere-surface rule cut at the horizon and at the Earth's terminator.
  ``montecarlo``: one direction per sample, uniform in the Sun's cone, or drawn over the
  Earth's lit, visible part (docs: derivations, §4). Every beam is a ray traced
  against the source's mesh. The Sun's radiance is uniform, Φ/(4π² R_S²); the Earth's is
  Lambertian, (A/π) E_sun μ_s at the hit, times the fraction of the Sun that the hit facet sees
  (the Moon's shadow, with occlusion on).
* Shading (``shading``): ``auto`` (default) shades the packaged icospheres on the exact
  sphere they tessellate (a documented fast path) and every other mesh on its facets;
  ``smooth`` uses crease-limited interpolated normals on user meshes; ``flat`` the facets
  everywhere. The mesh decides hits and shadows in every mode.
* Occlusion (on by default; ``occlusion=False`` is the paper's assumption): the Earth blocks
  Sun beams (lunar eclipse); the Moon blocks the Sun for Earth facets; a non-convex Moon mesh
  shadows itself (convex meshes skip those rays: the sample's own horizon decides exactly).
* The observer's own Earth: whatever the occlusion setting, the Earth hides lunar samples from
  a detector outside it (traced with Embree; a site on the ground uses its geodetic horizon
  plane), as in the analytic and reference methods.

Neglected physics: refraction and extinction in the Earth's atmosphere (the umbra is darker
than a real eclipse's red Moon), solar limb darkening, polarisation, multiple Moon-Earth
bounces, the Sun's extent when it lights the Earth (O(ρ²) ≈ 2e-5, see :mod:`lunarviz.methods.reference`).

This module runs the estimators (:func:`trace_path`); the traced scene and its jobs are in
:mod:`lunarviz.methods.tracer.trace_scene` and the modules it names.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from lunarviz.methods.tracer.settings import (
    PATHS,
    TraceSettings,
)
from lunarviz.methods.tracer.trace_scene import TraceScene
from lunarviz.surfaces.moon_map import map_scale

__all__ = ["PathResult", "TraceScene", "TraceSettings", "trace_path"]


@dataclass
class PathResult:
    """One path (moonshine or earthshine) at one phase, for every BRDF."""

    mean: dict  # brdf -> detector irradiance [W m-2]
    #: brdf -> standard deviation of one run [W m-2], pooled from the samples within every run
    #: (reliable at any number of runs; 0 for deterministic; NaN when undefined: one ray)
    std: dict
    run_values: dict  # brdf -> list of per-run values [W m-2]
    within_std: dict  # brdf -> list of per-run standard deviations estimated inside each run
    rays: int
    seconds: float
    facets: dict = field(default_factory=dict)  # per-facet arrays (last run)
    #: brdf -> standard deviation of the mean over runs [W m-2]: std / sqrt(runs)
    sem: dict = field(default_factory=dict)
    #: brdf -> spread (ddof 1) of the run values [W m-2]; NaN with one run (a diagnostic)
    spread: dict = field(default_factory=dict)
    #: earthshine only: brdf -> mean for an Earth of albedo 1 [W m-2] (same rays; the
    #: earthshine-weighted albedo of the Earth is ``mean / mean_unit``)
    mean_unit: dict = field(default_factory=dict)
    #: a spectral run (``spectral=``): brdf -> node irradiances at the grey Sun, mean over runs:
    #: moonshine (L,); earthshine (P + 1, L), the Earth's components then an Earth of albedo 1
    #: (:class:`lunarviz.spectral.shading.SpectralShader`)
    spectral: dict = field(default_factory=dict)

    @classmethod
    def zero(cls, brdfs) -> "PathResult":
        """The result of a path no light takes (a Moon the observer cannot see): zeros, no ray."""
        z = {k: 0.0 for k in brdfs}
        return cls(mean=dict(z), std=dict(z), run_values={k: [0.0] for k in brdfs},
                   within_std={k: [0.0] for k in brdfs}, rays=0, seconds=0.0, sem=dict(z), spread=dict(z),
                   mean_unit=dict(z))


def _albedo_scale(ts: TraceScene, brdfs: dict) -> float:
    """The factor from the lunar map's values to the single-scattering albedo w of the BRDFs
    being shaded that are not linear in it (the largest: its reflectance's branch point at w = 1
    is the nearest), for the mapped lune rule's albedo nodes in γ = √(1 - w); 0 (nodes in the map's
    value) without a map or such a BRDF, or in a spectral run (whose w varies with wavelength)."""
    amap = ts.settings.moon_map()
    if amap is None:
        return 0.0
    return max((map_scale(amap.absolute, b) for b in brdfs.values() if not getattr(b, "linear_in_albedo", False)),
               default=0.0)


def trace_path(ts: TraceScene, path: str, brdfs: dict, keep_facets: bool = False, spectral=None) -> PathResult:
    """Trace ``path`` once per run and shade every BRDF from the one transport; ``spectral`` (a
    :class:`~lunarviz.spectral.shading.SpectralShader`) also shades every node wavelength from it."""
    s = ts.settings
    body = PATHS[path]
    ts.sampling.per_facet = keep_facets  # per-facet arrays need facet samples (never the lune rule's)
    ts.sampling.summed = not keep_facets
    ts.sampling.rough_brdf = any(getattr(b, "rough", False) for b in brdfs.values())
    ts.sampling.albedo_scale = 0.0 if spectral is not None else _albedo_scale(ts, brdfs)
    t0 = time.perf_counter()
    r0 = ts.rays_cast
    runs = 1 if s.estimator == "deterministic" else s.runs
    vals = {k: [] for k in brdfs}
    units = {k: [] for k in brdfs}
    within = {k: [] for k in brdfs}
    facets = {}
    spec_runs = []
    nf = ts.moon.n_faces
    for run in range(runs):
        if s.estimator == "deterministic":
            chunks = ts.deterministic.transport(body)
        else:
            chunks = ts.montecarlo.transport(body, [s.seed, run, 0 if path == "moonshine" else 1])
        tot = {k: 0.0 for k in brdfs}
        tot_unit = {k: 0.0 for k in brdfs}
        sq = {k: 0.0 for k in brdfs}
        count = 0
        keep = keep_facets and run == runs - 1
        fac = {}
        spec = {}
        for tr, owner in chunks:
            count += len(owner)
            if spectral is not None:
                got = spectral.moonshine(tr) if body == "sun" else spectral.earthshine(tr)
                for k, v in got.items():
                    spec[k] = spec[k] + v if k in spec else v
            for k, b in brdfs.items():
                L, L_unit = tr.radiances(b)
                contrib = L * tr.geom
                if L_unit is not None:
                    tot_unit[k] += float(np.dot(L_unit, tr.geom))
                tot[k] += float(contrib.sum())
                sq[k] += float(np.dot(contrib, contrib))
                if keep:
                    key = f"{path}_contribution_{k}"
                    fac[key] = fac.get(key, 0.0) + np.bincount(owner, contrib, nf)
            if keep:
                lit_s, free_s = tr.lit_fraction_parts()
                for key, per_sample in ((f"{path}_irr_sum", tr.irradiance_on_sample()),
                                        (f"{path}_lit_sum", lit_s),
                                        (f"{path}_free_sum", free_s),
                                        (f"{path}_count", np.ones(len(owner))),
                                        (f"{path}_rays", (tr.e_beam > 0).sum(1).astype(float)),
                                        (f"{path}_geom", tr.geom)):
                    fac[key] = fac.get(key, 0.0) + np.bincount(owner, per_sample, nf)
        spec_runs.append(spec)
        for k in brdfs:
            vals[k].append(tot[k])
            units[k].append(tot_unit[k])
            if s.estimator == "montecarlo" and count > 1:
                # contributions c_i = f_i / (N p_i): Var(Σ c) = N Var(c), Var(c) from the sums
                var_c = (sq[k] - tot[k] ** 2 / count) / (count - 1)
                within[k].append(float(np.sqrt(max(count * var_c, 0.0))))
            elif s.estimator == "montecarlo":
                within[k].append(float("nan"))  # one sample: no spread to estimate σ from
            else:
                within[k].append(0.0)
        if keep:
            zero = np.zeros(nf)
            for k in brdfs:
                facets[f"{path}_contribution_{k}"] = np.asarray(fac.get(f"{path}_contribution_{k}", zero))
            cnt = np.asarray(fac.get(f"{path}_count", zero))
            facets[f"{path}_irradiance"] = np.asarray(fac.get(f"{path}_irr_sum", zero)) / np.maximum(cnt, 1)
            facets[f"{path}_rays"] = np.asarray(fac.get(f"{path}_rays", zero))
            facets[f"{path}_geom"] = np.asarray(fac.get(f"{path}_geom", zero))
            facets[f"{path}_lit_sum"] = np.asarray(fac.get(f"{path}_lit_sum", zero))
            facets[f"{path}_free_sum"] = np.asarray(fac.get(f"{path}_free_sum", zero))
    std, sem, spread = {}, {}, {}
    for k in brdfs:
        if s.estimator == "deterministic":
            std[k] = sem[k] = spread[k] = 0.0
            continue
        # pooled: every run's σ is estimated from its own N samples, so the pooled value is as
        # good with one run as with many (the spread of a few runs is not: with 4 runs its
        # relative error is ~40 %, enough to show "7.9 σ" deviations in a quick report)
        std[k] = float(np.sqrt(np.mean(np.square(within[k]))))
        sem[k] = std[k] / np.sqrt(runs)
        spread[k] = float(np.std(vals[k], ddof=1)) if runs >= 2 else float("nan")
    return PathResult(mean={k: float(np.mean(v)) for k, v in vals.items()}, std=std,
                      run_values=vals, within_std=within, rays=ts.rays_cast - r0,
                      seconds=time.perf_counter() - t0, facets=facets, sem=sem, spread=spread,
                      mean_unit={k: float(np.mean(v)) for k, v in units.items()} if body == "earth" else {},
                      spectral={k: np.mean([r[k] for r in spec_runs], axis=0) for k in spec_runs[0]}
                      if spectral is not None and spec_runs and spec_runs[0] else {})
