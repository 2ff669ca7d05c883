"""Each link's support by the image edges across its own sides.

A link's silhouette score (coverage and chamfer) cannot tell a finger that lies wrongly over the
hand: the hand's own edges lie near its outline wherever it goes. The edge a true link makes runs
*along* its side, so the image gradient there points *across* it. Each link's visible side points
(both sides at ``side_fractions`` of its length, those no nearer pill covers:
:func:`~jaxhand.score._term.visible_outline`) are searched within ``side_edge_px`` along the
side's normal for a gradient component across the side of at least ``side_edge_gradient`` grey
levels per px, in any colour channel of a colour frame (skin against a wall of the same grey
still makes an edge); a link's share is the fraction of its points that find one (NaN without
points).
"""

from __future__ import annotations

import cv2
import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..model import Model
from ._foreground import as_grey
from ._score import ScoreConfig
from ._term import _pill_geometry, _sides, visible_outline

__all__ = ["link_sides", "side_edge_share"]


@eqx.filter_jit
def link_sides(model: Model, camera, q, fractions: tuple[float, ...]):
    """Both sides' points of every link at ``fractions`` (``(2 * links * k, 2)``: the +normal side,
    then the -normal side, each link by link), their unit normals and which no nearer pill covers."""
    geometry = _pill_geometry(model, camera, jnp.asarray(q))
    points, visible = visible_outline(model, geometry, fractions)
    n_side = 2 * model.n_links * len(fractions)
    _, normal, _, _ = _sides(*(g[:model.n_links] for g in geometry[:4]), fractions)
    normal = jnp.repeat(normal, len(fractions), axis=0)
    return points[:n_side], jnp.concatenate([normal, normal]), visible[:n_side]


def side_edge_share(image, model: Model, camera, q, config: ScoreConfig) -> np.ndarray:
    """(links,) each link's share of visible side points with an edge across the side (NaN: none
    visible), on ``image`` (grey or BGR) at pose ``q`` seen by ``camera`` (a rig camera)."""
    a = np.asarray(image)
    colour = a.ndim == 3 and a.shape[2] == 3 and np.issubdtype(a.dtype, np.integer)
    planes = (a if colour else as_grey(image)[..., None]).astype(np.float32)   # (H, W, channels): B, G, R or grey
    if config.blur_sigma_px > 0:
        planes = cv2.GaussianBlur(planes, (0, 0), config.blur_sigma_px).reshape(planes.shape)
    gx = cv2.Sobel(planes, cv2.CV_32F, 1, 0, ksize=3).reshape(planes.shape) / 8.0   # levels per px
    gy = cv2.Sobel(planes, cv2.CV_32F, 0, 1, ksize=3).reshape(planes.shape) / 8.0
    points, normals, visible = (np.asarray(a) for a in link_sides(model, camera, q, tuple(config.side_fractions)))
    offsets = np.arange(-config.side_edge_px, config.side_edge_px + 0.25, 0.5)
    at = points[:, None, :] + offsets[None, :, None] * normals[:, None, :]        # (m, offsets, 2)
    height, width = planes.shape[:2]
    x, y = np.rint(at[..., 0]).astype(int), np.rint(at[..., 1]).astype(int)
    inside = (x >= 0) & (x < width) & (y >= 0) & (y < height)
    x, y = np.clip(x, 0, width - 1), np.clip(y, 0, height - 1)
    across = np.max(np.abs(gx[y, x] * normals[:, None, 0, None] + gy[y, x] * normals[:, None, 1, None]), axis=-1)
    hit = np.any(inside & (across >= config.side_edge_gradient), axis=1)
    owner = np.tile(np.repeat(np.arange(model.n_links), len(config.side_fractions)), 2)
    count = np.bincount(owner[visible], minlength=model.n_links)
    hits = np.bincount(owner[visible & hit], minlength=model.n_links)
    return np.where(count > 0, hits / np.maximum(count, 1), np.nan)
