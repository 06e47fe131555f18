"""Per-facet results on the lunar mesh (cell data) for one phase and one BRDF: the arrays, with no
tracer loaded (:func:`lunarviz.methods.tracer.facets.trace_facets` computes them).

Arrays (one value per lunar facet, zero where a facet is dark or unseen):

* ``solar_irradiance_W_m2``, ``earth_irradiance_W_m2`` — irradiance on the facet;
* ``moonshine_radiance_W_m2_sr``, ``earthshine_radiance_W_m2_sr`` — radiance toward the
  detector;
* ``moonshine_contribution_W_m2``, ``earthshine_contribution_W_m2`` — each facet's share of the
  detector irradiance (they sum to the totals exactly);
* ``incidence_deg``, ``emission_deg``, ``phase_deg`` — at the centroid, for the Sun's centre
  and the detector; ``earth_incidence_deg``, ``earth_phase_deg`` for the Earth's centre;
* ``brdf_per_sr``, ``reflectance_factor`` — the BRDF at those angles (sunlight), and
  ``earth_brdf_per_sr`` (earthlight);
* ``moonshine_rays``, ``earthshine_rays`` — beams traced per facet (rays that carried light);
* ``albedo_parameter`` — the BRDF's albedo parameter on the facet (Lambert albedo or Hapke w:
  the scalar, or the lunar albedo map's area average, :mod:`lunarviz.surfaces.maps`).

Earth facets carry ``albedo`` (their Lambert albedo: uniform, or the land/ocean/cloud surface
averaged by area) and ``radiance_toward_moon_W_m2_sr``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class FacetResult:
    """Per-facet arrays of one task on the Moon's mesh (and on the Earth's and the Sun's).

    Parameters
    ----------
    vertices : numpy.ndarray
        (nv, 3) Moon-centred [m], the Moon's body frame (MOON_ME on dates).
    faces : numpy.ndarray
        (nf, 3) vertex indices.
    cell_data : dict
        The arrays of the module docstring, one value per facet.
    totals : dict
        Detector irradiances [W m⁻²] per path (and per BRDF), rays, seconds.
    info : dict
        The task's geometry and settings.
    bodies : dict
        The other bodies: ``{"earth": (vertices, faces, cell_data), "sun": ...}``, vertices centred
        on each body [m]; centres in ``info["<body>_m"]``.
    """

    vertices: np.ndarray  # (nv, 3) Moon-centred [m], the Moon's body frame (MOON_ME on dates)
    faces: np.ndarray  # (nf, 3)
    cell_data: dict
    totals: dict
    info: dict
    #: the other bodies: ``{"earth": (vertices, faces, cell_data), "sun": ...}``, vertices
    #: centred on each body [m]; centres in ``info["<body>_m"]``
    bodies: dict = field(default_factory=dict)

    @property
    def n_faces(self) -> int:
        return len(self.faces)
