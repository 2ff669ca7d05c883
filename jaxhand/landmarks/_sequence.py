"""Whole-sequence landmark fits: every frame's pose and (optionally) one hand shape, as one
least-squares problem with a temporal smoothness residual.

Unknowns: ``Q`` (frames, n_q), one state per frame, and ``theta`` (p,), the shape of
:mod:`._shape` shared by every frame. Residuals, stacked:

- per frame t, the landmark residuals of :mod:`._residuals` with the shaped model at ``Q_t``;
- per pair of consecutive frames, ``w * (Q_{t+1} - Q_t)`` with ``w`` = ``smooth_px_per_rad`` for
  angles and quaternion entries and ``smooth_px_per_mm`` for lengths (a change of 1 rad between
  frames costs as much as a ``w``-pixel landmark error);
- per triple of consecutive frames, ``a * (Q_{t+1} - 2 Q_t + Q_{t-1})`` with ``a`` =
  ``accel_px_per_rad`` / ``accel_px_per_mm`` (off by default): a penalty on acceleration, which
  unlike the first difference does not pull a steady motion towards standing still;
- per frame and finger, the DIP-PIP coupling ``c (q_dip - rho q_pip)`` of
  :func:`jaxhand.priors.dip_pip_coupling` with ``c`` = ``dip_pip_px_per_rad`` (off by default): a
  finger's distal joint follows its middle one, which leaves one camera fewer mirror branches and
  the short distal link's noise less room; with ``dip_pip_ratio_prior_px`` > 0 each finger's
  ratio ``rho`` is an unknown shared by every frame (appended to ``theta``), pulled towards
  ``dip_pip_ratio`` by ``dip_pip_ratio_prior_px (rho - dip_pip_ratio)``: the hand's own coupling
  is measured from the sequence rather than assumed;
- a prior ``w_s (s - 1)`` on each scale and ``w_o o`` on each palm offset (mm), which keeps
  directions no landmark sees (and one camera's scale-depth ambiguity) determined.

Solver: Levenberg-Marquardt on the normal equations, whose matrix is block banded in ``Q`` (the
smoothness couples frames at most two apart) with a dense border for ``theta``. Grouping the
frames in pairs makes the band block tridiagonal with 2n x 2n blocks; each step eliminates ``Q``
by a block Thomas recursion (``lax.scan`` forward and back, one 2n x 2n Cholesky per pair of
frames) and solves the p x p Schur complement for ``theta``, so a step costs O(frames n^3), not
O((frames n)^3). Trials are clipped into the joint limits and the shape bounds, quaternions
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
from ..priors import DIP_PIP_RATIO, DipPipCoupling, dip_pip_coupling
from ..solve import StateSpace
from ._convention import LandmarkMap, landmark_map
from ._residuals import LandmarkArgs, Landmarks, landmark_residuals
from ._shape import HandShape, apply_shape

__all__ = ["SequenceConfig", "SequenceResult", "fit_sequence", "sequence_coupling", "rest_weights"]


def _f(x):
    return jnp.asarray(x, dtype=float)


class SequenceConfig(eqx.Module):
    """Options of :func:`fit_sequence`.

    Attributes:
        max_steps: static. Most Levenberg-Marquardt trials.
        smooth_px_per_rad: traced. Weight of the change of an angle (or quaternion entry) between
            consecutive frames; 0 fits the frames independently (calibration over unrelated poses).
        smooth_px_per_mm: traced. The same for lengths (palm translation, prismatic joints).
        accel_px_per_rad: traced. Weight of an angle's second difference over three consecutive
            frames (px per rad); 0: off.
        accel_px_per_mm: traced. The same for lengths (px per mm).
        scale_prior_px: traced. Weight of ``scale - 1`` (px per unit of scale). The default keeps a
            one-camera fit of detector landmarks near the model's proportions (without it, the
            real video's fit drove phalanges to the 0.5 and 1.7 bounds); calibration with 3-D
            points uses 1 (:func:`~jaxhand.landmarks.calibrate_landmarks`).
        offset_prior_px_per_mm: traced. Weight of a palm offset (px per mm); calibration uses 0.1.
        dip_pip_px_per_rad: traced. Weight of every finger's ``q_dip - dip_pip_ratio * q_pip`` per
            frame (px per rad); 0: off.
        dip_pip_ratio: traced. DIP flexion over PIP flexion in that term (with the next field: the
            ratios' start and prior).
        dip_pip_ratio_prior_px: traced. > 0: every finger's ratio is estimated, with this weight
            (px per unit of ratio) on its distance to ``dip_pip_ratio``; 0: the ratio is fixed.
            Static in effect: whether it is 0 decides the unknowns (read on the host).
        branch_rest_px_per_rad: read on the host. Weight (px per rad) of every joint angle's
            distance to the model's default (rest) state per frame in the choice of branch only
            (the paths of :func:`~jaxhand.landmarks.smoothest_paths` and the per-finger pick of
            :func:`~jaxhand.landmarks.block_costs`), not in this solve: of one camera's mirror
            branches that fit the points alike it picks the one nearer rest, without biasing
            the angles the landmarks do see; 0: off.
        scale_bounds: traced (2,). Scales are clipped into [lo, hi].
        offset_bound_mm: traced. Palm offsets are clipped into [-bound, bound] mm.
        ftol: traced, relative. Stop when an accepted step lowers the cost by <= ftol * cost.
        lambda0: traced. Initial relative damping.
    """

    max_steps: int = eqx.field(static=True, default=60)
    smooth_px_per_rad: Float[Array, ""] = eqx.field(converter=_f, default=20.0)
    smooth_px_per_mm: Float[Array, ""] = eqx.field(converter=_f, default=0.5)
    accel_px_per_rad: Float[Array, ""] = eqx.field(converter=_f, default=0.0)
    accel_px_per_mm: Float[Array, ""] = eqx.field(converter=_f, default=0.0)
    scale_prior_px: Float[Array, ""] = eqx.field(converter=_f, default=20.0)
    offset_prior_px_per_mm: Float[Array, ""] = eqx.field(converter=_f, default=1.0)
    dip_pip_px_per_rad: Float[Array, ""] = eqx.field(converter=_f, default=0.0)
    dip_pip_ratio: Float[Array, ""] = eqx.field(converter=_f, default=DIP_PIP_RATIO)
    dip_pip_ratio_prior_px: Float[Array, ""] = eqx.field(converter=_f, default=0.0)
    branch_rest_px_per_rad: Float[Array, ""] = eqx.field(converter=_f, default=0.0)
    scale_bounds: Float[Array, " 2"] = eqx.field(converter=_f, default=(0.5, 2.0))
    offset_bound_mm: Float[Array, ""] = eqx.field(converter=_f, default=30.0)
    ftol: Float[Array, ""] = eqx.field(converter=_f, default=1e-9)
    lambda0: Float[Array, ""] = eqx.field(converter=_f, default=1e-3)


class SequenceResult(eqx.Module):
    """Outcome of :func:`fit_sequence`.

    Attributes:
        q: (frames, n_q) states.
        theta: (p,) the shape (empty without one).
        dip_pip_ratio: (fingers,) the DIP-PIP ratios used (estimated or as configured).
        cost: final total cost (px^2), ``start_cost`` the first.
        data_cost: (frames,) landmark and DIP-PIP cost per frame at the result (px^2).
        iterations: trials taken; converged: the cost rule fired.
    """

    q: Float[Array, "frames nq"]
    theta: Float[Array, " p"]
    dip_pip_ratio: Float[Array, " fingers"]
    cost: Float[Array, ""]
    start_cost: Float[Array, ""]
    data_cost: Float[Array, " frames"]
    iterations: Array
    converged: Array


def _block_tridiag_solve(D, L, R):
    """Solve the block tridiagonal SPD system with diagonal blocks ``D`` (M, b, b), blocks ``L``
    (M - 1, b, b) below the diagonal (block (m + 1, m)) and right-hand sides ``R`` (M, b, k) by
    the block Thomas recursion."""
    def fwd(carry, x):
        L_prev, Y_prev = carry
        D_m, R_m, L_m = x
        # Schur update with the previous pivot block: D_m - L S'^-1 L^T, R_m - L S'^-1 Y'
        Dp = D_m - L_m @ jax.scipy.linalg.cho_solve((L_prev, True), L_m.T)
        Yp = R_m - L_m @ jax.scipy.linalg.cho_solve((L_prev, True), Y_prev)
        C = jnp.linalg.cholesky(Dp)
        return (C, Yp), (C, Yp)

    C0 = jnp.linalg.cholesky(D[0])
    _, (Cs, Ys) = jax.lax.scan(fwd, (C0, R[0]), (D[1:], R[1:], L))
    Cs = jnp.concatenate([C0[None], Cs])
    Ys = jnp.concatenate([R[:1], Ys])

    def bwd(x_next, inp):
        C, Y, L_m = inp
        x = jax.scipy.linalg.cho_solve((C, True), Y - L_m.T @ x_next)
        return x, x

    xM = jax.scipy.linalg.cho_solve((Cs[-1], True), Ys[-1])
    _, xs = jax.lax.scan(bwd, xM, (Cs[:-1], Ys[:-1], L), reverse=True)
    return jnp.concatenate([xs, xM[None]])


def _temporal_bands(T: int) -> tuple[tuple[np.ndarray, ...], tuple[np.ndarray, ...]]:
    """The bands of the first- and second-difference Gram matrices D1^T D1 and D2^T D2 over T
    frames (static): (v0 (T,), v1 (T,)) and (a0 (T,), a1 (T,), a2 (T,)), entry t of band k
    being element (t, t + k) (0 past the end)."""
    v0, v1 = np.zeros(T), np.zeros(T)
    a0, a1, a2 = np.zeros(T), np.zeros(T), np.zeros(T)
    for r in range(T - 1):          # rows (-1, 1) at frames r, r + 1
        v0[r] += 1
        v0[r + 1] += 1
        v1[r] -= 1
    for r in range(T - 2):          # rows (1, -2, 1) at frames r, r + 1, r + 2
        a0[r:r + 3] += (1, 4, 1)
        a1[r:r + 2] -= 2
        a2[r] += 1
    return (v0, v1), (a0, a1, a2)


def _pairs(T: int) -> int:
    return (T + 1) // 2


def _pair_blocks(D, e, a):
    """The normal matrix's Q part grouped in pairs of frames: (M, 2n, 2n) diagonal and (M - 1,
    2n, 2n) sub-diagonal blocks, from the data blocks ``D`` (T, n, n) and the smoothness weights
    ``e``, ``a`` (n,) (squared). An odd T gets a padding frame with an identity block."""
    T, n = D.shape[0], D.shape[1]
    M = _pairs(T)
    (v0, v1), (a0, a1, a2) = _temporal_bands(T)
    pad = 2 * M - T
    eye = jnp.eye(n, dtype=D.dtype)
    D = jnp.concatenate([D, jnp.broadcast_to(eye, (pad, n, n))]) if pad else D
    v0, v1, a0, a1, a2 = (np.concatenate([x, np.zeros(pad)])[:, None] for x in (v0, v1, a0, a1, a2))
    band0, band1, band2 = v0 * e + a0 * a, v1 * e + a1 * a, a2 * a      # (2M, n) each
    D = D + jax.vmap(jnp.diag)(band0)
    diag = jax.vmap(jnp.diag)
    z = jnp.zeros((M, n, n), D.dtype)
    top = jnp.concatenate([D[0::2], diag(band1[0::2])], axis=-1)
    bottom = jnp.concatenate([diag(band1[0::2]), D[1::2]], axis=-1)
    Dm = jnp.concatenate([top, bottom], axis=-2)
    # block (m + 1, m): frames (2m + 2, 2m + 3) x (2m, 2m + 1)
    lo = jnp.concatenate([jnp.concatenate([diag(band2[0::2]), diag(band1[1::2])], axis=-1),
                          jnp.concatenate([z, diag(band2[1::2])], axis=-1)], axis=-2)[:-1]
    return Dm, lo


def _smooth_gradient(Q, e, a):
    """d/dQ of 0.5 |sqrt(e) D1 Q|^2 + 0.5 |sqrt(a) D2 Q|^2."""
    T, n = Q.shape
    g = jnp.zeros_like(Q)
    if T > 1:
        d1 = e * (Q[1:] - Q[:-1])
        g = g + jnp.concatenate([-d1, jnp.zeros((1, n), Q.dtype)]) + jnp.concatenate([jnp.zeros((1, n), Q.dtype), d1])
    if T > 2:
        d2 = a * (Q[2:] - 2 * Q[1:-1] + Q[:-2])
        z1, z2 = jnp.zeros((1, n), Q.dtype), jnp.zeros((2, n), Q.dtype)
        g = g + jnp.concatenate([d2, z2]) - 2 * jnp.concatenate([z1, d2, z1]) + jnp.concatenate([z2, d2])
    return g


class _Problem(eqx.Module):
    model: Model
    cameras: tuple
    lmap: LandmarkMap
    shape: HandShape | None
    landmarks: Landmarks          # leading frame axis
    theta0: Array
    coupling: DipPipCoupling      # weights in px per rad
    n_ratios: int = eqx.field(static=True)     # estimated ratios at the end of theta (0: none)


def sequence_coupling(model: Model, config: SequenceConfig) -> DipPipCoupling:
    """The DIP-PIP term of ``config`` on ``model`` (residuals in px; no finger: none)."""
    c = dip_pip_coupling(model, weight=1.0, ratio=float(config.dip_pip_ratio))
    return eqx.tree_at(lambda t: t.weight, c, c.weight * config.dip_pip_px_per_rad)


def _unit_weights(model: Model, config: SequenceConfig, dtype):
    is_len = np.array([k == "length" for k in model.q_kinds])
    return jnp.where(is_len, config.smooth_px_per_mm, config.smooth_px_per_rad).astype(dtype)


def _accel_weights(model: Model, config: SequenceConfig, dtype):
    is_len = np.array([k == "length" for k in model.q_kinds])
    return jnp.where(is_len, config.accel_px_per_mm, config.accel_px_per_rad).astype(dtype)


def rest_weights(model: Model, config: SequenceConfig) -> np.ndarray:
    """(n_q,) weights of the branch choice's rest prior: ``branch_rest_px_per_rad`` on the joint
    angles, 0 on the base."""
    joint = np.asarray(model.is_angle) & (np.arange(model.n_q) >= model.n_base_q)
    return np.where(joint, float(config.branch_rest_px_per_rad), 0.0)


def _prior_weights(prob: _Problem, config: SequenceConfig, dtype):
    ratios = jnp.full((prob.n_ratios,), config.dip_pip_ratio_prior_px, dtype)
    if prob.shape is None:
        return ratios
    return jnp.concatenate([jnp.full((prob.shape.n_scales,), config.scale_prior_px, dtype),
                            jnp.full((len(prob.shape.palm),), config.offset_prior_px_per_mm, dtype), ratios])


def _ratios(prob: _Problem, theta):
    return theta[theta.shape[0] - prob.n_ratios:] if prob.n_ratios else prob.coupling.ratio


def _frame_residuals(prob: _Problem, q, theta, lm):
    model = prob.model if prob.shape is None else apply_shape(prob.model, prob.shape, theta)
    r = landmark_residuals(q, LandmarkArgs(model=model, cameras=prob.cameras, lmap=prob.lmap, landmarks=lm))
    coupling = eqx.tree_at(lambda c: c.ratio, prob.coupling, _ratios(prob, theta))
    return jnp.concatenate([r, coupling(q)])


def _total_cost(prob, config, Q, theta):
    r = jax.vmap(lambda q, lm: _frame_residuals(prob, q, theta, lm))(Q, prob.landmarks)
    w = _unit_weights(prob.model, config, Q.dtype)
    smooth = w * (Q[1:] - Q[:-1])
    accel = _accel_weights(prob.model, config, Q.dtype) * (Q[2:] - 2 * Q[1:-1] + Q[:-2])
    prior = _prior_weights(prob, config, Q.dtype) * (theta - prob.theta0)
    data = 0.5 * jnp.sum(r * r, axis=-1)
    return (jnp.sum(data) + 0.5 * jnp.sum(smooth * smooth) + 0.5 * jnp.sum(accel * accel)
            + 0.5 * jnp.sum(prior * prior)), data


def _project(prob: _Problem, config: SequenceConfig, Q, theta):

    space = StateSpace.of(prob.model)
    Q = jax.vmap(lambda q: space.normalize(space.clip(q)))(Q)
    if prob.shape is not None:
        n = prob.shape.n_scales
        k = prob.shape.size
        theta = jnp.concatenate([jnp.clip(theta[:n], config.scale_bounds[0], config.scale_bounds[1]),
                                 jnp.clip(theta[n:k], -config.offset_bound_mm, config.offset_bound_mm), theta[k:]])
    if prob.n_ratios:          # a ratio stays within [0, 1.5]: a distal joint flexing with the middle one
        theta = jnp.concatenate([theta[:-prob.n_ratios], jnp.clip(theta[-prob.n_ratios:], 0.0, 1.5)])
    return Q, theta


@eqx.filter_jit
def _solve(prob: _Problem, Q0, config: SequenceConfig):
    T, n = Q0.shape
    p = prob.theta0.shape[0]
    dtype = Q0.dtype
    w = _unit_weights(prob.model, config, dtype)
    wp = _prior_weights(prob, config, dtype)
    e = w * w
    wa = _accel_weights(prob.model, config, dtype)
    a = wa * wa

    def linearise(Q, theta):
        def one(q, lm):
            def f(x):
                return _frame_residuals(prob, x[:n], x[n:], lm)
            x = jnp.concatenate([q, theta])
            J = jax.jacfwd(f)(x)
            return f(x), J
        r, J = jax.vmap(one)(Q, prob.landmarks)                     # (T, m), (T, m, n + p)
        Jq, Jt = J[..., :n], J[..., n:]
        D, lo = _pair_blocks(jnp.einsum("tri,trj->tij", Jq, Jq), e, a)
        gq = jnp.einsum("tri,tr->ti", Jq, r) + _smooth_gradient(Q, e, a)
        Bm = jnp.einsum("tri,trj->tij", Jq, Jt)
        C = jnp.einsum("tri,trj->ij", Jt, Jt) + jnp.diag(wp * wp)
        gt = jnp.einsum("tri,tr->i", Jt, r) + wp * wp * (theta - prob.theta0)
        return D, lo, gq, Bm, C, gt

    M = _pairs(T)

    def paired(X):          # (T, n, k) -> (M, 2n, k), an odd T padded with a zero frame
        X = jnp.concatenate([X, jnp.zeros((2 * M - T,) + X.shape[1:], X.dtype)])
        return X.reshape(M, 2 * n, X.shape[-1])

    space = StateSpace.of(prob.model)
    bounded = jnp.asarray(space.bounded)

    def step(Q, theta, lin, lam):
        D, lo, gq, Bm, C, gt = lin
        dD = jnp.diagonal(D, axis1=-2, axis2=-1)
        # Guard: a DOF no landmark sees has a zero diagonal; the floor keeps every block SPD.
        Dd = D + lam * jax.vmap(jnp.diag)(jnp.maximum(dD, 1e-9 * jnp.max(dD) + 1e-30))
        # Active set: an entry at a limit whose descent direction points outside is held this
        # step (its rows and columns become the identity, its right-hand side 0). Without it the
        # clipped step of such an entry is rejected again and again (the fist's thumb at its
        # limits stalled the solve at its step cap; benchmarks/landmarks_devset.py).
        tol = 1e-9 * jnp.maximum(1.0, jnp.abs(space.lower))
        held = bounded & (((Q <= space.lower + tol) & (gq > 0)) | ((Q >= space.upper - tol) & (gq < 0)))
        free = (~held).astype(dtype)                                # (T, n)
        fp = paired(free[..., None])[..., 0]                        # (M, 2n); padding: held
        Dd = Dd * fp[:, :, None] * fp[:, None, :] + jax.vmap(jnp.diag)(1 - fp)
        lo = lo * fp[1:, :, None] * fp[:-1, None, :]
        Bm = Bm * free[..., None]
        Rhs = jnp.concatenate([-gq[..., None], Bm], axis=-1) * free[..., None]     # (T, n, 1 + p)
        X = _block_tridiag_solve(Dd, lo, paired(Rhs)).reshape(2 * M, n, -1)[:T]
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
    return SequenceResult(q=Q, theta=theta[:theta.shape[0] - prob.n_ratios], dip_pip_ratio=_ratios(prob, theta),
                          cost=H, start_cost=H0, data_cost=data, iterations=k,
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
    coupling = sequence_coupling(model, config)
    n_ratios = len(coupling.fingers) if float(config.dip_pip_ratio_prior_px) > 0 else 0
    th = np.concatenate([th, np.full(n_ratios, float(config.dip_pip_ratio))])
    prob = _Problem(model=model, cameras=rig, lmap=lmap, shape=shape, landmarks=lm, theta0=jnp.asarray(th),
                    coupling=coupling, n_ratios=n_ratios)
    return _solve(prob, jnp.asarray(Q0), config)
