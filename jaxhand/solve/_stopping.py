"""Stopping rules shared by every solver (thesis §3.2): step norm, cost stagnation, iteration cap,
plus the guards that turn divergence and non-finite numbers into a status.

Each rule is a pure function of one iteration's numbers, so the driver reads as a list of
rules and each rule can be tested on its own.
"""

from __future__ import annotations

import jax.numpy as jnp
from jaxtyping import Array, Bool, Float

__all__ = ["step_norm", "small_step", "stagnant_cost", "cost_blew_up"]


def step_norm(dq: Float[Array, " nq"]) -> Float[Array, ""]:
    """``sum |dq|``: the thesis's step measure (§3.2.3), in q units (rad, mm)."""
    return jnp.sum(jnp.abs(dq))


def small_step(accepted: Bool[Array, ""], dq_taken: Float[Array, " nq"], dq_next: Float[Array, " nq"],
               xtol: Float[Array, ""]) -> Bool[Array, ""]:
    """Step rule: the update just applied, or the next one proposed, has ``sum |dq| <= xtol``.

    The proposed step counts too: at an exact solution Gauss-Newton proposes a zero step, and a
    trust-region method that can no longer reduce the cost shrinks its steps towards zero.
    """
    return (accepted & (step_norm(dq_taken) <= xtol)) | (step_norm(dq_next) <= xtol)


def stagnant_cost(accepted: Bool[Array, ""], H_prev: Float[Array, ""], H_new: Float[Array, ""],
                  ftol: Float[Array, ""]) -> Bool[Array, ""]:
    """Cost rule: an update changed H by at most ``ftol * H`` (H = 0 stays 0: stagnant)."""
    return accepted & (jnp.abs(H_prev - H_new) <= ftol * H_prev)


def cost_blew_up(H: Float[Array, ""], H0: Float[Array, ""], factor: Float[Array, ""]) -> Bool[Array, ""]:
    """Divergence guard: the cost exceeds ``factor`` times its start value (or a tiny floor)."""
    return H > factor * jnp.maximum(H0, jnp.finfo(H0.dtype).tiny)
