"""The iteration driver shared by every solver: one ``lax.while_loop`` around an optimistix
solver's ``step``, with the thesis's stopping rules, a history buffer and status mapping.

Why not ``optimistix.least_squares``: it stops on its own Cauchy test, keeps no history and
maps failures to its own results; the thesis's examples need the step-norm and cost rules,
their iteration tables need ``(q_k, H_k)`` at every k, and a tracker needs the starting state
back (never NaN) when a solve fails. The algorithms themselves (descents, searches,
accept/reject) remain optimistix's: this loop only calls ``solver.step``.

Iteration count: iteration k evaluates r and J at one new trial point (the first evaluation,
at q_0, is iteration 0). For Gauss-Newton every trial is an update, so ``iterations`` is the
thesis's k; a trust-region method may reject a trial, which then leaves q unchanged.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import optimistix as optx
from jaxtyping import Array, Bool, Float

from ._config import FitConfig
from ._parts import GaussNewtonFamily, StateSpace, is_finite
from ._result import FitResult
from ._status import Status
from ._stopping import cost_blew_up, small_step, stagnant_cost

__all__ = ["solve_least_squares", "jacobian_once"]

# Reasons the loop stopped (internal codes, mapped to Status after the loop).
_RUNNING, _CONVERGED, _DIVERGED, _NONFINITE = 0, 1, 2, 3


class _WithAux(eqx.Module):
    """``fn(y, args) -> (r, None)``: optimistix solvers expect an aux output."""

    fn: Callable = eqx.field(static=True)

    def __call__(self, y, args):
        return self.fn(y, args), None


def jacobian_once(fn: Callable, jac: Callable | None = None) -> Callable:
    """``fn(y, args)`` whose forward-mode derivative builds the whole Jacobian once.

    optimistix linearises the residuals and then applies the linearisation several times per
    iteration (to build J for the linear solve, for the trust region's predicted reduction).
    With this rule the linearisation computes J in the primal pass and every later application
    is the product ``J @ dy``: the kinematics and their derivative are traced once per iteration
    instead of once per use, which cuts the compile time (benchmarks/README.md).

    Args:
        fn: the residuals ``fn(y, args) -> r``.
        jac: optional ``jac(y, args) -> (r, J)``, the residuals and their Jacobian together
            (e.g. :func:`jaxhand.residuals.residuals_and_jacobian`); default ``jax.jacfwd(fn)``.

    The derivative with respect to ``args`` is not provided (the solvers never need it), so a
    fit must not be differentiated with respect to its features through this function.
    """

    @jax.custom_jvp
    def f(y, args):
        return fn(y, args)

    @f.defjvp
    def f_jvp(primals, tangents):
        y, args = primals
        dy = tangents[0]
        if jac is None:
            J, r = jax.jacfwd(lambda y_: (fn(y_, args),) * 2, has_aux=True)(y)
        else:
            r, J = jac(y, args)
        return r, J @ dy

    return f


class _StepView(NamedTuple):
    """What the loop reads from an optimistix Gauss-Newton-family state after a step."""

    residual: Array        # r at the point of the last evaluation
    accepted_steps: Array  # steps accepted so far (a new one means the trial point was taken)
    y_eval: Array          # the next trial point the solver proposes
    result: Array          # optimistix's RESULTS code of the step
    jacobian: Array        # J at the last accepted point (the descent's)


def _read_state(state) -> _StepView:
    """The one place that reads optimistix's private solver state (``_GaussNewtonState`` and
    its descent's state): optimistix has no public accessor for the residual, the accepted-step
    count, the proposed point or the descent's Jacobian, which the thesis's stopping rules and
    the rank test need. Its field names are not a stable API, hence the pin to optimistix 0.1.x
    in ``pyproject.toml``; a new optimistix release is checked here first."""
    return _StepView(residual=state.f_info.residual, accepted_steps=state.num_accepted_steps,
                     y_eval=state.y_eval, result=state.result, jacobian=state.descent_state.J)


def _half_sumsq(r):
    return 0.5 * jnp.sum(r * r)


def solve_least_squares(fn: Callable, solver: GaussNewtonFamily, q0: Float[Array, " nq"], args,
                        space: StateSpace, config: FitConfig, *, jac: Callable | None = None,
                        rank_test: bool | Bool[Array, ""] = True) -> FitResult:
    """Minimise ``H(q) = 1/2 ||fn(q, args)||^2`` from ``q0`` with ``solver`` (traceable, not jitted).

    ``jac(q, args) -> (r, J)``, when given, supplies the residuals with their Jacobian (see
    :func:`jacobian_once`); otherwise J is ``jax.jacfwd(fn)``. ``rank_test=False`` (a Python or
    traced bool) skips the SVD of the rank test, for a solve whose status nobody reads (the
    tracker's intermediate robust passes): ``rank`` then reads ``space.dof`` and a converged
    solve ``ok``.

    Stops at the first of: the step rule, the cost rule (:mod:`._stopping`), a non-finite
    iterate, the divergence guard, or ``config.max_steps`` iterations. Then:

    - non-finite, or diverged (cost above ``divergence_factor * H_0`` during the solve, or
      above ``H_0`` at its end): returns ``q0`` and ``H_0`` with that status;
    - converged: ``ok``, or ``singular`` when J at the result has rank < ``space.dof``;
    - otherwise ``max_steps`` with the last iterate.
    """
    f = _WithAux(jacobian_once(fn, jac))
    options: dict = {}
    tags: frozenset = frozenset()
    f_struct = jax.eval_shape(fn, q0, args)
    state = solver.init(f, q0, args, options, f_struct, None, tags)
    dynamic0, static = eqx.partition(state, eqx.is_array)
    dtype = q0.dtype
    n_hist = config.max_steps + 1 if config.history else 0
    hist_q = jnp.broadcast_to(q0, (n_hist,) + q0.shape)
    hist_H = jnp.zeros((n_hist,), dtype)

    # One loop for everything, so the solver step (kinematics, Jacobian, linear solve) is traced
    # once: pass 0 evaluates r and J at q0 and proposes the first step; pass k >= 1 is
    # iteration k. (Tracing the first evaluation apart doubled the compile time.)
    def cond(carry):
        _, _, k, code, _, _, _, _ = carry
        return (code == _RUNNING) & (k <= config.max_steps)

    def body(carry):
        y, dynamic, k, _, H, H0, hist_q, hist_H = carry
        state = eqx.combine(dynamic, static)
        y_new, new_state, _ = solver.step(f, y, args, options, state, tags)
        old, new = _read_state(state), _read_state(new_state)
        H_new = _half_sumsq(new.residual)
        H0 = jnp.where(k == 0, H_new, H0)
        H = jnp.where(k == 0, H_new, H)
        accepted = (new.accepted_steps > old.accepted_steps) & (k > 0)
        proposal = new.y_eval - y_new
        finite = is_finite(H_new, y_new, proposal) & (new.result == optx.RESULTS.successful)
        converged = (k > 0) & (small_step(accepted, y_new - y, proposal, config.xtol)
                               | stagnant_cost(accepted, H, H_new, config.ftol))
        code = jnp.where(~finite, _NONFINITE,
                         jnp.where(cost_blew_up(H_new, H0, config.divergence_factor), _DIVERGED,
                                   jnp.where(converged, _CONVERGED, _RUNNING)))
        if n_hist:
            hist_q = hist_q.at[k].set(y_new)
            hist_H = hist_H.at[k].set(H_new)
        new_dynamic, _ = eqx.partition(new_state, eqx.is_array)
        return y_new, new_dynamic, k + 1, code, H_new, H0, hist_q, hist_H

    zero = jnp.zeros((), dtype)
    carry = (q0, dynamic0, jnp.array(0), jnp.array(_RUNNING), zero, zero, hist_q, hist_H)
    y, dynamic, k, code, H, H0, hist_q, hist_H = jax.lax.while_loop(cond, body, carry)
    k = k - 1   # iterations after the evaluation at q0
    state = eqx.combine(dynamic, static)

    # Rank of J at the result (full rank = every DOF determined by the features); J is the one
    # the descent built at the last accepted point.
    def svd_rank(J):
        s = jnp.linalg.svd(J, compute_uv=False)
        return jnp.sum(s > config.rank_rtol * s[0])

    J_last = _read_state(state).jacobian
    if rank_test is True:
        rank = svd_rank(J_last)
    else:
        full = jnp.ones(space.dof, bool)   # the rank as svd_rank counts it, of a full-rank J
        rank = jax.lax.cond(rank_test, svd_rank, lambda J: jnp.sum(full), J_last)

    finite = is_finite(y, H) & (code != _NONFINITE)
    diverged = finite & ((code == _DIVERGED) | (H > H0))
    failed = ~finite | diverged
    converged = (code == _CONVERGED) & ~failed
    status = Status.where(
        ~finite, Status.nonfinite,
        Status.where(diverged, Status.diverged,
                     Status.where(converged, Status.where(rank < space.dof, Status.singular, Status.ok),
                                  Status.max_steps)))
    q_out = jnp.where(failed, q0, y)
    H_out = jnp.where(failed, H0, H)
    if n_hist:
        # Entries past the last iteration repeat the returned state, and non-finite entries (of a
        # failed solve) become the start: the path stays visible, no NaN leaves the solve.
        later = jnp.arange(n_hist) > k
        hist_q = jnp.where(later[:, None], q_out, hist_q)
        hist_H = jnp.where(later, H_out, hist_H)
        hist_q = jnp.where(jnp.isfinite(hist_q), hist_q, q0)
        hist_H = jnp.where(jnp.isfinite(hist_H), hist_H, H0)
    H0_out = jnp.where(jnp.isfinite(H0), H0, jnp.finfo(H0.dtype).max)
    return FitResult(q=q_out, cost=jnp.where(jnp.isfinite(H_out), H_out, H0_out), start_cost=H0_out,
                    iterations=k, converged=converged, status=status, rank=rank, history_q=hist_q,
                    history_cost=hist_H)
