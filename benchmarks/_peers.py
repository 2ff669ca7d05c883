"""Peers of jaxhand's batched solver, vmapped the same way over problems: optimistix's
``GaussNewton`` and ``LevenbergMarquardt`` (``optx.least_squares``) and jaxopt's ``GaussNewton``
and ``LevenbergMarquardt`` (jaxopt is a dev/benchmark dependency only: it is no longer
developed upstream). None of them knows joint limits."""

from __future__ import annotations

import jax
import jax.numpy as jnp


def vmapped_peers(res, jac, max_steps: int) -> dict:
    """name -> jitted ``run(args_batch, q0s) -> (q, cost, converged, iterations)``, each a vmap
    of one solve of ``res(q, args)`` over the problems and their starts ``q0s`` (B, n_q).
    ``jac(q, args)`` is kept for a peer that takes a Jacobian: jaxopt 0.8.5's LM fails with
    ``jac_fun`` (no attribute ``_jac_fun``), so it differentiates ``res`` itself."""
    del jac
    import jaxopt
    import optimistix as optx

    def optx_solver(solver):
        @jax.jit
        def run(batch, q0s):
            def one(a, q0):
                sol = optx.least_squares(res, solver, q0, args=a, max_steps=max_steps, throw=False)
                r = res(sol.value, a)
                return sol.value, 0.5 * jnp.sum(r * r), sol.result == optx.RESULTS.successful, sol.stats["num_steps"]
            return jax.vmap(one)(batch, q0s)
        return run

    def jaxopt_solver(make):
        @jax.jit
        def run(batch, q0s):
            def one(a, q0):
                sol = make().run(q0, a)
                r = res(sol.params, a)
                return sol.params, 0.5 * jnp.sum(r * r), sol.state.iter_num < max_steps, sol.state.iter_num
            return jax.vmap(one)(batch, q0s)
        return run

    tol = dict(rtol=1e-8, atol=1e-8)
    return {
        "optimistix_gauss_newton": optx_solver(optx.GaussNewton(**tol)),
        "optimistix_levenberg_marquardt": optx_solver(optx.LevenbergMarquardt(**tol)),
        "jaxopt_gauss_newton": jaxopt_solver(lambda: jaxopt.GaussNewton(res, maxiter=max_steps, tol=1e-8)),
        "jaxopt_levenberg_marquardt": jaxopt_solver(lambda: jaxopt.LevenbergMarquardt(
            res, maxiter=max_steps, tol=1e-8, xtol=1e-10, gtol=1e-8, materialize_jac=True, solver="cholesky")),
    }
