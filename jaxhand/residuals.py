"""Link and tip residuals, stacked over tips, links and cameras (thesis §3.1.1, DigitEyes §5.1, §5.3).

For one camera, with the model at state q projected into pixels:

- tip residual (thesis eq. 3.1): ``t_i(q) - t_i^obs``, two entries (x, y) per tip slot;
- link residual (thesis eq. 3.2): ``a x_k(q) + b y_k(q) - rho`` at ``k = 1..K`` points along the
  projected link axis, the point ``k`` at fraction ``f_k`` from the link's start (its joint) to its
  end. ``(a, b)`` is the observed line's unit normal, so the residual is the signed distance in
  pixels from the model point to the observed line.

The default fractions are ``(0.25, 0.75)``: two points, so each line constrains both the
position and the direction of its link, placed away from the link ends because the ends are
where the image front end is least reliable (joints shared with the neighbouring link, the
tip's cap). The thesis's worked examples use ``P = 3`` and ``P = 2`` on ``L = 5`` links, i.e.
fractions ``(0.6, 0.4)``; pass those to reproduce them. DigitEyes puts the points at the
base and the tip of the link, i.e. ``(0.0, 1.0)``.

Layout of the residual vector (static, so it never changes with the data): for each camera in
rig order, first ``2 * tips`` tip entries (tip-major, then x, y), then ``K * links`` link entries
(link-major, then point). A perspective camera projects exactly: its link residual is the
distance from the projected axis point to the observed line, in pixels.

Weights and masks: a slot's residuals are multiplied by ``sqrt(weight)``, so the cost
``H = 1/2 ||r||^2 = 1/2 sum weight * (raw residual)^2`` weights squared pixel errors by
``weight`` (an inverse variance, px^-2 relative to a 1-px error). An invalid slot gives exact
zeros, and its stored numbers are replaced *before* any arithmetic, so NaN or inf left in a
masked slot can reach neither the residuals nor their Jacobian.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from ._errors import InputError
from .camera import as_rig
from .features import Features, validate_features
from .kinematics import link_points
from .kinematics import pose as pose_at
from .model import Model

__all__ = ["DEFAULT_LINK_FRACTIONS", "ResidualArgs", "make_residual_args", "residuals", "cost",
           "residual_jacobian", "residuals_and_jacobian", "point_jacobian", "residual_labels", "n_residuals",
           "feature_distances", "masked_features"]

#: Default fractions along each link axis (0 = its joint, 1 = its end) of the link residual points.
DEFAULT_LINK_FRACTIONS = (0.25, 0.75)


class ResidualArgs(eqx.Module):
    """Everything the residuals need besides q: the optimistix ``args`` of :func:`residuals`.

    Attributes:
        model: the articulated model (static structure, traced numbers).
        cameras: the rig, one camera per entry of ``features``.
        features: one :class:`~jaxhand.features.Features` per camera (traced arrays).
        fractions: (K,) fractions along each link axis of the link residual points (traced; K
            is static and sets the residual length).
        priors: pose priors stacked under the image residuals, each an ``equinox.Module`` called
            as ``prior(q) -> residuals`` (e.g. :mod:`jaxhand.priors`; a residual of 1 is one
            prior sigma); which priors there are is static, their numbers traced.
    """

    model: Model
    cameras: tuple
    features: tuple
    fractions: Float[Array, " K"]
    priors: tuple = ()


def make_residual_args(model: Model, cameras, features, link_fractions=DEFAULT_LINK_FRACTIONS, *,
                       validate: bool = True, priors: tuple = ()) -> ResidualArgs:
    """Bundle model, rig, features and link-point fractions for :func:`residuals`.

    Raises:
        InputError: the features do not match the model and rig, or a fraction is not a finite
            number (fractions outside [0, 1] extrapolate along the axis and are refused).
    """
    rig = as_rig(cameras)
    feats = validate_features(model, rig, features) if validate else tuple(features)
    fr = np.asarray(link_fractions, dtype=float).reshape(-1)
    if fr.size == 0 or not np.all(np.isfinite(fr)) or np.any((fr < 0) | (fr > 1)):
        raise InputError(f"link_fractions: expected one or more numbers in [0, 1], got {link_fractions!r}")
    return ResidualArgs(model=model, cameras=rig, features=feats, fractions=jnp.asarray(fr), priors=tuple(priors))


def _camera_residuals(model: Model, camera, feats: Features, pose, fractions) -> Float[Array, " r"]:
    tips_px, _ = camera.project(pose.tips)                                        # (tips, 2)
    pts_px, _ = camera.project(link_points(pose, fractions))                      # (links, K, 2)
    return _stack_residuals(feats, tips_px, pts_px)


def masked_features(feats: Features, dtype):
    """The features of one camera with masked slots replaced (before any arithmetic) and sqrt of
    the weights (the one masking rule of the residuals, shared with the batched edge kernel):
    tip_valid (tips, 1), tip_obs (tips, 2), sqrt_tip_w (tips,), lines (links, 3), sqrt_line_w (links,).

    A masked tip observation becomes 0, so NaN there cannot leak into the residuals or (through
    0 * NaN) into their derivative; a masked line becomes (0, 0, 0), whose residual is exactly 0
    at every q."""
    tip_valid = feats.tip_valid[:, None]
    tip_obs = jnp.where(tip_valid, feats.tips, 0.0).astype(dtype)
    tip_w = jnp.where(feats.tip_valid, feats.tip_weight, 0.0).astype(dtype)
    lines = jnp.where(feats.line_valid[:, None], feats.lines, 0.0).astype(dtype)
    line_w = jnp.where(feats.line_valid, feats.line_weight, 0.0).astype(dtype)
    return tip_valid, tip_obs, jnp.sqrt(tip_w), lines, jnp.sqrt(line_w)


def _unweighted(feats: Features, tips_px, pts_px):
    """The raw residuals of one camera: tip offsets ``t(q) - t_obs`` (tips, 2) and signed
    distances of the link points to their observed lines (links, K), px, exact zeros in masked
    slots. The one distance rule of :func:`residuals` and :func:`feature_distances`."""
    tip_valid, tip_obs, _, lines, _ = masked_features(feats, tips_px.dtype)
    d_tip = jnp.where(tip_valid, tips_px - tip_obs, 0.0)
    d_link = jnp.sum(lines[:, None, :2] * pts_px, axis=-1) - lines[:, None, 2]
    return d_tip, d_link


def _stack_residuals(feats: Features, tips_px, pts_px) -> Float[Array, " r"]:
    """One camera's residual vector from its projected tips (tips, 2) and link points (links, K, 2)."""
    _, _, sqrt_tip_w, _, sqrt_line_w = masked_features(feats, tips_px.dtype)
    d_tip, d_link = _unweighted(feats, tips_px, pts_px)
    r_tip = d_tip * sqrt_tip_w[:, None]
    r_link = d_link * sqrt_line_w[:, None]
    return jnp.concatenate([r_tip.reshape(-1), r_link.reshape(-1)])


def feature_distances(model: Model, cameras: tuple, features: tuple, q: Float[ArrayLike, " nq"],
                      fractions: Float[ArrayLike, " K"]) -> tuple[tuple[Float[Array, " links"], Float[Array, " tips"]],
                                                               ...]:
    """Per camera, each link line's largest distance (px) to the model's link points and each
    tip's distance (px) to the model's tip at state q, unweighted, 0 where a feature is invalid
    (traceable, not jitted): what the tracker's gate and robust reweighting judge features by."""
    pose = pose_at(model, q)
    out = []
    for cam, f in zip(cameras, features):
        tips_px, _ = cam.project(pose.tips)
        pts_px, _ = cam.project(link_points(pose, fractions))
        d_tip, d_link = _unweighted(f, tips_px, pts_px)
        out.append((jnp.max(jnp.abs(d_link), axis=-1), jnp.linalg.norm(d_tip, axis=-1)))
    return tuple(out)


def residuals(q: Float[ArrayLike, " nq"], args: ResidualArgs) -> Float[Array, " r"]:
    """The stacked residual vector at state q (optimistix signature ``fn(y, args)``), pixels."""
    pose = pose_at(args.model, q)
    return jnp.concatenate([_camera_residuals(args.model, cam, f, pose, args.fractions)
                            for cam, f in zip(args.cameras, args.features)] + [p(q) for p in args.priors])


def cost(q: Float[ArrayLike, " nq"], args: ResidualArgs) -> Float[Array, ""]:
    """H(q) = 1/2 ||r(q)||^2 (thesis eq. 3.3), px^2."""
    r = residuals(q, args)
    return 0.5 * jnp.sum(r * r)


@eqx.filter_jit
def residual_jacobian(q: Float[ArrayLike, " nq"], args: ResidualArgs) -> Float[Array, "r nq"]:
    """dr/dq by forward-mode autodiff (thesis eqs. 3.6-3.8), px per q unit (jitted)."""
    return jax.jacfwd(residuals)(q, args)


def _quat_rate(quat: Float[Array, 4]) -> Float[Array, "3 4"]:
    """d omega / d quat for the rotation of the normalised quaternion (w, x, y, z): the spatial
    angular velocity ``omega = 2 E(q/|q|) qdot / |q|`` (DigitEyes eq. 10; the normalisation's own
    derivative is orthogonal to E's rows). A zero quaternion (mapped to the identity by the
    kinematics, whatever its rate) gives 0."""
    n = jnp.linalg.norm(quat)
    # Guard: n = 0 would divide by zero; the safe denominator keeps both branches finite.
    safe = jnp.where(n > 0, n, 1.0)
    w, x, y, z = quat / safe
    E = jnp.stack([jnp.stack([-x, w, -z, y]), jnp.stack([-y, z, w, -x]), jnp.stack([-z, -y, x, w])])
    return jnp.where(n > 0, 2.0 * E / safe, 0.0)


def point_jacobian(model: Model, q: Float[ArrayLike, " nq"], frames: Float[ArrayLike, "frames 4 4"],
                   points: Float[ArrayLike, "p 3"], attached: np.ndarray) -> Float[Array, "p 3 nq"]:
    """d p_world / d q of world points rigidly attached to frames, from the joint axes
    (the geometric Jacobian, DigitEyes eqs. 8-10), mm per q unit.

    Columns: a revolute joint j above the point's frame gives ``z_j x (p - o_j)``, a prismatic
    one ``z_j`` (z_j and o_j: joint j's axis and origin in the world, from ``frames``); a free
    base gives ``R_world_mount`` for its translation and ``[R_world_mount dω/dq_k] x (p - o_root)``
    for its quaternion entries; a planar base its mount's x and y axes and
    ``z_mount x (p - o_root)`` for its yaw.

    Args:
        frames: T_world_frame of every frame at q (``kinematics.pose(model, q).frames``).
        attached: static (p,) index of the frame each point is attached to.
    """
    dtype = points.dtype
    moving = np.array([f for f in range(model.n_frames) if model.q_index[f] >= 0], dtype=int)
    J = jnp.zeros(points.shape + (model.n_q,), dtype)
    if moving.size:
        z, o = frames[moving, :3, 2], frames[moving, :3, 3]                           # (F, 3)
        revolute = np.array([model.joint_kinds[f] == "revolute" for f in moving])
        cols = jnp.where(revolute[None, :, None], jnp.cross(z[None], points[:, None] - o[None]), z[None])
        above = model.ancestors[np.asarray(attached, dtype=int)][:, moving]           # (p, F), static
        select = np.zeros((moving.size, model.n_q))                                   # frame -> q entry
        select[np.arange(moving.size), np.array(model.q_index)[moving]] = 1.0
        J = jnp.einsum("pfk,fq->pkq", cols * jnp.asarray(above, dtype)[..., None], jnp.asarray(select, dtype))
    if model.base_kind == "fixed":
        return J
    from .kinematics import base_pose

    R_mount = model.T_world_mount[:3, :3].astype(dtype)
    r = points - base_pose(model, q)[:3, 3]                                          # (p, 3) from the root
    n = points.shape[0]
    if model.base_kind == "free":
        omega = R_mount @ _quat_rate(q[:4])                                            # (3, 4)
        J_quat = jnp.swapaxes(jnp.cross(omega.T[None], r[:, None]), 1, 2)             # (p, 3, 4)
        base = jnp.concatenate([J_quat, jnp.broadcast_to(R_mount, (n, 3, 3))], axis=-1)
    else:  # planar: x, y along the mount's axes, yaw about its z
        yaw = jnp.cross(R_mount[:, 2][None], r)
        base = jnp.stack([jnp.broadcast_to(R_mount[:, 0], (n, 3)), jnp.broadcast_to(R_mount[:, 1], (n, 3)), yaw],
                         axis=-1)
    return J + jnp.concatenate([base, jnp.zeros((n, 3, model.n_q - base.shape[-1]), dtype)], axis=-1)


def _project_with_jacobian(camera, points: Float[Array, "p 3"]) -> tuple[Float[Array, "p 2"], Float[Array, "p 2 3"]]:
    """Pixels of world points and d pixel / d p_world at each (forward-mode autodiff of the
    camera alone: three tangents per point, exact for any camera, its depth clamp included)."""
    def one(p):
        px = camera.project(p)[0]
        return px, px

    J, px = jax.vmap(jax.jacfwd(one, has_aux=True))(points)
    return px, J


def residuals_and_jacobian(q: Float[ArrayLike, " nq"], args: ResidualArgs) -> tuple[Float[Array, " r"],
                                                                                 Float[Array, "r nq"]]:
    """:func:`residuals` and their Jacobian dr/dq from the geometric Jacobian of the residual
    points (:func:`point_jacobian`) chained with each camera's pixel Jacobian.

    Equal to ``jax.jacfwd(residuals)`` up to rounding, and cheaper: the kinematics are evaluated
    once instead of carrying one tangent per q entry through every 4x4 product.
    """
    model = args.model
    pose = pose_at(model, q)
    K = args.fractions.shape[0]
    pts = link_points(pose, args.fractions)                                           # (links, K, 3)
    points = jnp.concatenate([pose.tips, pts.reshape(-1, 3)])
    link_frame = np.array(model.link_frame, dtype=int)
    attached = np.concatenate([link_frame[np.array(model.tip_links, dtype=int)], np.repeat(link_frame, K)])
    J_world = point_jacobian(model, q, pose.frames, points, attached)                 # (p, 3, nq)
    nt, nl = model.n_tips, model.n_links
    rs, Js = [], []
    for cam, f in zip(args.cameras, args.features):
        px, dpx = _project_with_jacobian(cam, points)
        rs.append(_stack_residuals(f, px[:nt], px[nt:].reshape(nl, K, 2)))
        tip_valid, _, sqrt_tip_w, lines, sqrt_line_w = masked_features(f, px.dtype)
        J_tip = jnp.where(tip_valid[..., None], dpx[:nt] @ J_world[:nt], 0.0) * sqrt_tip_w[:, None, None]
        # d(a x + b y - rho): the line normal times the pixel Jacobian, per link point
        normal_world = jnp.einsum("lc,lkcd->lkd", lines[:, :2], dpx[nt:].reshape(nl, K, 2, 3))
        J_link = (jnp.einsum("lkd,lkdq->lkq", normal_world, J_world[nt:].reshape(nl, K, 3, -1))
                  * sqrt_line_w[:, None, None])
        Js += [J_tip.reshape(2 * nt, -1), J_link.reshape(nl * K, -1)]
    for prior in args.priors:   # small functions of q alone: forward-mode autodiff is cheap
        rs.append(prior(q))
        Js.append(jax.jacfwd(prior)(q))
    return jnp.concatenate(rs), jnp.concatenate(Js)


def n_residuals(model: Model, n_cameras: int, n_fractions: int) -> int:
    """Length of the image residual vector (the priors of :class:`ResidualArgs` come after it)."""
    return n_cameras * (2 * model.n_tips + n_fractions * model.n_links)


def residual_labels(model: Model, n_cameras: int, link_fractions=DEFAULT_LINK_FRACTIONS) -> list[str]:
    """A readable name for every residual entry, in the order of :func:`residuals`
    (e.g. ``cam0/tip/index_dip/x``, ``cam1/link/index_pip@0.75``)."""
    out = []
    for c in range(n_cameras):
        out += [f"cam{c}/tip/{name}/{ax}" for name in model.tip_names for ax in "xy"]
        out += [f"cam{c}/link/{name}@{f:g}" for name in model.link_names for f in link_fractions]
    return out
