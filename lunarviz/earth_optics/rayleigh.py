"""Rayleigh scattering by dry air: optical depth and phase function.

Optical depth: Bodhaine, Wood, Dutton & Slusser (1999), *J. Atmos. Oceanic Technol.* 16,
1854–1861, Eq. 30 (sea level, 1013.25 hPa, 45° latitude, 360 ppm CO₂; λ in µm), scaled by
pressure. Phase function with the molecular depolarisation ratio ρₙ (Chandrasekhar 1950;
Hansen & Travis 1974, Eq. 2.15)::

    P(Θ) = 3 / (4 (1 + 2γ)) · [(1 + 3γ) + (1 − γ) cos²Θ],   γ = ρₙ / (2 − ρₙ)

normalised to ∫P dΩ/4π = 1, whose Legendre expansion ends at order 2: χ₀ = 1,
χ₂ = (1 − γ) / (2 (1 + 2γ)) (DISORT's moment ``pmom[2] = χ₂/5``). Neglected: polarisation
(the scalar equation: a few per cent on the Rayleigh radiance, largest near 90° scattering;
Mishchenko et al. 1994), the King factor's small change with λ in ρₙ (ρₙ fixed at 0.0279,
Young 1980), aerosols. (Ozone absorbs above the layer: :mod:`.ozone`.)
"""

from __future__ import annotations

import numpy as np

from lunarviz.constants import SEA_LEVEL_HPA

#: molecular depolarisation ratio of air (Young 1980, *Appl. Opt.* 19, 3427)
DEPOLARISATION = 0.0279


def optical_depth(wavelength_nm, pressure_hpa: float = SEA_LEVEL_HPA) -> np.ndarray:
    """Rayleigh optical depth of the whole atmosphere above ``pressure_hpa`` at λ [nm]
    (Bodhaine et al. 1999, Eq. 30; 0.0973 at 550 nm at sea level)."""
    lam = np.asarray(wavelength_nm, dtype=float) * 1e-3
    l2 = lam * lam
    tau = 0.0021520 * (1.0455996 - 341.29061 / l2 - 0.90230850 * l2) / (1.0 + 0.0027059889 / l2 - 85.968563 * l2)
    return tau * (pressure_hpa / SEA_LEVEL_HPA)


def gamma(depolarisation: float = DEPOLARISATION) -> float:
    """γ = ρₙ / (2 − ρₙ) of the phase function."""
    return depolarisation / (2.0 - depolarisation)


def phase_function(cos_scattering, depolarisation: float = DEPOLARISATION) -> np.ndarray:
    """P(Θ) normalised to 1 over 4π (the module's equation)."""
    g = gamma(depolarisation)
    c = np.asarray(cos_scattering, dtype=float)
    return 0.75 / (1.0 + 2.0 * g) * ((1.0 + 3.0 * g) + (1.0 - g) * c * c)


def legendre_moment_2(depolarisation: float = DEPOLARISATION) -> float:
    """χ₂ / 5, DISORT's second phase-function moment (0.1 without depolarisation)."""
    g = gamma(depolarisation)
    return (1.0 - g) / (2.0 * (1.0 + 2.0 * g)) / 5.0
