"""FitResult: what a fit returns (every field an array, batched by fit_batch)."""

from __future__ import annotations

import equinox as eqx
import numpy as np
from jaxtyping import Array, Bool, Float, Int

from ._status import Status, status_name

__all__ = ["FitResult"]


class FitResult(eqx.Module):
    """The outcome of :func:`~jaxhand.fit` (one problem) or :func:`~jaxhand.fit_batch` (every
    field gains the leading batch axis).

    Attributes:
        q: (nq,) the estimate; the starting state when ``status`` is diverged or nonfinite.
        cost: H(q) = 1/2 ||r(q)||^2, px^2.
        start_cost: H(q0), px^2.
        iterations: trial steps taken (evaluations of r and J after the one at q0).
        converged: a stopping rule fired (status ok or singular).
        status: a :class:`Status` (ok, max_steps, diverged, singular, nonfinite).
        rank: numerical rank of J at q (compare with ``model.dof``).
        history_q: (max_steps + 1, nq) q_k for k = 0.. (q_0 the start); rows past
            ``iterations`` repeat ``q``. Zero rows unless ``FitConfig(history=True)``.
        history_cost: (max_steps + 1,) H_k, likewise.
    """

    q: Float[Array, "*b nq"]
    cost: Float[Array, " *b"]
    start_cost: Float[Array, " *b"]
    iterations: Int[Array, " *b"]
    converged: Bool[Array, " *b"]
    status: Status
    rank: Int[Array, " *b"]
    history_q: Float[Array, "*b h nq"]
    history_cost: Float[Array, "*b h"]

    def status_name(self) -> str | np.ndarray:
        """The status as a name ('ok', ...), or an array of names for a batch."""
        return status_name(self.status)
