"""What a spectral run asks for: wavelengths or bands, the nodes they are shaded at, and the weights
that turn node transports into spectral or band values.

A run's transport T(λ) [W m⁻², lit by the grey Sun of power Φ] is shaded at node wavelengths λ_j
(:mod:`lunarviz.spectral.shading`); its outputs are ``E_o = (4π au²/Φ) Σ_j W_oj T(λ_j)``:

* ``--wavelengths``: the nodes are the wavelengths and ``W = diag(E_sun(λ_j))`` [W m⁻² nm⁻¹ at
  1 au], so ``E(λ)`` [W m⁻² nm⁻¹] is the grey transport times the Sun's spectral power over its
  grey power (:func:`lunarviz.spectral.solar.solar_scale`);
* ``--band``: the nodes cover each band every 10 nm and ``W_oj`` integrates E_sun·S against
  node j's hat function (:func:`lunarviz.spectral.bands.band_weights`): ``E_o = ∫ E S dλ`` [W m⁻²].

``solar_1au`` is each output's solar irradiance at 1 au (``E_sun(λ)``, or ``∫ E_sun S dλ``); rows
carry it at the Moon, scaled by the Sun-Moon distance as the transport's Sun is.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lunarviz.errors import LunarvizError
from lunarviz.parsing import parse_float_list, wavelength_label
from lunarviz.spectral.bands import band_nodes, band_weights, parse_bands
from lunarviz.spectral.solar import AU_M, SolarSpectrum, solar_spectrum

#: at most this many wavelengths in one run (memory per chunk grows with it: 5000 × a few
#: component sums; rows grow with it times tasks times BRDFs)
MAX_WAVELENGTHS = 5000
#: wavelengths outside this range [nm] are refused before any table is read
WAVELENGTH_RANGE = (100.0, 100_000.0)


@dataclass(frozen=True)
class SpectralRequest:
    kind: str  # "wavelength" or "band"
    labels: tuple  # wavelengths [nm] or band names
    nodes: np.ndarray  # (L,) node wavelengths [nm]
    weights: np.ndarray  # (O, L) [W m-2 nm-1 at 1 au per node], see the module docstring
    solar_1au: np.ndarray  # (O,) [W m-2 nm-1] or [W m-2]
    solar: SolarSpectrum
    centres_nm: tuple = ()  # each output's wavelength, or its band's response-weighted mean [nm]

    @property
    def value_suffix(self) -> str:
        """The unit suffix of the rows' irradiance fields."""
        return "_W_m2_nm" if self.kind == "wavelength" else "_W_m2"

    def outputs(self, node_values: np.ndarray, phi_w: float) -> np.ndarray:
        """``(4π au²/Φ) W @ T``: spectral [W m⁻² nm⁻¹] or band [W m⁻²] values from node
        transports (L,) or (..., L) at the grey Sun of power ``phi_w`` [W]."""
        return (4.0 * np.pi * AU_M**2 / phi_w) * (np.asarray(node_values) @ self.weights.T)

    def averages(self, node_values: np.ndarray) -> np.ndarray:
        """Solar-weighted means of node transports over each output (their own values for
        wavelengths): the grey-Sun-level quantities the albedo inversion takes."""
        return np.asarray(node_values) @ (self.weights / self.weights.sum(axis=1, keepdims=True)).T


def parse_wavelengths(text: str) -> tuple[float, ...]:
    """``LIST|START:STOP:STEP`` [nm] (stop inclusive), distinct, order kept as given."""
    lam = parse_float_list(text, "wavelength", *WAVELENGTH_RANGE)
    if len(lam) > MAX_WAVELENGTHS:
        raise LunarvizError(f"{len(lam)} wavelengths: at most {MAX_WAVELENGTHS} in one run")
    labels = [wavelength_label(v) for v in lam]
    if len(set(labels)) != len(labels):
        dup = next(v for v in labels if labels.count(v) > 1)
        raise LunarvizError(f"wavelength {dup} nm is listed twice (to 12 significant digits)")
    return tuple(lam)


def spectral_request(wavelengths: str | None, bands: str | None, solar: str) -> SpectralRequest | None:
    """The request of a run's ``wavelengths``/``bands`` options; ``None`` for a grey run."""
    if wavelengths is None and bands is None:
        return None
    if wavelengths is not None and bands is not None:
        raise LunarvizError("give --wavelengths (spectral rows) or --band (band-integrated rows), not both")
    sun = solar_spectrum(solar)
    if wavelengths is not None:
        lam = np.array(parse_wavelengths(wavelengths))
        e = sun.at(lam)
        return SpectralRequest("wavelength", tuple(float(x) for x in lam), lam, np.diag(e), e, sun,
                               tuple(float(x) for x in lam))
    return band_request(parse_bands(bands), sun)


def band_request(bs, sun: SolarSpectrum) -> SpectralRequest:
    """The request of bands ``bs`` (:class:`~lunarviz.spectral.bands.Band`, distinct names) lit by ``sun``."""
    nodes = np.unique(np.concatenate([band_nodes(b) for b in bs]))
    W = np.stack([band_weights(b, nodes, sun) for b in bs])
    # a node no band weighs (a gap in a response wider than the node step) is not shaded: the
    # outputs W @ T do not change, exactly
    used = np.any(W > 0, axis=0)
    nodes, W = nodes[used], W[:, used]
    return SpectralRequest("band", tuple(b.name for b in bs), nodes, W, W.sum(axis=1), sun,
                           tuple(b.centre_nm for b in bs))
