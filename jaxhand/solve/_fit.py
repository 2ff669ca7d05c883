"""fit and fit_batch: validate at the boundary, then one jitted solve (or a vmapped batch of them)."""

from __future__ import annotations

from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._errors import InputError
from ..camera import as_rig
from ..features import Features, raise_on_values, validate_features
from ..kinematics import validate_q
from ..model import Model
from ..residuals import DEFAULT_LINK_FRACTIONS, ResidualArgs, residuals, residuals_and_jacobian
from ._batched import BatchConfig, check_batch_config, solve_batched
from ._config import FitConfig, check_config
from ._damped import make_damped_gauss_newton
from ._driver import solve_least_squares
from ._edges import EdgeLanes
from ._parts import GaussNewtonFamily, StateSpace
from ._result import FitResult
from .bounded_trust_region import make_bounded_trust_region
from .constant_damping import constant_damping_config
from .gauss_newton import gauss_newton_config
from .levenberg_marquardt import make_levenberg_marquardt
from .step_limited import step_limited_config

__all__ = ["SOLVERS", "fit", "fit_batch", "solver_named"]

_Builder = Callable[[FitConfig, StateSpace], GaussNewtonFamily]


def _unchanged(config: FitConfig) -> FitConfig:
    return config


#: Solver names accepted by :func:`fit`: the builder of the compiled program and the config it
#: runs with. ``gn``, ``gn_eta`` and ``lm_fixed`` are one damped, step-limited Gauss-Newton
#: update with different (traced) numbers, so they share one compiled program (see ``_damped``).
_SOLVERS: dict[str, tuple[_Builder, Callable[[FitConfig], FitConfig]]] = {
    "gn": (make_damped_gauss_newton, gauss_newton_config),          # thesis eq. 3.4
    "gn_eta": (make_damped_gauss_newton, step_limited_config),      # thesis §3.2.4, fixed or adaptive eta
    "lm_fixed": (make_damped_gauss_newton, constant_damping_config),  # DigitEyes eq. 5, constant mu I
    "lm": (make_levenberg_marquardt, _unchanged),                   # optimistix LevenbergMarquardt
    "bounded": (make_bounded_trust_region, _unchanged),             # Coleman-Li trust region in the limits
}
SOLVERS: tuple[str, ...] = tuple(_SOLVERS)


def solver_named(name: str) -> str:
    """Check a solver name; the error lists the valid ones."""
    if not isinstance(name, str) or name not in _SOLVERS:
        raise InputError(f"unknown solver {name!r}; valid solvers: {', '.join(SOLVERS)}")
    return name


def fit_traced(model: Model, rig: tuple, feats: tuple, q0, build: _Builder, config: FitConfig,
               rank_test=True, priors: tuple = ()) -> FitResult:
    """The solve of :func:`fit` for traced use (no validation, not jitted): ``build`` and
    ``config`` come from :func:`solver_program`; ``rank_test`` (a bool, or traced) runs the SVD
    of the status's rank test; ``priors`` are stacked under the image residuals
    (:attr:`~jaxhand.residuals.ResidualArgs.priors`; the result's cost then includes theirs)."""
    space = StateSpace.of(model)
    q0 = space.normalize(q0)
    if build is make_bounded_trust_region:   # every iterate inside the limits, the start included
        q0 = space.interior(q0)
    args = ResidualArgs(model=model, cameras=rig, features=feats, fractions=config.link_fractions,
                        priors=tuple(priors))
    jac = residuals_and_jacobian if config.jacobian == "geometric" else None
    return solve_least_squares(residuals, build(config, space), q0, args, space, config, jac=jac,
                               rank_test=rank_test)




def solver_program(solver: str, config: FitConfig | None) -> tuple[_Builder, FitConfig]:
    """The static builder of ``solver``'s compiled program and the (checked, solver-adjusted)
    config it runs with; raises :class:`~jaxhand.InputError` for an unknown name or a bad value."""
    build, configure = _SOLVERS[solver_named(solver)]
    return build, configure(FitConfig() if config is None else check_config(config))


_fit_jit = eqx.filter_jit(fit_traced)


@eqx.filter_jit
def _fit_batch_jit(model, rig, feats, q0s, build, config):
    return jax.vmap(lambda f, q: fit_traced(model, rig, f, q, build, config))(feats, q0s)


def fit(model: Model, cameras, features, q0, *, solver: str = "lm", config: FitConfig | None = None) -> FitResult:
    """Fit the model's state to one frame's features (jitted; compiles once per model
    structure, rig, feature layout, solver and static config).

    Args:
        model: the articulated model.
        cameras: one camera or a rig (tuple of cameras).
        features: one :class:`~jaxhand.features.Features` per camera (a single one for one camera).
        q0: (n_q,) the starting state (e.g. the tracker's prediction). A free base's quaternion
            is normalised first; the ``bounded`` solver also moves q0 inside the joint limits.
        solver: one of :data:`SOLVERS`: ``gn`` (thesis eq. 3.4), ``gn_eta`` (step-limited,
            thesis §3.2.4), ``lm_fixed`` (DigitEyes eq. 5), ``lm`` (optimistix, adaptive
            damping), ``bounded`` (trust region inside the joint limits).
        config: a :class:`FitConfig` (default ``FitConfig()``).

    Returns:
        A :class:`FitResult`; q is always finite.

    Raises:
        InputError: wrong shapes, non-finite q0 or features, bad config values, unknown solver.
    """
    build, config = solver_program(solver, config)
    rig = as_rig(cameras)
    feats = validate_features(model, rig, features)
    q0 = validate_q(model, q0, name="q0")
    return _fit_jit(model, rig, _as_arrays(feats), jnp.asarray(q0), build, config)


def fit_batch(model: Model, cameras, features, q0, *, solver: str = "lm",
              config: FitConfig | BatchConfig | None = None) -> FitResult:
    """:func:`fit` over a leading batch axis: ``jax.vmap`` of the same solve, one compilation;
    or, with ``solver="batch"``, the batched bounded Levenberg-Marquardt of
    :mod:`jaxhand.solve._batched` (normal equations per lane, active set at the joint limits,
    slow lanes regrouped; ``config`` a :class:`~jaxhand.solve.internal.BatchConfig`), which does
    not wait for the slowest problem; its residuals are computed for a chunk of problems at once,
    lanes last, with only the Jacobian's structural nonzeros (a point moves with the joints of
    its own chain: :class:`~jaxhand.solve.internal.EdgeLanes`), and it has no history.

    Args:
        features: one Features per camera whose every array has a leading batch axis B.
        q0: (B, n_q) starting states, or (n_q,) for the same start everywhere.

    Returns:
        A :class:`FitResult` whose fields have the leading axis B.
    """
    rig = as_rig(cameras)
    if solver == "batch":
        if config is not None and not isinstance(config, BatchConfig):
            raise InputError(f"config: solver 'batch' takes a BatchConfig, got {type(config).__name__}")
        config = check_batch_config(config)
        feats = _validate_batch_features(model, rig, features)
        q0s = _validate_batch_q(model, q0, int(np.asarray(feats[0].lines).shape[0]))
        fn = EdgeLanes(model=model, cameras=rig, fractions=jnp.asarray(DEFAULT_LINK_FRACTIONS))
        return solve_batched(fn, _as_arrays(feats), jnp.asarray(q0s), StateSpace.of(model), config, fn.pattern())
    build, config = solver_program(solver, config)
    feats = _validate_batch_features(model, rig, features)
    B = int(np.asarray(feats[0].lines).shape[0])
    q0s = _validate_batch_q(model, q0, B)
    return _fit_batch_jit(model, rig, _as_arrays(feats), jnp.asarray(q0s), build, config)


def _as_arrays(feats: tuple[Features, ...]) -> tuple[Features, ...]:
    """Features with every field a JAX array of the working precision (bools stay bools), so a
    NumPy or float32 input does not trigger a new compilation."""
    dtype = jnp.asarray(0.0).dtype   # float64 (jaxhand enables x64)

    def conv(x):
        if isinstance(x, jax.Array) and x.dtype in (dtype, jnp.bool_) and not x.weak_type:
            return x
        a = np.asarray(x)
        return jnp.asarray(a, dtype=bool if a.dtype == bool else dtype)

    return tuple(jax.tree_util.tree_map(conv, f) for f in feats)


def _validate_batch_q(model: Model, q0, B: int) -> np.ndarray:
    try:
        q = np.asarray(q0, dtype=float)
    except (TypeError, ValueError) as err:
        raise InputError(f"q0: cannot convert to a float array ({err})") from err
    if q.shape == (model.n_q,):
        q = np.broadcast_to(q, (B, model.n_q))
    if q.shape != (B, model.n_q):
        raise InputError(f"q0: expected shape ({B}, {model.n_q}) or ({model.n_q},) for model {model.name!r}, "
                         f"got {q.shape}")
    bad = ~np.isfinite(q)
    if bad.any():
        b, i = np.argwhere(bad)[0]
        raise InputError(f"q0[{b}]: non-finite value for {model.q_names[i]!r}")
    return q


def _validate_batch_features(model: Model, rig: tuple, features) -> tuple[Features, ...]:
    """The checks of :func:`~jaxhand.features.validate_features`, vectorised over a batch."""
    feats = (features,) if isinstance(features, Features) else tuple(features)
    if len(feats) != len(rig):
        raise InputError(f"features: expected one Features per camera ({len(rig)}), got {len(feats)}")
    shapes = {"lines": (model.n_links, 3), "line_valid": (model.n_links,), "line_weight": (model.n_links,),
              "tips": (model.n_tips, 2), "tip_valid": (model.n_tips,), "tip_weight": (model.n_tips,)}
    B = None
    for c, f in enumerate(feats):
        for name, shape in shapes.items():
            a = np.asarray(getattr(f, name))
            if a.ndim != len(shape) + 1 or a.shape[1:] != shape:
                raise InputError(f"features[{c}].{name}: expected shape (B, {', '.join(map(str, shape))}) for "
                                 f"{model.name!r}, got {a.shape}")
            if B is None:
                B = a.shape[0]
            elif a.shape[0] != B:
                raise InputError(f"features[{c}].{name}: batch size {a.shape[0]} differs from {B}")
    if B == 0:
        raise InputError("features: the batch is empty")
    raise_on_values(feats)   # the checks reduce over the batch axis too
    return feats
