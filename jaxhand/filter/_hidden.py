"""Damping the extrapolation of joints a frame does not observe (issue 13, "no drift with time").

The g-h-k filter corrects a joint's velocity and acceleration only through its innovation. A
joint the frame's features do not constrain (a finger hidden behind another) gets none: the
solve leaves it where the prediction put it, so the velocity and acceleration it had when it was
last seen are integrated frame after frame, until the joint reaches a limit. Here each entry's
share of being seen comes from the solve's image information, and the velocity and acceleration
of an unseen entry decay instead of carrying it on.

With the image information ``Lambda = J^T J`` (px^2 per unit of q squared) of the frame's
features at the solve, the marginal information of entry j (what the frame says about q_j with
every other entry free) is

    m_j = 1 / [(Lambda + eps I)^-1]_jj,

its share of being seen ``s_j = min(1, m_j / m0_j)`` against ``m0_j``, the same for every feature
slot of the model valid with weight 1 (what the frame would say if nothing were hidden; unitless,
so a joint the view sees poorly by nature, foreshortened or abducting, still counts as seen), and
after the update each entry keeps

    v_j <- k_j v_j,   a_j <- k_j a_j,   k_j = s_j + (1 - s_j) exp(-T / tau)

of its velocity and acceleration: a seen entry keeps them, a hidden one loses them with the time
constant ``tau`` (so the extrapolation of a hidden joint stops after about ``v tau``, at any
frame rate).
"""

from __future__ import annotations

import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Float

from ._ghk import GHKState

__all__ = ["marginal_information", "seen_share", "damp_unseen"]


def marginal_information(information: Float[ArrayLike, "*k n n"], eps) -> Float[Array, "*k n"]:
    """``1 / [(Lambda + eps I)^-1]_jj`` per entry: the information on q_j with the other entries
    free (0 for an entry without features, up to ``eps``). ``eps`` > 0, in the units of Lambda.
    A stack of matrices takes one eigen-decomposition call (see
    :func:`jaxhand.priors.information_weight` for why that matters under ``vmap``)."""
    lam = jnp.asarray(information)
    lam = 0.5 * (lam + jnp.swapaxes(lam, -1, -2))
    eig, vec = jnp.linalg.eigh(lam)
    # rounding may leave eig slightly < 0
    variance = jnp.sum(vec**2 / (jnp.maximum(eig, 0.0) + eps)[..., None, :], axis=-1)
    return 1.0 / variance


def seen_share(information: Float[ArrayLike, "n n"], reference: Float[ArrayLike, "n n"]) -> Float[Array, " n"]:
    """``min(1, m_j / m0_j)`` in [0, 1]: the :func:`marginal_information` of ``information`` over
    that of ``reference`` (the information with nothing hidden); 1 for an entry the reference
    does not see either (nothing is hidden from it)."""
    ref = jnp.asarray(reference)
    n = ref.shape[-1]
    eps = 1e-9 * (jnp.trace(ref) / n) + jnp.finfo(ref.dtype).tiny   # the scale of the reference's information
    m, m0 = marginal_information(jnp.stack([jnp.asarray(information, ref.dtype), ref]), eps)
    # Guard: an entry the reference does not see has m0 ~ eps; the denominator stays finite
    seen = jnp.where(m0 > 1e3 * eps, m / jnp.where(m0 > 1e3 * eps, m0, 1.0), 1.0)
    return jnp.clip(seen, 0.0, 1.0)


def damp_unseen(state: GHKState, seen: Float[ArrayLike, " n"], keep_unseen) -> GHKState:
    """The filter state with each entry's velocity and acceleration scaled by
    ``seen + (1 - seen) keep_unseen`` (``keep_unseen = exp(-T / tau)``, the share an unseen entry
    keeps per frame); the position is unchanged."""
    seen = jnp.asarray(seen)
    keep = seen + (1.0 - seen) * keep_unseen
    return GHKState(x=state.x, v=keep * state.v, a=keep * state.a)
