"""Gaussian-derivative peaks (thesis appendix D §11.1.2).

As :mod:`._derivative`, but the derivative is the profile convolved with a sampled derivative of a
Gaussian of ``sigma`` samples (the profile's ends extended with their end values, as the thesis
prescribes). Averaging several neighbours lowers the noise the plain difference amplifies
(its variance ``2 σ_n²``, thesis §11.1.2), at the price of blurring close edges together.
"""

from __future__ import annotations

from .._config import SearchConfig
from ._common import Edges, Profiles, boundary_peaks, gaussian_derivative

__all__ = ["gaussian_peaks"]


def gaussian_peaks(profiles: Profiles, config: SearchConfig) -> Edges:
    """Boundaries at the Gaussian-derivative peaks of the right sign, one per half profile."""
    d, ok, pos = gaussian_derivative(profiles.values, profiles.usable, config.sigma)
    c = profiles.centre
    n = profiles.shape[-1]
    return boundary_peaks(d, ok, pos, ((0.0, c), (c, n - 1.0)), profiles, config.sign, config.min_strength,
                          config.subsample)
