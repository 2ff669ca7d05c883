"""Step-limited Gauss-Newton (thesis §3.2.4): the Gauss-Newton step, shortened.

The thesis's RR example diverges from a distant start because a full Gauss-Newton correction
there is not *incremental*; it converges when the update becomes::

    q_{k+1} = q_k - eta_k (J_k^T J_k)^+ J_k^T r_k

Two ways to choose eta_k, combined:

- fixed: ``eta_k = config.eta`` (the thesis uses eta = 0.1; convergence then becomes linear,
  the error shrinking by about ``1 - eta`` per iteration: 97 iterations in Table 3.6);
- adaptive: ``eta_k = config.eta * min(1, cap_i / |dq_i|)`` over the entries of the full step
  ``dq``, with caps ``config.max_step_rad`` for angles (and quaternion entries) and
  ``config.max_step_mm`` for lengths. Far from the solution the correction is cut to the cap,
  keeping it incremental; near the solution the steps are below the caps and the iteration
  is plain Gauss-Newton again, with its quadratic convergence.

With the defaults (eta = 1, caps 0.3 rad and 20 mm) only the adaptive rule acts; the
thesis's fixed-eta run is ``FitConfig(eta=0.1, max_step_rad=inf, max_step_mm=inf)``.
Stopping rules as for Gauss-Newton (``jaxhand.solve._stopping``).

Optimistix parts: ``NewtonDescent`` (SVD) wrapped in a per-entry step cap, and
``LearningRate(eta)``.
"""

from __future__ import annotations

import jax.numpy as jnp
import lineax as lx
import numpy as np
import optimistix as optx

from ._config import FitConfig
from ._parts import GaussNewtonFamily, Retracted, StateSpace, StepCapped

__all__ = ["make_step_limited"]


def make_step_limited(config: FitConfig, space: StateSpace) -> GaussNewtonFamily:
    """Gauss-Newton with the step factor eta and the per-entry step caps of ``config``."""
    cap = jnp.where(np.array(space.is_length), config.max_step_mm, config.max_step_rad)
    descent = Retracted(StepCapped(optx.NewtonDescent(linear_solver=lx.SVD()), cap), space)
    return GaussNewtonFamily(descent, optx.LearningRate(config.eta))
