"""Whole-sequence landmark fits: every frame's pose and (optionally) one hand shape, as one
least-squares problem with a temporal smoothness residual.

Unknowns: ``Q`` (frames, n_q), one state per frame, and ``theta`` (p,), the shape of
:mod:`._shape` shared by every frame. Residuals, stacked:

- per frame t, the landmark residuals of :mod:`._residuals` with the shaped model at ``Q_t``;
- per pair of consecutive frames, ``w * (Q_{t+1} - Q_t)`` with ``w`` = ``smooth_px_per_rad`` for
  angles and quaternion entries and ``smooth_px_per_mm`` for lengths (a change of 1 rad between
  frames costs as much as a ``w``-pixel landmark error);
- a prior ``w_s (s - 1)`` on each scale and ``w_o o`` on each palm offset (mm), which keeps
  directions no landmark sees (and one camera's scale-depth ambiguity) determined.

Solver: Levenberg-Marquardt on the normal equations, whose matrix is block tridiagonal in ``Q``
(the smoothness couples neighbours only) with a dense border for ``theta``. Each step
eliminates ``Q`` by a block Thomas recursion (``lax.scan`` forward and back, one n x n Cholesky
per frame) and solves the p x p Schur complement for ``theta``, so a step costs O(frames n^3),
not O((frames n)^3). Trials are clipped into the joint limits and the shape bounds, quaternions
renormalised; a trial that lowers the total cost is taken (lambda / 3), otherwise lambda x 4.
Stops when an accepted step lowers the cost by at most ``ftol`` of it, or after ``max_steps``.
The per-frame Jacobians are ``jax.jacfwd`` in (q, theta) together.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._errors import InputError
from ..camera import as_rig
from ..model import Model
from ._convention import LandmarkMap, landmark_map
from ._residuals import LandmarkArgs, Landmarks, landmark_residuals
from ._shape import HandShape, apply_shape

__all__ = ["SequenceConfig", "SequenceResult", "fit_sequence"]


def _f(x):
    return jnp.asarray(x, dtype=float)


class SequenceConfig(eqx.Module):
    """Options of :func:`fit_sequence`.

    Attributes:
        max_steps: static. Most Levenberg-Marquardt trials.
        smooth_px_per_rad: traced. Weight of the change of an angle (or quaternion entry) between
            consecutive frames; 0 fits the frames independently (calibration over unrelated poses).
        smooth_px_per_mm: traced. The same for lengths (palm translation, prismatic joints).
        scale_prior_px: traced. Weight of ``scale - 1`` (px per unit of scale). The default keeps a
            one-camera fit of detector landmarks near the model's proportions (without it, the
            real video's fit drove phalanges to the 0.5 and 1.7 bounds); calibration with 3-D
            points uses 1 (:func:`~jaxhand.landmarks.calibrate_landmarks`).
        offset_prior_px_per_mm: traced. Weight of a palm offset (px per mm); calibration uses 0.1.
        scale_bounds: traced (2,). Scales are clipped into [lo, hi].
        offset_bound_mm: traced. Palm offsets are clipped into [-bound, bound] mm.
        ftol: traced, relative. Stop when an accepted step lowers the cost by <= ftol * cost.
        lambda0: traced. Initial relative damping.
    """

    max_steps: int = eqx.field(static=True, default=60)
    smooth_px_per_rad: Float[Array, ""] = eqx.field(converter=_f, default=20.0)
    smooth_px_per_mm: Float[Array, ""] = eqx.field(converter=_f, default=0.5)
    scale_prior_px: Float[Array, ""] = eqx.field(converter=_f, default=20.0)
    offset_prior_px_per_mm: Float[Array, ""] = eqx.field(converter=_f, default=1.0)
    scale_bounds: Float[Array, " 2"] = eqx.field(converter=_f, default=(0.5, 2.0))
    offset_bound_mm: Float[Array, ""] = eqx.field(converter=_f, default=30.0)
    ftol: Float[Array, ""] = eqx.field(converter=_f, default=1e-9)
    lambda0: Float[Array, ""] = eqx.field(converter=_f, default=1e-3)


class SequenceResult(eqx.Module):
    """Outcome of :func:`fit_sequence`.

    Attributes:
        q: (frames, n_q) states.
        theta: (p,) the shape (empty without one).
        cost: final total cost (px^2), ``start_cost`` the first.
        data_cost: (frames,) landmark cost per frame at the result (px^2).
        iterations: trials taken; converged: the cost rule fired.
    """

    q: Float[Array, "frames nq"]
    theta: Float[Array, " p"]
    cost: Float[Array, ""]
    start_cost: Float[Array, ""]
    data_cost: Float[Array, " frames"]
    iterations: Array
    converged: Array


def _block_tridiag_solve(D, e, R):
    """Solve the block tridiagonal SPD system with diagonal blocks ``D`` (T, n, n), off-diagonal
    blocks ``-diag(e)`` and right-hand sides ``R`` (T, n, k) by the block Thomas recursion."""
    E = -jnp.diag(e)

    def fwd(carry, x):
        L_prev, Y_prev = carry
        D_t, R_t = x
        # Schur update with the previous pivot block: D_t - E D'^-1 E, R_t - E D'^-1 Y'
        Dp = D_t - E @ jax.scipy.linalg.cho_solve((L_prev, True), E)
        Yp = R_t - E @ jax.scipy.linalg.cho_solve((L_prev, True), Y_prev)
        L = jnp.linalg.cholesky(Dp)
        return (L, Yp), (L, Yp)

    L0 = jnp.linalg.cholesky(D[0])
    _, (Ls, Ys) = jax.lax.scan(fwd, (L0, R[0]), (D[1:], R[1:]))
    Ls = jnp.concatenate([L0[None], Ls])
    Ys = jnp.concatenate([R[:1], Ys])

    def bwd(x_next, inp):
        L, Y = inp
        x = jax.scipy.linalg.cho_solve((L, True), Y - E @ x_next)
        return x, x

    xT = jax.scipy.linalg.cho_solve((Ls[-1], True), Ys[-1])
    _, xs = jax.lax.scan(bwd, xT, (Ls[:-1], Ys[:-1]), reverse=True)
    return jnp.concatenate([xs, xT[None]])


class _Problem(eqx.Module):
    model: Model
    cameras: tuple
    lmap: LandmarkMap
    shape: HandShape | None
    landmarks: Landmarks          # leading frame axis
    theta0: Array


def _unit_weights(model: Model, config: SequenceConfig, dtype):
    is_len = np.array([k == "length" for k in model.q_kinds])
    return jnp.where(is_len, config.smooth_px_per_mm, config.smooth_px_per_rad).astype(dtype)


def _prior_weights(shape: HandShape | None, config: SequenceConfig, dtype):
    if shape is None:
        return jnp.zeros((0,), dtype)
    return jnp.concatenate([jnp.full((shape.n_scales,), config.scale_prior_px, dtype),
                            jnp.full((len(shape.palm),), config.offset_prior_px_per_mm, dtype)])


def _frame_residuals(prob: _Problem, q, theta, lm):
    model = prob.model if prob.shape is None else apply_shape(prob.model, prob.shape, theta)
    return landmark_residuals(q, LandmarkArgs(model=model, cameras=prob.cameras, lmap=prob.lmap, landmarks=lm))


def _total_cost(prob, config, Q, theta):
    r = jax.vmap(lambda q, lm: _frame_residuals(prob, q, theta, lm))(Q, prob.landmarks)
    w = _unit_weights(prob.model, config, Q.dtype)
    smooth = w * (Q[1:] - Q[:-1])
    prior = _prior_weights(prob.shape, config, Q.dtype) * (theta - prob.theta0)
    data = 0.5 * jnp.sum(r * r, axis=-1)
    return jnp.sum(data) + 0.5 * jnp.sum(smooth * smooth) + 0.5 * jnp.sum(prior * prior), data


def _project(prob: _Problem, config: SequenceConfig, Q, theta):
    from ..solve import StateSpace

    space = StateSpace.of(prob.model)
    Q = jax.vmap(lambda q: space.normalize(space.clip(q)))(Q)
    if prob.shape is not None:
        n = prob.shape.n_scales
        theta = jnp.concatenate([jnp.clip(theta[:n], config.scale_bounds[0], config.scale_bounds[1]),
                                 jnp.clip(theta[n:], -config.offset_bound_mm, config.offset_bound_mm)])
    return Q, theta


@eqx.filter_jit
def _solve(prob: _Problem, Q0, config: SequenceConfig):
    T, n = Q0.shape
    p = prob.theta0.shape[0]
    dtype = Q0.dtype
    w = _unit_weights(prob.model, config, dtype)
    wp = _prior_weights(prob.shape, config, dtype)
    e = w * w
    count = jnp.concatenate([jnp.ones(1), jnp.full((T - 2,), 2.0), jnp.ones(1)]) if T > 1 else jnp.zeros(1)

    def linearise(Q, theta):
        def one(q, lm):
            def f(x):
                return _frame_residuals(prob, x[:n], x[n:], lm)
            x = jnp.concatenate([q, theta])
            J = jax.jacfwd(f)(x)
            return f(x), J
        r, J = jax.vmap(one)(Q, prob.landmarks)                     # (T, m), (T, m, n + p)
        Jq, Jt = J[..., :n], J[..., n:]
        D = jnp.einsum("tri,trj->tij", Jq, Jq) + (count[:, None] * e)[:, :, None] * jnp.eye(n, dtype=dtype)
        gq = jnp.einsum("tri,tr->ti", Jq, r)
        dQ = jnp.zeros_like(Q)
        if T > 1:
            dQ = jnp.concatenate([jnp.zeros((1, n), dtype), e * (Q[1:] - Q[:-1])]) - jnp.concatenate(
                [e * (Q[1:] - Q[:-1]), jnp.zeros((1, n), dtype)])
        gq = gq + dQ
        Bm = jnp.einsum("tri,trj->tij", Jq, Jt)
        C = jnp.einsum("tri,trj->ij", Jt, Jt) + jnp.diag(wp * wp)
        gt = jnp.einsum("tri,tr->i", Jt, r) + wp * wp * (theta - prob.theta0)
        return D, gq, Bm, C, gt

    def step(Q, theta, lin, lam):
        D, gq, Bm, C, gt = lin
        dD = jnp.diagonal(D, axis1=-2, axis2=-1)
        # Guard: a DOF no landmark sees has a zero diagonal; the floor keeps every block SPD.
        Dd = D + lam * jax.vmap(jnp.diag)(jnp.maximum(dD, 1e-9 * jnp.max(dD) + 1e-30))
        Rhs = jnp.concatenate([-gq[..., None], Bm], axis=-1)        # (T, n, 1 + p)
        X = _block_tridiag_solve(Dd, e, Rhs)
        xg, XB = X[..., 0], X[..., 1:]
        if p:
            dC = jnp.diagonal(C)
            S = C + lam * jnp.diag(jnp.maximum(dC, 1e-9 * jnp.max(dC) + 1e-30)) - jnp.einsum("tij,tik->jk", Bm, XB)
            rhs = -gt - jnp.einsum("tij,ti->j", Bm, xg)
            dth = jnp.linalg.solve(S, rhs)
            dQ = xg - jnp.einsum("tij,j->ti", XB, dth)
        else:
            dth = jnp.zeros((0,), dtype)
            dQ = xg
        return _project(prob, config, Q + dQ, theta + dth)

    Q, theta = _project(prob, config, Q0, prob.theta0)
    H0, _ = _total_cost(prob, config, Q, theta)

    def cond(c):
        k, _, _, _, _, _, running = c
        return running & (k < config.max_steps)

    def body(c):
        k, Q, theta, H, lin, lam, _ = c
        Qt, tt = step(Q, theta, lin, lam)
        Ht, _ = _total_cost(prob, config, Qt, tt)
        accept = jnp.isfinite(Ht) & (Ht < H)
        done = accept & (H - Ht <= config.ftol * H)
        Q2 = jnp.where(accept, Qt, Q)
        t2 = jnp.where(accept, tt, theta)
        lin2 = jax.lax.cond(accept, lambda: linearise(Qt, tt), lambda: lin)
        lam2 = jnp.where(accept, jnp.maximum(lam / 3.0, 1e-12), jnp.minimum(lam * 4.0, 1e12))
        return k + 1, Q2, t2, jnp.where(accept, Ht, H), lin2, lam2, ~done & (lam2 < 1e12)

    init = (jnp.array(0), Q, theta, H0, linearise(Q, theta), jnp.asarray(config.lambda0, dtype), jnp.array(True))
    k, Q, theta, H, _, _, running = jax.lax.while_loop(cond, body, init)
    _, data = _total_cost(prob, config, Q, theta)
    return SequenceResult(q=Q, theta=theta, cost=H, start_cost=H0, data_cost=data, iterations=k,
                          converged=~running)


def fit_sequence(model: Model, cameras, landmarks: Landmarks, q_init, *, shape: HandShape | None = None,
                 theta0=None, config: SequenceConfig | None = None, lmap: LandmarkMap | None = None
                 ) -> SequenceResult:
    """Fit a whole sequence of landmark frames as one problem (see the module docstring).

    Args:
        landmarks: :class:`Landmarks` with a leading frame axis (frames, cams, 21, 2).
        q_init: (frames, n_q) starting states (e.g. per-frame fits, each from the previous).
        shape: a :class:`~jaxhand.landmarks.HandShape` to estimate, shared by every frame; None
            keeps the model's shape.
        theta0: starting (and prior) shape; default the nominal (scales 1, offsets 0).
        config: a :class:`SequenceConfig`.
        lmap: where the landmarks sit on the model (default ``landmark_map(model)``: skin tips).

    Raises:
        InputError: shapes or non-finite starts.
    """
    config = SequenceConfig() if config is None else config
    if not isinstance(config, SequenceConfig):
        raise InputError(f"config: expected a SequenceConfig, got {type(config).__name__}")
    rig = as_rig(cameras)
    if landmarks.px.ndim != 4 or landmarks.px.shape[1] != len(rig):
        raise InputError(f"landmarks.px: expected shape (frames, {len(rig)}, 21, 2), got {landmarks.px.shape}")
    T = landmarks.px.shape[0]
    Q0 = np.asarray(q_init, float)
    if Q0.shape != (T, model.n_q) or not np.all(np.isfinite(Q0)):
        raise InputError(f"q_init: expected finite values of shape ({T}, {model.n_q}), got {Q0.shape}")
    if shape is None:
        th = np.zeros(0)
    else:
        th = shape.nominal() if theta0 is None else np.asarray(theta0, float)
        if th.shape != (shape.size,) or not np.all(np.isfinite(th)):
            raise InputError(f"theta0: expected {shape.size} finite values, got shape {th.shape}")
    dtype = jnp.asarray(0.0).dtype
    lm = jax.tree_util.tree_map(lambda x: jnp.asarray(x, dtype=bool if x.dtype == bool else dtype), landmarks)
    lmap = landmark_map(model) if lmap is None else lmap
    prob = _Problem(model=model, cameras=rig, lmap=lmap, shape=shape, landmarks=lm, theta0=jnp.asarray(th))
    return _solve(prob, jnp.asarray(Q0), config)
