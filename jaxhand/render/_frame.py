"""One synthetic frame: a grey image of a model's pills with exact ground-truth maps.

Steps (thesis app. C, done per pixel instead of with faceted patches and a screen capture):

1. forward kinematics gives every pill's axis ends in the world; the camera moves them into its frame;
2. every pixel's ray is intersected with the pills inside their projected bounding boxes and a
   z-buffer keeps the nearest hit (:mod:`._raycast`);
3. binary mode paints the silhouettes; shaded mode lights each visible point with Lambert diffuse
   and Phong specular terms, using the exact normal of the pill at that point (the direction from
   its closest axis point), which the thesis approximates with Gouraud/Phong interpolation;
4. antialiasing samples average down to pixels, the background shows where nothing was hit, then
   optional blur and Gaussian noise, and the result is rounded to 8 bits.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import cv2
import jax.numpy as jnp
import numpy as np

from .._errors import InputError
from ..camera import Orthographic, Perspective
from ..kinematics import forward, validate_q
from ..model import Model
from ._config import RenderConfig, make_background
from ._raycast import cast, pill_normals, pills_in_camera, ray_grid

__all__ = ["RenderResult", "render_frame", "pill_geometry", "degrade"]


def degrade(image, blur_sigma_px: float = 0.0, noise_sigma: float = 0.0,
            rng: np.random.Generator | None = None) -> np.ndarray:
    """``image`` as a camera would give it: a Gaussian blur of ``blur_sigma_px`` (0: none), then
    Gaussian noise of ``noise_sigma`` grey levels drawn from ``rng`` (0: none), rounded and
    clipped to 8 bits. The dev set's cluttered copy was made this way (data/mujoco/README.md)."""
    if blur_sigma_px < 0 or noise_sigma < 0:
        raise InputError(f"degrade: blur and noise must be >= 0, got {blur_sigma_px}, {noise_sigma}")
    if noise_sigma > 0 and rng is None:
        raise InputError("degrade: noise needs a random generator (rng=np.random.default_rng(seed))")
    image = np.asarray(image, float)
    if blur_sigma_px > 0:
        image = cv2.GaussianBlur(image, (0, 0), blur_sigma_px)
    if noise_sigma > 0:
        image = image + rng.normal(0.0, noise_sigma, image.shape)
    return np.clip(np.rint(image), 0, 255).astype(np.uint8)


@dataclass(frozen=True)
class RenderResult:
    """A rendered frame and its ground truth (all at the camera's pixel grid, indexed [y, x]).

    Attributes:
        image: (H, W) uint8 grey image.
        link_id: (H, W) int16 index of the link seen at each pixel centre, -1 on background.
        depth: (H, W) float64 camera-frame depth (mm, ``p_cam.z``) at each pixel centre, ``inf`` on
            background.
        visible_fraction: (links,) visible pixels of each link over the pixels its pill covers when
            rendered alone (0 for a pill that covers no pixel of the image). Both counts are taken
            inside the image, so a pill cut by the image border is not counted as occluded. Pills
            next to each other on a finger share their joint sphere, and the nearer (or larger) one
            shows there, so an unoccluded link typically has 0.6-0.95, not 1.
        visible_px: (links,) pixels showing each link.
        alone_px: (links,) pixels each pill covers when rendered alone.
    """

    image: np.ndarray
    link_id: np.ndarray
    depth: np.ndarray
    visible_fraction: np.ndarray
    visible_px: np.ndarray
    alone_px: np.ndarray


def pill_geometry(model: Model, q) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """World-frame pill axes (link_start, link_end: (links, 3) mm) and radii (links,) at state q."""
    pose = forward(model, jnp.asarray(q, dtype=jnp.float64))
    return np.asarray(pose.link_start), np.asarray(pose.link_end), np.asarray(model.link_radius_mm)


@functools.lru_cache(maxsize=8)
def _cached_background(spec: str, size: tuple[int, int], seed: int) -> np.ndarray:
    bg = make_background(spec, size, seed)
    bg.setflags(write=False)
    return bg


def _background(config: RenderConfig, size: tuple[int, int]) -> np.ndarray:
    spec = config.background
    if isinstance(spec, str):
        return _cached_background(spec, size, config.seed)
    return make_background(spec, size, config.seed)


def _shade(config: RenderConfig, normal: np.ndarray, view: np.ndarray, albedo: np.ndarray) -> np.ndarray:
    """Lambert + Phong intensity in [0, 1] of surface samples.

    ``albedo (ambient + (1 - ambient) max(n.l, 0)) + specular max(r.v, 0)^shininess`` with r the
    light's mirror direction about n, so ``r.v = 2 (n.l)(n.v) - l.v``; no specular where n.l <= 0.

    Args:
        normal: (3, n) unit normals; view: (3, n) or (3, 1) unit vectors towards the camera;
        albedo: (n,) per sample.
    """
    light = np.asarray(config.light_dir, float)
    light = light / np.linalg.norm(light)
    n_l = light @ normal
    value = albedo * (config.ambient + (1.0 - config.ambient) * np.maximum(n_l, 0.0))
    if config.specular > 0:
        n_v = np.einsum("ij,ij->j", normal, np.broadcast_to(view, normal.shape))
        r_v = np.maximum(2.0 * n_l * n_v - light @ view, 0.0)
        value = value + config.specular * np.where(n_l > 0, r_v**config.shininess, 0.0)
    return np.clip(value, 0.0, 1.0)


def render_frame(model: Model, camera, q, config: RenderConfig | None = None, *, frame_index: int = 0,
                 use_bbox: bool = True) -> RenderResult:
    """Render ``model`` at state ``q`` as seen by ``camera``.

    Args:
        model: any model; every link is drawn as its pill.
        camera: an :class:`~jaxhand.Orthographic` or :class:`~jaxhand.Perspective` camera; the
            image has its ``size``.
        q: (n_q,) state (radians, mm); it need not lie inside the joint limits.
        config: drawing settings (default: shaded, black background, no noise).
        frame_index: combined with ``config.seed`` to draw this frame's pixel noise.
        use_bbox: evaluate each pill only inside its projected bounding box (the fast path;
            False is the naive full-image peer used by the benchmark).

    Returns:
        The image with its link-ID and depth maps and per-link visibility.

    Raises:
        InputError: a wrongly shaped or non-finite q, an unsupported camera or a bad background.
    """
    config = RenderConfig() if config is None else config
    if not isinstance(camera, (Orthographic, Perspective)):
        raise InputError(f"camera: expected an Orthographic or Perspective camera, got {type(camera).__name__}")
    q = validate_q(model, q)
    w, h = camera.size
    k = int(config.antialias)
    start, end, radius = pill_geometry(model, q)
    grid = ray_grid(camera, k)
    pills = pills_in_camera(camera, start, end, radius)
    zbuf = cast(grid, pills, use_bbox=use_bbox)

    background = _background(config, (w, h))
    if config.mode == "binary":
        mask = zbuf.link_id >= 0
        fg = float(config.foreground)
    else:
        albedo = np.asarray(config.albedo, float)
        if albedo.ndim == 1 and albedo.shape != (model.n_links,):
            raise InputError(f"albedo: expected one value or {model.n_links} (one per link of {model.name!r}), "
                             f"got {len(albedo)}")
        albedo = np.broadcast_to(albedo, (model.n_links,))
        mask, normal, view = pill_normals(grid, pills, zbuf)
        fg = 255.0 * _shade(config, normal, view, albedo[zbuf.link_id[mask]])
    if k == 1:
        image = background.copy()
        image[mask] = fg
    else:
        # Average the k x k samples of each pixel; the background fills the uncovered share.
        samples = np.zeros(mask.shape)
        samples[mask] = fg
        coverage = mask.reshape(h, k, w, k).mean(axis=(1, 3))
        image = samples.reshape(h, k, w, k).mean(axis=(1, 3)) + (1.0 - coverage) * background
    rng = np.random.default_rng([int(config.seed), int(frame_index)]) if config.noise_sigma > 0 else None
    image = degrade(image, config.blur_sigma_px, config.noise_sigma, rng)

    c = (k - 1) // 2  # pixel-centre sample of each block
    link_id = np.ascontiguousarray(zbuf.link_id[c::k, c::k])
    depth = np.ascontiguousarray(zbuf.depth[c::k, c::k])
    visible = np.bincount(link_id[link_id >= 0], minlength=model.n_links).astype(np.int64)
    alone = zbuf.alone
    frac = np.where(alone > 0, visible / np.maximum(alone, 1), 0.0)
    return RenderResult(image=image, link_id=link_id, depth=depth, visible_fraction=frac, visible_px=visible,
                        alone_px=alone)
