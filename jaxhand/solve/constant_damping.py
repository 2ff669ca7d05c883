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
hand models' sigma^2 (1 to 1e4) and still regularises exact rank loss.

Stopping rules: shared (``jaxhand.solve._stopping``).

Optimistix parts: ``DampedNewtonDescent`` (QR of the stacked system ``[J; sqrt(mu) I]``)
with ``LearningRate(1 / mu)``: optimistix's damped descent reads its step size as 1/lambda.
"""

from __future__ import annotations

import lineax as lx
import optimistix as optx

from ._config import FitConfig
from ._parts import GaussNewtonFamily, Retracted, StateSpace

__all__ = ["make_constant_damping"]


def make_constant_damping(config: FitConfig, space: StateSpace) -> GaussNewtonFamily:
    """DigitEyes' update with ``S = config.mu * I``."""
    descent = Retracted(optx.DampedNewtonDescent(linear_solver=lx.QR()), space)
    return GaussNewtonFamily(descent, optx.LearningRate(1.0 / config.mu))
