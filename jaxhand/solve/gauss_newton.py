"""Plain Gauss-Newton, the thesis's update (eq. 3.4).

Each iteration linearises the residuals at q_k and jumps to the minimum of the linear model::

    q_{k+1} = q_k - (J_k^T J_k)^-1 J_k^T r_k

Every step is taken (no line search, no damping), exactly as in the thesis; the free base's
quaternion is renormalised after each update. The thesis warns that J^T J must not be singular;
here the normal equations get a damping floor of 1e-10 times their largest diagonal entry
(see :mod:`._damped`), below the rounding error of J^T J's useful directions, so the step is
Gauss-Newton's to working precision, while a rank-deficient J (a link whose features are all
masked, a DOF the view cannot see) gives a finite step that leaves the undetermined directions
alone instead of inf or NaN.

Stopping rules (shared, see ``jaxhand.solve._stopping``): ``sum |q_{k+1} - q_k| <= xtol``,
``|H_k - H_{k+1}| <= ftol H_k``, or ``max_steps`` updates (``max_steps=1`` is the thesis's
fast mode of one update per frame).

Program: the damped family of :mod:`._damped` (shared with ``gn_eta`` and ``lm_fixed``).
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp

from ._config import FitConfig

__all__ = ["gauss_newton_config"]

def fixed(value: float):
    """A config number fixed by a solver, made when its program is configured (in the dtype then in
    force) and not weakly typed, like FitConfig fields, so it causes no recompile."""
    return jnp.asarray(value, dtype=float)


def gauss_newton_config(config: FitConfig) -> FitConfig:
    """``config`` with mu = 0, eta = 1 and no step caps: the damped family becomes eq. 3.4."""
    return eqx.tree_at(lambda c: (c.mu, c.eta, c.max_step_rad, c.max_step_mm), config,
                       (fixed(0.0), fixed(1.0), fixed(jnp.inf), fixed(jnp.inf)))
