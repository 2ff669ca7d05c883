"""Width-restricted search (thesis appendix D §11.2): basic and compensated.

The phalanx width is known (twice the predicted radius), so each boundary is only searched in a
window of width τ (``search_window`` radii) about where the width puts it, ``centre ∓ r``
(basic restriction, §11.2.1). The compensated variant (§11.2.2) first moves both windows by the
displacement that best aligns the profile's derivative with a synthetic width template (a positive
and a negative peak one width apart), found by correlation; so a misplaced tracker no longer pins
the windows to the wrong place. Both use the Gaussian derivative, as the thesis does from §11.2 on.
"""

from __future__ import annotations

import numpy as np

from .._config import SearchConfig
from ._common import Edges, Profiles, boundary_peaks, correlate_shifts, gaussian_derivative, width_template

__all__ = ["width_restricted", "width_compensated"]


def _restricted(profiles: Profiles, config: SearchConfig, d, ok, pos, centre) -> Edges:
    half = config.search_window * profiles.radius / 2
    r = profiles.radius
    ranges = ((centre - r - half, centre - r + half), (centre + r - half, centre + r + half))
    return boundary_peaks(d, ok, pos, ranges, profiles, config.sign, config.min_strength, config.subsample)


def width_restricted(profiles: Profiles, config: SearchConfig) -> Edges:
    """Basic restriction (§11.2.1): Gaussian-derivative peaks within ``τ / 2`` of ``centre ∓ r``."""
    d, ok, pos = gaussian_derivative(profiles.values, profiles.usable, config.sigma)
    return _restricted(profiles, config, d, ok, pos, profiles.centre)


def width_compensated(profiles: Profiles, config: SearchConfig) -> Edges:
    """Compensated restriction (§11.2.2): windows re-centred by correlation with a width template."""
    d, ok, pos = gaussian_derivative(profiles.values, profiles.usable, config.sigma)
    n = profiles.shape[-1]
    tmpl = width_template(n, profiles.centre, 2 * profiles.radius, config.template_sigma,
                           config.sign)
    C, shifts = correlate_shifts(d, ok, tmpl, profiles.max_shift(config.max_shift))
    best = shifts[np.argmax(C, axis=-1)]
    edges = _restricted(profiles, config, d, ok, pos, profiles.centre + best[..., None])
    return Edges(pos=edges.pos, strength=edges.strength, valid=edges.valid, surface=C, shifts=shifts)
