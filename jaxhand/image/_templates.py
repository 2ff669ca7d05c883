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

__all__ = ["capture_templates", "take_templates", "seen_axis_offsets", "shift_profiles"]


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


def take_templates(obs: Observation, config: ImageConfig, values_stored: np.ndarray, mask_stored: np.ndarray,
                   only_missing: bool) -> tuple[np.ndarray, np.ndarray]:
    """Store this view's profiles as templates where it shows a link well enough.

    A link qualifies when it has samplers and at least ``template_min_visible`` of it is visible;
    its samples that show the link overwrite the stored ones, the others keep theirs. With
    ``only_missing`` only links without any template take one. With
    ``config.template_recentre`` the new profiles are first shifted so the axis they show sits on
    the template's centre (:func:`seen_axis_offsets`).
    """
    share = obs.visibility.visible_share
    take = obs.samplers.ok & (share >= config.template_min_visible)
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
    config, rig, greys, q, chain = prepare(images, model, cameras, q, config, "q")
    state = matching_state(state, len(rig), model, config)
    model = state.model_radii(model)
    templates, masks = [], []
    for c, (grey, cam) in enumerate(zip(greys, rig)):
        obs = observe(CameraContext(grey=grey, model=model, camera=cam, chain=chain, config=config, clock=Clock()), q)
        t, m = take_templates(obs, config, state.templates[c], state.template_mask[c], only_missing=False)
        templates.append(t)
        masks.append(m)
    return dataclasses.replace(state, templates=tuple(templates), template_mask=tuple(masks))
