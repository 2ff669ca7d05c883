"""Jacobian checks: ``jax.jacfwd`` against central differences and the geometric Jacobian.

The geometric Jacobian is DigitEyes' analytic one (eqs. 8-10), for a point p attached to frame f:

- revolute joint j above f: ``dp/dq_j = z_j x (p - o_j)`` (eq. 8; z_j and o_j are joint j's axis
  and origin in the world);
- prismatic joint j above f: ``dp/dq_j = z_j``;
- free palm translation: ``dp/dt = R_world_mount`` (eq. 9);
- free palm quaternion entry k: ``dp/dq_k = [R_world_mount J_w]_k x (p - o_root)`` (eq. 10), with
  ``J_w = 2 E(q)/|q|`` mapping quaternion rates to the angular velocity (``omega = 2 qdot q*``);
- planar palm: x, y along the mount's x and y axes, yaw ``z_mount x (p - o_root)``.

Pixels follow by the chain rule through :meth:`Camera.pixel_jacobian`.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .camera import Camera
from .kinematics import pose as pose_at
from .model import Model

__all__ = ["keypoints", "keypoint_pixels", "autodiff_jacobian", "central_difference_jacobian",
           "geometric_jacobian", "projected_geometric_jacobian", "jacobian_errors"]


def keypoints(model: Model, q) -> tuple[Float[Array, "p 3"], np.ndarray]:
    """Link start and end points (world) stacked, and the frame each is attached to."""
    pose = pose_at(model, q)
    frames = np.concatenate([model.link_frame, model.link_frame]).astype(int)
    return jnp.concatenate([pose.link_start, pose.link_end]), frames


def keypoint_pixels(model: Model, camera: Camera, q) -> Float[Array, "p 2"]:
    return camera.project(keypoints(model, q)[0])[0]


@eqx.filter_jit
def autodiff_jacobian(model: Model, camera: Camera, q) -> Float[Array, "p 2 nq"]:
    """d pixel / d q of every link end by forward-mode autodiff (``jax.jacfwd``)."""
    return jax.jacfwd(keypoint_pixels, argnums=2)(model, camera, q)


@eqx.filter_jit
def _keypoint_pixels_batch(model: Model, camera: Camera, qs):
    return jax.vmap(lambda q: keypoint_pixels(model, camera, q))(qs)


def central_difference_jacobian(f_batch, q, eps: float = 1e-6) -> np.ndarray:
    """Central differences ``(f(q + e_i eps) - f(q - e_i eps)) / 2 eps``, stacked on the last axis.

    ``f_batch`` maps a stack of states (k, nq) to a stack of outputs (k, ...); all 2 nq
    perturbed states are evaluated in one call.
    """
    q = np.asarray(q, dtype=float)
    steps = eps * np.eye(q.size)
    out = np.asarray(f_batch(np.concatenate([q + steps, q - steps])))
    diff = (out[: q.size] - out[q.size:]) / (2 * eps)
    return np.moveaxis(diff, 0, -1)


def geometric_jacobian(model: Model, q) -> Float[Array, "p 3 nq"]:
    """d p_world / d q of every link end from the joint axes (DigitEyes eqs. 8-10): the solver's
    :func:`jaxhand.residuals.point_jacobian` at the link ends."""
    from .residuals import point_jacobian

    q = jnp.asarray(q)
    p, attached = keypoints(model, q)
    return point_jacobian(model, q, pose_at(model, q).frames, p, attached)


@eqx.filter_jit
def projected_geometric_jacobian(model: Model, camera: Camera, q) -> Float[Array, "p 2 nq"]:
    """The geometric Jacobian mapped into pixels through the camera."""
    p, _ = keypoints(model, jnp.asarray(q))
    return camera.pixel_jacobian(p) @ geometric_jacobian(model, q)


def jacobian_errors(model: Model, camera: Camera, q, eps: float = 1e-6) -> dict[str, float]:
    """Relative max-abs differences of the autodiff Jacobian from central differences and the
    geometric Jacobian (each divided by max(1, max |J_autodiff|)). Use float64."""
    q = jnp.asarray(q, dtype=float)
    J = np.asarray(autodiff_jacobian(model, camera, q))
    scale = max(1.0, float(np.abs(J).max()))
    fd = central_difference_jacobian(lambda qs: _keypoint_pixels_batch(model, camera, jnp.asarray(qs)), q, eps)
    geo = np.asarray(projected_geometric_jacobian(model, camera, q))
    return {"finite_difference": float(np.abs(J - fd).max() / scale),
            "geometric": float(np.abs(J - geo).max() / scale)}
