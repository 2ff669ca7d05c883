"""One frame's 2-D landmarks as extra residuals of the tracker's solve (``--fuse-landmarks``).

A :class:`LandmarkTerm` holds the frame's numbers only (pixels and square-root weights of the
21 points in the rig's first camera: traced, so every frame reuses one compiled program); the
tracker's frame program binds it to its model and rig (:meth:`LandmarkTerm.bind`), which gives a
pose prior in the sense of :mod:`jaxhand.priors`, ``prior(q) -> residuals``: the 2-D residuals
of :func:`~jaxhand.landmarks.landmark_residuals`, ``sqrt(w_i) (pi(p_i(q)) - x_i)`` px, stacked
under the image residuals. A missing point has weight 0 (exact zeros).
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from .._errors import InputError
from ..model import Model
from ..priors import AbstractTerm
from ._convention import POINT_NAMES, landmark_map
from ._residuals import LandmarkArgs, Landmarks, landmark_residuals

__all__ = ["LandmarkTerm", "LandmarkPrior", "landmark_term"]

N_POINTS = len(POINT_NAMES)


class LandmarkPrior(eqx.Module):
    """The 2-D landmark residuals of one camera as a prior: ``prior(q) -> (42,)`` px."""

    args: LandmarkArgs

    def __call__(self, q: Float[ArrayLike, " nq"]) -> Float[Array, " r"]:
        return landmark_residuals(jnp.asarray(q), self.args)[: 2 * N_POINTS]


class LandmarkTerm(AbstractTerm):
    """One frame's landmarks in the rig's first camera, unbound (arrays only).

    Attributes:
        px: (21, 2) pixels (0 where missing).
        sqrt_weight: (21,) square roots of the weights (0 where missing).
    """

    px: Float[Array, "21 2"]
    sqrt_weight: Float[Array, " 21"]

    def bind(self, model: Model, rig: tuple) -> LandmarkPrior:
        """The prior of these landmarks on ``model`` seen by ``rig[0]`` (traceable)."""
        dtype = self.px.dtype
        lm = Landmarks(px=self.px[None], px_valid=jnp.ones((1, N_POINTS), bool), px_weight=self.sqrt_weight[None] ** 2,
                       mm=jnp.zeros((N_POINTS, 3), dtype), mm_valid=jnp.zeros((N_POINTS,), bool),
                       mm_weight=jnp.zeros((N_POINTS,), dtype))
        return LandmarkPrior(LandmarkArgs(model=model, cameras=(rig[0],), lmap=landmark_map(model), landmarks=lm))


def landmark_term(px, weight) -> LandmarkTerm:
    """A :class:`LandmarkTerm` from (21, 2) pixels (NaN where missing) and (21,) weights >= 0.

    Raises:
        InputError: wrong shapes or negative / non-finite weights.
    """
    px = np.asarray(px, float)
    w = np.broadcast_to(np.asarray(weight, float), (N_POINTS,))
    if px.shape != (N_POINTS, 2):
        raise InputError(f"landmark term: expected ({N_POINTS}, 2) pixels, got shape {px.shape}")
    if not np.all(np.isfinite(w)) or np.any(w < 0):
        raise InputError("landmark term: weights must be finite and >= 0")
    ok = np.all(np.isfinite(px), -1) & (w > 0)
    dtype = jnp.asarray(0.0).dtype
    return LandmarkTerm(px=jnp.asarray(np.where(ok[:, None], px, 0.0), dtype),
                        sqrt_weight=jnp.asarray(np.sqrt(np.where(ok, w, 0.0)), dtype))
