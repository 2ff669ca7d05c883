"""Profile templates (thesis §4.3.1, fig. 4.8): taken where a link is seen well enough, re-centred
on the axis they show, and stored in the :class:`ImageState` the tracker carries."""

from __future__ import annotations

import dataclasses

import numpy as np

from ..model import Model
from ._config import ImageConfig
from ._context import CameraContext, Observation, against_background, matching_state, observe, prepare
from ._diagnostics import Clock
from ._regression import plls
from ._state import ImageState
from .searches import Profiles, search_named

__all__ = ["capture_templates", "refresh_templates", "take_templates", "refresh_gate", "clear_share", "link_ends",
           "seen_axis_offsets", "shift_profiles"]


def seen_axis_offsets(obs: Observation, config: ImageConfig) -> np.ndarray:
    """Where each profile shows its link's axis, relative to the profile centre (samples).

    Both boundaries are the Gaussian-derivative peaks of each half profile (§11.1.2); a profile
    counts when both are found, their distance is the predicted width within
    ``recentre.width_tolerance``, both lie against the background and the link's window covers
    the profile's middle (``recentre.core``). The midpoints of one link are smoothed by a PLLS
    line along the link (the phalanx is straight), refitted ``recentre.refits`` times without the
    midpoints more than ``recentre.outlier_samples`` off it; a link left with too few profiles
    gets 0 everywhere (no correction), and so does a link whose line stays within
    ``recentre.deadband`` samples of the centre.

    Returns:
        (links, samplers) offsets in samples.
    """
    sc, rc = config.samplers, config.recentre
    L, M, N = obs.values.shape
    profiles = Profiles(values=obs.values, usable=obs.usable, window=obs.window, centre=sc.centre,
                        radius=sc.samples_per_radius, spacing_px=obs.samplers.spacing_px)
    edges = search_named("gaussian")(profiles, config.search)
    width = edges.pos[..., 1] - edges.pos[..., 0]
    r = sc.samples_per_radius
    core = np.abs(np.arange(N) - sc.centre) <= rc.core * r
    covered = np.all(obs.window[..., core], axis=-1)
    ok = (edges.valid.all(-1) & (np.abs(width - 2 * r) <= rc.width_tolerance * r) & covered & obs.samplers.ok[:, None]
          & against_background(obs, config.visibility.background_reach).all(-1))
    mid = np.where(ok, edges.pos.mean(-1) - sc.centre, 0.0)
    x = np.arange(M, dtype=float)
    for _ in range(rc.refits):
        c, fit_ok = plls(x, mid, ok)
        ok &= np.abs(mid - (c[:, 0, None] + c[:, 1, None] * x)) <= rc.outlier_samples
    c, fit_ok = plls(x, mid, ok)
    use = fit_ok & (ok.sum(-1) >= max(rc.min_profiles, M // 2))
    line = c[:, 0, None] + c[:, 1, None] * x
    use &= np.max(np.abs(line), axis=-1) > rc.deadband
    return np.where(use[:, None], line, 0.0)


def shift_profiles(values: np.ndarray, mask: np.ndarray, offsets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Profiles resampled so the sample at ``offsets`` (per profile) lands on the centre:
    ``out(j) = values(j + offset)`` by linear interpolation; a sample is kept where both of its
    neighbours were in ``mask`` and inside the profile."""
    n = values.shape[-1]
    pos = np.arange(n) + offsets[..., None]
    k0 = np.floor(pos).astype(int)
    f = pos - k0
    inside = (k0 >= 0) & (k0 + 1 <= n - 1)
    a, b = np.clip(k0, 0, n - 1), np.clip(k0 + 1, 0, n - 1)
    va, vb = np.take_along_axis(values, a, -1), np.take_along_axis(values, b, -1)
    exact = f == 0.0  # a whole-sample shift needs one neighbour only (also covers the last sample)
    keep = np.where(exact, np.take_along_axis(mask, a, -1) & (k0 >= 0) & (k0 <= n - 1),
                    inside & np.take_along_axis(mask, a, -1) & np.take_along_axis(mask, b, -1))
    return np.where(keep, (1.0 - f) * va + f * vb, 0.0), keep


def clear_share(obs: Observation, config: ImageConfig) -> np.ndarray:
    """(links,) the share of each link's profiles, among those its window covers across the
    middle (``recentre.core``), whose two boundaries both lie against the background
    (``visibility.background_reach``); 0 for a link with no such profile."""
    sc = config.samplers
    core = np.abs(np.arange(obs.window.shape[-1]) - sc.centre) <= config.recentre.core * sc.samples_per_radius
    covered = np.all(obs.window[..., core], axis=-1) & obs.samplers.ok[:, None]
    clear = covered & against_background(obs, config.visibility.background_reach).all(-1)
    return clear.sum(-1) / np.maximum(covered.sum(-1), 1)


def link_ends(obs: Observation) -> np.ndarray:
    """(links, 2, 2) the projected start and end of each link (px), as the refresh gate stores them."""
    return np.stack([obs.start, obs.end], axis=1).astype(float)


def refresh_gate(obs: Observation, config: ImageConfig, mask_stored: np.ndarray,
                 refreshed_px: np.ndarray | None) -> np.ndarray:
    """(links,) whether a refresh at this (solved) pose may replace a link's stored template
    (:class:`~jaxhand.image.RefreshConfig`): one of its projected ends has moved at least
    ``refresh.min_move`` radii since the ends ``refreshed_px`` (links, 2, 2) of its last refresh
    (NaN or None: never refreshed), and at least ``refresh.min_clear`` of its profiles show
    their boundaries against the background. A link without a stored template always may."""
    rc = config.refresh
    ok = np.ones(len(mask_stored), bool)
    if rc.min_move > 0 and refreshed_px is not None:
        moved = np.max(np.linalg.norm(link_ends(obs) - refreshed_px, axis=-1), axis=-1)
        radius = np.asarray(obs.samplers.radius_px, float)
        # Guard: NaN (never refreshed, or a link without samplers) compares False, so it refreshes
        ok &= ~(moved < rc.min_move * radius)
    if rc.min_clear > 0:
        ok &= clear_share(obs, config) >= rc.min_clear
    return ok | ~mask_stored.any(axis=(1, 2))


def take_templates(obs: Observation, config: ImageConfig, values_stored: np.ndarray, mask_stored: np.ndarray,
                   only_missing: bool, gate: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Store this view's profiles as templates where it shows a link well enough.

    A link qualifies when it has samplers and at least ``template_min_visible`` of it is visible;
    its samples that show the link overwrite the stored ones, the others keep theirs. With
    ``only_missing`` only links without any template take one. With
    ``config.template_recentre`` the new profiles are first shifted so the axis they show sits on
    the template's centre (:func:`seen_axis_offsets`). With ``gate`` (links,) (a refresh at a
    solved pose, :func:`refresh_gate`) a link where it is False keeps its stored template.
    """
    share = obs.visibility.visible_share
    take = obs.samplers.ok & (share >= config.template_min_visible)
    if gate is not None:
        take &= gate
    if only_missing:
        take &= ~mask_stored.any(axis=(1, 2))
    if not take.any():  # nothing to store: skip the re-centring search
        return values_stored.copy(), mask_stored.copy()
    values, seen = obs.values, obs.window & obs.usable
    if config.template_recentre:
        values, seen = shift_profiles(values, seen, seen_axis_offsets(obs, config))
    new = take[:, None, None] & seen
    return np.where(new, values, values_stored), mask_stored | new


def capture_templates(images, model: Model, cameras, q, config: ImageConfig | None = None,
                      state: ImageState | None = None) -> ImageState:
    """Store (or refresh) the profile templates of every link seen at pose ``q``.

    ``q`` should overlay the hand in the images: the hand-set initial pose of the first frame, and
    then each frame's converged estimate, so the templates follow the fingers' changing look
    (call it after every solve). A link's template is taken when at least
    ``config.template_min_visible`` of it is visible: the samples that show the link (inside its
    outline, off nearer fingers, inside the image) overwrite the stored ones and join the
    template's mask; the samples hidden now keep what earlier views stored.

    Args:
        images: one image per camera (a single array for one camera).
        model: the model.
        cameras: a camera or a rig.
        q: (n_q,) the pose the images show.
        config: the front end's settings (its sampler layout shapes the templates).
        state: templates to update; None starts from none (a state with another layout is
            replaced).

    Returns:
        The updated :class:`ImageState`.

    Raises:
        InputError: bad images, q or config.
    """
    return _capture(images, model, cameras, q, config, state, gated=False)


def refresh_templates(images, model: Model, cameras, q, config: ImageConfig | None = None,
                      state: ImageState | None = None) -> ImageState:
    """:func:`capture_templates` at a *solved* pose ``q``, where the frame can vouch for it.

    A tracker that re-takes every template at each solved pose stores each solve's error and
    matches it again next frame, so a small error grows (template drift), the more the more
    frames a motion takes. Here a link keeps its stored template unless :func:`refresh_gate` lets
    it go (``config.refresh``): the link has moved far enough in the image since its last refresh
    (so a slow motion gets as many refreshes as a fast one over the same path), and, if asked,
    enough of its boundaries are seen against the background. Links without a template take one.

    Args and returns as :func:`capture_templates`.

    Raises:
        InputError: bad images, q or config.
    """
    return _capture(images, model, cameras, q, config, state, gated=True)


def _capture(images, model: Model, cameras, q, config: ImageConfig | None, state: ImageState | None,
             gated: bool) -> ImageState:
    config, rig, greys, q, chain = prepare(images, model, cameras, q, config, "q")
    state = matching_state(state, len(rig), model, config)
    model = state.model_radii(model)
    templates, masks, ends = [], [], []
    for c, (grey, cam) in enumerate(zip(greys, rig)):
        obs = observe(CameraContext(grey=grey, model=model, camera=cam, chain=chain, config=config, clock=Clock()), q)
        gate = None
        if gated:
            last = None if state.refreshed_px is None else state.refreshed_px[c]
            gate = refresh_gate(obs, config, state.template_mask[c], last)
        t, m = take_templates(obs, config, state.templates[c], state.template_mask[c], only_missing=False, gate=gate)
        templates.append(t)
        masks.append(m)
        if gated:   # a link whose template was (re-)taken now remembers where
            last = np.full((len(m), 2, 2), np.nan) if last is None else last
            taken = gate & obs.samplers.ok & (obs.visibility.visible_share >= config.template_min_visible)
            ends.append(np.where(taken[:, None, None], link_ends(obs), last))
    refreshed = tuple(ends) if gated else state.refreshed_px
    return dataclasses.replace(state, templates=tuple(templates), template_mask=tuple(masks), refreshed_px=refreshed)
