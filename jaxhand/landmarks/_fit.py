"""Fitting landmarks: one frame with any of jaxhand's solvers, or a batch with the batched
bounded Levenberg-Marquardt of :mod:`jaxhand.solve.internal` (lanes last, normal equations by an
unrolled Cholesky, an active set at the joint limits, chunks; its module docstring says why),
on the lanes-last landmark residuals (:func:`lane_residuals_and_jacobian`).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._errors import InputError
from ..camera import as_rig
from ..kinematics import validate_q
from ..model import Model
from ..priors import DipPipCoupling
from ..solve import FitConfig, FitResult, StateSpace, solve_least_squares
from ..solve.bounded_trust_region import make_bounded_trust_region
from ..solve.internal import BatchConfig, SparsePattern, batch_lm, check_batch_config, solve_batched
from ..solve.levenberg_marquardt import make_levenberg_marquardt
from ._convention import LandmarkMap
from ._residuals import (
    LandmarkArgs,
    Landmarks,
    lane_jacobian_pattern,
    lane_residuals_and_jacobian,
    make_landmark_args,
    stacked_residuals,
    stacked_residuals_and_jacobian,
)

__all__ = ["BatchConfig", "fit_landmarks", "fit_landmarks_batch", "LANDMARK_SOLVERS", "batch_lm"]

#: Solvers of :func:`fit_landmarks`: optimistix's Levenberg-Marquardt (``lm``), the bounded trust
#: region (``bounded``) and the batch solver's projected Levenberg-Marquardt (``fast``).
LANDMARK_SOLVERS = ("lm", "bounded", "fast")


class _LaneResiduals(eqx.Module):
    """The lanes-last landmark residuals of one model and rig, as a pytree callable (so that the
    batch solver's compiled programs are cached across calls)."""

    model: Model
    cameras: tuple
    lmap: LandmarkMap
    use_3d: bool = eqx.field(static=True)
    coupling: DipPipCoupling | None = None

    def __call__(self, q, landmarks):
        args = LandmarkArgs(model=self.model, cameras=self.cameras, lmap=self.lmap, landmarks=landmarks)
        r, J = lane_residuals_and_jacobian(q, args, use_3d=self.use_3d)
        if self.coupling is None:
            return r, J
        # one row per finger, w (q_dip - rho q_pip): its two nonzeros in column order
        c = self.coupling
        pip, dip = np.array(c.pip_index), np.array(c.dip_index)
        rc = c.weight[:, None] * (q[dip] - c.ratio[:, None] * q[pip])
        d_pip = jnp.broadcast_to((-c.weight * c.ratio)[:, None], rc.shape)
        d_dip = jnp.broadcast_to(c.weight[:, None], rc.shape)
        first = (pip < dip)[:, None]
        Jc = jnp.stack([jnp.where(first, d_pip, d_dip), jnp.where(first, d_dip, d_pip)], axis=1)
        Jc = Jc.reshape(-1, q.shape[-1]).astype(J.dtype)
        return jnp.concatenate([r, rc.astype(r.dtype)]), jnp.concatenate([J, Jc])

    def pattern(self):
        base = lane_jacobian_pattern(self.model, self.lmap, len(self.cameras), use_3d=self.use_3d)
        if self.coupling is None:
            return base
        jac = np.zeros((base.m + len(self.coupling.fingers), base.n), bool)
        jac[base.rows, base.cols] = True
        jac[base.m + np.arange(len(self.coupling.fingers)), self.coupling.pip_index] = True
        jac[base.m + np.arange(len(self.coupling.fingers)), self.coupling.dip_index] = True
        return SparsePattern(jac)


def _as_float_landmarks(landmarks: Landmarks) -> Landmarks:
    dtype = jnp.asarray(0.0).dtype
    return jax.tree_util.tree_map(lambda x: jnp.asarray(x, dtype=bool if x.dtype == bool else dtype), landmarks)


def fit_landmarks_batch(model: Model, cameras, landmarks: Landmarks, q0, *,
                        config: BatchConfig | None = None, lmap: LandmarkMap | None = None,
                        coupling: DipPipCoupling | None = None) -> FitResult:
    """Fit B frames of landmarks at once (one compiled program per model structure, rig and
    chunk size): the batch solver of this module, vmapped over problems.

    Args:
        landmarks: :class:`Landmarks` whose arrays have a leading batch axis B.
        q0: (B, n_q) starts, or (n_q,) for the same start everywhere.
        config: a :class:`BatchConfig`.
        lmap: where the landmarks sit on the model (default ``landmark_map(model)``: skin tips).
        coupling: optional :class:`~jaxhand.priors.DipPipCoupling` whose residuals (in px: its
            weight in px per rad) join every problem's landmark residuals.

    Returns:
        A :class:`~jaxhand.FitResult` with leading axis B (no history).

    Raises:
        InputError: shapes, non-finite starts, a camera count that differs from the rig's.
    """
    config = check_batch_config(config)
    rig = as_rig(cameras)
    if landmarks.px.ndim != 4:
        raise InputError(f"landmarks.px: expected shape (B, cams, 21, 2) for a batch, got {landmarks.px.shape}")
    args = make_landmark_args(model, rig, landmarks, lmap=lmap)
    B = landmarks.px.shape[0]
    q = np.asarray(q0, float)
    if q.shape == (model.n_q,):
        q = np.broadcast_to(q, (B, model.n_q))
    if q.shape != (B, model.n_q) or not np.all(np.isfinite(q)):
        raise InputError(f"q0: expected finite values of shape ({B}, {model.n_q}) or ({model.n_q},), got {q.shape}")
    use_3d = bool(np.any(np.asarray(landmarks.mm_valid) & (np.asarray(landmarks.mm_weight) > 0)))
    fn = _LaneResiduals(model=model, cameras=rig, lmap=args.lmap, use_3d=use_3d, coupling=coupling)
    return solve_batched(fn, _as_float_landmarks(landmarks), jnp.asarray(q), StateSpace.of(model), config,
                         fn.pattern())


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
                  config: FitConfig | BatchConfig | None = None, edges=None,
                  lmap: LandmarkMap | None = None) -> FitResult:
    """Fit one frame's landmarks (and, with ``edges``, link and tip features in the same stack).

    Args:
        landmarks: one frame's :class:`Landmarks` (``make_landmarks``).
        q0: (n_q,) the start.
        solver: ``"bounded"`` (trust region inside the joint limits), ``"lm"`` (optimistix
            Levenberg-Marquardt, limits not enforced) or ``"fast"`` (the batch solver on one problem).
        config: a :class:`~jaxhand.FitConfig` (``lm``, ``bounded``; default with the geometric
            Jacobian) or a :class:`BatchConfig` (``fast``).
        edges: optional :class:`~jaxhand.residuals.ResidualArgs` of the same model and rig.
        lmap: where the landmarks sit on the model (default ``landmark_map(model)``: skin tips).

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
        res = fit_landmarks_batch(model, rig, lm, q0[None], config=config, lmap=lmap)
        return jax.tree_util.tree_map(lambda x: x[0], res)
    config = FitConfig(jacobian="geometric") if config is None else config
    if not isinstance(config, FitConfig):
        raise InputError(f"config: solver {solver!r} takes a FitConfig, got {type(config).__name__}")
    args = make_landmark_args(model, rig, _as_float_landmarks(landmarks), lmap=lmap, edges=edges)
    return _single_jit(args, jnp.asarray(q0), solver, config)
