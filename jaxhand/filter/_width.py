"""Phalanx width estimation (thesis appendix E).

The width of a phalanx is a constant, so only the position part of the g-h-k filter is used.
With N redundant width measures p^i of the same phalanx (one per profile), the prediction is the
last estimate and the update is

    p = (1 - g) p_pred + (g / N) sum_i p^i,

that is, the prediction corrected by g times the mean innovation. Invalid measures are left out
of the mean; a phalanx with none keeps its prediction.
"""

from __future__ import annotations

import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Bool, Float

__all__ = ["width_update"]


def width_update(p_pred: Float[ArrayLike, " links"], measures: Float[ArrayLike, "links n"],
                 valid: Bool[ArrayLike, "links n"], g) -> Float[Array, " links"]:
    """One appendix-E update of each link's width from its profiles' width measures."""
    count = jnp.sum(valid, axis=-1)
    total = jnp.sum(jnp.where(valid, measures, 0.0), axis=-1)
    mean = total / jnp.where(count > 0, count, 1).astype(total.dtype)  # guard: no valid measure -> keep the prediction
    return jnp.where(count > 0, (1.0 - g) * p_pred + g * mean, p_pred)
