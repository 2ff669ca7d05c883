"""Levenberg-Marquardt with adaptive damping: optimistix's ``LevenbergMarquardt``.

The damped update ``dq = -(J^T J + lambda I)^-1 J^T r`` with lambda adapted by a classical
trust-region test on the ratio of actual to predicted cost reduction,
``rho = (H(q + dq) - H(q)) / (m(dq) - m(0))`` with the Gauss-Newton model
``m(dq) = 1/2 ||J dq + r||^2``:

- rho < 0.01: reject the step and quadruple lambda (step size x 0.25);
- rho > 0.99: accept it and divide lambda by 3.5;
- otherwise accept it and keep lambda.

lambda starts at 1 (px^2 per q unit^2), small next to the hand models' J^T J, so the first
step is nearly the Gauss-Newton step. A rejected trial leaves q unchanged but counts as an
iteration (it costs an evaluation of r and J). These are exactly the parts of
``optimistix.LevenbergMarquardt`` (``DampedNewtonDescent`` with QR, ``ClassicalTrustRegion``),
with the step retracted onto the state space (quaternion renormalised) before it is judged.

Stopping rules: shared (``jaxhand.solve._stopping``); the step rule also fires when the
trust region has shrunk the proposed step below ``xtol``.
"""

from __future__ import annotations

import lineax as lx
import optimistix as optx

from ._config import FitConfig
from ._parts import GaussNewtonFamily, Retracted, StateSpace

__all__ = ["make_levenberg_marquardt"]


def make_levenberg_marquardt(config: FitConfig, space: StateSpace) -> GaussNewtonFamily:
    """optimistix's Levenberg-Marquardt (adaptive damping) on the state space ``space``."""
    del config
    descent = Retracted(optx.DampedNewtonDescent(linear_solver=lx.QR()), space)
    return GaussNewtonFamily(descent, optx.ClassicalTrustRegion())
