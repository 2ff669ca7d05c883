"""Fitting landmarks: one frame with any of jaxhand's solvers, or a batch with a fixed-budget,
vmapped Levenberg-Marquardt built for throughput.

Why ``fit_batch`` of the general solvers is slow per problem (measured in
``benchmarks/landmarks.py``): ``jax.vmap`` of a ``lax.while_loop`` runs every lane until the
slowest has stopped (finished lanes are carried along by selects); optimistix's
Levenberg-Marquardt solves each step by QR of the whole (r x n) Jacobian, which on a CPU is a
loop of small LAPACK calls; the default Jacobian is ``jax.jacfwd`` (one tangent per q entry
through every 4x4 product); and each solve ends with an SVD for its rank test. The batch solver
here instead:

1. evaluates r and J together from the geometric Jacobian of the landmark points;
2. solves the damped normal equations ``(J^T J + lambda diag(J^T J)) dq = -J^T r`` by a batched
   Cholesky factorisation of an (n x n) matrix (n = 21 or 28: far cheaper than QR of J);
3. clips every trial into the joint limits (projected Levenberg-Marquardt) and renormalises the
   quaternion; a trial that lowers the cost is taken and lambda divided by ``lambda_down``,
   otherwise lambda is multiplied by ``lambda_up``;
4. stops a lane when its accepted step changed the cost by at most ``ftol * H + atol_px2`` or
   moved q by at most ``xtol`` (sum of |dq|), and the whole loop when every lane has stopped or
   after ``max_steps`` trials;
5. runs the batch in chunks of ``chunk`` problems (``lax.map`` over chunks of a vmapped loop), so
   a slow lane holds back only its own chunk;
6. skips the rank test (``rank`` reads the model's DOF) unless ``rank_test`` is set.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._errors import InputError
from ..camera import as_rig
from ..kinematics import validate_q
from ..model import Model
from ..solve import FitConfig, FitResult, StateSpace, Status, solve_least_squares
from ..solve.bounded_trust_region import make_bounded_trust_region
from ..solve.levenberg_marquardt import make_levenberg_marquardt
from ._convention import landmark_map
from ._residuals import (
    LandmarkArgs,
    Landmarks,
    landmark_residuals_and_jacobian,
    make_landmark_args,
    stacked_residuals,
    stacked_residuals_and_jacobian,
)

__all__ = ["BatchConfig", "fit_landmarks", "fit_landmarks_batch", "LANDMARK_SOLVERS", "batch_lm"]

#: Solvers of :func:`fit_landmarks`: optimistix's Levenberg-Marquardt (``lm``), the bounded trust
#: region (``bounded``) and the batch solver's projected Levenberg-Marquardt (``fast``).
LANDMARK_SOLVERS = ("lm", "bounded", "fast")


def _f(x):
    return jnp.asarray(x, dtype=float)


class BatchConfig(eqx.Module):
    """Options of the batch solver (:func:`fit_landmarks_batch`, and ``solver="fast"``).

    Attributes:
        max_steps: static. Most trial steps per problem.
        chunk: static. Problems per vmapped loop (a slow problem holds back its chunk only).
        rank_test: static. Compute the rank of J at the result (an eigen-decomposition per problem).
        ftol: traced, relative. Stop when an accepted step changes the cost by <= ftol * H + atol_px2.
        atol_px2: traced, px^2. Absolute part of that rule (noise-free data reach H ~ 0).
        xtol: traced, q units. Stop when the step moves q by at most xtol (sum of |dq|).
        lambda0: traced. Initial relative damping (times diag(J^T J)).
        lambda_up, lambda_down: traced. Damping factors after a rejected / accepted trial.
    """

    max_steps: int = eqx.field(static=True, default=40)
    chunk: int = eqx.field(static=True, default=256)
    rank_test: bool = eqx.field(static=True, default=False)
    ftol: Float[Array, ""] = eqx.field(converter=_f, default=1e-8)
    atol_px2: Float[Array, ""] = eqx.field(converter=_f, default=1e-12)
    xtol: Float[Array, ""] = eqx.field(converter=_f, default=1e-9)
    lambda0: Float[Array, ""] = eqx.field(converter=_f, default=1e-3)
    lambda_up: Float[Array, ""] = eqx.field(converter=_f, default=4.0)
    lambda_down: Float[Array, ""] = eqx.field(converter=_f, default=3.0)


def _check_batch_config(config: BatchConfig) -> BatchConfig:
    if not isinstance(config, BatchConfig):
        raise InputError(f"config: expected a BatchConfig, got {type(config).__name__}")
    if config.max_steps < 1 or config.chunk < 1:
        raise InputError(f"config: max_steps and chunk must be >= 1, got {config.max_steps}, {config.chunk}")
    for name in ("ftol", "atol_px2", "xtol", "lambda0"):
        v = float(getattr(config, name))
        if not np.isfinite(v) or v < 0:
            raise InputError(f"config.{name}: must be finite and >= 0, got {v}")
    if not float(config.lambda_up) > 1 or not float(config.lambda_down) > 1:
        raise InputError("config.lambda_up and config.lambda_down must be > 1")
    return config


class _LMState(eqx.Module):
    q: Array
    r: Array
    J: Array
    H: Array
    lam: Array
    running: Array
    k: Array


def _lm_step(fn, args, space: StateSpace, config: BatchConfig, s: _LMState) -> _LMState:
    """One projected Levenberg-Marquardt trial for one problem (frozen when not running)."""
    A = s.J.T @ s.J
    g = s.J.T @ s.r
    d = jnp.diagonal(A)
    # Guard: a column of J that is zero (a DOF no landmark sees) would leave M singular; the
    # floor, 1e-12 of the largest diagonal entry, keeps the Cholesky factor finite.
    d = jnp.maximum(d, 1e-12 * jnp.max(d) + jnp.finfo(d.dtype).tiny)
    M = A + s.lam * jnp.diag(d)
    L = jnp.linalg.cholesky(M)
    dq = -jax.scipy.linalg.cho_solve((L, True), g)
    dq = jnp.where(jnp.isfinite(dq), dq, 0.0)
    q_t = space.normalize(space.clip(s.q + dq))
    r_t, J_t = fn(q_t, args)
    H_t = 0.5 * jnp.sum(r_t * r_t)
    ok = jnp.isfinite(H_t) & jnp.all(jnp.isfinite(J_t))
    accept = ok & (H_t < s.H) & s.running
    moved = jnp.sum(jnp.abs(q_t - s.q))
    done = (accept & ((s.H - H_t <= config.ftol * s.H + config.atol_px2) | (moved <= config.xtol))) | (
        ~accept & (moved <= config.xtol)) | (s.H <= config.atol_px2)
    lam = jnp.where(accept, jnp.maximum(s.lam / config.lambda_down, 1e-12),
                    jnp.minimum(s.lam * config.lambda_up, 1e12))
    keep = lambda new, old: jnp.where(accept, new, old)  # noqa: E731
    return _LMState(q=keep(q_t, s.q), r=keep(r_t, s.r), J=keep(J_t, s.J), H=keep(H_t, s.H),
                    lam=jnp.where(s.running, lam, s.lam), running=s.running & ~done,
                    k=s.k + s.running.astype(s.k.dtype))


def _status(finite, converged, singular):
    return Status.where(~finite, Status.nonfinite,
                        Status.where(converged, Status.where(singular, Status.singular, Status.ok), Status.max_steps))


def batch_lm(fn, args, q0s: Float[Array, "B nq"], space: StateSpace, config: BatchConfig) -> FitResult:
    """The batch solver on problems ``args`` (pytree with leading axis B) from ``q0s``
    (traceable; computes in q0s's dtype). ``fn(q, args_one) -> (r, J)``."""
    config = jax.tree_util.tree_map(lambda x: x.astype(q0s.dtype), config)   # follow the input dtype
    # The stopping rules cannot fire below the dtype's rounding: in float32 an ftol of 1e-8, an
    # atol of 1e-12 px^2 and an xtol of 1e-9 never held and lanes ran to max_steps
    # (benchmarks/landmarks.py: 34 median iterations vs 16 in float64). Floors from the dtype's
    # eps (no effect in float64): ftol >= 100 eps, atol >= (1e4 eps)^2 px^2, xtol >= 1e3 eps.
    eps = jnp.finfo(q0s.dtype).eps
    config = eqx.tree_at(lambda c: (c.ftol, c.atol_px2, c.xtol), config,
                         (jnp.maximum(config.ftol, 100 * eps), jnp.maximum(config.atol_px2, (1e4 * eps) ** 2),
                          jnp.maximum(config.xtol, 1e3 * eps)))
    def solve_chunk(inputs):
        a, q0 = inputs
        q0 = jax.vmap(lambda q: space.normalize(space.clip(q)))(q0)
        r0, J0 = jax.vmap(fn)(q0, a)
        H0 = 0.5 * jnp.sum(r0 * r0, axis=-1)
        n = q0.shape[0]
        s = _LMState(q=q0, r=r0, J=J0, H=H0, lam=jnp.full((n,), config.lambda0, q0.dtype),
                     running=jnp.isfinite(H0), k=jnp.zeros((n,), jnp.int32))
        step = jax.vmap(lambda a1, st: _lm_step(fn, a1, space, config, st))

        def cond(c):
            k, st = c
            return (k < config.max_steps) & jnp.any(st.running)

        def body(c):
            k, st = c
            return k + 1, step(a, st)

        _, s = jax.lax.while_loop(cond, body, (jnp.array(0), s))
        finite = jnp.isfinite(s.H) & jnp.all(jnp.isfinite(s.q), -1)
        converged = ~s.running & finite
        if config.rank_test:
            ev = jnp.linalg.eigvalsh(jnp.einsum("bri,brj->bij", s.J, s.J))
            rank = jnp.sum(ev > 1e-18 * ev[:, -1:], axis=-1)   # eigenvalues of J^T J: squares of s_i
        else:
            rank = jnp.full((n,), space.dof, jnp.int32)
        status = jax.vmap(_status)(finite, converged, rank < space.dof)
        return FitResult(q=jnp.where(finite[:, None], s.q, q0), cost=jnp.where(finite, s.H, H0), start_cost=H0,
                         iterations=s.k, converged=converged, status=status, rank=rank.astype(jnp.int32),
                         history_q=jnp.zeros((n, 0, q0.shape[-1]), q0.dtype), history_cost=jnp.zeros((n, 0), q0.dtype))

    B = q0s.shape[0]
    size = min(config.chunk, B)
    n_chunks = -(-B // size)
    pad = n_chunks * size - B

    def chunked(x):
        x = jnp.concatenate([x, jnp.repeat(x[-1:], pad, axis=0)]) if pad else x
        return x.reshape((n_chunks, size) + x.shape[1:])

    out = jax.lax.map(solve_chunk, (jax.tree_util.tree_map(chunked, args), chunked(q0s)))
    return jax.tree_util.tree_map(lambda x: x.reshape((n_chunks * size,) + x.shape[2:])[:B], out)


@eqx.filter_jit
def _batch_jit(model, rig, lmap, landmarks, q0s, config):
    space = StateSpace.of(model)

    def fn(q, lm):
        return landmark_residuals_and_jacobian(q, LandmarkArgs(model=model, cameras=rig, lmap=lmap, landmarks=lm))

    return batch_lm(fn, landmarks, q0s, space, config)


def _as_float_landmarks(landmarks: Landmarks) -> Landmarks:
    dtype = jnp.asarray(0.0).dtype
    return jax.tree_util.tree_map(lambda x: jnp.asarray(x, dtype=bool if x.dtype == bool else dtype), landmarks)


def fit_landmarks_batch(model: Model, cameras, landmarks: Landmarks, q0, *,
                        config: BatchConfig | None = None) -> FitResult:
    """Fit B frames of landmarks at once (one compiled program per model structure, rig and
    chunk size): the batch solver of this module, vmapped over problems.

    Args:
        landmarks: :class:`Landmarks` whose arrays have a leading batch axis B.
        q0: (B, n_q) starts, or (n_q,) for the same start everywhere.
        config: a :class:`BatchConfig`.

    Returns:
        A :class:`~jaxhand.FitResult` with leading axis B (no history).

    Raises:
        InputError: shapes, non-finite starts, a camera count that differs from the rig's.
    """
    config = _check_batch_config(BatchConfig() if config is None else config)
    rig = as_rig(cameras)
    if landmarks.px.ndim != 4:
        raise InputError(f"landmarks.px: expected shape (B, cams, 21, 2) for a batch, got {landmarks.px.shape}")
    args = make_landmark_args(model, rig, landmarks)
    B = landmarks.px.shape[0]
    q = np.asarray(q0, float)
    if q.shape == (model.n_q,):
        q = np.broadcast_to(q, (B, model.n_q))
    if q.shape != (B, model.n_q) or not np.all(np.isfinite(q)):
        raise InputError(f"q0: expected finite values of shape ({B}, {model.n_q}) or ({model.n_q},), got {q.shape}")
    return _batch_jit(model, rig, args.lmap, _as_float_landmarks(landmarks), jnp.asarray(q), config)


@eqx.filter_jit
def _single_jit(args: LandmarkArgs, q0, solver: str, config: FitConfig):
    space = StateSpace.of(args.model)
    q0 = space.normalize(q0)
    build = make_bounded_trust_region if solver == "bounded" else make_levenberg_marquardt
    if solver == "bounded":
        q0 = space.interior(q0)
    jac = stacked_residuals_and_jacobian if config.jacobian == "geometric" else None
    return solve_least_squares(stacked_residuals, build(config, space), q0, args, space, config, jac=jac)


def fit_landmarks(model: Model, cameras, landmarks: Landmarks, q0, *, solver: str = "bounded",
                  config: FitConfig | BatchConfig | None = None, edges=None) -> FitResult:
    """Fit one frame's landmarks (and, with ``edges``, link and tip features in the same stack).

    Args:
        landmarks: one frame's :class:`Landmarks` (``make_landmarks``).
        q0: (n_q,) the start.
        solver: ``"bounded"`` (trust region inside the joint limits), ``"lm"`` (optimistix
            Levenberg-Marquardt, limits not enforced) or ``"fast"`` (the batch solver on one problem).
        config: a :class:`~jaxhand.FitConfig` (``lm``, ``bounded``; default with the geometric
            Jacobian) or a :class:`BatchConfig` (``fast``).
        edges: optional :class:`~jaxhand.residuals.ResidualArgs` of the same model and rig.

    Raises:
        InputError: unknown solver, shapes, a non-finite start.
    """
    if solver not in LANDMARK_SOLVERS:
        raise InputError(f"unknown landmark solver {solver!r}; valid: {', '.join(LANDMARK_SOLVERS)}")
    rig = as_rig(cameras)
    q0 = validate_q(model, q0, name="q0")
    if landmarks.px.ndim != 3:
        raise InputError(f"landmarks.px: expected shape (cams, 21, 2) for one frame, got {landmarks.px.shape}")
    if solver == "fast":
        if edges is not None:
            raise InputError("solver 'fast' fits landmarks only; use 'lm' or 'bounded' with edges")
        lm = jax.tree_util.tree_map(lambda x: x[None], landmarks)
        res = fit_landmarks_batch(model, rig, lm, q0[None], config=config)
        return jax.tree_util.tree_map(lambda x: x[0], res)
    config = FitConfig(jacobian="geometric") if config is None else config
    if not isinstance(config, FitConfig):
        raise InputError(f"config: solver {solver!r} takes a FitConfig, got {type(config).__name__}")
    args = make_landmark_args(model, rig, _as_float_landmarks(landmarks), lmap=landmark_map(model), edges=edges)
    return _single_jit(args, jnp.asarray(q0), solver, config)
