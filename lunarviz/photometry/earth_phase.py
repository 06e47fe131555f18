"""The Earth as a Lambertian sphere: its intensity law and the printed paper Eq. 8.

A Lambertian sphere of Bond albedo A and radius R under irradiance E has geometric albedo
p = 2A/3 and intensity toward phase angle β (Russell 1916; Lester et al. 1979)::

    I(β) = (2/3) A R² E · [(π - β) cos β + sin β] / π            [W sr⁻¹]

which integrates over all directions to π R² A E (energy conservation). The paper's printed
Eq. 8 drops the factor 2/3 (paper notes, item 1); it is available only as ``law="paper_eq8"``.
"""

from __future__ import annotations

import numpy as np

from lunarviz.errors import LunarvizError
from lunarviz.options import EARTH_LAWS


def lambert_phase_function(beta) -> np.ndarray:
    """Lambert-sphere phase function f_L(β) = [(π - β) cos β + sin β]/π, f_L(0) = 1.

    Near β = π the two terms cancel (f_L = ε³/(3π) for ε = π - β); there the Taylor series
    (sin ε - ε cos ε)/π = (ε³/3 - ε⁵/30 + ε⁷/840)/π is used (error < ε⁹/45360 relative ~1e-15
    at ε < 0.05).
    """
    beta = np.asarray(beta, dtype=float)
    eps = np.pi - beta
    direct = ((np.pi - beta) * np.cos(beta) + np.sin(beta)) / np.pi
    e2 = eps * eps
    series = eps * e2 * (1.0 / 3.0 - e2 / 30.0 + e2 * e2 / 840.0) / np.pi
    return np.where(np.abs(eps) < 0.05, series, direct)


def earth_intensity(beta, albedo: float, radius: float, irradiance: float,
                    law: str = "lambert") -> np.ndarray:
    """Intensity of the Earth toward phase angle β [rad] [W sr⁻¹].

    ``law="lambert"`` is the correct Lambert-sphere law; ``law="paper_eq8"`` is Eq. 8 as
    printed, 3/2 times brighter.
    """
    if law not in EARTH_LAWS:
        raise LunarvizError(f"Earth intensity law {law!r} is not one of {', '.join(EARTH_LAWS)}")
    factor = 2.0 / 3.0 if law == "lambert" else 1.0
    return factor * albedo * radius**2 * irradiance * lambert_phase_function(beta)
