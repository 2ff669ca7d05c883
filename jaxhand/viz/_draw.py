"""Overlays drawn with OpenCV: link axes, pill outlines, joints and tips of a projected model."""

from __future__ import annotations

import cv2
import numpy as np

from ..camera import Camera
from ..kinematics import View, project_pose
from ..model import Model

__all__ = ["draw_view", "draw_points", "sketch_model"]

_SHIFT = 4  # sub-pixel drawing: OpenCV takes fixed-point coordinates with 4 fractional bits


#: pixels beyond this (a point near a perspective camera's plane) or not finite are not drawn:
#: OpenCV's fixed-point coordinates are 32-bit
_MAX_PX = 1e6


def _pt(p) -> tuple[int, int]:
    return (int(round(p[0] * (1 << _SHIFT))), int(round(p[1] * (1 << _SHIFT))))


def _drawable(*points) -> bool:
    return all(bool(np.all(np.isfinite(p)) and np.all(np.abs(p) < _MAX_PX)) for p in points)


#: the colour of links drawn as not seen (``draw_view``'s ``dim``)
DIM = (150, 150, 150)


def draw_view(image: np.ndarray, view: View, color=(0, 0, 255), *, outline: bool = False, thickness: int = 1,
              joints: bool = True, dim=None) -> np.ndarray:
    """Draw a projected model onto a BGR uint8 image (in place; also returned).

    Args:
        image: (H, W, 3) uint8 BGR image.
        view: the model seen by this image's camera (:func:`jaxhand.project_pose`).
        color: BGR colour of the link axes.
        outline: also draw each pill's projected outline (two side lines and end circles).
        thickness: line thickness in pixels.
        joints: mark joint centres (circles) and tips (filled dots).
        dim: optional (n_links,) flags: those links drawn in grey (:data:`DIM`), e.g. the links
            whose joint the frame did not see.
    """
    s, e = np.asarray(view.link_start_px), np.asarray(view.link_end_px)
    r = np.asarray(view.link_radius_px)
    dim = np.zeros(len(s), bool) if dim is None else np.asarray(dim, bool)
    for k in range(len(s)):  # drawing API is per primitive; a few dozen links per frame
        if not _drawable(s[k], e[k], r[k]):
            continue
        colour = DIM if dim[k] else color
        cv2.line(image, _pt(s[k]), _pt(e[k]), colour, thickness, cv2.LINE_AA, _SHIFT)
        if outline:
            d = e[k] - s[k]
            n = np.array([-d[1], d[0]]) / max(np.linalg.norm(d), 1e-9) * r[k]
            for sign in (1, -1):
                cv2.line(image, _pt(s[k] + sign * n), _pt(e[k] + sign * n), colour, 1, cv2.LINE_AA, _SHIFT)
            for c in (s[k], e[k]):
                cv2.circle(image, _pt(c), int(round(r[k] * (1 << _SHIFT))), colour, 1, cv2.LINE_AA, _SHIFT)
        if joints:
            cv2.circle(image, _pt(s[k]), 2 << _SHIFT, colour, 1, cv2.LINE_AA, _SHIFT)
    if joints:
        for t in np.asarray(view.tips_px):
            if not _drawable(t):
                continue
            cv2.circle(image, _pt(t), 3 << _SHIFT, color, -1, cv2.LINE_AA, _SHIFT)
    return image


def draw_points(image: np.ndarray, px, color=(0, 255, 0), radius: int = 3) -> np.ndarray:
    """Filled dots at the (n, 2) pixels ``px`` (in place; also returned), skipping missing (NaN)
    and undrawable points."""
    for p in np.asarray(px, float).reshape(-1, 2):
        if _drawable(p):
            cv2.circle(image, _pt(p), radius << _SHIFT, color, -1, cv2.LINE_AA, _SHIFT)
    return image


def sketch_model(model: Model, camera: Camera, q, *, background: int = 0) -> np.ndarray:
    """A quick BGR picture of the model at state q: pill outlines and axes on a plain background."""
    w, h = camera.size
    image = np.full((h, w, 3), background, np.uint8)
    return draw_view(image, project_pose(model, camera, q), (80, 200, 255), outline=True)
