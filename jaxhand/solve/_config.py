"""FitConfig: the options of every solver, with defaults, units and static/traced split."""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._errors import InputError
from ..residuals import DEFAULT_LINK_FRACTIONS

__all__ = ["FitConfig", "check_config", "JACOBIANS"]

#: Values of :attr:`FitConfig.jacobian`.
JACOBIANS = ("autodiff", "geometric")


def _f(x):
    return jnp.asarray(x, dtype=float)


class FitConfig(eqx.Module):
    """Options of :func:`~jaxhand.fit` (static fields recompile when changed; traced ones do not).

    Attributes:
        max_steps: static. Iteration cap: the most trial steps (evaluations of r and J after the
            one at the start). 1 is the thesis's fast mode of one update per frame (§3.1.2).
        history: static. Record ``(q_k, H_k)`` for ``k = 0..max_steps`` in the result.
        jacobian: static. How the residual Jacobian is computed: ``"autodiff"`` (``jax.jacfwd``
            of the residuals) or ``"geometric"`` (the joint-axis Jacobian of DigitEyes eqs. 8-10
            chained with the camera's, :func:`jaxhand.residuals.residuals_and_jacobian`). They
            agree to rounding; the geometric one is several times cheaper on CPU
            (benchmarks/README.md).
        link_fractions: traced (its length is static). Fractions along each link axis of the
            link residual points (see :mod:`jaxhand.residuals`).
        xtol: traced, q units (rad, mm). Step rule: stop when the last update or the next
            proposed update has ``sum |dq| <= xtol`` (the thesis's ``sum |q_{k+1} - q_k|``).
        ftol: traced, relative. Cost-stagnation rule: stop when an update changes the cost by
            at most ``ftol * H``.
        eta: traced. ``gn_eta`` only: the fixed step factor of thesis §3.2.4,
            ``q_{k+1} = q_k - eta (J^T J)^-1 J^T r``.
        max_step_rad: traced, rad. ``gn_eta`` only: the largest change of an angle (or a
            quaternion entry) per update; longer steps are scaled down as a whole (the
            adaptive eta). ``inf`` disables it.
        max_step_mm: traced, mm. ``gn_eta`` only: the same cap for prismatic joints and
            translations.
        mu: traced, px^2 per q unit^2. ``lm_fixed`` only: DigitEyes' constant diagonal
            conditioning ``S = mu I`` (DigitEyes eq. 5); must be > 0.
        divergence_factor: traced. A solve whose cost exceeds ``divergence_factor * H_0`` stops
            as diverged.
        rank_rtol: traced. Singular values of J below ``rank_rtol * s_max`` count as zero in the
            rank test that tells ``ok`` from ``singular``.
    """

    max_steps: int = eqx.field(static=True, default=50)
    history: bool = eqx.field(static=True, default=False)
    jacobian: str = eqx.field(static=True, default="autodiff")
    link_fractions: Float[Array, " K"] = eqx.field(converter=_f, default=DEFAULT_LINK_FRACTIONS)
    xtol: Float[Array, ""] = eqx.field(converter=_f, default=1e-10)
    ftol: Float[Array, ""] = eqx.field(converter=_f, default=1e-12)
    eta: Float[Array, ""] = eqx.field(converter=_f, default=1.0)
    max_step_rad: Float[Array, ""] = eqx.field(converter=_f, default=0.3)
    max_step_mm: Float[Array, ""] = eqx.field(converter=_f, default=20.0)
    mu: Float[Array, ""] = eqx.field(converter=_f, default=1e-3)
    divergence_factor: Float[Array, ""] = eqx.field(converter=_f, default=1e6)
    rank_rtol: Float[Array, ""] = eqx.field(converter=_f, default=1e-9)


def check_config(config: FitConfig) -> FitConfig:
    """Boundary check of a FitConfig's values.

    Raises:
        InputError: naming the field and its value.
    """
    if not isinstance(config, FitConfig):
        raise InputError(f"config: expected a FitConfig, got {type(config).__name__}")
    if not isinstance(config.max_steps, (int, np.integer)) or config.max_steps < 1:
        raise InputError(f"config.max_steps: expected an integer >= 1, got {config.max_steps!r}")
    if config.jacobian not in JACOBIANS:
        raise InputError(f"config.jacobian: expected one of {', '.join(JACOBIANS)}, got {config.jacobian!r}")

    def val(name):
        a = np.asarray(getattr(config, name), dtype=float)
        if a.shape != () or np.isnan(a):
            raise InputError(f"config.{name}: expected a number, got {getattr(config, name)!r}")
        return float(a)

    rules = {"xtol": lambda v: v >= 0, "ftol": lambda v: v >= 0, "eta": lambda v: 0 < v <= 1,
             "max_step_rad": lambda v: v > 0, "max_step_mm": lambda v: v > 0, "mu": lambda v: 0 < v < np.inf,
             "divergence_factor": lambda v: v > 1, "rank_rtol": lambda v: 0 < v < 1}
    words = {"xtol": ">= 0", "ftol": ">= 0", "eta": "in (0, 1]", "max_step_rad": "> 0", "max_step_mm": "> 0",
             "mu": "finite and > 0", "divergence_factor": "> 1", "rank_rtol": "in (0, 1)"}
    for name, ok in rules.items():
        v = val(name)
        if not ok(v):
            raise InputError(f"config.{name}: must be {words[name]}, got {v!r}")
    fr = np.asarray(config.link_fractions, dtype=float)
    if fr.ndim != 1 or fr.size == 0 or not np.all(np.isfinite(fr)) or np.any((fr < 0) | (fr > 1)):
        raise InputError(f"config.link_fractions: expected one or more numbers in [0, 1], got {fr.tolist()!r}")
    return config
