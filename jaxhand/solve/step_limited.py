"""Step-limited Gauss-Newton (thesis §3.2.4): the Gauss-Newton step, shortened.

The thesis's RR example diverges from a distant start because a full Gauss-Newton correction
there is not *incremental*; it converges when the update becomes::

    q_{k+1} = q_k - eta_k (J_k^T J_k)^-1 J_k^T r_k

Two ways to choose eta_k, combined:

- fixed: ``eta_k = config.eta`` (the thesis uses eta = 0.1; convergence then becomes linear,
  the error shrinking by about ``1 - eta`` per iteration: 97 iterations in Table 3.6);
- adaptive: ``eta_k = config.eta * min(1, cap_i / |dq_i|)`` over the entries of the full step
  ``dq``, with caps ``config.max_step_rad`` for angles (and quaternion entries) and
  ``config.max_step_mm`` for lengths. Far from the solution the correction is cut to the cap,
  keeping it incremental; near the solution the steps are below the caps and the iteration
  is plain Gauss-Newton again, with its quadratic convergence.

With the defaults (eta = 1, caps 0.3 rad and 20 mm) only the adaptive rule acts; the
thesis's fixed-eta run is ``FitConfig(eta=0.1, max_step_rad=inf, max_step_mm=inf)``. The
Gauss-Newton step is computed as in :mod:`.gauss_newton` (mu = 0 and the relative damping
floor of :mod:`._damped`; ``config.mu`` is not used). Stopping rules as for Gauss-Newton (``jaxhand.solve._stopping``).

Program: the damped family of :mod:`._damped` (shared with ``gn`` and ``lm_fixed``).
"""

from __future__ import annotations

import equinox as eqx

from ._config import FitConfig
from .gauss_newton import fixed

__all__ = ["step_limited_config"]


def step_limited_config(config: FitConfig) -> FitConfig:
    """``config`` with mu = 0 (Gauss-Newton's step); eta and the caps are the config's."""
    return eqx.tree_at(lambda c: c.mu, config, fixed(0.0))
