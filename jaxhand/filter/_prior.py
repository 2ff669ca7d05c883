"""An information-weighted temporal prior (thesis ch. 7; issue 13 item 5).

The thesis's g-h-k filter blends the solve and the prediction with one fixed gain for every
joint. Chapter 7 proposes a compromise weighted by how well each joint is seen. Here the solve
reports, with its estimate ``z`` (the raw q), its information ``Lambda = J^T J / sigma^2``: the
Gauss-Newton Hessian of the image residuals (J in px per rad or mm, sigma the feature noise in
px). A Kalman filter over a constant-velocity state then weighs the two per direction in q
space: a joint whose features pin it down (large information) follows the solve, a joint with
no features (zero rows in Lambda) keeps the prediction, and everything in between is mixed by the
ratio of prediction covariance to measurement covariance. With exact features and sigma small
the estimate tends to the raw solve, so the filter adds no lag where the image decides.

State ``x = [q; q_dot]`` (``2n``), per entry a constant-velocity model with white-noise
acceleration of spectral density ``a^2`` (units^2 / s^3):

    F = [[I, T I], [0, I]],   Q = a^2 [[T^3/3, T^2/2], [T^2/2, T]]        (predict: x = F x, P = F P F^T + Q)

Measurement ``z = H x + v``, ``H = [I 0]``, with information ``Lambda = R^-1`` (possibly singular,
so R is never formed). With ``S0 = H P H^T`` and ``M = I + Lambda S0`` (invertible for PSD Lambda and P):

    K = P H^T (S0 + Lambda^-1)^-1 = P H^T M^-1 Lambda = G Lambda,   G = P H^T M^-1
    x = x + K (z - H x)
    P = (I - K H) P (I - K H)^T + G Lambda G^T                            (Joseph form; K R K^T = G Lambda G^T)

Residual form (to stack the prediction into the solve instead): with ``C`` the Cholesky factor
of the predicted position covariance ``P_qq = C C^T``, the residuals ``r = C^-1 (q - q_pred)`` have
``|r|^2 = (q - q_pred)^T P_qq^-1 (q - q_pred)``. After such a MAP solve, :func:`prior_update_map`
gives the same posterior as :func:`prior_update` from the MAP estimate alone: the measurement sees
only q, so the velocity follows by conditioning, ``v = v_pred + P_vq P_qq^-1 (q_map - q_pred)``.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import jax.scipy.linalg as jsl
from jaxtyping import Array, ArrayLike, Bool, Float

__all__ = ["PriorState", "prior_init", "prior_predict", "prior_update", "prior_update_map", "prior_residuals",
           "prior_information", "solve_information"]


class PriorState(eqx.Module):
    """Constant-velocity state ``x = [q; q_dot]`` and its covariance ``P`` (traced).

    Units follow q: rad (or mm) and rad/s (mm/s); P in their squares.
    """

    x: Float[Array, " s"]
    P: Float[Array, "s s"]

    def __check_init__(self):
        s = self.x.shape[-1]
        if s % 2 or self.P.shape[-2:] != (s, s):
            raise ValueError(f"PriorState: x needs an even length 2n and P shape (2n, 2n), got {self.x.shape}, "
                             f"{self.P.shape}")

    @property
    def n(self) -> int:
        """Entries of q (static)."""
        return self.x.shape[-1] // 2

    @property
    def q(self) -> Float[Array, " n"]:
        """The position part (the estimate or prediction of q)."""
        return self.x[: self.n]

    @property
    def P_qq(self) -> Float[Array, "n n"]:
        """The position block of P."""
        return self.P[: self.n, : self.n]


def _sym(P):
    return 0.5 * (P + jnp.swapaxes(P, -1, -2))


def prior_init(q0: Float[ArrayLike, " n"], sigma_q, sigma_v, v0: Float[ArrayLike, " n"] | None = None) -> PriorState:
    """A state at ``q0`` (velocity ``v0``, default 0) with diagonal covariance.

    Args:
        q0: initial q (rad / mm).
        sigma_q: standard deviation of q0 (scalar or per entry, rad / mm).
        sigma_v: standard deviation of the velocity (scalar or per entry, rad/s / mm/s).
        v0: initial velocity (default zero).
    """
    q0 = jnp.asarray(q0)
    n = q0.shape[0]
    v0 = jnp.zeros_like(q0) if v0 is None else jnp.asarray(v0, q0.dtype)
    var = jnp.concatenate([jnp.broadcast_to(jnp.asarray(sigma_q, q0.dtype) ** 2, (n,)),
                           jnp.broadcast_to(jnp.asarray(sigma_v, q0.dtype) ** 2, (n,))])
    return PriorState(x=jnp.concatenate([q0, v0]), P=jnp.diag(var))


def prior_predict(state: PriorState, dt_s, accel_sigma) -> PriorState:
    """The constant-velocity prediction ``x = F x``, ``P = F P F^T + Q`` for a frame interval.

    Args:
        state: the last estimate.
        dt_s: frame interval T (s).
        accel_sigma: ``a``, the square root of the white-noise acceleration's spectral density
            (scalar or per entry; rad / s^1.5): over one frame q drifts by about ``a sqrt(T^3 / 3)``.
    """
    n = state.n
    dtype = state.x.dtype
    T = jnp.asarray(dt_s, dtype)
    a2 = jnp.broadcast_to(jnp.asarray(accel_sigma, dtype) ** 2, (n,))
    q, v = state.x[:n], state.x[n:]
    x = jnp.concatenate([q + T * v, v])
    eye = jnp.eye(n, dtype=dtype)
    F = jnp.block([[eye, T * eye], [jnp.zeros_like(eye), eye]])
    Q = jnp.block([[jnp.diag(a2 * T**3 / 3), jnp.diag(a2 * T**2 / 2)],
                   [jnp.diag(a2 * T**2 / 2), jnp.diag(a2 * T)]])
    return PriorState(x=x, P=_sym(F @ state.P @ F.T + Q))


def _masked(information, valid, n, dtype):
    lam = _sym(jnp.asarray(information, dtype))
    valid = jnp.broadcast_to(jnp.asarray(valid), (n,))
    return jnp.where(valid[:, None] & valid[None, :], lam, 0.0)


def _gain(state: PriorState, lam):
    """G = P H^T M^-1 with M = I + Lambda S0, and K = G Lambda (see the module docstring)."""
    n = state.n
    PHt = state.P[:, :n]
    M = jnp.eye(n, dtype=lam.dtype) + lam @ state.P_qq
    G = jnp.linalg.solve(M.T, PHt.T).T
    return G, G @ lam


def _joseph(state: PriorState, G, K, lam):
    n = state.n
    s = 2 * n
    IKH = jnp.eye(s, dtype=lam.dtype).at[:, :n].add(-K)
    return _sym(IKH @ state.P @ IKH.T + G @ lam @ G.T)


def prior_update(state: PriorState, z: Float[ArrayLike, " n"], information: Float[ArrayLike, "n n"],
                 valid: Bool[ArrayLike, " n"] | bool = True) -> PriorState:
    """Correct the prediction with the solve's estimate ``z`` and its information.

    Args:
        state: the prediction (:func:`prior_predict`).
        z: the raw solve's q.
        information: ``J^T J / sigma^2`` of the solve at z (:func:`solve_information`; units 1/rad^2);
            it may be singular (joints without features).
        valid: per entry (or for all): False drops that entry's rows and columns of the
            information, so it keeps the prediction; False everywhere returns the prediction.

    Returns:
        The posterior, with P updated in Joseph form (symmetric PSD under rounding).
    """
    n = state.n
    lam = _masked(information, valid, n, state.x.dtype)
    G, K = _gain(state, lam)
    x = state.x + K @ (jnp.asarray(z, state.x.dtype) - state.q)
    return PriorState(x=x, P=_joseph(state, G, K, lam))


def prior_update_map(state: PriorState, q_map: Float[ArrayLike, " n"], information: Float[ArrayLike, "n n"],
                     valid: Bool[ArrayLike, " n"] | bool = True, *, jitter=1e-12) -> PriorState:
    """The posterior after a solve that already included :func:`prior_residuals`.

    The MAP solve returns the posterior q; the velocity follows by conditioning on it
    (``v = v_pred + P_vq P_qq^-1 (q_map - q_pred)``) and P is the same as in :func:`prior_update`.

    Args:
        state: the prediction the prior residuals were built from.
        q_map: the solve's estimate with the prior stacked in.
        information: the image residuals' ``J^T J / sigma^2`` at q_map (prior rows excluded).
        valid: as in :func:`prior_update`.
        jitter: added to P_qq's diagonal (rad^2) before conditioning, as in :func:`prior_residuals`.
    """
    n = state.n
    lam = _masked(information, valid, n, state.x.dtype)
    G, K = _gain(state, lam)
    dq = jnp.asarray(q_map, state.x.dtype) - state.q
    chol = jnp.linalg.cholesky(state.P_qq + jitter * jnp.eye(n, dtype=state.x.dtype))
    dv = state.P[n:, :n] @ jsl.cho_solve((chol, True), dq)
    return PriorState(x=state.x + jnp.concatenate([dq, dv]), P=_joseph(state, G, K, lam))


def prior_residuals(q: Float[ArrayLike, " n"], state: PriorState, *, jitter=1e-12) -> Float[Array, " n"]:
    """Prior residuals ``C^-1 (q - q_pred)`` with ``C C^T = P_qq + jitter I`` (unitless).

    Stacked under the image residuals (weighted as ``1/sigma``), a least-squares solve then
    minimises the negative log-posterior; ``|r|^2`` is the Mahalanobis distance to the prediction.

    Args:
        q: the solve's variable (rad / mm).
        state: the prediction (:func:`prior_predict`).
        jitter: added to the diagonal of P_qq (rad^2) so the factor exists when an entry has
            zero variance (no process noise); it caps that entry's weight at ``1/sqrt(jitter)``.
    """
    n = state.n
    P = state.P_qq + jitter * jnp.eye(n, dtype=state.x.dtype)
    C = jnp.linalg.cholesky(P)
    return jsl.solve_triangular(C, q - state.q, lower=True)


def prior_information(state: PriorState, *, jitter=1e-12) -> Float[Array, "n n"]:
    """``(P_qq + jitter I)^-1``: the prediction's information on q (the Hessian of |prior_residuals|^2 / 2)."""
    n = state.n
    eye = jnp.eye(n, dtype=state.x.dtype)
    C = jnp.linalg.cholesky(state.P_qq + jitter * eye)
    return _sym(jsl.cho_solve((C, True), eye))


def solve_information(J: Float[ArrayLike, "r n"], sigma_px) -> Float[Array, "n n"]:
    """``J^T J / sigma^2``: the Gauss-Newton information of a solve's (weighted) residuals.

    Args:
        J: Jacobian of the residuals (px per unit of q) at the solution; masked rows are zero.
        sigma_px: feature noise (px), scalar.
    """
    return _sym(J.T @ J) / jnp.asarray(sigma_px, J.dtype) ** 2
