"""The image front end's entry points: :func:`extract_features`, :func:`capture_templates` and
:func:`update_widths`.

Per camera (thesis ch. 4, DESIGN.md data flow):

1. one jitted kinematics call gives the predicted link ends, depths, radii and tips in pixels,
   converted to NumPy once;
2. place the link samplers (§4.1) and compute the visibility windows (§4.3.3);
3. sample every profile in one ``cv2.remap`` (§4.2);
4. search every profile for both boundaries with the configured search (§4.3, app. D);
5. fit both boundary lines of every link (RANSAC + PCA) and the axial line between them, or
   offset a lone boundary by the radius (§4.4, DigitEyes §4);
6. place the tip samplers on the terminal axial lines (eq. 4.1), sample them in a second remap
   and take the strongest derivative of the right sign as the tip boundary (§11.1.1).
"""

from __future__ import annotations

import dataclasses
import functools
import time
from collections.abc import Callable, Sequence

import jax.numpy as jnp
import numpy as np

from jaxhand import InputError
from jaxhand.camera import Perspective, as_rig
from jaxhand.features import Features
from jaxhand.kinematics import project_pose, validate_q
from jaxhand.model import Model

from ._config import ImageConfig
from ._lines import axial_line, line_params, offset_towards, ransac_pca
from ._regression import plls
from ._sampling import as_grey, sample_profiles
from ._state import ImageState
from ._trackers import LinkSamplers, TipSamplers, place_link_samplers, place_tip_samplers
from ._visibility import Visibility, compute_visibility, convex_edges, inside_polygons, same_chain, window_masks
from .searches import TEMPLATE_SEARCHES, Edges, Profiles, search_named
from .searches._common import gaussian_derivative, masked_argmax, simple_derivative

__all__ = ["extract_features", "capture_templates", "measure_widths", "update_widths", "Diagnostics",
           "CameraDiagnostics", "as_images", "WindowOutlines"]


@dataclasses.dataclass(frozen=True)
class CameraDiagnostics:
    """What one camera's analysis saw and decided, for overlays like thesis figs. 4.2-4.23.

    Attributes:
        samplers: link sampler placement (centres, sample positions, ``ends`` for drawing).
        visibility: pill outlines, truncated polygons, window polygons, depth order, visible share.
        profiles: the sampled profiles, their usable samples, windows and templates.
        edges: the search's raw result (positions in samples, strengths, surface if any).
        edge_px: (links, samplers, 2, 2) boundary points in pixels (NaN where not found).
        boundary_lines: (links, 2, 3) fitted boundary lines (a, b, rho).
        boundary_valid: (links, 2) the boundary line was fitted.
        inliers: (links, 2, samplers) RANSAC inliers of each boundary line.
        axial_lines: (links, 3) the link features' lines (a, b, rho).
        single_edge: (links,) the axial line came from one boundary offset by the radius.
        tip_samplers: tip sampler placement (refined tips, directions, sample positions).
        tip_edge_px: (tips, 2) tip boundary points found (NaN where none).
        tip_strength: (tips,) derivative at the tip boundary, grey levels per pixel.
        reacquired: (links,) the link's line (and tip) came from a search with its joint turned
            (``ImageConfig.reacquire_deg``); the other diagnostics show the search at the
            prediction.
    """

    samplers: LinkSamplers
    visibility: Visibility
    profiles: Profiles
    edges: Edges
    edge_px: np.ndarray
    boundary_lines: np.ndarray
    boundary_valid: np.ndarray
    inliers: np.ndarray
    axial_lines: np.ndarray
    single_edge: np.ndarray
    tip_samplers: TipSamplers
    tip_edge_px: np.ndarray
    tip_strength: np.ndarray
    reacquired: np.ndarray | None = None


@dataclasses.dataclass(frozen=True)
class Diagnostics:
    """Diagnostics of one :func:`extract_features` call.

    Attributes:
        method: the search used.
        cameras: one :class:`CameraDiagnostics` per camera.
        state: the image state after this frame (templates filled in for links that had none and
            were seen well enough); pass it to the next frame.
        timings_s: wall time of each stage summed over the cameras (s): "kinematics", "samplers",
            "visibility", "sampling", "search", "lines", "tips".
    """

    method: str
    cameras: tuple[CameraDiagnostics, ...]
    state: ImageState
    timings_s: dict[str, float] = dataclasses.field(default_factory=dict)


class _Clock:
    """Accumulates the wall time of named stages."""

    def __init__(self):
        self.totals: dict[str, float] = {}
        self._t = time.perf_counter()

    def lap(self, name: str) -> None:
        t = time.perf_counter()
        self.totals[name] = self.totals.get(name, 0.0) + (t - self._t)
        self._t = t


def as_images(images, n_cameras: int, sizes: Sequence[tuple[int, int]]) -> list[np.ndarray]:
    """Validate one image per camera and convert each once to float32 grey levels.

    A single array is accepted for a one-camera rig.

    Raises:
        InputError: wrong count, type, dtype, shape or size, naming the image.
    """
    if isinstance(images, np.ndarray):
        if n_cameras != 1:
            raise InputError(f"images: expected a sequence of {n_cameras} images (one per camera), got one array")
        images = [images]
    try:
        items = list(images)
    except TypeError as err:
        raise InputError(f"images: expected a sequence of images, got {type(images).__name__}") from err
    if len(items) != n_cameras:
        raise InputError(f"images: expected one image per camera ({n_cameras}), got {len(items)}")
    return [as_grey(im, f"images[{i}]", sizes[i]) for i, im in enumerate(items)]


def _layout(config: ImageConfig) -> tuple[int, int, float]:
    s = config.samplers
    return (s.per_link, s.points, float(s.scope))


@dataclasses.dataclass(frozen=True)
class _Observation:
    """A view's predicted geometry, samplers, visibility and sampled profiles."""

    start: np.ndarray
    end: np.ndarray
    tips: np.ndarray
    samplers: LinkSamplers
    visibility: Visibility
    values: np.ndarray
    usable: np.ndarray
    window: np.ndarray

    @functools.cached_property
    def outline_edges(self):
        """:func:`convex_edges` of the outlines, computed once for every point test of this view."""
        return convex_edges(self.visibility.outlines)


def _observe(grey: np.ndarray, model: Model, camera, q: np.ndarray, chain: np.ndarray, config: ImageConfig,
             clock: _Clock | None = None) -> _Observation:
    clock = _Clock() if clock is None else clock
    view = project_pose(model, camera, jnp.asarray(q))
    start, end = np.asarray(view.link_start_px, float), np.asarray(view.link_end_px, float)
    depth, radius = np.asarray(view.link_depth, float), np.asarray(view.link_radius_px, float)
    clock.lap("kinematics")
    samplers = place_link_samplers(start, end, radius, config.samplers)
    clock.lap("samplers")
    r_ends = _end_radii(camera, depth, radius, samplers.ok)
    vis = compute_visibility(start, end, depth, r_ends[:, 0], r_ends[:, 1], chain, camera.size, config.visibility)
    clock.lap("visibility")
    values, usable = sample_profiles(grey, samplers.points, config.samplers.interpolation)
    clock.lap("sampling")
    window = window_masks(vis.windows, samplers.points) & usable
    clock.lap("visibility")
    return _Observation(start=start, end=end, tips=np.asarray(view.tips_px, float), samplers=samplers,
                        visibility=vis, values=values, usable=usable, window=window)


def _edges_to_px(samplers: LinkSamplers, edges: Edges, centre: float) -> np.ndarray:
    off = (edges.pos - centre) * samplers.spacing_px[:, None, None]  # (links, samplers, 2), px along the normal
    pts = samplers.centres[:, :, None, :] + off[..., None] * samplers.normal[:, None, None, :]
    ok = edges.valid & samplers.ok[:, None, None] & np.all(np.isfinite(pts), -1)
    return np.where(ok[..., None], pts, np.nan), ok


def _fit_links(obs: _Observation, edge_px: np.ndarray, edge_ok: np.ndarray, config: ImageConfig):
    lc = config.lines
    s = obs.samplers
    pts = np.swapaxes(np.nan_to_num(edge_px), 1, 2)  # (links, 2, samplers, 2)
    ok_pts = np.swapaxes(edge_ok, 1, 2)
    p, v, ok, inliers = ransac_pca(pts, ok_pts, lc.tau_px, lc.min_inliers)
    both = ok[:, 0] & ok[:, 1]
    p_ax, v_ax = axial_line(p[:, 0], v[:, 0], p[:, 1], v[:, 1], lc.det_eps)
    single = lc.single_edge & (ok[:, 0] ^ ok[:, 1])
    k = np.where(ok[:, 0], 0, 1)
    p_one = np.take_along_axis(p, k[:, None, None], 1)[:, 0]
    v_one = np.take_along_axis(v, k[:, None, None], 1)[:, 0]
    mid = 0.5 * (np.nan_to_num(obs.start) + np.nan_to_num(obs.end))
    p_one = offset_towards(p_one, v_one, mid, s.radius_px)
    p_ax = np.where(single[:, None], p_one, p_ax)
    v_ax = np.where(single[:, None], v_one, v_ax)
    v_ax = np.where((np.sum(v_ax * s.direction, -1) < 0)[:, None], -v_ax, v_ax)  # point from start to end
    lines = line_params(p_ax, v_ax)
    share = obs.visibility.visible_share
    valid = s.ok & (both | single) & (share >= lc.min_visible) & np.all(np.isfinite(lines), -1)
    weight = (share if lc.weight_by_visibility else np.ones_like(share)) * np.where(single, lc.single_edge_weight,
                                                                                    1.0)
    boundary = line_params(p, v)
    lines = np.where(valid[:, None], lines, np.array([1.0, 0.0, 0.0]))
    return lines, valid, np.where(valid, weight, 0.0), boundary, ok, inliers, single & valid, p_ax, v_ax


def _tips(grey: np.ndarray, model: Model, obs: _Observation, line_ok: np.ndarray, p_ax: np.ndarray,
          v_ax: np.ndarray, config: ImageConfig):
    tc = config.tips
    s = obs.samplers
    tl = np.asarray(model.tip_links, int)
    # The terminal axial line when it was measured, else the predicted link axis.
    p = np.where(line_ok[tl, None], p_ax[tl], np.nan_to_num(obs.start[tl]))
    v = np.where(line_ok[tl, None], v_ax[tl], s.direction[tl])
    ts = place_tip_samplers(np.nan_to_num(obs.tips), p, v, s.radius_px[tl], tc)
    values, usable = sample_profiles(grey, ts.points, config.samplers.interpolation)
    if tc.sigma > 0:
        d, d_ok, pos = gaussian_derivative(values, usable, tc.sigma)
    else:
        d, d_ok, pos = simple_derivative(values, usable)
    # Outwards past the tip a bright hand gives way to background: a falling edge.
    k, val, off = masked_argmax(-config.search.sign * d, d_ok, True)
    found = np.isfinite(val)
    strength = np.where(found & (ts.spacing_px > 0), val / np.where(ts.spacing_px > 0, ts.spacing_px, 1.0), 0.0)
    along = (pos[k] + off - (tc.points - 1) / 2) * ts.spacing_px
    centre = ts.refined + ts.radius_px[:, None] * ts.v0
    edge = centre + along[:, None] * ts.v0
    tip = edge - ts.radius_px[:, None] * ts.v0
    seen = window_masks(obs.visibility.windows[tl], tip[:, None, :])[:, 0]
    # Past the tip boundary there must be background: over another link the boundary is weak
    # or missing, and the strongest derivative lies elsewhere (thesis §4.4 assumes a clear tip).
    beyond = tip[:, None, :] + (ts.radius_px[:, None] * np.array([1.1, 1.4]))[..., None] * ts.v0[:, None, :]
    seen &= np.all(_off_other_links(obs, beyond, tl), axis=-1)
    valid = (s.ok[tl] & found & (strength >= tc.min_strength) & (strength > 0) & seen
             & (obs.visibility.visible_share[tl] >= config.lines.min_visible) & np.all(np.isfinite(tip), -1)
             & (line_ok[tl] | (not tc.need_line)))
    return (np.where(valid[:, None], tip, 0.0), valid, ts, np.where(valid[:, None], edge, np.nan),
            np.where(valid, strength, 0.0))


def _seen_axis_offsets(obs: _Observation, config: ImageConfig, deadband: float = 0.75) -> np.ndarray:
    """Where each profile shows its link's axis, relative to the profile centre (samples).

    Both boundaries are the Gaussian-derivative peaks of each half profile (§11.1.2); a profile
    counts when both are found, their distance is the predicted width within 20 % and the link's
    window covers the profile's middle (no nearer finger across it). The midpoints of one link
    are smoothed by a PLLS line along the link (the phalanx is straight), refitted twice without
    the midpoints more than a sample off it; a link left with fewer than half of its profiles
    (at least three) gets 0 everywhere (no correction), and so does a link whose line stays
    within ``deadband`` samples of the centre.

    Returns:
        (links, samplers) offsets in samples.
    """
    sc, search = config.samplers, config.search
    L, M, N = obs.values.shape
    profiles = Profiles(values=obs.values, usable=obs.usable, window=obs.window, centre=sc.centre,
                        radius=sc.samples_per_radius, spacing_px=obs.samplers.spacing_px)
    edges = search_named("gaussian")(profiles, search)
    width = edges.pos[..., 1] - edges.pos[..., 0]
    r = sc.samples_per_radius
    core = np.abs(np.arange(N) - sc.centre) <= 0.7 * r
    covered = np.all(obs.window[..., core], axis=-1)
    ok = (edges.valid.all(-1) & (np.abs(width - 2 * r) <= 0.4 * r) & covered & obs.samplers.ok[:, None]
          & _against_background(obs).all(-1))
    mid = np.where(ok, edges.pos.mean(-1) - sc.centre, 0.0)
    x = np.arange(M, dtype=float)
    for _ in range(2):  # refit without the midpoints more than one sample off the line
        c, fit_ok = plls(x, mid, ok)
        ok &= np.abs(mid - (c[:, 0, None] + c[:, 1, None] * x)) <= 1.0
    c, fit_ok = plls(x, mid, ok)
    use = fit_ok & (ok.sum(-1) >= max(3, M // 2))
    line = c[:, 0, None] + c[:, 1, None] * x
    # Shading shifts the two boundaries unequally by a fraction of a sample; correct only a
    # template that is off by more than that (drift), so a well placed one stays as it is.
    use &= np.max(np.abs(line), axis=-1) > deadband
    return np.where(use[:, None], line, 0.0)


def _off_other_links(obs: _Observation, points: np.ndarray, links: np.ndarray | None = None) -> np.ndarray:
    """True where a point of link ``links[i]`` (``points[i, ...]``) lies outside the outline of every
    other link: other fingers, and also the neighbouring phalanges of its own finger, which near
    a bent joint widen the silhouette on the inner side."""
    outlines = obs.visibility.outlines
    L = len(outlines)
    links = np.arange(L) if links is None else np.asarray(links, int)
    pts = np.asarray(points, float)
    inside = inside_polygons(outlines, pts, edges=obs.outline_edges)  # (links, ..., L): each point, each outline
    own = np.arange(L) == links.reshape((-1,) + (1,) * (pts.ndim - 1))
    return ~np.any(inside & ~own, axis=-1)


def _against_background(obs: _Observation, reach: tuple[float, ...] = (1.1, 1.25, 1.4)) -> np.ndarray:
    """(links, samplers, 2) the points ``reach`` radii to each side of a profile's centre (boundary
    0: towards smaller sample indices, boundary 1: larger) lie off every other link's outline
    (:func:`_off_other_links`), so that boundary is the link's own, seen against the background."""
    s = obs.samplers
    at = np.concatenate([-np.asarray(reach), np.asarray(reach)])
    off = (s.radius_px[:, None] * at)[:, None, :, None] * s.normal[:, None, None, :]
    clear = _off_other_links(obs, s.centres[:, :, None, :] + off)  # (links, samplers, 2 * reaches)
    return np.stack([clear[..., :len(reach)].all(-1), clear[..., len(reach):].all(-1)], -1)


def _shift_profiles(values: np.ndarray, mask: np.ndarray, offsets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
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


def _take_templates(obs: _Observation, config: ImageConfig, values_stored: np.ndarray, mask_stored: np.ndarray,
                    only_missing: bool) -> tuple[np.ndarray, np.ndarray]:
    """Store this view's profiles as templates where it shows a link well enough.

    A link qualifies when it has samplers and at least ``template_min_visible`` of it is visible;
    its samples that show the link overwrite the stored ones, the others keep theirs. With
    ``only_missing`` only links without any template take one. With
    ``config.template_recentre`` the new profiles are first shifted so the axis they show sits on
    the template's centre (:func:`_seen_axis_offsets`).
    """
    share = obs.visibility.visible_share
    take = obs.samplers.ok & (share >= config.template_min_visible)
    if only_missing:
        take &= ~mask_stored.any(axis=(1, 2))
    if not take.any():  # nothing to store: skip the re-centring search
        return values_stored.copy(), mask_stored.copy()
    values, seen = obs.values, obs.window & obs.usable
    if config.template_recentre:
        values, seen = _shift_profiles(values, seen, _seen_axis_offsets(obs, config))
    new = take[:, None, None] & seen
    return np.where(new, values, values_stored), mask_stored | new


def _prepare(images, model: Model, cameras, q, config: ImageConfig | None, name: str):
    config = ImageConfig() if config is None else config
    if not isinstance(config, ImageConfig):
        raise InputError(f"config: expected an ImageConfig, got {type(config).__name__}")
    rig = as_rig(cameras)
    greys = as_images(images, len(rig), [c.size for c in rig])
    q = validate_q(model, q, name=name)
    chain = same_chain(model.link_frame, model.ancestors)
    return config, rig, greys, q, chain


def _matching_state(state: ImageState | None, n_cameras: int, model: Model, config: ImageConfig) -> ImageState:
    """``state`` when its templates fit this rig, model and layout, else an empty one (keeping
    estimated radii of the right shape)."""
    layout = _layout(config)
    if state is not None and state.matches(n_cameras, model.n_links, layout):
        return state
    radius = None if state is None or np.shape(state.radius_mm) != (model.n_links,) else state.radius_mm
    return dataclasses.replace(ImageState.empty(n_cameras, model.n_links, layout), radius_mm=radius)


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
    config, rig, greys, q, chain = _prepare(images, model, cameras, q, config, "q")
    state = _matching_state(state, len(rig), model, config)
    model = state.model_radii(model)
    templates, masks = [], []
    for c, (grey, cam) in enumerate(zip(greys, rig)):
        obs = _observe(grey, model, cam, q, chain, config)
        t, m = _take_templates(obs, config, state.templates[c], state.template_mask[c], only_missing=False)
        templates.append(t)
        masks.append(m)
    return dataclasses.replace(state, templates=tuple(templates), template_mask=tuple(masks))


#: Width measures outside these multiples of the radius in use are implausible (the profile spans
#: ``±scope`` radii, 1.75 by default, so a boundary beyond it cannot be seen anyway).
_WIDTH_RATIO_RANGE = (0.5, 1.6)
#: A link's width measures count when at least this many agree with their median to this share.
_WIDTH_MIN_COUNT, _WIDTH_AGREEMENT = 4, 0.1


def _width_ratios(obs: _Observation, config: ImageConfig) -> tuple[np.ndarray, np.ndarray]:
    """(links, samplers) each profile's width between its two Gaussian-derivative boundaries in
    units of the radius in use, and whether it counts: both boundaries found, both against the
    background (no other link's outline next to them), the link's window over the profile's
    middle, and the ratio within :data:`_WIDTH_RATIO_RANGE`."""
    sc = config.samplers
    n = obs.values.shape[-1]
    profiles = Profiles(values=obs.values, usable=obs.usable, window=obs.window, centre=sc.centre,
                        radius=sc.samples_per_radius, spacing_px=obs.samplers.spacing_px)
    edges = search_named("gaussian")(profiles, config.search)
    ratio = (edges.pos[..., 1] - edges.pos[..., 0]) / (2 * sc.samples_per_radius)
    core = np.abs(np.arange(n) - sc.centre) <= 0.5 * sc.samples_per_radius
    ok = (edges.valid.all(-1) & np.all(obs.window[..., core], axis=-1) & obs.samplers.ok[:, None]
          & _against_background(obs).all(-1) & (ratio >= _WIDTH_RATIO_RANGE[0]) & (ratio <= _WIDTH_RATIO_RANGE[1]))
    return np.where(ok, ratio, np.nan), ok


def _row_median(values: np.ndarray, ok: np.ndarray) -> np.ndarray:
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
    neighbouring or nearer finger cannot pose as a boundary.

    Returns:
        (radius_mm, valid): (links, cameras x samplers) measures in mm (NaN where not valid) and
        their validity.

    Raises:
        InputError: bad images, q or config.
    """
    config, rig, greys, q, chain = _prepare(images, model, cameras, q, config, "q")
    model = _matching_state(state, len(rig), model, config).model_radii(model)
    radius = np.asarray(model.link_radius_mm, float)
    ratios, oks = [], []
    for grey, cam in zip(greys, rig):
        ratio, ok = _width_ratios(_observe(grey, model, cam, q, chain, config), config)
        ratios.append(ratio)
        oks.append(ok)
    ratio, ok = np.concatenate(ratios, -1), np.concatenate(oks, -1)
    # Consistent measures only: a link needs _WIDTH_MIN_COUNT of them, each within
    # _WIDTH_AGREEMENT of their median (an edge taken from a touching neighbour stands out).
    med = _row_median(ratio, ok)[:, None]
    ok &= np.abs(np.nan_to_num(ratio) - med) <= _WIDTH_AGREEMENT * med
    ok &= ok.sum(-1, keepdims=True) >= _WIDTH_MIN_COUNT
    return np.where(ok, ratio * radius[:, None], np.nan), ok


#: The estimated radii stay within these multiples of the model's (a run of wrong poses cannot
#: shrink or grow a phalanx without bound).
_RADIUS_RANGE = (0.5, 2.0)


def update_widths(images, model: Model, cameras, q, config: ImageConfig | None = None,
                  state: ImageState | None = None, *, gain: float | None = None,
                  fill_unmeasured: bool = False) -> ImageState:
    """``state`` with every phalanx radius updated from this frame's width measures at pose ``q``
    (thesis appendix E: the radius is a constant, so the prediction is the last estimate and the
    update moves it by ``config.width_gain`` times the mean innovation of the link's valid
    measures; a link without one keeps its estimate). The first update starts from the model's
    radii; every estimate stays within :data:`_RADIUS_RANGE` times the model's radius.

    Args:
        gain: the update's gain (default ``config.width_gain``); 1 takes the measures' mean.
        fill_unmeasured: a link without a valid measure takes the model's radius times the median
            ratio of estimate to model radius of the links that have one (one scale for the whole
            hand), for a first estimate at the hand-set pose, where phalanges that touch a
            neighbour cannot be measured.

    Raises:
        InputError: bad images, q or config.
    """
    from jaxhand.filter import width_update

    config = ImageConfig() if config is None else config
    if gain is not None and not 0 <= gain <= 1:
        raise InputError(f"update_widths: gain must lie in [0, 1], got {gain!r}")
    rig = as_rig(cameras)
    state = _matching_state(state, len(rig), model, config)
    measures, valid = measure_widths(images, model, rig, q, config, state)
    nominal = np.asarray(model.link_radius_mm, float)
    current = np.asarray(state.model_radii(model).link_radius_mm, float)
    radius = np.asarray(width_update(jnp.asarray(current), jnp.asarray(np.nan_to_num(measures)), jnp.asarray(valid),
                                     config.width_gain if gain is None else gain))
    measured = valid.any(-1) & (nominal > 0)
    if fill_unmeasured and measured.any():
        scale = np.median(radius[measured] / nominal[measured])
        radius = np.where(measured, radius, nominal * scale)
    radius = np.clip(radius, _RADIUS_RANGE[0] * nominal, _RADIUS_RANGE[1] * nominal)
    return dataclasses.replace(state, radius_mm=radius)


@dataclasses.dataclass(frozen=True)
class _View:
    """One camera's search, line fits and tips around one pose (:func:`_search_view`).

    ``p_ax`` and ``v_ax`` are the axial lines as a point and a direction (what the tip samplers are
    placed on); the tip fields are None where the tips were not searched.
    """

    profiles: Profiles
    edges: Edges
    edge_px: np.ndarray
    lines: np.ndarray
    valid: np.ndarray
    weight: np.ndarray
    boundary: np.ndarray
    bvalid: np.ndarray
    inliers: np.ndarray
    single: np.ndarray
    p_ax: np.ndarray
    v_ax: np.ndarray
    tips: np.ndarray | None
    tip_valid: np.ndarray | None
    ts: TipSamplers | None
    tip_edge: np.ndarray | None
    tip_strength: np.ndarray | None


def _search_view(grey: np.ndarray, model: Model, obs: _Observation, config: ImageConfig, search, tmpl: np.ndarray,
                 tmask: np.ndarray, clock: _Clock, *, boundary_clear: np.ndarray | None = None,
                 tips: bool = True) -> _View:
    """Steps 4-6 of the module docstring for one camera's observation ``obs``.

    Every step but the tips' treats each link (row) on its own, given its profiles, samplers,
    visible share and (for the WSSD snap) ``boundary_clear``; so ``obs`` may also hold rows of
    different views (:func:`_search_turns`), with ``boundary_clear`` computed in each row's own
    view (None: :func:`_against_background` of ``obs``) and ``tips=False`` (step 6 looks at every
    link's outline; the tip fields are then None).
    """
    sc = config.samplers
    snapping = config.method in TEMPLATE_SEARCHES and config.search.snap > 0
    if snapping and boundary_clear is None:
        boundary_clear = _against_background(obs)
    profiles = Profiles(values=obs.values, usable=obs.usable, window=obs.window, centre=sc.centre,
                        radius=sc.samples_per_radius, spacing_px=obs.samplers.spacing_px, templates=tmpl,
                        template_valid=tmask.any(axis=(1, 2)) & obs.samplers.ok,
                        template_mask=tmask,
                        boundary_clear=boundary_clear if snapping else None)
    clock.lap("search")  # template bookkeeping counts with the search
    edges = search(profiles, config.search)
    clock.lap("search")
    edge_px, edge_ok = _edges_to_px(obs.samplers, edges, sc.centre)
    lines, valid, weight, boundary, bvalid, inliers, single, p_ax, v_ax = _fit_links(obs, edge_px, edge_ok, config)
    clock.lap("lines")
    tip_fields = (None,) * 5
    if tips:
        tip_fields = _tips(grey, model, obs, valid, p_ax, v_ax, config)
        clock.lap("tips")
    tip_pts, tip_valid, ts, tip_edge, tip_strength = tip_fields
    return _View(profiles=profiles, edges=edges, edge_px=edge_px, lines=lines, valid=valid, weight=weight,
                 boundary=boundary, bvalid=bvalid, inliers=inliers, single=single, p_ax=p_ax, v_ax=v_ax,
                 tips=tip_pts, tip_valid=tip_valid, ts=ts, tip_edge=tip_edge, tip_strength=tip_strength)


def _parent_links(model: Model) -> np.ndarray:
    """(links,) the link on the nearest frame above each link's frame (-1: none)."""
    by_frame = {f: k for k, f in enumerate(model.link_frame)}
    out = np.full(model.n_links, -1)
    for k, f in enumerate(model.link_frame):
        j = model.parents[f]
        while j >= 0 and j not in by_frame:
            j = model.parents[j]
        out[k] = by_frame.get(j, -1)
    return out


#: Only a link predicted (almost) wholly in view is searched for again when its line is missing.
_REACQUIRE_MIN_VISIBLE = 0.9


def _end_radii(camera, depth: np.ndarray, radius: np.ndarray, ok: np.ndarray) -> np.ndarray:
    """(links, 2) the radius in pixels of each link end's circle: a perspective camera shows each
    end's circle at its own size (the radius at the link's mid depth scaled as 1/depth); NaN for
    a link without samplers."""
    if isinstance(camera, Perspective):
        mid = depth.mean(-1, keepdims=True)
        with np.errstate(divide="ignore", invalid="ignore"):
            r_ends = radius[:, None] * mid / depth
    else:
        r_ends = np.stack([radius, radius], -1)
    return np.where(ok[:, None], r_ends, np.nan)


def _same_bits(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(links,) row ``k`` of ``a`` and of ``b`` hold the same bits (NaNs, signed zeros and all)."""
    a, b = np.ascontiguousarray(a, float), np.ascontiguousarray(b, float)
    return np.all((a.view(np.uint64) == b.view(np.uint64)).reshape(len(a), -1), axis=-1)


@dataclasses.dataclass(frozen=True)
class _Turns:
    """Links searched again with their joints turned (:func:`_search_turns`).

    Attributes:
        links: (turns,) the link searched at each turn.
        view: the search and line fits, row ``i`` for link ``links[i]`` at turn ``i`` (no tips).
        observe: ``observe(i)`` gives turn ``i``'s :class:`_Observation` for the tip search: its
            link geometry, samplers, tips and outlines are every link's at that turn; its
            windows and visible shares are right for ``links[i]`` only (the others are not cut
            by nearer pills), and it holds no profiles.
    """

    links: np.ndarray
    view: _View
    observe: Callable[[int], _Observation]


def _search_turns(grey: np.ndarray, model: Model, cam, chain: np.ndarray, config: ImageConfig, search,
                  tmpl: np.ndarray, tmask: np.ndarray, links: np.ndarray, qs: Sequence[np.ndarray],
                  clock: _Clock) -> _Turns:
    """Link ``links[i]`` searched and fitted in the view at pose ``qs[i]``, for every turn ``i`` at once.

    Row ``i`` is, bit for bit, row ``links[i]`` of ``_search_view(grey, model, _observe(grey, model,
    cam, qs[i], chain, config), ...)``: steps 2-5 of the module docstring treat each link on its
    own except where one link's outline meets another's, so the turns' searched links are stacked
    as the rows of one batch. Each turn takes one jitted kinematics call, as :func:`_observe`;
    then the link poses of all turns (each distinct one once: a turn moves only its link and the
    links below it) are placed in one call and outlined in one :func:`compute_visibility` call,
    in which only the searched links are cut, each by the nearer pills of its own turn's other
    chains, as in its own view; only the searched links' profiles are sampled (one remap),
    searched (one search call) and fitted (one RANSAC call). The WSSD snap (whether a boundary
    lies against the background) looks at each turn's own outlines. Tips are left to the
    caller: only the winning turn's is needed.
    """
    n, L = len(qs), model.n_links
    links = np.asarray(links, int)
    views = [project_pose(model, cam, jnp.asarray(qc)) for qc in qs]
    geometry = [(np.asarray(v.link_start_px, float), np.asarray(v.link_end_px, float),
                 np.asarray(v.link_depth, float), np.asarray(v.link_radius_px, float)) for v in views]
    tips = [np.asarray(v.tips_px, float) for v in views]
    clock.lap("kinematics")
    # One row per distinct link pose: the first turn's links, then each later turn's links that
    # moved (bit for bit), and each turn's searched link in a row of its own; rows[i, k] holds
    # link k at turn i.
    rows = np.tile(np.arange(L), (n, 1))
    parts, count = [geometry[0]], L
    for i in range(1, n):
        moved = ~np.all([_same_bits(a, b) for a, b in zip(geometry[i], geometry[0])], axis=0)
        moved[links[i]] = True
        new = np.flatnonzero(moved)
        rows[i, new] = count + np.arange(len(new))
        parts.append(tuple(a[new] for a in geometry[i]))
        count += len(new)
    start, end, depth, radius = (np.concatenate(a) for a in zip(*parts))
    samplers = place_link_samplers(start, end, radius, config.samplers)
    clock.lap("samplers")
    r_ends = _end_radii(cam, depth, radius, samplers.ok)
    searched = rows[np.arange(n), links]
    # compute_visibility cuts row a by a nearer pill b only where not keep[a, b]: each turn's
    # searched link by its own turn's other chains, nothing else.
    keep = np.ones((count, count), bool)
    for i, k in enumerate(links):
        keep[searched[i], rows[i]] = chain[k]
    vis = compute_visibility(start, end, depth, r_ends[:, 0], r_ends[:, 1], keep, cam.size, config.visibility)
    clock.lap("visibility")
    pts = samplers.points[searched]
    values, usable = sample_profiles(grey, pts, config.samplers.interpolation)
    clock.lap("sampling")
    window = window_masks(vis.windows[searched], pts) & usable
    clock.lap("visibility")

    def observe(i: int) -> _Observation:
        at = rows[i]
        s = LinkSamplers(**{f.name: getattr(samplers, f.name)[at] for f in dataclasses.fields(LinkSamplers)})
        v = Visibility(outlines=vis.outlines[at], depth=vis.depth[at], order=None, visible=vis.visible[at],
                       windows=vis.windows[at], visible_share=vis.visible_share[at])
        return _Observation(start=start[at], end=end[at], tips=tips[i], samplers=s, visibility=v, values=None,
                            usable=None, window=None)

    clear = None
    if config.method in TEMPLATE_SEARCHES and config.search.snap > 0:
        clear = np.stack([_against_background(observe(i))[k] for i, k in enumerate(links)])
    batch = _Observation(
        start=start[searched], end=end[searched], tips=None,
        samplers=LinkSamplers(**{f.name: getattr(samplers, f.name)[searched]
                                 for f in dataclasses.fields(LinkSamplers)}),
        visibility=Visibility(outlines=vis.outlines[searched], depth=vis.depth[searched], order=None,
                              visible=vis.visible[searched], windows=vis.windows[searched],
                              visible_share=vis.visible_share[searched]),
        values=values, usable=usable, window=window)
    view = _search_view(grey, model, batch, config, search, tmpl[links], tmask[links], clock, boundary_clear=clear,
                        tips=False)
    return _Turns(links=links, view=view, observe=observe)


def _turns_to_try(model: Model, q: np.ndarray, config: ImageConfig, obs: _Observation, view: _View
                  ) -> list[tuple[int, np.ndarray]]:
    """(link, turned pose) of every turn :func:`_reacquire` tries, link by link in order: the
    links that qualify (see there), each with its joint turned by ``config.reacquire_deg``
    both ways within the joint limits (a turn the limits cancel is left out)."""
    parent = _parent_links(model)
    frame_q = np.array([model.q_index[f] for f in model.link_frame])
    anchored = np.where(parent >= 0, view.valid[np.maximum(parent, 0)], True)
    todo = np.flatnonzero(~view.valid & anchored & (obs.visibility.visible_share >= _REACQUIRE_MIN_VISIBLE)
                          & obs.samplers.ok & (frame_q >= 0)
                          & np.array([model.joint_kinds[f] == "revolute" for f in model.link_frame]))
    lo, hi = np.asarray(model.q_lower, float), np.asarray(model.q_upper, float)
    turns = []
    for link in todo:
        j = frame_q[link]
        for turn in np.radians([a * sign for a in config.reacquire_deg for sign in (1.0, -1.0)]):
            qc = q.copy()
            qc[j] = np.clip(q[j] + turn, lo[j], hi[j])
            if qc[j] != q[j]:
                turns.append((int(link), qc))
    return turns


def _reacquire(grey: np.ndarray, model: Model, cam, q: np.ndarray, chain: np.ndarray, config: ImageConfig, search,
               tmpl: np.ndarray, tmask: np.ndarray, obs: _Observation, view: _View, clock: _Clock
               ) -> tuple[_View, np.ndarray]:
    """Search again for the links the prediction shows but the search did not find.

    A link qualifies when it has samplers, is predicted in full view (visible share of at least
    :data:`_REACQUIRE_MIN_VISIBLE`: a link partly behind another is missing for that reason), no
    line was found for it and its parent link's line was (so its joint is where the model says):
    its own joint is then turned by each of ``config.reacquire_deg`` both ways (within the joint
    limits) and the view searched again; the turn whose search finds the link's line with the
    most boundary inliers, at least one per sampler, gives that link's line (and tip): a turn
    that only grazes the phalanx finds fewer inliers on a line several degrees off. Not in the
    documents: a distal phalanx that moves faster than the filter predicts
    otherwise leaves its profiles and is not found again while the prediction lags.

    All turns of all qualifying links are searched as one batch (:func:`_search_turns`) and only
    the winning turn's tip is searched for: the results are, bit for bit, those of observing and
    searching each turn's whole view (:func:`_reacquire_full`), in about a quarter of the time
    (six turns of one index + thumb view with iMWPLLS: 6 ms instead of 24). The turns' work is
    timed under the stages it belongs to (kinematics, visibility, ..., tips).
    """
    if model.n_links == 1:  # a one-link view skips the cutting; the batch would cut by an empty pill
        return _reacquire_full(grey, model, cam, q, chain, config, search, tmpl, tmask, obs, view, clock)
    tried = _turns_to_try(model, q, config, obs, view)
    reacquired = np.zeros(model.n_links, bool)
    if not tried:
        return view, reacquired
    links = np.array([k for k, _ in tried])
    turns = _search_turns(grey, model, cam, chain, config, search, tmpl, tmask, links, [qc for _, qc in tried], clock)
    found = turns.view

    def tip(i: int, link: int) -> tuple[np.ndarray, bool]:
        # The tip of the winning turn's link, from its line alone (the other links' lines only
        # place their own tips).
        line_ok = np.zeros(model.n_links, bool)
        p_ax, v_ax = np.zeros((model.n_links, 2)), np.tile([1.0, 0.0], (model.n_links, 1))
        line_ok[link], p_ax[link], v_ax[link] = found.valid[i], found.p_ax[i], found.v_ax[i]
        tips, tip_valid, *_ = _tips(grey, model, turns.observe(i), line_ok, p_ax, v_ax, config)
        clock.lap("tips")
        t = model.tip_links.index(link)
        return tips[t], tip_valid[t]

    return _take_best_turns(model, view, links, found.valid, found.inliers.sum(axis=(1, 2)),
                            lambda i: {k: getattr(found, k)[i] for k in _TURN_FIELDS}, tip)


def _reacquire_full(grey: np.ndarray, model: Model, cam, q: np.ndarray, chain: np.ndarray, config: ImageConfig,
                    search, tmpl: np.ndarray, tmask: np.ndarray, obs: _Observation, view: _View, clock: _Clock
                    ) -> tuple[_View, np.ndarray]:
    """:func:`_reacquire` the straightforward way, each turn's whole view observed and searched
    (the reference the batch is tested against; also a one-link model's)."""
    tried = _turns_to_try(model, q, config, obs, view)
    links = np.array([k for k, _ in tried], int)
    views = [_search_view(grey, model, _observe(grey, model, cam, qc, chain, config), config, search, tmpl, tmask,
                          clock) for _, qc in tried]

    def tip(i: int, link: int) -> tuple[np.ndarray, bool]:
        t = model.tip_links.index(link)
        return views[i].tips[t], views[i].tip_valid[t]

    return _take_best_turns(model, view, links, np.array([v.valid[k] for v, k in zip(views, links)], bool),
                            np.array([v.inliers[k].sum() for v, k in zip(views, links)], int),
                            lambda i: {f: getattr(views[i], f)[links[i]] for f in _TURN_FIELDS}, tip)


#: The per-link fields of a :class:`_View` a winning turn replaces (its tip aside).
_TURN_FIELDS = ("lines", "valid", "weight", "single")


def _take_best_turns(model: Model, view: _View, links: np.ndarray, valid: np.ndarray, score: np.ndarray,
                     row: Callable[[int], dict], tip: Callable[[int, int], tuple]) -> tuple[_View, np.ndarray]:
    """``view`` with each turned link's fields from its best turn: turn ``i`` searched link
    ``links[i]``, found it (``valid[i]``) with ``score[i]`` boundary inliers; the turn with the
    most, at least one per sampler (the first of equals), gives ``row(i)`` and, for a tip link,
    ``tip(i, link)``. Returns the view and which links were re-acquired."""
    out = {k: getattr(view, k).copy() for k in (*_TURN_FIELDS, "tips", "tip_valid")}
    reacquired = np.zeros(model.n_links, bool)
    for link in dict.fromkeys(links.tolist()):
        best, best_score = None, view.profiles.values.shape[1] - 1   # at least one inlier per sampler
        for i in np.flatnonzero(links == link):  # in the order the turns were made
            if valid[i] and score[i] > best_score:
                best, best_score = i, score[i]
        if best is None:
            continue
        reacquired[link] = True
        for k, v in row(best).items():
            out[k][link] = v
        if link in model.tip_links:
            t = model.tip_links.index(link)
            out["tips"][t], out["tip_valid"][t] = tip(best, link)
    return dataclasses.replace(view, **out), reacquired


def extract_features(images, model: Model, cameras, q_pred, config: ImageConfig | None = None,
                     state: ImageState | None = None) -> tuple[tuple[Features, ...], Diagnostics]:
    """Link lines and tip points of every camera's image, searched around the predicted pose.

    Args:
        images: one image per camera, in the rig's order (a single array for one camera): 2-D
            uint8 or float grey levels (0-255), or (H, W, 3) uint8 BGR; each must have its
            camera's size. NaN pixels are allowed (profiles through them are dropped).
        model: the model.
        cameras: a camera or a rig.
        q_pred: (n_q,) the predicted pose that places the trackers and the windows.
        config: settings (default :class:`ImageConfig`, the WSSD search).
        state: stored templates (for the "wssd" search; see :func:`capture_templates`). Links
            without a template get one from this frame at ``q_pred`` when enough of them is seen,
            as the thesis's first frame does with its hand-set pose; the updated state comes back
            in ``diagnostics.state``. Templates are never refreshed here: the prediction is not
            the pose the image shows; refresh them with :func:`capture_templates` at the solved pose.

    Returns:
        (features, diagnostics): one :class:`~jaxhand.features.Features` per camera (lines with
        unit normals oriented like :func:`~jaxhand.features.line_through` of each predicted link,
        weights scaled by each link's visible share) and the :class:`Diagnostics`.

    Raises:
        InputError: bad images (count, type, dtype, shape, size), q_pred or config.
    """
    config, rig, greys, q, chain = _prepare(images, model, cameras, q_pred, config, "q_pred")
    search = search_named(config.method)
    state = _matching_state(state, len(rig), model, config)
    model = state.model_radii(model)
    features, diags, templates, masks = [], [], [], []
    clock = _Clock()
    for c, (grey, cam) in enumerate(zip(greys, rig)):
        obs = _observe(grey, model, cam, q, chain, config, clock)
        tmpl, tmask = state.templates[c], state.template_mask[c]
        if config.method in TEMPLATE_SEARCHES:
            tmpl, tmask = _take_templates(obs, config, tmpl, tmask, only_missing=True)
        templates.append(tmpl)
        masks.append(tmask)
        view = _search_view(grey, model, obs, config, search, tmpl, tmask, clock)
        reacquired = np.zeros(model.n_links, bool)
        if config.reacquire_deg:
            view, reacquired = _reacquire(grey, model, cam, q, chain, config, search, tmpl, tmask, obs, view, clock)
        tip_valid = view.tip_valid
        features.append(Features(lines=jnp.asarray(view.lines), line_valid=jnp.asarray(view.valid),
                                 line_weight=jnp.asarray(view.weight), tips=jnp.asarray(view.tips),
                                 tip_valid=jnp.asarray(tip_valid),
                                 tip_weight=jnp.asarray(tip_valid.astype(float))))
        diags.append(CameraDiagnostics(samplers=obs.samplers, visibility=obs.visibility, profiles=view.profiles,
                                       edges=view.edges, edge_px=view.edge_px, boundary_lines=view.boundary,
                                       boundary_valid=view.bvalid, inliers=view.inliers, axial_lines=view.lines,
                                       single_edge=view.single, tip_samplers=view.ts, tip_edge_px=view.tip_edge,
                                       tip_strength=view.tip_strength, reacquired=reacquired))
    new_state = dataclasses.replace(state, templates=tuple(templates), template_mask=tuple(masks))
    return tuple(features), Diagnostics(method=config.method, cameras=tuple(diags), state=new_state,
                                        timings_s=dict(clock.totals))


class WindowOutlines(Sequence):
    """Per camera, the exterior coordinates of the window polygons (for overlays), converted
    from shapely only when a camera's list is first read.

    ``windows[c]`` is a list of (k, 2) arrays, one per non-empty polygonal window of camera
    ``c``, in link order; it behaves as a read-only list of such lists.
    """

    def __init__(self, diagnostics: Diagnostics):
        self._windows = [cd.visibility.windows for cd in diagnostics.cameras]
        self._coords: dict[int, list[np.ndarray]] = {}

    def __len__(self) -> int:
        return len(self._windows)

    def __getitem__(self, c):
        if isinstance(c, slice):
            return [self[i] for i in range(*c.indices(len(self)))]
        c = range(len(self))[c]  # negative indices; IndexError past the end
        if c not in self._coords:
            self._coords[c] = [np.asarray(w.exterior.coords) for w in self._windows[c]
                               if w is not None and not w.is_empty and w.geom_type == "Polygon"]
        return self._coords[c]

    def __repr__(self) -> str:
        return f"WindowOutlines({len(self)} cameras)"
