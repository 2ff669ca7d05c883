"""One camera's view of one frame: the per-camera context the pipeline's steps share, and the
observation at one pose (predicted geometry, samplers, visibility, sampled profiles), with the
point tests on its outlines; also the entry points' common input checks."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from typing import no_type_check

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._errors import InputError
from ..camera import Perspective, as_rig
from ..kinematics import occluder_pills, pose, validate_q
from ..model import Model
from ._config import ImageConfig
from ._diagnostics import Clock
from ._geometry import predicted_geometry
from ._sampling import as_grey, sample_profiles
from ._state import ImageState
from ._trackers import LinkSamplers, place_link_samplers
from ._visibility import OccluderPills, Visibility, compute_visibility, same_chain
from ._xy import all_last

__all__ = ["CameraContext", "Observation", "observe", "observe_occluders", "end_radii", "off_other_links",
           "against_background", "as_images", "prepare", "matching_state", "layout"]


@dataclasses.dataclass(frozen=True)
class CameraContext:
    """What every step of one camera's analysis of one frame works with.

    Attributes:
        grey: (H, W) float32 grey image (:func:`jaxhand.image.as_grey`).
        model: the model, with the radii in use (the image state's estimate, else its own).
        camera: the camera.
        chain: (links, links) :func:`same_chain` of the model.
        config: the front end's settings.
        clock: stage timings, shared by the cameras of one call.
        search: the configured search (None where none is run).
        templates, template_mask: (links, samplers, points) the templates in use (None: none).
    """

    grey: np.ndarray
    model: Model
    camera: object
    chain: np.ndarray
    config: ImageConfig
    clock: Clock
    search: Callable | None = None
    templates: np.ndarray | None = None
    template_mask: np.ndarray | None = None


@dataclasses.dataclass(frozen=True)
class Observation:
    """A view's predicted geometry, samplers, visibility and sampled profiles.

    Attributes:
        start, end: (links, 2) projected link ends (px).
        tips: (tips, 2) projected tips (px); None in a batch of turns.
        samplers: the link samplers.
        visibility: outlines, windows and visible shares.
        values, usable: (links, samplers, points) sampled profiles and their usable samples.
        window: (links, samplers, points) the samples inside their link's window (and usable).
    """

    start: np.ndarray
    end: np.ndarray
    tips: np.ndarray | None
    samplers: LinkSamplers
    visibility: Visibility
    values: np.ndarray | None
    usable: np.ndarray | None
    window: np.ndarray | None


def end_radii(camera, depth: np.ndarray, radius: np.ndarray, ok: np.ndarray) -> np.ndarray:
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


@eqx.filter_jit
def _occluder_ends(model: Model, camera, q):
    """(occluders, 2, 2) pixels, (occluders, 2) depths (mm) and radii (px at each end's depth) of
    the occluder pills' two ends (the kinematics call of :func:`observe_occluders`)."""
    occ = occluder_pills(model, pose(model, q))
    ends = jnp.stack([occ.start, occ.end], -2)
    px, depth = camera.project(ends)
    J = camera.pixel_jacobian(ends)  # a sphere's image radius: r times the local scale (px per mm)
    return px, depth, occ.radius_mm[:, None] * jnp.abs(jnp.linalg.det(J @ jnp.swapaxes(J, -1, -2))) ** 0.25


def observe_occluders(model: Model, camera, q: np.ndarray) -> OccluderPills | None:
    """The model's occluder-only pills (palm, forearm) seen by ``camera`` at ``q``; None for a
    model without occluders. Ends behind a perspective camera get NaN (their outline is empty)."""
    if not model.n_occluders:
        return None
    px, depth, radius = (np.asarray(a, float) for a in _occluder_ends(model, camera, np.asarray(q, float)))
    behind = ~(depth > 0) if isinstance(camera, Perspective) else np.zeros(depth.shape, bool)
    radius = np.where(behind, np.nan, radius)
    return OccluderPills(start_px=px[:, 0], end_px=px[:, 1], depth=depth, radius_start=radius[:, 0],
                         radius_end=radius[:, 1])


def observe(ctx: CameraContext, q: np.ndarray) -> Observation:
    """Steps 1-3 of the pipeline at pose ``q``: kinematics, samplers, visibility (cut by the
    model's occluder pills too), profiles."""
    config, clock = ctx.config, ctx.clock
    geo = predicted_geometry(ctx.model, ctx.camera, q)
    start, end, depth, radius = geo.start, geo.end, geo.depth, geo.radius
    occluders = observe_occluders(ctx.model, ctx.camera, q)
    clock.lap("kinematics")
    samplers = place_link_samplers(start, end, radius, config.samplers)
    clock.lap("samplers")
    r_ends = end_radii(ctx.camera, depth, radius, samplers.ok)
    vis = compute_visibility(start, end, depth, r_ends[:, 0], r_ends[:, 1], ctx.chain, ctx.camera.size,
                             config.visibility, occluders)
    clock.lap("visibility")
    values, usable = sample_profiles(ctx.grey, samplers.points, config.samplers.interpolation)
    clock.lap("sampling")
    window = vis.window_mask(samplers.points) & usable
    clock.lap("visibility")
    return Observation(start=start, end=end, tips=geo.tips, samplers=samplers,
                       visibility=vis, values=values, usable=usable, window=window)


def off_other_links(obs: Observation, points: np.ndarray, links: np.ndarray | None = None,
                    ignore: np.ndarray | None = None) -> np.ndarray:
    """True where a point of link ``links[i]`` (``points[i, ...]``) lies outside the outline of every
    other link: other fingers, and also the neighbouring phalanges of its own finger, which near
    a bent joint widen the silhouette on the inner side (``ignore`` (n, links): links that do not
    count for point row i)."""
    vis = obs.visibility
    links = np.arange(len(vis.outlines)) if links is None else np.asarray(links, int)
    return ~vis.inside_others(points, links, ignore)


def against_background(obs: Observation, reach: Sequence[float]) -> np.ndarray:
    """(links, samplers, 2) the points ``reach`` radii to each side of a profile's centre (boundary
    0: towards smaller sample indices, boundary 1: larger) lie off every other link's outline
    (:func:`off_other_links`), so that boundary is the link's own, seen against the background
    (``VisibilityConfig.background_reach``)."""
    s = obs.samplers
    at = np.concatenate([-np.asarray(reach, float), np.asarray(reach, float)])
    off = (s.radius_px[:, None] * at)[:, None, :, None] * s.normal[:, None, None, :]
    clear = off_other_links(obs, s.centres[:, :, None, :] + off)  # (links, samplers, 2 * reaches)
    n = len(reach)
    return np.stack([all_last(clear[..., :n]), all_last(clear[..., n:])], -1)


def as_images(images, n_cameras: int, sizes: Sequence[tuple[int, int]]) -> list[np.ndarray]:
    """Validate one image per camera and convert each once to float32 grey levels.

    A single array is accepted for a one-camera rig.

    Raises:
        InputError: wrong count, type, dtype, shape, size or range, naming the image.
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


def layout(config: ImageConfig) -> tuple[int, int, float]:
    """(samplers per link, points per profile, scope): what shapes the templates."""
    s = config.samplers
    return (s.per_link, s.points, float(s.scope))


@no_type_check   # the front end's argument checks (InputError naming the argument), which a checker would preempt
def prepare(images, model: Model, cameras, q, config: ImageConfig | None, name: str):
    """The entry points' checks: (config, rig, grey images, q, chain)."""
    config = ImageConfig() if config is None else config
    if not isinstance(config, ImageConfig):
        raise InputError(f"config: expected an ImageConfig, got {type(config).__name__}")
    rig = as_rig(cameras)
    greys = as_images(images, len(rig), [c.size for c in rig])
    q = validate_q(model, q, name=name)
    return config, rig, greys, q, model_chain(model)


_CHAINS: dict[int, tuple[Model, np.ndarray]] = {}


def model_chain(model: Model) -> np.ndarray:
    """:func:`same_chain` of ``model``, kept for the last few models (a tracker calls with one
    model every frame; the model's ancestor table is rebuilt on each access)."""
    hit = _CHAINS.get(id(model))
    if hit is not None and hit[0] is model:
        return hit[1]
    chain = same_chain(model.link_frame, model.ancestors)
    chain.setflags(write=False)
    if len(_CHAINS) >= 8:
        _CHAINS.pop(next(iter(_CHAINS)))
    _CHAINS[id(model)] = (model, chain)
    return chain


def matching_state(state: ImageState | None, n_cameras: int, model: Model, config: ImageConfig) -> ImageState:
    """``state`` when its templates fit this rig, model and layout, else an empty one (keeping
    estimated radii of the right shape)."""
    lay = layout(config)
    if state is not None and state.matches(n_cameras, model.n_links, lay):
        return state
    radius = None if state is None or np.shape(state.radius_mm) != (model.n_links,) else state.radius_mm
    return dataclasses.replace(ImageState.empty(n_cameras, model.n_links, lay), radius_mm=radius)
