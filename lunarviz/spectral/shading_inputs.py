"""What a spectral run shades with, besides the grey BRDF models and the Earth's surface."""

from __future__ import annotations

from dataclasses import dataclass, field

from lunarviz.options import BY_NAME, THETA_MOON_MODEL
from lunarviz.spectral.request import SpectralRequest


@dataclass(frozen=True)
class SpectralInputs:
    """A spectral run's light: the request (node wavelengths, outputs, the Sun's spectrum), the
    lunar preset and overrides whose band-by-band fits give each node's BRDF parameters
    (:func:`lunarviz.spectral.moon.parameters_at`), and the spectra of the Earth's classes.

    Parameters
    ----------
    request : SpectralRequest
        Node wavelengths [nm], their weights into the outputs and the solar spectrum at 1 au.
    moon_model : str
        The lunar BRDF preset (``paper``, ``rolo-fit``, ``rolo-fit-map``).
    params : dict
        Lunar BRDF overrides ``{brdf: {name: value}}`` (grey: the same at every node).
    earth_spectra : str
        ``surface`` (the classes' packaged spectra) or ``grey`` (their grey albedos).
    """

    request: SpectralRequest
    moon_model: str = THETA_MOON_MODEL
    params: dict = field(default_factory=dict)
    earth_spectra: str = BY_NAME["earth_spectra"].default
