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

Optimistix parts: ``NewtonDescent`` (SVD linear solver) and ``LearningRate(1)``.
"""

from __future__ import annotations

import lineax as lx
import optimistix as optx

from ._config import FitConfig
from ._parts import GaussNewtonFamily, Retracted, StateSpace

__all__ = ["make_gauss_newton"]


def make_gauss_newton(config: FitConfig, space: StateSpace) -> GaussNewtonFamily:
    """The thesis's Gauss-Newton solver (eq. 3.4) for the state space ``space``."""
    del config
    descent = Retracted(optx.NewtonDescent(linear_solver=lx.SVD()), space)
    return GaussNewtonFamily(descent, optx.LearningRate(1.0))
