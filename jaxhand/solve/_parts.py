"""Shared solver parts: the state-space layout, a Gauss-Newton-type solver assembled from a
descent and a search, and descent wrappers (retraction onto the state manifold, step cap).

Every jaxhand solver is a :class:`GaussNewtonFamily`: optimistix's ``AbstractGaussNewton``
machinery (evaluate r and J, ask the search whether to accept, ask the descent for the next
step) with the descent and the search chosen per solver, as optimistix composes its own
``GaussNewton`` and ``LevenbergMarquardt``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import lineax as lx
import numpy as np
import optimistix as optx
from jaxtyping import Array, Bool, Float, PyTree, Scalar

from ..kinematics import clip_to_limits, normalize_quaternion
from ..model import Model

__all__ = ["StateSpace", "GaussNewtonFamily", "Retracted", "StepLimited", "is_finite"]


class StateSpace(eqx.Module):
    """The layout of q that solvers need: limits, units and the free base's quaternion.

    Attributes:
        lower, upper: traced. Joint limits (rad, mm; the quaternion entries' [-1, 1]).
        is_length: static. True for entries in mm (prismatic joints, base translations).
        has_quaternion: static. The first 4 entries are a (w, x, y, z) quaternion that is
            renormalised after every update.
        dof: static. Degrees of freedom (n_q less one for the quaternion's norm).
    """

    lower: Float[Array, " nq"]
    upper: Float[Array, " nq"]
    is_length: tuple[bool, ...] = eqx.field(static=True)
    has_quaternion: bool = eqx.field(static=True)
    dof: int = eqx.field(static=True)

    @classmethod
    def of(cls, model: Model) -> StateSpace:
        kinds = model.q_kinds
        return cls(lower=model.q_lower, upper=model.q_upper, is_length=tuple(k == "length" for k in kinds),
                   has_quaternion=model.base_kind == "free", dof=model.dof)

    @property
    def bounded(self) -> np.ndarray:
        """Static mask of the entries a bounded solver keeps inside [lower, upper]: all but the
        quaternion, whose box is implied by its unit norm."""
        mask = np.ones(len(self.is_length), dtype=bool)
        if self.has_quaternion:
            mask[:4] = False
        return mask

    def normalize(self, q: Float[Array, " nq"]) -> Float[Array, " nq"]:
        """q with its quaternion (if any) scaled to unit norm (:func:`jaxhand.kinematics.normalize_quaternion`)."""
        return normalize_quaternion(q, self.has_quaternion)

    def clip(self, q: Float[Array, " nq"]) -> Float[Array, " nq"]:
        """q clipped into the limits, bounded entries only (:func:`jaxhand.kinematics.clip_to_limits`)."""
        return clip_to_limits(q, self.lower, self.upper, self.has_quaternion)

    def interior(self, q: Float[Array, " nq"], rel: float = 1e-10) -> Float[Array, " nq"]:
        """q clipped strictly inside the limits, by ``rel * max(1, |bound|)`` (bounded entries)."""
        lo = self.lower + rel * jnp.maximum(1.0, jnp.abs(self.lower))
        hi = self.upper - rel * jnp.maximum(1.0, jnp.abs(self.upper))
        mid = 0.5 * (self.lower + self.upper)
        return jnp.where(self.bounded, jnp.clip(q, jnp.minimum(lo, mid), jnp.maximum(hi, mid)), q)


def _quiet(**kwargs) -> None:
    del kwargs


class GaussNewtonFamily(optx.AbstractGaussNewton):
    """A Gauss-Newton-type least-squares solver from any descent and search.

    ``rtol``/``atol``/``norm`` feed optimistix's own (Cauchy) termination test, which jaxhand's
    driver does not use: it applies the thesis's stopping rules itself (see ``_stopping``).
    """

    rtol: float
    atol: float
    norm: Callable[[PyTree], Scalar]
    descent: optx.AbstractDescent
    search: optx.AbstractSearch
    verbose: Callable[..., None]

    def __init__(self, descent: optx.AbstractDescent, search: optx.AbstractSearch):
        self.rtol = 0.0
        self.atol = 0.0
        self.norm = optx.max_norm
        self.descent = descent
        self.search = search
        self.verbose = _quiet


class _RetractedState(eqx.Module):
    y: Array
    J: Array
    inner: Any


class Retracted(optx.AbstractDescent):
    """Wrap a descent so that every step lands back on the state space, with J built once.

    ``query`` materialises the Jacobian once per accepted point (the inner descent then gets a
    matrix operator, so its linear solve does not rebuild it, and the driver reads J from
    here for its rank test); ``step`` takes the inner descent's ``dq`` and returns
    ``retract(q + dq) - q``, where ``retract`` renormalises the free base's quaternion and, with
    ``clip``, clips into the joint limits. The search then judges the step actually taken.
    """

    inner: optx.AbstractDescent
    space: StateSpace
    clip: bool = eqx.field(static=True, default=False)

    def init(self, y, f_info_struct) -> _RetractedState:
        m = f_info_struct.residual.shape[0]
        J = jnp.zeros((m, y.shape[0]), y.dtype)
        return _RetractedState(y, J, self.inner.init(y, _as_matrix_struct(f_info_struct)))

    def query(self, y, f_info, state: _RetractedState) -> _RetractedState:
        J = f_info.jac.as_matrix()
        f_info = optx.FunctionInfo.ResidualJac(f_info.residual, lx.MatrixLinearOperator(J))
        return _RetractedState(y, J, self.inner.query(y, f_info, state.inner))

    def step(self, step_size: Scalar, state: _RetractedState):
        diff, result = self.inner.step(step_size, state.inner)
        y_new = state.y + diff
        if self.clip:
            y_new = self.space.clip(y_new)
        return self.space.normalize(y_new) - state.y, result


def _as_matrix_struct(f_info_struct):
    """A zero ResidualJac shaped like ``f_info_struct`` with a matrix Jacobian (for inner ``init``,
    which only reads shapes)."""
    r = f_info_struct.residual
    n = jax.tree_util.tree_leaves(f_info_struct.jac.in_structure())[0].shape[0]
    return optx.FunctionInfo.ResidualJac(jnp.zeros(r.shape, r.dtype),
                                         lx.MatrixLinearOperator(jnp.zeros((r.shape[0], n), r.dtype)))


class StepLimited(optx.AbstractDescent):
    """Wrap a descent to scale its steps by ``eta`` and keep every entry within its cap.

    The inner step ``dq`` becomes ``eta * dq / max(1, s)`` with ``s = max_i |dq_i| / cap_i``: the
    direction is kept and the correction stays incremental (thesis §3.2.4). ``eta = 1`` and
    infinite caps leave the step unchanged.
    """

    inner: optx.AbstractDescent
    eta: Float[Array, ""]
    cap: Float[Array, " nq"]

    def init(self, y, f_info_struct):
        return self.inner.init(y, f_info_struct)

    def query(self, y, f_info, state):
        return self.inner.query(y, f_info, state)

    def step(self, step_size: Scalar, state):
        diff, result = self.inner.step(step_size, state)
        ratio = jnp.max(jnp.abs(diff) / self.cap)
        # Guard: ratio <= 1 (or NaN from a failed solve, handled by the driver) keeps the step.
        scale = jnp.where(ratio > 1, 1.0 / jnp.where(ratio > 1, ratio, 1.0), 1.0)
        return diff * (self.eta * scale), result


def is_finite(*xs) -> Bool[Array, ""]:
    """True when every entry of every array is finite."""
    return jnp.all(jnp.stack([jnp.all(jnp.isfinite(x)) for x in xs]))
