"""The damped, step-limited Gauss-Newton family shared by ``gn``, ``gn_eta`` and ``lm_fixed``::

    dq_k = -(J_k^T J_k + lambda_k I)^-1 J_k^T r_k,  lambda_k = max(mu, 1e-10 max_i (J_k^T J_k)_ii)
    q_{k+1} = retract(q_k + eta_k dq_k),  eta_k = eta * min(1, min_i cap_i / |dq_i|)

Every step is taken. The three solvers are this update with different numbers (all traced, so
they share one compiled program per model):

- ``gn`` (thesis eq. 3.4): mu = 0, eta = 1, no cap;
- ``gn_eta`` (thesis §3.2.4): mu = 0, eta and caps from the config;
- ``lm_fixed`` (DigitEyes eq. 5, ``S = mu I``): mu from the config, eta = 1, no cap.

The relative floor on lambda is the numerical safeguard the thesis asks for ("make sure that
J^T J is not singular"): it caps the condition number of the solved system at 1e10, so a
rank-deficient J (a link whose features are all masked, a DOF the view cannot see) gives a
finite step that leaves the undetermined directions (nearly) alone, like a pseudo-inverse that
ignores singular values below 1e-5 of the largest. It is below the rounding error of J^T J's
useful directions, so the step is otherwise Gauss-Newton's; it never moves a fixed point
(dq = 0 exactly where J^T r = 0).

Optimistix parts: :class:`RidgeNewtonDescent` (an ``optimistix.AbstractDescent``; Cholesky of
the n x n system) with ``LearningRate(1)``, wrapped in :class:`~._parts.StepLimited` and
:class:`~._parts.Retracted` (which hands it J as a matrix, built once per accepted point).
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import jax.scipy.linalg as jsl
import numpy as np
import optimistix as optx
from jaxtyping import Array, Float, Scalar

from ._config import FitConfig
from ._parts import GaussNewtonFamily, Retracted, StateSpace, StepLimited

__all__ = ["RELATIVE_FLOOR", "RidgeNewtonDescent", "make_damped_gauss_newton"]

#: Floor of the damping relative to the largest diagonal entry of J^T J.
RELATIVE_FLOOR = 1e-10


class _RidgeState(eqx.Module):
    J: Float[Array, "m n"]
    r: Float[Array, " m"]


class RidgeNewtonDescent(optx.AbstractDescent):
    """``dq = -(J^T J + lambda I)^-1 J^T r`` with ``lambda = max(mu, RELATIVE_FLOOR max diag J^T J)``.

    Attributes:
        mu: traced, px^2 per q unit^2. The constant damping (0 for Gauss-Newton).
    """

    mu: Float[Array, ""]

    def init(self, y, f_info_struct) -> _RidgeState:
        m = f_info_struct.residual.shape[0]
        return _RidgeState(J=jnp.zeros((m, y.shape[0]), y.dtype), r=jnp.zeros(m, y.dtype))

    def query(self, y, f_info, state: _RidgeState) -> _RidgeState:
        del y, state
        return _RidgeState(J=f_info.jac.as_matrix(), r=f_info.residual)

    def step(self, step_size: Scalar, state: _RidgeState):
        del step_size   # every step is taken in full; eta and caps act in StepLimited
        A = state.J.T @ state.J
        # Guard: the floor keeps A + lambda I positive definite even for J = 0 (all masked).
        lam = jnp.maximum(self.mu, RELATIVE_FLOOR * jnp.max(jnp.diagonal(A))) + jnp.finfo(A.dtype).tiny
        dq = -jsl.cho_solve(jsl.cho_factor(A + lam * jnp.eye(A.shape[0], dtype=A.dtype)), state.J.T @ state.r)
        return dq, optx.RESULTS.successful


def make_damped_gauss_newton(config: FitConfig, space: StateSpace) -> GaussNewtonFamily:
    """The update above with ``mu = config.mu``, ``eta = config.eta`` and the config's caps."""
    cap = jnp.where(np.array(space.is_length), config.max_step_mm, config.max_step_rad)
    descent = Retracted(StepLimited(RidgeNewtonDescent(config.mu), config.eta, cap), space)
    return GaussNewtonFamily(descent, optx.LearningRate(1.0))
