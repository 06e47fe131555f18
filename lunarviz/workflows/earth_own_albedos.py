"""A run's model Earth described by its own albedos, apart from what the run's rows invert to.

A sweep reports ``earth_spherical_albedo``, ``earth_geometric_albedo`` and ``earth_phase_integral``
(:func:`lunarviz.surfaces.earth_albedos.earth_albedos`: exact over every direction) beside the
``bond_albedo`` that Eq. 17 estimates from the sampled phases' p*. Where they differ, the Eq. 17
estimate is biased by the Earth's departure from a Lambert sphere or by the phases missed.

The θ scene's Earth is lit the same way at every θ (the Sun and the Earth are fixed; its sub-solar
longitude is ``earth_rotation_deg``): one geometry. Dated runs: the mean over up to
:data:`MAX_DATES` of their dates, evenly spread (the sub-solar point moves with the hour and the
season); the dates used are listed. Spectral runs: per wavelength, or per band the solar- and
response-weighted means of the node values (the power ratios of the band). The analytic method with
``earth_law="paper_eq8"`` (the printed Eq. 8) reports that law's Earth, 3/2 as bright.
"""

from __future__ import annotations

import numpy as np

from lunarviz.options import earth_params
from lunarviz.parsing import wavelength_label
from lunarviz.surfaces.earth_albedos import earth_albedos
from lunarviz.surfaces.maps import map_frame

#: the most dates of a dated run at which the Earth's albedos are computed and averaged
MAX_DATES = 12


def run_earth_albedos(settings) -> dict:
    """``{earth_spherical_albedo, earth_geometric_albedo, earth_phase_integral, earth_albedo_at}``
    of a :class:`~lunarviz.scene.ResolvedScene`: floats for a grey run, ``{label: value}`` for a
    spectral one (labels as the rows' ``wavelength_nm`` text or ``band``); with a physical Earth
    also ``earth_parameters``, all of them with their defaults (the settings hold only those given)."""
    surface = settings.earth_model()
    request = settings.spectral_request()
    keys = settings.tasks()
    if settings.times is None:
        keys = keys[:1]
    else:
        keys = [keys[i] for i in sorted(set(np.linspace(0, len(keys) - 1, min(len(keys), MAX_DATES)).round()
                                            .astype(int)))]
    nodes = None if request is None else request.nodes
    sums = {"spherical": 0.0, "geometric": 0.0}
    for k in keys:
        sc = settings.geometry(k)
        a = earth_albedos(surface, sc, map_frame(sc, "earth", settings.earth_rotation_deg or 0.0), nodes,
                          settings.earth_spectra)
        for name in sums:
            sums[name] = sums[name] + a[name] / len(keys)
    if settings.method == "analytic" and settings.earth_law == "paper_eq8":
        # the paper's printed Eq. 8: 3/2 the Lambert sphere's intensity at every phase (docs: paper
        # notes, item 1): its Earth sends out 3/2 of the power a Lambert sphere of its albedo would
        sums = {name: 1.5 * v for name, v in sums.items()}
    if request is not None:
        sums = {name: request.averages(v) for name, v in sums.items()}
    values = {"earth_spherical_albedo": sums["spherical"], "earth_geometric_albedo": sums["geometric"],
              "earth_phase_integral": sums["spherical"] / sums["geometric"]}
    if request is None:
        out = {k: float(v[0]) for k, v in values.items()}
    else:
        label = wavelength_label if request.kind == "wavelength" else str
        out = {k: {label(lab): float(x) for lab, x in zip(request.labels, v)} for k, v in values.items()}
    out["earth_albedo_at"] = list(keys) if settings.times is not None else \
        f"the θ scene (sub-solar longitude {settings.earth_rotation_deg or 0.0:g}°)"
    if surface.physical:  # every parameter the physical Earth ran with, defaults included
        out["earth_parameters"] = earth_params(dict(surface.earth_params))
    return out
