"""A cloud: the reflectance factor of a plane-parallel water cloud, from the packaged DISORT table.

The cloud of :data:`~lunarviz.earth_optics.disort_tables.CLOUD` (optical depth 10, single-scattering
albedo 0.99999, Henyey–Greenstein g = 0.85, over a surface of albedo 0.06), solved by DISORT when
the tables were made (docs: the Earth as it reflects); here interpolated cubically in the zenith
angles and linearly in azimuth (5° nodes). Grey: a thick water cloud's albedo changes by ~3 % from
450 to 865 nm (King 1997), neglected. The Rayleigh layer above the cloud top is :mod:`.atmosphere`'s
job (the cloud class takes the optical depth above ``cloud_top_hpa``). Neglected: the droplets'
glory and rainbow (a Henyey–Greenstein phase function has neither), ice clouds, broken clouds' 3-D
effects.
"""

from __future__ import annotations

import numpy as np

from lunarviz.earth_optics.disort_tables import CLOUD_PHI_DEG, THETA_DEG, cubic_weights, load, theta_of


def cloud_reflectance(mu0, mu, phi_deg) -> np.ndarray:
    """The cloud's reflectance factor (azimuth 0 = viewer on the Sun's side)."""
    rf = load("cloud")["rf"]
    mu0, mu, phi = np.broadcast_arrays(np.asarray(mu0, float), np.asarray(mu, float), np.asarray(phi_deg, float))
    i0, w0 = cubic_weights(THETA_DEG, theta_of(mu0))
    i1, w1 = cubic_weights(THETA_DEG, theta_of(mu))
    a = np.abs(np.remainder(phi + 180.0, 360.0) - 180.0)  # fold into 0 … 180 (the plane of the Sun is a mirror)
    step = CLOUD_PHI_DEG[1] - CLOUD_PHI_DEG[0]
    j = np.clip((a // step).astype(int), 0, len(CLOUD_PHI_DEG) - 2)
    f = (a - CLOUD_PHI_DEG[j]) / step
    out = 0.0
    for jj, wj in ((j, 1.0 - f), (j + 1, f)):
        nodes = rf[i0[..., :, None], i1[..., None, :], jj[..., None, None]]
        out = out + wj * np.einsum("...a,...b,...ab->...", w0, w1, nodes)
    return out
