"""Phalanx widths (thesis appendix E): redundant radius measures from the profiles at the solved
pose, and the radius estimate they update."""

from __future__ import annotations

import dataclasses

import jax.numpy as jnp
import numpy as np

from .._errors import InputError
from ..camera import as_rig
from ..model import Model
from ._config import ImageConfig
from ._context import CameraContext, Observation, against_background, matching_state, observe, prepare
from ._diagnostics import Clock
from ._state import ImageState
from .searches import Profiles, search_named

__all__ = ["measure_widths", "update_widths", "width_ratios", "row_median"]


def width_ratios(obs: Observation, config: ImageConfig) -> tuple[np.ndarray, np.ndarray]:
    """(links, samplers) each profile's width between its two Gaussian-derivative boundaries in
    units of the radius in use, and whether it counts: both boundaries found, both against the
    background (no other link's outline next to them), the link's window over the profile's
    middle (``widths.core``), and the ratio within ``widths.ratio_range``."""
    sc, wc = config.samplers, config.widths
    n = obs.values.shape[-1]
    profiles = Profiles(values=obs.values, usable=obs.usable, window=obs.window, centre=sc.centre,
                        radius=sc.samples_per_radius, spacing_px=obs.samplers.spacing_px)
    edges = search_named("gaussian")(profiles, config.search)
    ratio = (edges.pos[..., 1] - edges.pos[..., 0]) / (2 * sc.samples_per_radius)
    core = np.abs(np.arange(n) - sc.centre) <= wc.core * sc.samples_per_radius
    ok = (edges.valid.all(-1) & np.all(obs.window[..., core], axis=-1) & obs.samplers.ok[:, None]
          & against_background(obs, config.visibility.background_reach).all(-1)
          & (ratio >= wc.ratio_range[0]) & (ratio <= wc.ratio_range[1]))
    return np.where(ok, ratio, np.nan), ok


def row_median(values: np.ndarray, ok: np.ndarray) -> np.ndarray:
    """Median of each row's ``ok`` entries (0 for a row without one)."""
    v = np.sort(np.where(ok, values, np.inf), axis=-1)
    n = ok.sum(-1)
    lo = np.take_along_axis(v, np.maximum(n - 1, 0)[:, None] // 2, -1)[:, 0]
    hi = np.take_along_axis(v, np.minimum(n // 2, v.shape[-1] - 1)[:, None], -1)[:, 0]
    return np.where(n > 0, 0.5 * (lo + hi), 0.0)


def measure_widths(images, model: Model, cameras, q, config: ImageConfig | None = None,
                   state: ImageState | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Redundant measures of every phalanx's radius (thesis appendix E), one per profile and camera.

    The links are sampled at pose ``q`` (the solved pose: the profiles must cross the phalanges)
    with the radii in use (``state``'s estimate, else the model's); a profile measures the radius
    as the distance between its two Gaussian-derivative boundaries (§11.1.2), in units of the
    radius in use, times that radius in mm. A profile counts only where both of its boundaries lie
    against the background and its link is visible across its middle, so the edge of a
    neighbouring or nearer finger cannot pose as a boundary; a link's measures count only where
    ``widths.min_count`` of them agree with their median to ``widths.agreement``.

    Returns:
        (radius_mm, valid): (links, cameras x samplers) measures in mm (NaN where not valid) and
        their validity.

    Raises:
        InputError: bad images, q or config.
    """
    config, rig, greys, q, chain = prepare(images, model, cameras, q, config, "q")
    model = matching_state(state, len(rig), model, config).model_radii(model)
    radius = np.asarray(model.link_radius_mm, float)
    wc = config.widths
    ratios, oks = [], []
    for grey, cam in zip(greys, rig):
        ctx = CameraContext(grey=grey, model=model, camera=cam, chain=chain, config=config, clock=Clock())
        ratio, ok = width_ratios(observe(ctx, q), config)
        ratios.append(ratio)
        oks.append(ok)
    ratio, ok = np.concatenate(ratios, -1), np.concatenate(oks, -1)
    med = row_median(ratio, ok)[:, None]
    ok &= np.abs(np.nan_to_num(ratio) - med) <= wc.agreement * med
    ok &= ok.sum(-1, keepdims=True) >= wc.min_count
    return np.where(ok, ratio * radius[:, None], np.nan), ok


def update_widths(images, model: Model, cameras, q, config: ImageConfig | None = None,
                  state: ImageState | None = None, *, gain: float | None = None,
                  fill_unmeasured: bool = False) -> ImageState:
    """``state`` with every phalanx radius updated from this frame's width measures at pose ``q``
    (thesis appendix E: the radius is a constant, so the prediction is the last estimate and the
    update moves it by ``config.width_gain`` times the mean innovation of the link's valid
    measures; a link without one keeps its estimate). The first update starts from the model's
    radii; every estimate stays within ``config.widths.radius_range`` times the model's radius.

    Args:
        gain: the update's gain (default ``config.width_gain``); 1 takes the measures' mean.
        fill_unmeasured: a link without a valid measure takes the model's radius times the median
            ratio of estimate to model radius of the links that have one (one scale for the whole
            hand), for a first estimate at the hand-set pose, where phalanges that touch a
            neighbour cannot be measured.

    Raises:
        InputError: bad images, q or config.
    """
    from ..filter import width_update

    config = ImageConfig() if config is None else config
    if gain is not None and not 0 <= gain <= 1:
        raise InputError(f"update_widths: gain must lie in [0, 1], got {gain!r}")
    rig = as_rig(cameras)
    state = matching_state(state, len(rig), model, config)
    measures, valid = measure_widths(images, model, rig, q, config, state)
    nominal = np.asarray(model.link_radius_mm, float)
    current = np.asarray(state.model_radii(model).link_radius_mm, float)
    radius = np.asarray(width_update(jnp.asarray(current), jnp.asarray(np.nan_to_num(measures)), jnp.asarray(valid),
                                     config.width_gain if gain is None else gain))
    measured = valid.any(-1) & (nominal > 0)
    if fill_unmeasured and measured.any():
        scale = np.median(radius[measured] / nominal[measured])
        radius = np.where(measured, radius, nominal * scale)
    lo, hi = config.widths.radius_range
    radius = np.clip(radius, lo * nominal, hi * nominal)
    return dataclasses.replace(state, radius_mm=radius)
