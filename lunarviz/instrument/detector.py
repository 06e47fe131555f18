"""The detector: expected charge, and frames in counts with their noise.

Per pixel and exposure t [s]:

* charge: ``N ~ Poisson(Ṅ t + D t)`` [e⁻] (photoelectrons at rate Ṅ and dark current D share one
  Poisson draw: the sum of independent Poisson variables), clipped at the full well;
* read-out: ``ADU = round(bias + (N + ε)/g)`` with ε ~ Normal(0, σ_read²) [e⁻], clipped to the
  ADC's 0 … 2^bits − 1 (round half to even: no offset, so the counts' mean is the expected count);
* ``EXPECTED_COUNTS = bias + min(Ṅ t + D t, full well)/g`` (not rounded).

So, unsaturated, ``g (COUNTS − EXPECTED_COUNTS)`` has mean 0 and variance ``Ṅ t + D t + σ_read² + g²/12``
[e⁻²] (the last term is the quantisation's: 0.02 e⁻² for ``salex``, 0.06 % of its σ_read²).

Frames are drawn one at a time from ``numpy.random.default_rng([seed, k])``: frame k is the same
whatever the number of frames asked for, and many frames need the memory of one.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from lunarviz.instrument.spec import Instrument


def expected_electrons(rate_e_s: np.ndarray, inst: Instrument, exposure_s: float) -> np.ndarray:
    """Mean charge per pixel [e⁻] before the full well: (Ṅ + D) t."""
    return (np.asarray(rate_e_s, dtype=float) + inst.dark_current_e_per_s) * exposure_s


def expected_counts(electrons: np.ndarray, inst: Instrument) -> np.ndarray:
    """Noise-free counts [ADU]: bias + min(charge, full well)/gain, at most the ADC's top."""
    return np.minimum(inst.bias_adu + np.minimum(electrons, inst.full_well_e) / inst.gain_e_per_adu, inst.adc_max)


def count_dtype(inst: Instrument):
    return np.uint16 if inst.bit_depth <= 16 else np.uint32


def draw_frame(electrons: np.ndarray, inst: Instrument, rng: np.random.Generator) -> np.ndarray:
    """One frame [ADU] (see the module docstring)."""
    charge = np.minimum(rng.poisson(electrons).astype(float), inst.full_well_e)
    adu = inst.bias_adu + (charge + rng.normal(0.0, inst.read_noise_e, charge.shape)) / inst.gain_e_per_adu
    return np.clip(np.rint(adu), 0, inst.adc_max).astype(count_dtype(inst))


def frames(electrons: np.ndarray, inst: Instrument, n: int, seed: int, stream: tuple = ()) -> Iterator[np.ndarray]:
    """Frames 0 … n−1, each from its own generator ``default_rng([seed, *stream, k])``."""
    for k in range(n):
        yield draw_frame(electrons, inst, np.random.default_rng([int(seed), *stream, k]))


def pixel_variance_e2(electrons: np.ndarray, inst: Instrument) -> np.ndarray:
    """Variance of one pixel's charge estimate [e⁻²]: shot noise + read noise + quantisation."""
    return np.asarray(electrons, dtype=float) + inst.read_noise_e**2 + inst.gain_e_per_adu**2 / 12.0
