"""Pose estimation: fit a model's state to image features by nonlinear least squares.

Five interchangeable solvers (``fit(..., solver=name)``), each an optimistix Gauss-Newton-type
solver assembled from a descent and a search, all driven by one loop with the thesis's
stopping rules:

- ``gn``: Gauss-Newton, thesis eq. 3.4 (:mod:`.gauss_newton`);
- ``gn_eta``: step-limited Gauss-Newton, fixed or adaptive eta, thesis §3.2.4 (:mod:`.step_limited`);
- ``lm_fixed``: DigitEyes' constant diagonal conditioning, J^T J + mu I (:mod:`.constant_damping`);
- ``lm``: optimistix's Levenberg-Marquardt, adaptive damping (:mod:`.levenberg_marquardt`);
- ``bounded``: trust region that keeps q inside the joint limits (:mod:`.bounded_trust_region`).

``gn``, ``gn_eta`` and ``lm_fixed`` are one damped, step-limited Gauss-Newton update with
different numbers (:mod:`._damped`), so per model they compile once between them. Results carry
a :class:`Status`; no NaN leaves a solve. :mod:`jaxhand.solve.internal` is the documented
internal face for traced use inside other compiled programs (the tracker's).
"""

from ._config import FitConfig
from ._driver import solve_least_squares
from ._fit import SOLVERS, fit, fit_batch, solver_named
from ._parts import StateSpace
from ._result import FitResult
from ._status import STATUS_NAMES, Status, status_name
from ._synthetic import features_from_poses

__all__ = ["fit", "fit_batch", "FitConfig", "FitResult", "Status", "STATUS_NAMES", "status_name", "SOLVERS",
           "solver_named", "solve_least_squares", "StateSpace", "features_from_poses"]
