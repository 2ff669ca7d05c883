"""Line regressions across a link's profiles (thesis appendix D §11.3, used in §4.3.2).

Each fits ``y = c0 + c1 x`` where ``x`` is the profile's number along the link and ``y`` a
displacement along the profile. All functions are vectorised over leading axes (one fit per
link), take a mask of the profiles that count, and return ``ok = False`` (with finite zeros)
where the normal equations are singular (fewer than two distinct x).
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

from ._linefit import padded_rows

__all__ = ["plls", "mwplls", "imwplls", "imwplls_crest_fit", "solve_2x2"]

# |det R| (relative to the squared trace) below which the 2x2 normal equations count as singular.
SINGULAR = 1e-12


def solve_2x2(R: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Solve ``R c = r`` for stacks of 2x2 systems by Cramer's rule.

    Returns:
        (c, ok): c with shape (..., 2) (zeros where singular) and the non-singular mask.
    """
    det = R[..., 0, 0] * R[..., 1, 1] - R[..., 0, 1] * R[..., 1, 0]
    scale = (np.abs(R[..., 0, 0]) + np.abs(R[..., 1, 1])) ** 2
    ok = np.abs(det) > SINGULAR * np.maximum(scale, 1e-300)
    safe = np.where(ok, det, 1.0)  # Guard: a singular system gets a dummy denominator, then zeros.
    # filled in place: np.stack's overhead is most of a small system's cost
    c = np.empty(np.broadcast_shapes(R.shape[:-2], r.shape[:-1]) + (2,), np.result_type(R, r, 1.0))
    np.divide(R[..., 1, 1] * r[..., 0] - R[..., 0, 1] * r[..., 1], safe, out=c[..., 0])
    np.divide(R[..., 0, 0] * r[..., 1] - R[..., 1, 0] * r[..., 0], safe, out=c[..., 1])
    c[~ok] = 0.0
    return c, np.asarray(ok)


def normal_equations(x: np.ndarray, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """R = sum_i a_i [[1, x_i], [x_i, x_i^2]] and r = sum_i b_i [1, x_i] over the last axis."""
    ax = a * x
    R = np.empty(ax.shape[:-1] + (2, 2))   # filled in place (no np.stack)
    R[..., 0, 0] = a.sum(-1)
    R[..., 0, 1] = R[..., 1, 0] = ax.sum(-1)
    R[..., 1, 1] = (ax * x).sum(-1)
    bx = b * x
    r = np.empty(bx.shape[:-1] + (2,))
    r[..., 0] = b.sum(-1)
    r[..., 1] = bx.sum(-1)
    return R, r


def plls(x: np.ndarray, y: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Partial linear least squares (thesis §11.3.1): minimise ``sum_i (y_i - c0 - c1 x_i)^2``
    over the masked points (errors measured along y only).

    Args:
        x, y, mask: (..., m) abscissae, ordinates and the points that count.

    Returns:
        (c, ok): (..., 2) coefficients ``(c0, c1)`` and the solvable mask.
    """
    w = mask.astype(float)
    x = np.broadcast_to(x, y.shape)
    R, r = normal_equations(x, w, w * np.where(mask, y, 0.0))
    return solve_2x2(R, r)


def mwplls(x: np.ndarray, ys: np.ndarray, weights: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Modified weighted PLLS (thesis §11.3.2).

    Every point j of every curve i contributes, with cost ``w_ji`` (the surface's amplitude):
    the partial error of curve i is ``e_i = sum_j w_ji (y_ji - c0 - c1 x_i)`` and ``sum_i e_i^2`` is
    minimised, which gives

        R = sum_i (sum_j w_ji)^2 [[1, x_i], [x_i, x_i^2]],
        r = sum_i W_i [1, x_i],   W_i = (sum_j w_ji y_ji)(sum_j w_ji),   c = R^-1 r.

    Args:
        x: (..., m) curve abscissae.
        ys: (..., m, n) or (n,) ordinate of each point of each curve.
        weights: (..., m, n) costs ``w_ji`` (non-negative).
        mask: (..., m) curves that count.

    Returns:
        (c, ok) as :func:`plls`.
    """
    w = np.where(mask[..., None], weights, 0.0)
    sw = w.sum(-1)
    W = (w * ys).sum(-1) * sw
    R, r = normal_equations(np.broadcast_to(x, sw.shape), sw * sw, W)
    return solve_2x2(R, r)


def imwplls(x: np.ndarray, ys: np.ndarray, weights: np.ndarray, mask: np.ndarray, halfwidth: float,
            max_iter: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Iterative MWPLLS (thesis §11.3.3): start from :func:`mwplls`, then refit with only the points
    within ``halfwidth`` (along y) of the current line, until the line stops moving (1e-9) or
    ``max_iter`` refits.

    Returns:
        (c, ok, iterations): as :func:`mwplls`, plus the refits each fit took.
    """
    c, ok = mwplls(x, ys, weights, mask)
    iters = np.zeros(ok.shape, int)
    active = ok.copy()
    xb = np.broadcast_to(x, mask.shape)
    for _ in range(max_iter):
        if not active.any():
            break
        line = c[..., 0, None] + c[..., 1, None] * xb
        near = np.abs(ys - line[..., None]) <= halfwidth
        c_new, ok_new = mwplls(x, ys, np.where(near, weights, 0.0), mask)
        step = active & ok_new
        moved = np.maximum(np.abs(c_new[..., 0] - c[..., 0]), np.abs(c_new[..., 1] - c[..., 1])) > 1e-9
        c = np.where(step[..., None], c_new, c)
        iters = iters + step
        active = step & moved
    return c, ok, np.asarray(iters)


def _mwplls_jax(x, ys, weights, mask):
    """:func:`mwplls` in JAX, for the compiled :func:`imwplls_crest_fit`."""
    w = jnp.where(mask[..., None], weights, 0.0)
    sw = w.sum(-1)
    W = (w * ys).sum(-1) * sw
    a = sw * sw
    ax = a * x
    r00, r01, r11 = a.sum(-1), ax.sum(-1), (ax * x).sum(-1)
    r0, r1 = W.sum(-1), (W * x).sum(-1)
    det = r00 * r11 - r01 * r01
    ok = jnp.abs(det) > SINGULAR * jnp.maximum((jnp.abs(r00) + jnp.abs(r11)) ** 2, 1e-300)
    safe = jnp.where(ok, det, 1.0)
    c = jnp.stack([(r11 * r0 - r01 * r1) / safe, (r00 * r1 - r01 * r0) / safe], -1)
    return jnp.where(ok[..., None], c, 0.0), ok


@functools.partial(jax.jit, static_argnames=("floor", "max_iter"))
def _imwplls_crest(C, shifts, curve_ok, halfwidth, *, floor, max_iter):
    """(links, 3) packed (c0, c1, ok) of :func:`imwplls` over the crest weights of the surfaces ``C``."""
    top = jnp.max(C, axis=-1, keepdims=True)
    weights = jnp.maximum(C - floor * jnp.maximum(top, 0.0), 0.0)  # crest_weights
    x = jnp.arange(C.shape[-2], dtype=float)
    c, ok = _mwplls_jax(x, shifts, weights, curve_ok)

    def refit(carry):
        i, c, active = carry
        near = jnp.abs(shifts - (c[..., 0, None] + c[..., 1, None] * x)[..., None]) <= halfwidth
        c_new, ok_new = _mwplls_jax(x, shifts, jnp.where(near, weights, 0.0), curve_ok)
        step = active & ok_new
        moved = jnp.maximum(jnp.abs(c_new[..., 0] - c[..., 0]), jnp.abs(c_new[..., 1] - c[..., 1])) > 1e-9
        return i + 1, jnp.where(step[..., None], c_new, c), step & moved

    _, c, _ = jax.lax.while_loop(lambda s: (s[0] < max_iter) & s[2].any(), refit, (0, c, ok))
    return jnp.concatenate([c, ok[..., None].astype(float)], -1)


def imwplls_crest_fit(C: np.ndarray, shifts: np.ndarray, curve_ok: np.ndarray, floor: float, halfwidth: float,
                      max_iter: int) -> tuple[np.ndarray, np.ndarray]:
    """:func:`imwplls` of the crest weights of (links, m, n) correlation surfaces ``C`` at displacements
    ``shifts`` (n,), with the curves ``curve_ok``: (c, ok) from one compiled call, the rows padded to
    :func:`padded_rows` sizes (re-acquisition's batches compile a bounded number of times)."""
    L = len(C)
    n = padded_rows(L)
    Cp = np.zeros((n,) + C.shape[1:])
    Cp[:L] = C
    okp = np.zeros((n,) + curve_ok.shape[1:], bool)
    okp[:L] = curve_ok
    out = np.asarray(_imwplls_crest(Cp, np.asarray(shifts, float), okp, float(halfwidth), floor=float(floor),
                                    max_iter=int(max_iter)))[:L]
    return out[:, :2], out[:, 2] > 0
