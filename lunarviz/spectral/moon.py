"""A spectral Moon: each lunar BRDF's parameters as functions of wavelength.

``--moon-model rolo-fit`` and ``rolo-fit-map`` carry a table per BRDF fitted to ROLO at its 32
band wavelengths (350-2383.6 nm; the fit and its residuals: docs, light in colour): w and the
phase function per band (and the map's contrast, below), the roughness θ̄ and the opposition
effect (B0, h) one value for all bands. Between the bands every parameter is linear in λ; outside
350-2383.6 nm a spectral run with such a model is refused. The ``paper`` model (Table 2, Apollo
soil 10084 at 750 nm, and the Lambert 0.10) has no colour: it is grey, the same parameters at
every wavelength, and so is every parameter a user sets with ``--param``: it replaces that
parameter's values at every λ, the rest of the table stays spectral.

A lunar albedo map relative to its mean (the pattern of maria and highlands) scales w(λ) (or the
Lambert albedo(λ)) per facet with a contrast k(λ): ``w_facet(λ) = w(λ) · (1 − k + k · map/⟨map⟩)``,
the documented colour law of the maria (bluer than the highlands: their contrast with the
highlands grows toward the red and near infrared). ``rolo-fit-map`` fits k per band with the
rest (``map_contrast`` in its table); other models keep k = 1, the map as it is. A map given as
the parameter itself (``FILE:MEAN``) is grey. Neglected: colour differences within the maria
and within the highlands (a map with a spectral dimension is left for later).
"""

from __future__ import annotations

import numpy as np

from lunarviz.errors import LunarvizError
from lunarviz.photometry.brdf import make_brdf
from lunarviz.photometry.presets import spectral_table


def parameters_at(moon_model: str, brdf: str, wavelength_nm, overrides: dict | None = None,
                  grey_model=None) -> dict[str, np.ndarray]:
    """Every parameter of ``brdf`` at each wavelength [nm]: ``{name: array}`` (same length).

    From the preset's spectral table (linear in λ between its wavelengths) where it has one,
    else the grey model's parameters (``grey_model``, the BRDF of the grey run) at every λ;
    ``overrides`` (the user's ``--param``) replace a parameter at every λ."""
    lam = np.atleast_1d(np.asarray(wavelength_nm, dtype=float))
    grey = (grey_model or make_brdf(brdf, moon_model=moon_model, params=overrides)).params
    out = {k: np.full(lam.shape, float(v)) for k, v in grey.items()}
    table = spectral_table(moon_model, brdf)
    if table is not None:
        tl = np.asarray(table["wavelength_nm"], dtype=float)
        bad = lam[(lam < tl[0]) | (lam > tl[-1])]
        if bad.size:
            raise LunarvizError(f"wavelength {bad[0]:g} nm: --moon-model {moon_model} is tabulated over "
                                f"{tl[0]:g}-{tl[-1]:g} nm (ROLO's bands)")
        for k, v in table["params"].items():
            if (k in out or k == MAP_CONTRAST) and k not in (overrides or {}):
                out[k] = np.interp(lam, tl, np.asarray(v, dtype=float))
    return out


#: the lunar map's contrast at λ (a parameter of the Moon, not of its BRDF): w_facet(λ) =
#: w(λ) · (1 − k(λ) + k(λ) · map/⟨map⟩); k = 1 is the map as given (the grey run)
MAP_CONTRAST = "map_contrast"


def models_at(grey_model, params: dict[str, np.ndarray], index: int):
    """The BRDF object at wavelength ``index`` of ``params`` (:func:`parameters_at`)."""
    return grey_model.with_params(**{k: float(v[index]) for k, v in params.items() if k != MAP_CONTRAST})
