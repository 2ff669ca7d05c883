"""The critically damped g-h-k filter (thesis §5.1.2, §5.2).

A constant-gain, three-state (position, velocity, acceleration) filter per q entry. With the
discount factor theta in [0, 1] the critically damped gains are (thesis §5.1.2)

    g = 1 - theta^3,   h = 1.5 (1 - theta^2)(1 - theta),   k = 0.5 (1 - theta)^3.

Prediction (eqs. 5.4-5.6), T the frame interval:

    x* = x + v T + a T^2 / 2,   v* = v + a T,   a* = a

Update with the measurement y (the pose estimate q_k, §5.2) and e = y - x* (eqs. 5.1-5.3):

    x = x* + g e,   v = v* + (h / T) e,   a = a* + (2 k / T^2) e.

theta -> 1 trusts history (heavy smoothing), theta = 0 takes the measurement as it is.

A tracker that reports the measurement itself (x = y) keeps no position error to correct the
velocity over later frames, so theta's h then forgets a change of motion only slowly;
:func:`ghk_follow` updates such a filter with its own velocity gain and no acceleration:

    x = y,   v = v* + (h_v / T) e,   a = 0.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Bool, Float

__all__ = ["GHKState", "ghk_gains", "ghk_init", "ghk_predict", "ghk_update", "ghk_follow"]


class GHKState(eqx.Module):
    """Position, velocity (per second) and acceleration (per second^2) of each q entry (traced)."""

    x: Float[Array, " n"]
    v: Float[Array, " n"]
    a: Float[Array, " n"]


def ghk_gains(theta) -> tuple[Array, Array, Array]:
    """(g, h, k) of the critically damped filter for discount factor theta (thesis §5.1.2)."""
    theta = jnp.asarray(theta)
    return 1.0 - theta**3, 1.5 * (1.0 - theta**2) * (1.0 - theta), 0.5 * (1.0 - theta) ** 3


def ghk_init(x0, v0=None, a0=None) -> GHKState:
    """Start at x0 with zero velocity and acceleration unless given."""
    x0 = jnp.asarray(x0)
    zero = jnp.zeros_like(x0)
    return GHKState(x=x0, v=zero if v0 is None else jnp.asarray(v0), a=zero if a0 is None else jnp.asarray(a0))


def ghk_predict(state: GHKState, dt_s) -> GHKState:
    """The prediction for the next frame (eqs. 5.4-5.6)."""
    return GHKState(x=state.x + state.v * dt_s + 0.5 * state.a * dt_s**2, v=state.v + state.a * dt_s, a=state.a)


def ghk_update(predicted: GHKState, y, theta, dt_s, valid: Bool[ArrayLike, " n"] | bool = True) -> GHKState:
    """Correct the prediction with measurement y (eqs. 5.1-5.3); entries with valid=False keep it."""
    g, h, k = ghk_gains(theta)
    e = jnp.where(valid, jnp.asarray(y) - predicted.x, 0.0)
    return GHKState(x=predicted.x + g * e, v=predicted.v + (h / dt_s) * e, a=predicted.a + (2.0 * k / dt_s**2) * e)


def ghk_follow(predicted: GHKState, y, velocity_gain, dt_s) -> GHKState:
    """The state at the measurement y itself, its velocity corrected by ``velocity_gain`` of the
    innovation over the frame and no acceleration (1: the last two measurements' straight line)."""
    y = jnp.asarray(y)
    return GHKState(x=y, v=predicted.v + velocity_gain * (y - predicted.x) / dt_s, a=jnp.zeros_like(predicted.a))
