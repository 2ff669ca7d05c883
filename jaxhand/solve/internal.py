"""The solver's internal face: what the tracker (and other compiled programs) share with
:func:`jaxhand.fit` for use inside their own traced code. Not a stable user API: names here may
change with the package; users call :func:`jaxhand.fit`.

- :func:`solver_program` checks a solver name and a :class:`~jaxhand.FitConfig` once, on the
  host, and returns the static builder of the compiled program with the config it runs with;
- :func:`fit_traced` is the body of :func:`jaxhand.fit` (no validation, no jit), to be traced
  inside a caller's program (a robust loop, a frame step);
- :func:`check_config` is the boundary check of a :class:`~jaxhand.FitConfig` that
  :func:`jaxhand.fit` runs (for configs that carry one, such as the tracker's);
- :data:`JACOBIANS` lists the values of :attr:`~jaxhand.FitConfig.jacobian`;
- :func:`batched_lm` / :func:`batch_lm` are the batched bounded Levenberg-Marquardt of
  :mod:`jaxhand.solve._batched` (lanes last / per-problem residuals), with its
  :class:`BatchConfig` and :func:`check_batch_config`;
- :func:`lane_frames`, :func:`lane_root`, :func:`lane_point_jacobian`: kinematics with the
  batch axis last, for residual kernels of that solver;
- :class:`EdgeLanes`: the link and tip residuals of that solver (lanes last, sparse J), the
  kernel of ``fit_batch(solver="batch")``.
"""

from ._batched import (
    BatchConfig,
    batch_lm,
    batched_lm,
    check_batch_config,
    lane_cholesky_solve,
    solve_batched,
)
from ._config import JACOBIANS, check_config
from ._edges import EdgeLanes
from ._fit import fit_traced, solver_program
from ._lanes import lane_contract, lane_frames, lane_matmul, lane_point_jacobian, lane_root, point_dependence
from ._sparsity import SparsePattern

__all__ = ["JACOBIANS", "EdgeLanes", "check_config", "fit_traced", "solver_program", "BatchConfig", "SparsePattern",
           "batch_lm", "batched_lm", "check_batch_config", "lane_cholesky_solve", "solve_batched", "lane_contract",
           "lane_frames", "lane_matmul", "lane_point_jacobian", "lane_root", "point_dependence"]
