"""Step 5's numbers (:func:`._view.fit_links`) as one compiled function: RANSAC + PCA of both boundaries,
the axial line, the single-boundary fallback and each link's validity, the same steps as
:mod:`._lines` (thesis §4.4, DigitEyes §4) in one call instead of many small NumPy ones.

Every result comes back packed in one float array, converted to NumPy once. Rows are padded to a
few sizes so re-acquisition's batches of other row counts compile a bounded number of times.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

from ._lines import axial_line_jnp, dot_jnp, line_params_jnp, offset_towards_jnp, ransac_pca_jnp

__all__ = ["fit_rows", "padded_rows"]


def padded_rows(n: int) -> int:
    """The row count ``n`` is padded to: the next power of two from 16 (one compilation per size)."""
    return max(16, 1 << (max(n, 1) - 1).bit_length())


@functools.partial(jax.jit, static_argnames=("tau_px", "min_inliers", "det_eps", "single_edge", "min_visible",
                                             "weight_by_visibility", "single_edge_weight"))
def _fit(edge_px, edge_ok, rows, *, tau_px, min_inliers, det_eps, single_edge, min_visible, weight_by_visibility,
         single_edge_weight):
    """(links, 19 + 2 samplers) packed :class:`._view.LineFit` fields of one padded batch; ``rows`` holds
    the axis midpoint (2), radius, direction (2), sampler validity and visible share of each link."""
    pts = jnp.swapaxes(jnp.where(edge_ok[..., None], edge_px, 0.0), 1, 2)  # (links, 2, samplers, 2)
    p, v, ok, inliers = ransac_pca_jnp(pts, jnp.swapaxes(edge_ok, 1, 2), tau_px, min_inliers)
    mid, radius, direction, s_ok, share = rows[:, 0:2], rows[:, 2], rows[:, 3:5], rows[:, 5] > 0, rows[:, 6]
    both = ok[:, 0] & ok[:, 1]
    p_ax, v_ax = axial_line_jnp(p[:, 0], v[:, 0], p[:, 1], v[:, 1], det_eps)
    single = (ok[:, 0] ^ ok[:, 1]) & single_edge
    p_one = jnp.where(ok[:, :1], p[:, 0], p[:, 1])
    v_one = jnp.where(ok[:, :1], v[:, 0], v[:, 1])
    p_one = offset_towards_jnp(p_one, v_one, mid, radius)  # towards the predicted axis
    p_ax = jnp.where(single[:, None], p_one, p_ax)
    v_ax = jnp.where(single[:, None], v_one, v_ax)
    v_ax = jnp.where((dot_jnp(v_ax, direction) < 0)[:, None], -v_ax, v_ax)  # point from start to end
    lines = line_params_jnp(p_ax, v_ax)
    valid = s_ok & (both | single) & (share >= min_visible) & jnp.isfinite(lines).all(-1)
    weight = (share if weight_by_visibility else jnp.ones_like(share)) * jnp.where(single, single_edge_weight, 1.0)
    lines = jnp.where(valid[:, None], lines, jnp.array([1.0, 0.0, 0.0]))
    L = len(lines)
    parts = [lines, valid[:, None], jnp.where(valid, weight, 0.0)[:, None], line_params_jnp(p, v).reshape(L, 6), ok,
             inliers.reshape(L, -1), (single & valid)[:, None], p_ax, v_ax]
    return jnp.concatenate([a.astype(float) for a in parts], -1)


def fit_rows(edge_px: np.ndarray, edge_ok: np.ndarray, mid: np.ndarray, radius_px: np.ndarray,
             direction: np.ndarray, sampler_ok: np.ndarray, share: np.ndarray, lc) -> dict[str, np.ndarray]:
    """:func:`._view.fit_links`'s fields for (links, samplers, 2, 2) boundary points ``edge_px`` (finite
    where ``edge_ok``), each link's predicted axis midpoint, radius and direction, sampler validity and
    visible share, with :class:`LineConfig` ``lc``; the rows padded and the result unpacked."""
    L, S = edge_ok.shape[:2]
    n = padded_rows(L)
    px = np.zeros((n, S, 2, 2))
    px[:L] = edge_px
    ok = np.zeros((n, S, 2), bool)
    ok[:L] = edge_ok
    rows = np.zeros((n, 7))
    rows[:L, 0:2], rows[:L, 2], rows[:L, 3:5], rows[:L, 5], rows[:L, 6] = mid, radius_px, direction, sampler_ok, share
    out = np.asarray(_fit(px, ok, rows, tau_px=float(lc.tau_px), min_inliers=int(lc.min_inliers),
                          det_eps=float(lc.det_eps), single_edge=bool(lc.single_edge),
                          min_visible=float(lc.min_visible), weight_by_visibility=bool(lc.weight_by_visibility),
                          single_edge_weight=float(lc.single_edge_weight)))[:L]
    k = 13 + 2 * S
    return dict(lines=out[:, 0:3], valid=out[:, 3] > 0, weight=out[:, 4], boundary=out[:, 5:11].reshape(L, 2, 3),
                bvalid=out[:, 11:13] > 0, inliers=out[:, 13:k].reshape(L, 2, S) > 0, single=out[:, k] > 0,
                p_ax=out[:, k + 1:k + 3], v_ax=out[:, k + 3:k + 5])
