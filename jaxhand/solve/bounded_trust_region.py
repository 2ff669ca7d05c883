"""Bounded trust region: damped Gauss-Newton in Coleman-Li scaled variables, every iterate
strictly inside the joint limits.

The thesis fitted with MATLAB's interior-reflective trust region. This solver follows the
same idea (Coleman & Li's affine scaling, which makes a bound that blocks the descent look
like a wall the step cannot reach) with the trust region handled by optimistix's
``ClassicalTrustRegion`` through a damping parameter, and the reflection replaced by a choice
among three interior candidates.

Per iteration, at q (inside the box ``l <= q <= u``) with residuals r, Jacobian J and gradient
``g = J^T r``:

1. Coleman-Li scaling, per bounded entry: ``v_i = u_i - q_i`` if ``g_i < 0`` (descent moves
   it up), ``v_i = q_i - l_i`` if ``g_i > 0``, else 1; ``d = sqrt(v)``, ``c_i = |g_i|`` where
   ``v_i`` is a distance (else 0). The free base's quaternion entries are unbounded here (their
   box is implied by the unit norm).
2. Damped scaled Gauss-Newton step: ``(D J^T J D + diag(c) + lambda I) h = -D g``,
   ``p = D h`` with ``D = diag(d)`` and ``lambda = 1 / step_size`` from the trust region
   (floored at 1e-12 of the largest diagonal entry so the system stays positive definite
   when J is rank-deficient). A blocking bound has ``d_i -> 0``, so the step along it
   vanishes smoothly instead of being cut.
3. Three interior candidates, with ``theta = max(0.995, 1 - ||D g||_inf)`` (the fraction of the
   way to a bound a step may go; it tends to 1 near a solution, so active bounds are
   approached superlinearly):
   a. ``p`` itself if ``q + p`` is inside, else ``p`` shortened to ``theta`` times its distance
      to the first bound it meets;
   b. ``q + p`` projected entrywise into ``[q + theta (l - q), q + theta (u - q)]`` (keeps the
      entries that are free to move when one entry meets its bound);
   c. the scaled steepest-descent (Cauchy) step along ``-D^2 g``: the minimiser of the
      Gauss-Newton model along it, no longer than ``||h||`` in scaled variables, shortened
      like (a).
   The candidate with the lowest Gauss-Newton model ``1/2 ||J p + r||^2`` is proposed.
4. ``ClassicalTrustRegion`` accepts or rejects the proposal on the ratio of actual to
   predicted reduction and scales lambda (see ``levenberg_marquardt``). The step is clipped
   into the box (a no-op up to rounding) and the quaternion renormalised before it is judged.

The start is moved strictly inside the box (by ``1e-10 max(1, |bound|)``), so every iterate,
start included, satisfies the limits.

Stopping rules: shared (``jaxhand.solve._stopping``): ``sum |dq| <= xtol`` for the step taken
or proposed, ``|dH| <= ftol H``, or ``max_steps``.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import jax.scipy.linalg as jsl
import optimistix as optx
from jaxtyping import Array, Float, Scalar

from ._config import FitConfig
from ._parts import GaussNewtonFamily, Retracted, StateSpace

__all__ = ["ColemanLiDescent", "make_bounded_trust_region"]


class _CLState(eqx.Module):
    y: Float[Array, " n"]
    J: Float[Array, "m n"]
    r: Float[Array, " m"]
    g: Float[Array, " n"]
    d: Float[Array, " n"]
    c: Float[Array, " n"]


def _distance_to_box(y, p, lo, hi):
    """Largest t >= 0 with lo <= y + t p <= hi (inf when p never meets a bound)."""
    # Guard: p_i = 0 never meets a bound; the safe denominator keeps the unused branch finite.
    safe = jnp.where(p == 0, 1.0, p)
    t = jnp.where(p > 0, (hi - y) / safe, jnp.where(p < 0, (lo - y) / safe, jnp.inf))
    return jnp.maximum(jnp.min(jnp.where(jnp.isnan(t), jnp.inf, t)), 0.0)


class ColemanLiDescent(optx.AbstractDescent):
    """The scaled, damped, box-interior descent of this module (steps 1-3 of its docstring).

    Attributes:
        space: the state space (limits, quaternion layout).
        theta_min: static. Smallest fraction of the distance to a bound a step may cover.
    """

    space: StateSpace
    theta_min: float = eqx.field(static=True, default=0.995)

    def _box(self):
        bounded = self.space.bounded
        return (jnp.where(bounded, self.space.lower, -jnp.inf), jnp.where(bounded, self.space.upper, jnp.inf))

    def init(self, y, f_info_struct) -> _CLState:
        m = f_info_struct.residual.shape[0]
        n = y.shape[0]
        z = jnp.zeros(n, y.dtype)
        return _CLState(y=y, J=jnp.zeros((m, n), y.dtype), r=jnp.zeros(m, y.dtype), g=z, d=z, c=z)

    def query(self, y, f_info, state: _CLState) -> _CLState:
        del state
        J = f_info.jac.as_matrix()
        r = f_info.residual
        g = J.T @ r
        lo, hi = self._box()
        up = (g < 0) & jnp.isfinite(hi)
        down = (g > 0) & jnp.isfinite(lo)
        v = jnp.where(up, hi - y, jnp.where(down, y - lo, 1.0))
        dv = jnp.where(up, -1.0, jnp.where(down, 1.0, 0.0))
        return _CLState(y=y, J=J, r=r, g=g, d=jnp.sqrt(jnp.maximum(v, 0.0)), c=g * dv)

    def step(self, step_size: Scalar, state: _CLState):
        y, J, r, g, d, c = state.y, state.J, state.r, state.g, state.d, state.c
        lo, hi = self._box()
        Jh = J * d[None, :]
        A = Jh.T @ Jh
        diag = jnp.diagonal(A) + c
        # Guard: step_size -> 0 means lambda -> inf (a zero step); the floor keeps A positive
        # definite when J is rank-deficient and lambda has shrunk towards 0.
        safe_size = jnp.where(step_size > 0, step_size, 1.0)
        lam = jnp.where(step_size > 0, 1.0 / safe_size, jnp.finfo(y.dtype).max / 1e4)
        lam = jnp.maximum(lam, 1e-12 * jnp.max(diag) + jnp.finfo(y.dtype).tiny)
        gh = d * g
        h = jsl.cho_solve(jsl.cho_factor(A + jnp.diag(c + lam)), -gh)
        p = d * h
        theta = jnp.maximum(self.theta_min, 1.0 - jnp.max(jnp.abs(gh)))

        def shortened(s, t_max=1.0):
            t_box = _distance_to_box(y, s, lo, hi)
            return jnp.where(t_box >= t_max, t_max, theta * t_box) * s

        p_trunc = shortened(p)
        p_proj = jnp.clip(y + p, y + theta * (lo - y), y + theta * (hi - y)) - y
        s = -d * gh
        Js = J @ s
        gh2 = jnp.sum(gh * gh)
        # Guard: a zero scaled gradient (or J s = 0) gives a zero Cauchy step, not 0/0.
        tau_model = jnp.where(jnp.sum(Js * Js) > 0, gh2 / jnp.where(jnp.sum(Js * Js) > 0, jnp.sum(Js * Js), 1.0),
                              jnp.inf)
        tau_radius = jnp.where(gh2 > 0, jnp.linalg.norm(h) / jnp.sqrt(jnp.where(gh2 > 0, gh2, 1.0)), 0.0)
        p_cauchy = shortened(s, jnp.minimum(tau_model, tau_radius))

        candidates = jnp.stack([p_trunc, p_proj, p_cauchy])
        res = candidates @ J.T + r
        model = 0.5 * jnp.sum(res * res, axis=-1)
        best = jnp.argmin(jnp.where(jnp.isfinite(model), model, jnp.inf))
        return candidates[best], optx.RESULTS.successful


def make_bounded_trust_region(config: FitConfig, space: StateSpace) -> GaussNewtonFamily:
    """The bounded trust-region solver for the state space ``space`` (limits from the model)."""
    del config
    descent = Retracted(ColemanLiDescent(space), space, clip=True)
    return GaussNewtonFamily(descent, optx.ClassicalTrustRegion())

