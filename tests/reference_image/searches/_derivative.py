"""Derivative peaks (thesis appendix D §11.1.1, DigitEyes §4).

Each profile is differentiated with ``D(k) = I(k+1) - I(k)`` (eq. 11.1) and each boundary is the
peak of the right sign: for a bright hand the first boundary is the largest positive derivative and
the second the largest negative one (DigitEyes: "peaks in the derivative with the correct sign").
Each peak is searched on its own side of the predicted axis, which keeps the edges of a
neighbouring finger from being taken for this one's. Positions are ``k + 0.5`` (the point half way
between the two samples, which the thesis names as the best choice) and, with ``subsample``, moved
to the vertex of the parabola through the peak and its neighbours. The method knows nothing of
occlusion.
"""

from __future__ import annotations

from .._config import SearchConfig
from ._common import Edges, Profiles, boundary_peaks, simple_derivative

__all__ = ["derivative_peaks"]


def derivative_peaks(profiles: Profiles, config: SearchConfig) -> Edges:
    """Boundaries at the simple-difference derivative peaks of the right sign, one per half profile."""
    d, ok, pos = simple_derivative(profiles.values, profiles.usable)
    c = profiles.centre
    n = profiles.shape[-1]
    return boundary_peaks(d, ok, pos, ((0.0, c), (c, n - 1.0)), profiles, config.sign, config.min_strength,
                          config.subsample)
