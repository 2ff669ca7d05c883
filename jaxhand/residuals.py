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
from jaxtyping import Array, Float

from ._errors import InputError
from .camera import as_rig
from .features import Features, validate_features
from .kinematics import _pose, link_points
from .model import Model

__all__ = ["DEFAULT_LINK_FRACTIONS", "ResidualArgs", "make_residual_args", "residuals", "cost",
           "residual_jacobian", "residual_labels", "n_residuals"]

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
    """

    model: Model
    cameras: tuple
    features: tuple
    fractions: Float[Array, " K"]


def make_residual_args(model: Model, cameras, features, link_fractions=DEFAULT_LINK_FRACTIONS, *,
                       validate: bool = True) -> ResidualArgs:
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
    return ResidualArgs(model=model, cameras=rig, features=feats, fractions=jnp.asarray(fr))


def _camera_residuals(model: Model, camera, feats: Features, pose, fractions) -> Float[Array, " r"]:
    dtype = pose.link_start.dtype
    # Tips: replace masked observations by 0 before subtracting, so NaN there cannot leak
    # into the result or (through 0 * NaN) into its derivative.
    tips_px, _ = camera.project(pose.tips)                                        # (tips, 2)
    tip_valid = feats.tip_valid[:, None]
    tip_obs = jnp.where(tip_valid, feats.tips, 0.0).astype(dtype)
    tip_w = jnp.where(feats.tip_valid, feats.tip_weight, 0.0).astype(dtype)
    r_tip = jnp.where(tip_valid, tips_px - tip_obs, 0.0) * jnp.sqrt(tip_w)[:, None]
    # Links: a masked line becomes (0, 0, 0), whose residual is exactly 0 at every q.
    pts_px, _ = camera.project(link_points(pose, fractions))                      # (links, K, 2)
    lines = jnp.where(feats.line_valid[:, None], feats.lines, 0.0).astype(dtype)
    line_w = jnp.where(feats.line_valid, feats.line_weight, 0.0).astype(dtype)
    r_link = (jnp.sum(lines[:, None, :2] * pts_px, axis=-1) - lines[:, None, 2]) * jnp.sqrt(line_w)[:, None]
    return jnp.concatenate([r_tip.reshape(-1), r_link.reshape(-1)])


def residuals(q: Float[Array, " nq"], args: ResidualArgs) -> Float[Array, " r"]:
    """The stacked residual vector at state q (optimistix signature ``fn(y, args)``), pixels."""
    pose = _pose(args.model, q)
    return jnp.concatenate([_camera_residuals(args.model, cam, f, pose, args.fractions)
                            for cam, f in zip(args.cameras, args.features)])


def cost(q: Float[Array, " nq"], args: ResidualArgs) -> Float[Array, ""]:
    """H(q) = 1/2 ||r(q)||^2 (thesis eq. 3.3), px^2."""
    r = residuals(q, args)
    return 0.5 * jnp.sum(r * r)


@eqx.filter_jit
def residual_jacobian(q: Float[Array, " nq"], args: ResidualArgs) -> Float[Array, "r nq"]:
    """dr/dq by forward-mode autodiff (thesis eqs. 3.6-3.8), px per q unit (jitted)."""
    return jax.jacfwd(residuals)(q, args)


def n_residuals(model: Model, n_cameras: int, n_fractions: int) -> int:
    """Length of the residual vector."""
    return n_cameras * (2 * model.n_tips + n_fractions * model.n_links)


def residual_labels(model: Model, n_cameras: int, link_fractions=DEFAULT_LINK_FRACTIONS) -> list[str]:
    """A readable name for every residual entry, in the order of :func:`residuals`
    (e.g. ``cam0/tip/index_dip/x``, ``cam1/link/index_pip@0.75``)."""
    out = []
    for c in range(n_cameras):
        out += [f"cam{c}/tip/{name}/{ax}" for name in model.tip_names for ax in "xy"]
        out += [f"cam{c}/link/{name}@{f:g}" for name in model.link_names for f in link_fractions]
    return out
