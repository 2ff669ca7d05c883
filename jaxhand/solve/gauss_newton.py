"""Plain Gauss-Newton, the thesis's update (eq. 3.4).

Each iteration linearises the residuals at q_k and jumps to the minimum of the linear model::

    q_{k+1} = q_k - (J_k^T J_k)^+ J_k^T r_k

computed as the least-squares solution of ``J_k dq = -r_k`` by SVD, i.e. with the
pseudo-inverse: a rank-deficient J (a link whose features are all masked, a DOF the view
cannot see) gives the minimum-norm step, which leaves the undetermined directions alone
instead of producing inf or NaN. Every step is taken (no line search, no damping), exactly as
in the thesis; the free base's quaternion is renormalised after each update.

Stopping rules (shared, see ``jaxhand.solve._stopping``): ``sum |q_{k+1} - q_k| <= xtol``,
``|H_k - H_{k+1}| <= ftol H_k``, or ``max_steps`` updates (``max_steps=1`` is the thesis's
fast mode of one update per frame).

As the thesis notes (§3.2.4), eq. 3.4 is the step-limited update with eta = 1 and no cap, so
this solver *is* :mod:`.step_limited` with that configuration, and shares its compiled
program (optimistix parts: ``NewtonDescent`` with the SVD solver, ``LearningRate(1)``).
"""

from __future__ import annotations

import math

import equinox as eqx
import jax.numpy as jnp

from ._config import FitConfig

__all__ = ["gauss_newton_config"]


_ONE = jnp.asarray(1.0)
_INF = jnp.asarray(math.inf)


def gauss_newton_config(config: FitConfig) -> FitConfig:
    """``config`` with eta = 1 and no step caps: the step-limited solver becomes eq. 3.4."""
    return eqx.tree_at(lambda c: (c.eta, c.max_step_rad, c.max_step_mm), config, (_ONE, _INF, _INF))
