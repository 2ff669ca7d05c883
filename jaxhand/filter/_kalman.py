"""The discrete Kalman filter (thesis §5.1.1), with the Joseph-form covariance update.

Process ``x_k = A x_{k-1} + B u_k + w``, ``w ~ N(0, Q)``; measurement ``y_k = H x_k + v``,
``v ~ N(0, R)``. Prediction ``x = A x + B u``, ``P = A P A^T + Q``; update
``K = P H^T (H P H^T + R)^-1``, ``x = x + K (y - H x)``, and
``P = (I - K H) P (I - K H)^T + K R K^T`` (Joseph form: algebraically equal to the thesis's
``(I - K H) P`` but keeps P symmetric positive semi-definite under rounding).
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float

__all__ = ["KalmanState", "kalman_predict", "kalman_update"]


class KalmanState(eqx.Module):
    """State estimate x and its error covariance P (traced)."""

    x: Float[Array, " n"]
    P: Float[Array, "n n"]


def kalman_predict(state: KalmanState, A, Q, B=None, u=None) -> KalmanState:
    """Time update: the a-priori estimate and covariance."""
    x = A @ state.x
    if B is not None:
        x = x + B @ u
    P = A @ state.P @ A.T + Q
    return KalmanState(x=x, P=0.5 * (P + P.T))


def kalman_update(state: KalmanState, y, H, R, valid=True) -> KalmanState:
    """Measurement update; with valid=False the a-priori estimate is returned unchanged."""
    S = H @ state.P @ H.T + R
    K = jnp.linalg.solve(S, H @ state.P).T  # P H^T S^-1, with S and P symmetric
    x = state.x + K @ (y - H @ state.x)
    IKH = jnp.eye(state.x.shape[0], dtype=state.P.dtype) - K @ H
    P = IKH @ state.P @ IKH.T + K @ R @ K.T
    P = 0.5 * (P + P.T)
    return KalmanState(x=jnp.where(valid, x, state.x), P=jnp.where(valid, P, state.P))
