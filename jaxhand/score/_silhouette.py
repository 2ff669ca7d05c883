"""The model's silhouette: capsules (pills) rasterised with OpenCV.

A capsule is the convex hull of the two spheres centred on its axis ends, so its image under
any camera that sees it entirely in front (orthographic, or perspective with every point at
positive depth) is the convex hull of the images of the two spheres: projective maps keep
segments straight. A sphere's image is bounded by the image of its rim, the circle where the
viewing rays touch it:

- orthographic (rays along the camera's z): the rim is the great circle ``c + r (cos t, sin t, 0)``;
- perspective (rays from the camera centre): the rim lies in the plane perpendicular to ``c`` at
  ``c (1 - r^2 / |c|^2)``, with radius ``r sqrt(|c|^2 - r^2) / |c|``; its image is the ellipse
  bounding the sphere's image.

Steps: sample every rim at ``rim_points`` angles (one vectorised NumPy pass over all capsules),
project the samples, take each capsule's convex hull and fill it with ``cv2.fillConvexPoly`` in
fixed point (4 fractional bits), far capsules first, so the label image (painter's algorithm by
mean depth) shows the nearer capsule where two overlap. The polygon's vertices lie on the exact
outline (moved inwards by ``shrink_px``, which offsets OpenCV's filling of boundary pixels), so
the mask is exact up to the chord error ``R (1 - cos(pi / rim_points))`` (0.05 px for a 10 px
radius at 32 points) and the rounding of pixels the outline passes through.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Bool, Float, Int

from .._errors import InputError
from ..camera import Orthographic, Perspective
from ..kinematics import Pills, all_pills, check_q_shape, pose
from ..model import Model

__all__ = ["Capsules", "capsules_from_model", "capsules_from_model_batch", "capsules_in_camera", "CameraNumbers",
           "camera_numbers", "capsule_outlines", "rasterize", "Silhouette"]

# Fixed-point bits of the polygon vertices handed to OpenCV (1/16 px).
_SHIFT = 4
# Capsules whose rim comes closer to a perspective camera than this (mm) are not drawn: the
# camera is inside or at the sphere and its image is not bounded.
_NEAR_MM = 1e-3


@dataclass(frozen=True)
class CameraNumbers:
    """A camera's numbers as NumPy values (read once per frame): ``p_cam = R p_world + t``.

    Perspective: ``K`` (3, 3); orthographic: ``scale`` (px/mm) and ``center`` (px).
    """

    R: np.ndarray
    t: np.ndarray
    size: tuple[int, int]
    perspective: bool
    K: np.ndarray | None = None
    scale: float = 1.0
    center: np.ndarray | None = None

    def project_cam(self, p_cam: Float[np.ndarray, "*n 3"]) -> Float[np.ndarray, "*n 2"]:
        """Pixels (x, y) of camera-frame points (..., 3); perspective needs ``z > 0``."""
        if self.perspective:
            u = p_cam @ self.K.T
            return u[..., :2] / u[..., 2:3]
        return self.scale * p_cam[..., :2] + self.center


def camera_numbers(camera) -> CameraNumbers:
    """:class:`CameraNumbers` of an :class:`~jaxhand.Orthographic` or :class:`~jaxhand.Perspective` camera."""
    if isinstance(camera, Perspective):
        return CameraNumbers(R=np.asarray(camera.R, float), t=np.asarray(camera.t, float), size=camera.size,
                             perspective=True, K=np.asarray(camera.K, float))
    if isinstance(camera, Orthographic):
        return CameraNumbers(R=np.asarray(camera.R, float), t=np.asarray(camera.t, float), size=camera.size,
                             perspective=False, scale=float(camera.scale), center=np.asarray(camera.center, float))
    raise InputError(f"camera: expected an Orthographic or Perspective camera, got {type(camera).__name__}")


@dataclass(frozen=True)
class Capsules:
    """Capsules in the world frame (mm): axis ends ``start``/``end`` (n, 3) and ``radius_mm`` (n,).

    ``occluder`` (n,) marks capsules that belong to the scene but not to the tracked links (a palm
    or forearm the model lacks); they are drawn into the silhouette and hide what lies behind them.
    """

    start: Float[np.ndarray, "n 3"]
    end: Float[np.ndarray, "n 3"]
    radius_mm: Float[np.ndarray, " n"]
    occluder: Bool[np.ndarray, " n"]

    @staticmethod
    def from_arrays(start, end, radius_mm, occluder=None) -> Capsules:
        """Validated capsules from array-likes.

        Raises:
            InputError: wrong shapes, non-finite values or a negative radius.
        """
        s, e, r = (np.asarray(a, float) for a in (start, end, radius_mm))
        if s.ndim != 2 or s.shape[1] != 3 or e.shape != s.shape or r.shape != (s.shape[0],):
            raise InputError(f"capsules: expected start/end (n, 3) and radius (n,), got {s.shape}, {e.shape}, "
                             f"{r.shape}")
        if not (np.all(np.isfinite(s)) and np.all(np.isfinite(e)) and np.all(np.isfinite(r)) and np.all(r >= 0)):
            raise InputError("capsules: ends must be finite and radii finite and >= 0")
        occ = np.zeros(len(r), bool) if occluder is None else np.asarray(occluder, bool).reshape(len(r))
        return Capsules(start=s, end=e, radius_mm=r, occluder=occ)

    def __add__(self, other: Capsules) -> Capsules:
        """Both sets, self first (e.g. the model's links and a static palm)."""
        return Capsules(start=np.vstack([self.start, other.start]), end=np.vstack([self.end, other.end]),
                        radius_mm=np.concatenate([self.radius_mm, other.radius_mm]),
                        occluder=np.concatenate([self.occluder, other.occluder]))

    @property
    def n(self) -> int:
        return len(self.radius_mm)


def _pills(model: Model, q) -> Pills:
    """Every pill of the model (links, then occluder pills) at state q."""
    return all_pills(model, pose(model, q))


_pills_one = eqx.filter_jit(_pills)
# One compiled kinematics call for a stack of states (hypotheses); the model is shared.
_pills_batch = eqx.filter_jit(jax.vmap(_pills, in_axes=(None, 0)))


def _capsules(model: Model, start, end, radius) -> Capsules:
    occ = np.arange(len(radius)) >= model.n_links   # the model's occluder pills come after its links
    return Capsules(start=np.asarray(start, float), end=np.asarray(end, float), radius_mm=np.asarray(radius, float),
                    occluder=occ)


def capsules_from_model(model: Model, q) -> Capsules:
    """The model's pills at state q (one jitted kinematics call), as world-frame capsules: its
    links, then its occluder-only pills (palm, forearm; flagged ``occluder``)."""
    check_q_shape(model, q)
    p = _pills_one(model, jnp.asarray(q, dtype=model.q_lower.dtype))
    return _capsules(model, p.start, p.end, p.radius_mm)


def capsules_from_model_batch(model: Model, qs) -> list[Capsules]:
    """:func:`capsules_from_model` at each state of ``qs`` (k, n_q), from one jitted, vmapped call."""
    qs = jnp.asarray(qs, dtype=model.q_lower.dtype)
    if qs.ndim != 2 or qs.shape[1] != model.n_q:
        raise InputError(f"qs: expected shape (k, {model.n_q}) for model {model.name!r}, got {qs.shape}")
    p = _pills_batch(model, qs)
    start, end, radius = (np.asarray(a, float) for a in (p.start, p.end, p.radius_mm))
    return [_capsules(model, start[i], end[i], radius[i]) for i in range(len(start))]


def capsules_in_camera(capsules: Capsules, cam: CameraNumbers
                       ) -> tuple[Float[np.ndarray, "n 2 3"], Float[np.ndarray, " n"]]:
    """Axis ends in the camera frame, stacked as (n, 2, 3) (mm), and the mean depth (n,) (mm)."""
    ends = np.stack([capsules.start, capsules.end], 1) @ cam.R.T + cam.t
    return ends, ends[..., 2].mean(-1)


def capsule_outlines(capsules: Capsules, cam: CameraNumbers, rim_points: int = 32, shrink_px: float = 0.0
                     ) -> tuple[Float[np.ndarray, "n m2 2"], Float[np.ndarray, " n"], Bool[np.ndarray, " n"]]:
    """The projected rims of every capsule's two end spheres.

    Args:
        capsules: world-frame capsules.
        cam: the camera's numbers.
        rim_points: samples per rim.
        shrink_px: every sphere's radius is reduced by this many pixels at its own depth
            (``fx / z`` px per mm under perspective, ``scale`` under orthographic).

    Returns:
        points: (n, 2 * rim_points, 2) pixels (x, y) whose convex hull is each capsule's image.
        depth: (n,) mean camera depth of each capsule's axis (mm).
        drawable: (n,) False where a perspective camera is inside or behind a sphere.
    """
    ends, depth = capsules_in_camera(capsules, cam)
    ppm = cam.scale if not cam.perspective else cam.K[0, 0] / np.maximum(ends[..., 2], _NEAR_MM)  # px per mm
    r = np.maximum(capsules.radius_mm[:, None] - shrink_px / ppm, 0.0)  # (n, 1) or (n, 2): per sphere
    r = np.broadcast_to(r, ends.shape[:2])
    t = np.linspace(0.0, 2 * np.pi, rim_points, endpoint=False)
    cos_t, sin_t = np.cos(t), np.sin(t)
    if not cam.perspective:
        circle = np.stack([cos_t, sin_t, np.zeros_like(t)], -1)  # (m, 3): the great circle seen along z
        rim = ends[:, :, None, :] + r[..., None, None] * circle
        drawable = np.ones(capsules.n, bool)
    else:
        d2 = np.sum(ends**2, -1)  # (n, 2) squared distance of each sphere centre from the camera
        drawable = np.all((d2 > (r + _NEAR_MM) ** 2) & (ends[..., 2] > r + _NEAR_MM), -1)
        # Guard: spheres the camera is inside get a dummy d2 so the rim stays finite (not drawn).
        d2 = np.where(d2 > r**2 + _NEAR_MM, d2, (r + 1.0) ** 2 + 1.0)
        centre = ends * (1.0 - r**2 / d2)[..., None]
        rho = r * np.sqrt(d2 - r**2) / np.sqrt(d2)
        axis = ends / np.sqrt(d2)[..., None]
        # Two unit vectors perpendicular to the viewing ray of each centre.
        helper = np.where(np.abs(axis[..., :1]) < 0.9, np.array([1.0, 0, 0]), np.array([0, 1.0, 0]))
        u = np.cross(axis, helper)
        u /= np.linalg.norm(u, axis=-1, keepdims=True)
        v = np.cross(axis, u)
        circle = cos_t[:, None] * u[:, :, None] + sin_t[:, None] * v[:, :, None]  # (n, 2, m, 3)
        rim = centre[:, :, None] + rho[..., None, None] * circle
        rim[~drawable] = np.array([0.0, 0.0, 1.0])  # dummy, finite; skipped when drawing
    px = cam.project_cam(rim)  # (n, 2, m, 2)
    return px.reshape(capsules.n, 2 * rim_points, 2), depth, drawable


@dataclass(frozen=True)
class Silhouette:
    """A rasterised model.

    Attributes:
        mask: (H, W) bool, True where any capsule covers the pixel centre.
        label: (H, W) int16 index of the nearest capsule (by mean axis depth) at each pixel, -1 on
            background.
        occluder: (n,) the capsules' occluder flags (from :class:`Capsules`).
        adjacent: (n, n) bool, capsules that join (end to end, as a pill chain or a finger and its
            palm capsule, or two occluders): the boundary between them is no contour in the image.
        box: (x0, y0, x1, y1), pixel bounds (end exclusive) that hold every drawn pixel, grown by
            one pixel and clipped to the image; (0, 0, 0, 0) when nothing is drawn. Work per pose
            (contours, per-link counts) is done on this crop only.
    """

    mask: Bool[np.ndarray, "H W"]
    label: Int[np.ndarray, "H W"]
    occluder: Bool[np.ndarray, " n"]
    adjacent: Bool[np.ndarray, "n n"]
    box: tuple[int, int, int, int] = (0, 0, 0, 0)

    def crop(self) -> tuple[slice, slice]:
        """(rows, cols) slices of :attr:`box`."""
        x0, y0, x1, y1 = self.box
        return slice(y0, y1), slice(x0, x1)


def _adjacency(capsules: Capsules) -> np.ndarray:
    """Capsules that join without an occluding contour between them.

    Two capsules join when a pair of their axis ends lies closer than half their summed radii
    (a pill chain, a finger and its palm capsule), and any two occluders join (a palm built of
    overlapping capsules is one body: its seams are shallow grooves, not contours).
    """
    e = np.stack([capsules.start, capsules.end], 1)  # (n, 2, 3)
    d = np.linalg.norm(e[:, None, :, None] - e[None, :, None, :], axis=-1).min(axis=(2, 3))
    r = capsules.radius_mm
    occ = capsules.occluder
    return (d < 0.5 * (r[:, None] + r[None, :])) | (occ[:, None] & occ[None, :])


def rasterize(capsules: Capsules, camera, *, rim_points: int = 32, shrink_px: float = 0.5) -> Silhouette:
    """Draw the capsules as a mask and a label image at the camera's size.

    Args:
        capsules: world-frame capsules (:func:`capsules_from_model`, plus any occluders).
        camera: an Orthographic or Perspective camera (or its :class:`CameraNumbers`).
        rim_points: samples on each sphere's rim (>= 8).
        shrink_px: outlines are moved inwards by this much (px) before filling: OpenCV fills every
            pixel its polygon's boundary passes through, which grows a filled shape by about half
            a pixel; 0.5 makes the mask match pixel-centre coverage (the renderer's link-ID map)
            to within the pixels on the outline (tests/test_score_silhouette.py).

    Returns:
        The :class:`Silhouette`. Capsules a perspective camera sits inside are left out.
    """
    cam = camera if isinstance(camera, CameraNumbers) else camera_numbers(camera)
    if rim_points < 8:
        raise InputError(f"rim_points: need >= 8, got {rim_points}")
    w, h = cam.size
    label = np.full((h, w), -1, np.int16)
    box = (0, 0, 0, 0)
    if capsules.n:
        pts, depth, drawable = capsule_outlines(capsules, cam, rim_points, shrink_px)
        if drawable.any():
            lo = np.floor(pts[drawable].reshape(-1, 2).min(0)).astype(int) - 1
            hi = np.ceil(pts[drawable].reshape(-1, 2).max(0)).astype(int) + 2
            x0, y0 = np.clip(lo, 0, [w, h])
            x1, y1 = np.clip(hi, 0, [w, h])
            box = (int(x0), int(y0), int(max(x1, x0)), int(max(y1, y0)))
        fixed = np.round(pts * (1 << _SHIFT))
        # Keep OpenCV's int32 fixed point far from overflow: clamp to a frame 64x the image.
        lim = 64.0 * max(w, h) * (1 << _SHIFT)
        fixed = np.clip(fixed, -lim, lim).astype(np.int32)
        for i in np.argsort(-depth, kind="stable"):  # far first: nearer capsules overwrite
            if drawable[i]:
                hull = cv2.convexHull(fixed[i])
                cv2.fillConvexPoly(label, hull, int(i), lineType=cv2.LINE_8, shift=_SHIFT)
    return Silhouette(mask=label >= 0, label=label, occluder=capsules.occluder, adjacent=_adjacency(capsules),
                      box=box)
