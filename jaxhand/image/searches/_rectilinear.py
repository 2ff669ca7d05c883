"""Rectilinearity restriction on the correlation surface (thesis appendix D §11.3).

Every profile's Gaussian derivative is correlated with the synthetic width template (as in the
compensated width search) at displacements ``-S..S``; the curves of one link, side by side, form a
correlation surface whose crest is a straight line because a phalanx is straight. A line
``y = c0 + c1 x`` (x: the profile's number along the link, y: displacement in samples) is fitted
to the crest, and each profile's boundaries are put one predicted radius either side of the line
(edges extrapolated from the width, as in §4.3.2), so they are collinear by construction.

- PLLS (§11.3.1): least squares through each curve's maximum.
- MWPLLS (§11.3.2): every point of every curve contributes, weighted by the surface's amplitude
  (above ``crest_floor`` times the curve's maximum; 0 gives the thesis's plain weighting).
- iMWPLLS (§11.3.3): MWPLLS repeated with only the points near the current line.
"""

from __future__ import annotations

import numpy as np

from .._config import SearchConfig
from .._regression import imwplls_crest_fit, mwplls, plls
from ._common import (
    Edges,
    Profiles,
    correlate_shifts,
    edges_about_centres,
    gaussian_derivative,
    masked_argmax,
    per_pixel,
    sample_at,
    width_template,
)

__all__ = ["plls_crest", "mwplls_crest", "imwplls_crest", "correlation_surface", "crest_weights"]


def correlation_surface(profiles: Profiles, config: SearchConfig) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The correlation surface of every link.

    Returns:
        (C, shifts, curve_ok): C (links, samplers, 2 S + 1), the displacement of each column, and
        (links, samplers) the curves whose derivative is valid along the whole profile.
    """
    d, ok, _ = gaussian_derivative(profiles.values, profiles.usable, config.sigma)
    tmpl = width_template(profiles.shape[-1], profiles.centre, 2 * profiles.radius, config.template_sigma,
                           config.sign)
    C, shifts = correlate_shifts(d, ok, tmpl, profiles.max_shift(config.max_shift))
    return C, shifts, ok.all(-1)


def _edges_from_line(profiles: Profiles, config: SearchConfig, C, shifts, curve_ok, c, fit_ok) -> Edges:
    m = C.shape[1]
    x = np.arange(m, dtype=float)
    y = c[..., 0, None] + c[..., 1, None] * x  # (links, samplers) crest displacement, samples
    # Correlating with a template of two unit peaks gives about twice the mean edge derivative.
    strength = 0.5 * per_pixel(sample_at(C, y - shifts[0]), profiles.spacing_px)
    inside = np.abs(y) <= shifts[-1]
    valid = curve_ok & fit_ok[:, None] & inside & (strength >= config.min_strength) & (strength > 0)
    pos = edges_about_centres(profiles.centre + y, 2 * profiles.radius)
    return Edges(pos=pos, strength=np.repeat(strength[..., None], 2, -1), valid=np.repeat(valid[..., None], 2, -1),
                 surface=C, shifts=shifts)


def plls_crest(profiles: Profiles, config: SearchConfig) -> Edges:
    """PLLS line through the maxima of the correlation curves (§11.3.1)."""
    C, shifts, curve_ok = correlation_surface(profiles, config)
    k, _, off = masked_argmax(C, np.ones(C.shape, bool), config.subsample)
    x = np.arange(C.shape[1], dtype=float)
    c, ok = plls(x, shifts[k] + off, curve_ok)
    return _edges_from_line(profiles, config, C, shifts, curve_ok, c, ok)


def crest_weights(C: np.ndarray, floor: float) -> np.ndarray:
    """MWPLLS costs: each curve's amplitude above ``floor`` times its maximum, never negative."""
    top = np.max(C, axis=-1, keepdims=True)
    return np.maximum(C - floor * np.maximum(top, 0.0), 0.0)


def mwplls_crest(profiles: Profiles, config: SearchConfig) -> Edges:
    """MWPLLS line over the whole positive correlation surface (§11.3.2)."""
    C, shifts, curve_ok = correlation_surface(profiles, config)
    x = np.arange(C.shape[1], dtype=float)
    c, ok = mwplls(x, shifts.astype(float), crest_weights(C, config.crest_floor), curve_ok)
    return _edges_from_line(profiles, config, C, shifts, curve_ok, c, ok)


def imwplls_crest(profiles: Profiles, config: SearchConfig) -> Edges:
    """Iterative MWPLLS line, refitted near the crest until it stops moving (§11.3.3)."""
    C, shifts, curve_ok = correlation_surface(profiles, config)
    c, ok = imwplls_crest_fit(C, shifts, curve_ok, config.crest_floor, config.crest_halfwidth * profiles.radius,
                              config.max_iter)
    return _edges_from_line(profiles, config, C, shifts, curve_ok, c, ok)
