"""A cloud: the reflectance factor of a plane-parallel liquid water cloud, from the packaged DISORT table.

The cloud of :data:`~lunarviz.earth_optics.disort_tables.CLOUD`: droplets with Hansen & Travis
(1974)'s gamma size distribution (effective radius 10 µm, effective variance 0.1), their Mie phase
function at 550 nm (forward peak, the rainbow near 141°, the glory at 180°: 1000 Legendre moments), over
a surface of albedo 0.06, at the optical depths of
:data:`~lunarviz.earth_optics.disort_tables.CLOUD_TAU`, solved by DISORT when the tables were made
(docs: the Earth as it reflects); here cubic in log τ, cubic in the zenith angles and linear in
azimuth (5° nodes: the glory, ~2° wide, is smoothed). Grey: a thick water cloud's albedo changes
by ~3 % from 450 to 865 nm (King 1997), neglected, and so is the phase function's change with λ.
The Rayleigh layer above the cloud top is :mod:`.atmosphere`'s job (the cloud class takes the
optical depth above ``cloud_top_hpa``). Neglected: ice clouds, the ground under the cloud (its
albedo is held at 0.06), broken clouds' 3-D effects.
"""

from __future__ import annotations

import numpy as np

from lunarviz.caches import memoize
from lunarviz.earth_optics.disort_tables import CLOUD_PHI_DEG, CLOUD_TAU, THETA_DEG, cubic_weights, load, theta_of
from lunarviz.errors import LunarvizError


@memoize(maxsize=8)
def _table_at(tau: float) -> np.ndarray:
    """The table (mu0, mu, phi) at optical depth τ (the nodes' own where τ is one)."""
    tables = load("cloud")
    if not np.array_equal(tables["tau"], CLOUD_TAU):
        raise LunarvizError("the packaged cloud table's optical depths are not CLOUD_TAU's: remake it with "
                            "scripts/make_earth_tables.py --only cloud")
    table = tables["rf"]
    hit = np.flatnonzero(np.isclose(CLOUD_TAU, tau, rtol=1e-12, atol=0.0))
    if len(hit):
        out = table[hit[0]].astype(float)
    else:
        ti, tw = cubic_weights(np.log(CLOUD_TAU), np.log(np.array([tau])))
        out = np.tensordot(tw[0], table[ti[0]].astype(float), axes=1)
    out.setflags(write=False)
    return out


def cloud_reflectance(mu0, mu, phi_deg, optical_depth: float = 10.0) -> np.ndarray:
    """The cloud's reflectance factor (azimuth 0 = viewer on the Sun's side) at ``optical_depth``."""
    tau = float(optical_depth)
    if not CLOUD_TAU[0] * (1 - 1e-12) <= tau <= CLOUD_TAU[-1] * (1 + 1e-12):
        raise LunarvizError(f"cloud optical depth {tau:g} is outside the tables' {CLOUD_TAU[0]:g}-{CLOUD_TAU[-1]:g}")
    rf = _table_at(tau)
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
