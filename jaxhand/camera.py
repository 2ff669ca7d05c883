"""Cameras: orthographic and perspective projection, rigs, camera files.

Conventions: a camera maps world points (mm) into its own frame with ``p_cam = R p_world + t``
(``R = R_cam_world``); the camera frame has x right, y down, z forward. Pixels are ``(x, y)``
with x the column, y the row and the origin at the centre of the top-left pixel. ``depth`` is
``p_cam.z`` (mm) for both kinds, so larger depth is farther from the camera.

- :class:`Orthographic`: ``pixel = scale * p_cam.xy + center`` (thesis §2.4.1 with
  ``[R|t] = [I|0]`` generalised to any view direction).
- :class:`Perspective`: ``pixel = (K p_cam).xy / (K p_cam).z`` (P = K[R|t]).

A rig is a tuple of cameras; residuals from every camera are stacked (DigitEyes §5.3).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Union

import cv2
import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from ._errors import CameraError

__all__ = ["Orthographic", "Perspective", "Camera", "as_rig", "load_camera", "save_camera", "look_at_rotation",
           "scale_camera", "scaled_size", "scaled_pixels"]

# Points closer to a perspective camera than this (mm) are clamped so projection stays finite.
_MIN_DEPTH_MM = 1e-6


def _floats(x) -> Array:
    """A camera's numbers as a float array: integers (a centre given as ``(160, 120)``) become floats."""
    x = jnp.asarray(x)
    return x if jnp.issubdtype(x.dtype, jnp.floating) else x.astype(float)


def _size(size) -> tuple[int, int]:
    try:
        w, h = (float(v) for v in size)
    except (TypeError, ValueError):
        raise CameraError(f"camera size must be two positive integers (width, height), got {size!r}") from None
    if not (w > 0 and h > 0 and w == int(w) and h == int(h)):
        raise CameraError(f"camera size must be two positive integers (width, height), got {size!r}")
    return (int(w), int(h))


class Orthographic(eqx.Module):
    """Orthographic camera: a view rotation, a scale (px/mm) and the pixel of the optical axis.

    Static: ``size`` (width, height) in pixels. Traced: ``R``, ``t``, ``scale``, ``center``.
    """

    R: Float[Array, "3 3"] = eqx.field(converter=_floats)
    t: Float[Array, 3] = eqx.field(converter=_floats)
    scale: Float[Array, ""] = eqx.field(converter=_floats)
    center: Float[Array, 2] = eqx.field(converter=_floats)
    size: tuple[int, int] = eqx.field(static=True, converter=_size)

    def to_camera(self, p_world: Float[ArrayLike, "*n 3"]) -> Float[Array, "*n 3"]:
        return p_world @ self.R.T + self.t

    def project(self, p_world: Float[ArrayLike, "*n 3"]) -> tuple[Float[Array, "*n 2"], Float[Array, " *n"]]:
        """Pixels and depth (mm) of world points."""
        p = self.to_camera(p_world)
        return self.scale * p[..., :2] + self.center, p[..., 2]

    def unproject(self, pixels: Float[ArrayLike, "*n 2"], depth: Float[ArrayLike, " *n"]) -> Float[Array, "*n 3"]:
        """World points at the given pixels and depths (inverse of :meth:`project`)."""
        p = jnp.concatenate([(pixels - self.center) / self.scale, depth[..., None]], axis=-1)
        return (p - self.t) @ self.R

    def pixel_jacobian(self, p_world: Float[ArrayLike, "*n 3"]) -> Float[Array, "*n 2 3"]:
        """d pixel / d p_world at each point."""
        J = self.scale * self.R[:2]
        return jnp.broadcast_to(J, p_world.shape[:-1] + (2, 3))

    def projection_matrix(self) -> np.ndarray:
        """The 3x4 affine camera matrix: [pixel; 1] = P [p_world; 1]."""
        P = np.zeros((3, 4))
        P[:2, :3] = float(self.scale) * np.asarray(self.R[:2])
        P[:2, 3] = float(self.scale) * np.asarray(self.t[:2]) + np.asarray(self.center)
        P[2, 3] = 1.0
        return P

    @classmethod
    def fit(cls, points_world, size=(320, 240), R=None, margin: float = 0.1) -> Orthographic:
        """A camera with rotation ``R`` (default identity) that frames ``points_world`` with a margin."""
        R = np.eye(3) if R is None else np.asarray(R, float)
        w, h = _size(size)
        p = np.asarray(points_world, float).reshape(-1, 3) @ R.T
        lo, hi = p[:, :2].min(0), p[:, :2].max(0)
        span = np.maximum(hi - lo, 1e-9)
        scale = (1 - 2 * margin) * min(w / span[0], h / span[1])
        mid = (lo + hi) / 2
        center = np.array([(w - 1) / 2, (h - 1) / 2]) - scale * mid
        t = np.array([0.0, 0.0, -p[:, 2].min() + 100.0])
        return cls(R=R, t=t, scale=scale, center=center, size=(w, h))


class Perspective(eqx.Module):
    """Pinhole camera ``P = K [R | t]``.

    Static: ``size`` (width, height). Traced: ``K``, ``R``, ``t``.
    """

    K: Float[Array, "3 3"] = eqx.field(converter=_floats)
    R: Float[Array, "3 3"] = eqx.field(converter=_floats)
    t: Float[Array, 3] = eqx.field(converter=_floats)
    size: tuple[int, int] = eqx.field(static=True, converter=_size)

    def to_camera(self, p_world: Float[ArrayLike, "*n 3"]) -> Float[Array, "*n 3"]:
        return p_world @ self.R.T + self.t

    def project(self, p_world: Float[ArrayLike, "*n 3"]) -> tuple[Float[Array, "*n 2"], Float[Array, " *n"]]:
        """Pixels and depth (mm) of world points; points behind the camera get clamped depth."""
        p = self.to_camera(p_world)
        u = p @ self.K.T
        # Guard: a point at or behind the camera centre would divide by ~0; clamp so the pixel
        # stays finite (such points are off-image anyway and the image front end masks them).
        w = jnp.where(u[..., 2] > _MIN_DEPTH_MM, u[..., 2], _MIN_DEPTH_MM)
        return u[..., :2] / w[..., None], p[..., 2]

    def unproject(self, pixels: Float[ArrayLike, "*n 2"], depth: Float[ArrayLike, " *n"]) -> Float[Array, "*n 3"]:
        ray = jnp.concatenate([pixels, jnp.ones_like(pixels[..., :1])], axis=-1) @ jnp.linalg.inv(self.K).T
        p = ray / ray[..., 2:3] * depth[..., None]
        return (p - self.t) @ self.R

    def pixel_jacobian(self, p_world: Float[ArrayLike, "*n 3"]) -> Float[Array, "*n 2 3"]:
        u = self.to_camera(p_world) @ self.K.T
        pix = u[..., :2] / u[..., 2:3]
        d_pix_d_pcam = (self.K[:2] - pix[..., :, None] * self.K[2]) / u[..., 2:3, None]
        return d_pix_d_pcam @ self.R

    def projection_matrix(self) -> np.ndarray:
        return np.asarray(self.K) @ np.hstack([np.asarray(self.R), np.asarray(self.t)[:, None]])

    @classmethod
    def from_opencv(cls, camera_matrix, rvec, tvec, size) -> Perspective:
        """From OpenCV's camera matrix and Rodrigues rotation/translation (world -> camera)."""
        K = np.asarray(camera_matrix, float)
        if K.shape != (3, 3):
            raise CameraError(f"camera_matrix must be 3x3, got shape {K.shape}")
        R, _ = cv2.Rodrigues(np.asarray(rvec, float).reshape(3, 1))
        return cls(K=K, R=R, t=np.asarray(tvec, float).reshape(3), size=size)

    def to_opencv(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(camera_matrix, rvec, tvec) for ``cv2.projectPoints``."""
        rvec, _ = cv2.Rodrigues(np.asarray(self.R, float))
        return np.asarray(self.K, float), rvec.reshape(3), np.asarray(self.t, float)

    @classmethod
    def look_at(cls, eye_mm, target_mm, *, up=(0.0, -1.0, 0.0), fov_deg: float = 40.0,
                size=(320, 240)) -> Perspective:
        """A camera at ``eye_mm`` looking at ``target_mm``; ``up`` is the world direction shown up."""
        w, h = _size(size)
        R = look_at_rotation(eye_mm, target_mm, up)
        f = 0.5 * w / np.tan(np.radians(fov_deg) / 2)
        K = np.array([[f, 0, (w - 1) / 2], [0, f, (h - 1) / 2], [0, 0, 1]])
        return cls(K=K, R=R, t=-R @ np.asarray(eye_mm, float), size=(w, h))


Camera = Union[Orthographic, Perspective]


def look_at_rotation(eye, target, up=(0.0, -1.0, 0.0)) -> np.ndarray:
    """R_cam_world whose z axis points from ``eye`` to ``target`` and whose -y axis is nearest ``up``."""
    z = np.asarray(target, float) - np.asarray(eye, float)
    if np.linalg.norm(z) < 1e-12:
        raise CameraError("look_at: eye and target coincide")
    z /= np.linalg.norm(z)
    x = np.cross(-np.asarray(up, float), z)
    if np.linalg.norm(x) < 1e-9:
        raise CameraError("look_at: 'up' is parallel to the viewing direction")
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return np.stack([x, y, z])


def as_rig(cameras) -> tuple[Camera, ...]:
    """A tuple of cameras from one camera or a sequence of them."""
    if isinstance(cameras, (Orthographic, Perspective)):
        return (cameras,)
    rig = tuple(cameras)
    if not rig or not all(isinstance(c, (Orthographic, Perspective)) for c in rig):
        raise CameraError("a rig must be a non-empty sequence of Orthographic/Perspective cameras")
    return rig


def scaled_size(size, factor: float) -> tuple[int, int]:
    """(width, height) of an image of ``size`` resized by ``factor`` (rounded, at least 1 px)."""
    w, h = _size(size)
    return max(1, round(w * factor)), max(1, round(h * factor))


def scaled_pixels(px, size, new_size) -> np.ndarray:
    """Pixel coordinates ``px`` (..., 2) of an image of ``size`` in the image resized to
    ``new_size`` (width, height), pixel centres at integers: ``(u + 0.5) * s - 0.5``."""
    s = np.asarray(new_size, float) / np.asarray(size, float)
    return (np.asarray(px, float) + 0.5) * s - 0.5


def scale_camera(camera: Camera, factor: float) -> Camera:
    """The camera that sees the same scene in its images resized by ``factor`` (0 < factor, e.g.
    0.5 for half the width and height), pixel centres kept at integer coordinates: a pixel ``u``
    becomes ``(u + 0.5) * s - 0.5`` (:func:`scaled_pixels`) with ``s`` the exact ratio of the
    rounded sizes per axis.

    Raises:
        CameraError: a factor that is not a finite number > 0.
    """
    if not (np.isfinite(factor) and factor > 0):
        raise CameraError(f"scale: expected a finite factor > 0 (e.g. 0.5 for half size), got {factor!r}")
    w, h = camera.size
    size = scaled_size(camera.size, factor)
    s = np.array([size[0] / w, size[1] / h])
    if isinstance(camera, Orthographic):
        if abs(s[0] - s[1]) > 1e-3 * s.max():
            raise CameraError(f"scale {factor}: an orthographic camera of {w}x{h} px needs a factor that keeps "
                              "its aspect ratio in whole pixels")
        return Orthographic(R=camera.R, t=camera.t, scale=camera.scale * s.mean(),
                            center=scaled_pixels(camera.center, camera.size, size), size=size)
    S = np.array([[s[0], 0.0, 0.5 * s[0] - 0.5], [0.0, s[1], 0.5 * s[1] - 0.5], [0.0, 0.0, 1.0]])
    return Perspective(K=S @ np.asarray(camera.K), R=camera.R, t=camera.t, size=size)


# ---- camera files (JSON) ----

def _has_bool(x) -> bool:
    """Whether a JSON value holds a boolean anywhere in its nested lists."""
    return isinstance(x, bool) or (isinstance(x, list) and any(_has_bool(v) for v in x))


def _camera_from_dict(d: dict, src: str) -> Camera:
    def arr(key, shape):
        if key not in d:
            raise CameraError(f"{src}: missing field {key!r}")
        try:   # JSON true/false are not numbers, though NumPy would read them as 1/0
            a = None if _has_bool(d[key]) else np.asarray(d[key], float)
        except (TypeError, ValueError):   # a string, a ragged list, a null
            a = None
        if a is None or a.shape != shape or not np.all(np.isfinite(a)):
            want = "a number" if shape == () else f"finite numbers of shape {shape} (nested lists)"
            raise CameraError(f"{src}: field {key!r} must be {want}, got {d[key]!r}")
        return a

    kind = d.get("kind")
    allowed = {"orthographic": {"kind", "R", "t", "scale", "center", "size"},
               "perspective": {"kind", "K", "R", "t", "size"}}
    if not isinstance(kind, str) or kind not in allowed:
        raise CameraError(f"{src}: field 'kind' must be 'orthographic' or 'perspective', got {kind!r}")
    unknown = set(d) - allowed[kind]
    if unknown:
        raise CameraError(f"{src}: unknown field(s) {sorted(unknown)} for a {kind} camera")
    R = arr("R", (3, 3))
    if not np.allclose(R @ R.T, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0:
        raise CameraError(f"{src}: field 'R' is not a rotation matrix")
    size = arr("size", (2,))
    if not np.all((size > 0) & (size == np.round(size))):
        raise CameraError(f"{src}: field 'size' must be two positive integers (width, height), got {d['size']!r}")
    if kind == "orthographic":
        scale = float(arr("scale", ()))
        if scale <= 0:
            raise CameraError(f"{src}: field 'scale' must be > 0, got {scale}")
        return Orthographic(R=R, t=arr("t", (3,)), scale=scale, center=arr("center", (2,)), size=size)
    K = arr("K", (3, 3))
    if not (K[0, 0] > 0 and K[1, 1] > 0 and np.allclose(K[2], [0.0, 0.0, 1.0]) and K[1, 0] == 0):
        raise CameraError(f"{src}: field 'K' must be an intrinsic matrix [[fx, s, cx], [0, fy, cy], [0, 0, 1]] "
                          f"with fx, fy > 0 px, got {d['K']!r}")
    return Perspective(K=K, R=R, t=arr("t", (3,)), size=size)


def camera_to_dict(camera: Camera) -> dict:
    if isinstance(camera, Orthographic):
        return {"kind": "orthographic", "R": np.asarray(camera.R).tolist(), "t": np.asarray(camera.t).tolist(),
                "scale": float(camera.scale), "center": np.asarray(camera.center).tolist(),
                "size": list(camera.size)}
    return {"kind": "perspective", "K": np.asarray(camera.K).tolist(), "R": np.asarray(camera.R).tolist(),
            "t": np.asarray(camera.t).tolist(), "size": list(camera.size)}


def camera_from_dict(d: object, source: str = "<dict>") -> Camera:
    if not isinstance(d, dict):
        raise CameraError(f"{source}: expected an object")
    return _camera_from_dict(d, source)


def load_camera(path: str | Path) -> tuple[Camera, ...]:
    """Load one camera (an object) or a rig (a list of objects) from a JSON file."""
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except OSError as err:
        raise CameraError(f"{path}: cannot read camera file ({err.strerror})") from err
    except json.JSONDecodeError as err:
        raise CameraError(f"{path}: cannot parse: {err}") from err
    items = data if isinstance(data, list) else [data]
    if not items:
        raise CameraError(f"{path}: the file lists no camera")
    return tuple(camera_from_dict(d, f"{path}[{i}]" if isinstance(data, list) else str(path))
                 for i, d in enumerate(items))


def save_camera(cameras, path: str | Path) -> Path:
    """Write a camera or rig as JSON (one object, or a list for several cameras)."""
    rig = as_rig(cameras)
    data = camera_to_dict(rig[0]) if len(rig) == 1 else [camera_to_dict(c) for c in rig]
    Path(path).write_text(json.dumps(data, indent=2) + "\n")
    return Path(path)
