"""Levenberg-Marquardt with constant damping: DigitEyes' conditioned Gauss-Newton (eq. 5).

DigitEyes stabilises the Gauss-Newton update with a constant diagonal conditioning matrix S;
with ``S = mu I`` (thesis §3.1.2 writes the same update)::

    q_{k+1} = q_k - (J_k^T J_k + mu I)^-1 J_k^T r_k

Every step is taken. ``mu > 0`` makes the system positive definite, so a singular
``J^T J`` (a masked link, an unobservable DOF) still gives a finite step, which does not move
the undetermined directions. The fixed points are the stationary points of H, so the
iteration converges to the same minimum as Gauss-Newton, linearly with rate about
``mu / (sigma_min^2 + mu)`` (sigma_min: J's smallest non-zero singular value) instead of
quadratically. ``config.mu`` is in px^2 per q unit^2; the default 1e-3 is negligible next to the
hand models' sigma^2 (1 to 1e4) and still regularises exact rank loss. (The family's relative
floor, 1e-10 of J^T J's largest diagonal entry, takes over only where it exceeds mu.)

Stopping rules: shared (``jaxhand.solve._stopping``).

Program: the damped family of :mod:`._damped` with eta = 1 and no cap (shared with ``gn`` and
``gn_eta``).
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp

from ._config import FitConfig
from .gauss_newton import fixed

__all__ = ["constant_damping_config"]


def constant_damping_config(config: FitConfig) -> FitConfig:
    """``config`` with eta = 1 and no step caps; mu is the config's."""
    return eqx.tree_at(lambda c: (c.eta, c.max_step_rad, c.max_step_mm), config,
                       (fixed(1.0), fixed(jnp.inf), fixed(jnp.inf)))
