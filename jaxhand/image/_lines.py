"""Line fitting (thesis §4.4): boundary lines by deterministic RANSAC and PCA, the axial line from
two boundary lines, the single-boundary fallback (DigitEyes §4), and (a, b, rho) conversion.

Everything is vectorised over leading axes (all links, both boundaries, at once).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from ._xy import dot_xy

__all__ = ["ransac_pca", "axial_line", "offset_towards", "line_params", "line_point_direction", "ransac_pca_jnp",
           "axial_line_jnp", "offset_towards_jnp", "line_params_jnp", "dot_jnp"]


def ransac_pca(points: np.ndarray, valid: np.ndarray, tau_px: float, min_inliers: int
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Fit a line to each group of points: exhaustive RANSAC over all pairs, then PCA of the inliers.

    Every pair of valid, distinct points defines a line; a point is an inlier of it when its
    Euclidean distance is below ``tau_px``. The pair with the most inliers wins (the first such
    pair in the order (0, 1), (0, 2), ..., (1, 2), ... on ties, so the result is deterministic), and
    its inliers are refined by PCA: the line passes through their centre of mass along the main
    axis of their 2x2 covariance (total least squares).

    Args:
        points: (..., m, 2) points of each group.
        valid: (..., m) which points take part.
        tau_px: inlier distance.
        min_inliers: fewest inliers (>= 2) for a line.

    Returns:
        (p, v, ok, inliers): a point (..., 2) and a unit direction (..., 2) of each line, whether the
        group gave a line, and (..., m) the inlier mask (all False where not ok). Where not ok,
        ``p`` and ``v`` are finite dummies.
    """
    pts = np.asarray(points, float)
    valid = np.asarray(valid, bool)
    if pts.shape[-2] < 2:   # no pair: no line
        zeros = np.zeros(pts.shape[:-2] + (2,))
        return zeros, zeros + [1.0, 0.0], np.zeros(pts.shape[:-2], bool), np.zeros(valid.shape, bool)
    return tuple(np.asarray(a) for a in _ransac_pca(pts, valid, float(tau_px), int(min_inliers)))


def axial_line(p1: np.ndarray, v1: np.ndarray, p2: np.ndarray, v2: np.ndarray, det_eps: float = 1e-9
               ) -> tuple[np.ndarray, np.ndarray]:
    """The axial line between two boundary lines (thesis §4.4, eqs. 4.2-4.4, fig. 4.22).

    Direction: with unit ``v1`` and ``v2``, ``v_ax = (v1 + v2) / 2`` if ``|v1 + v2| >= |v1 - v2|``, else
    ``(v1 - v2) / 2``: the bisector making the smaller angle with both lines (normalised here).
    Point: the intersection ``p1 + k1 v1 = p2 + k2 v2``, from ``k = V^-1 (p2 - p1)`` with
    ``V = [v1, -v2]``, when ``|det V| > det_eps``; otherwise the lines count as parallel and the
    point is the midpoint ``(p1 + p2) / 2`` (eq. 4.4).

    Args:
        p1, v1, p2, v2: (..., 2) a point and a unit direction of each boundary line.
        det_eps: the parallelism threshold on ``|det V|`` (the thesis uses 1e-9).

    Returns:
        (p_ax, v_ax): a point on the axial line and its unit direction.
    """
    args = (np.asarray(a, float) for a in (p1, v1, p2, v2))
    return tuple(np.asarray(a) for a in _axial_line(*args, float(det_eps)))


def offset_towards(p: np.ndarray, v: np.ndarray, target: np.ndarray, distance: np.ndarray) -> np.ndarray:
    """Move a line (point ``p``, unit direction ``v``) by ``distance`` along its normal, towards the side
    where ``target`` lies (DigitEyes §4: a single boundary offset by the radius towards the axis)."""
    return np.asarray(_offset_towards(*(np.asarray(a, float) for a in (p, v, target, distance))))


def line_params(p: np.ndarray, v: np.ndarray, reference: np.ndarray | None = None) -> np.ndarray:
    """(a, b, rho) of the line through ``p`` along ``v``: unit normal ``(a, b) = (v_y, -v_x)`` and
    ``rho = a p_x + b p_y``, so ``a x + b y = rho`` on the line.

    With ``reference`` (..., 2), ``v`` is first flipped to point the same way as it, so the normal
    matches :func:`jaxhand.features.line_through` of a segment running along ``reference``.
    """
    v = np.asarray(v, float)
    if reference is not None:
        v = np.where((dot_xy(v, reference) < 0)[..., None], -v, v)
    return np.asarray(_line_params(np.asarray(p, float), v))


def line_point_direction(lines: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A point (the foot of the perpendicular from the origin) and the direction of (a, b, rho) lines;
    the direction is the one :func:`line_params` turns back into the same normal."""
    n = lines[..., :2]
    return n * lines[..., 2:3], np.stack([-n[..., 1], n[..., 0]], -1)


# The traced kernels: the one implementation of these rules, also inside the compiled line fit
# (:mod:`._linefit`); the functions above are their NumPy faces.

def _principal(sxx, sxy, syy):
    """Unit eigenvector of the largest eigenvalue of [[sxx, sxy], [sxy, syy]], in closed form: the
    row of ``C - lambda_min I`` without cancellation ((1, 0) where the matrix is a multiple of I)."""
    half = 0.5 * (sxx - syy)
    root = jnp.sqrt(half * half + sxy * sxy)
    wide = half >= 0  # the x spread dominates: (lambda - syy, sxy) has no cancellation
    vx = jnp.where(wide, half + root, sxy)
    vy = jnp.where(wide, sxy, root - half)
    n = jnp.sqrt(vx * vx + vy * vy)
    ok = n > 0
    safe = jnp.where(ok, n, 1.0)
    return jnp.where(ok, vx / safe, 1.0), jnp.where(ok, vy / safe, 0.0)


def ransac_pca_jnp(pts, valid, tau_px, min_inliers):
    """The traced :func:`ransac_pca` for (..., m, 2) points with m >= 2."""
    m = pts.shape[-2]
    pts = jnp.where(valid[..., None], pts, 0.0)
    i, j = np.triu_indices(m, k=1)
    P = len(i)
    x, y = pts[..., 0], pts[..., 1]
    # Both ends of every pair in one gather: XLA's CPU runtime runs independent gathers side by side
    # on its worker threads, and handing them over cost more than the gathers (benchmarks/README.md).
    ends = jnp.stack([x, y, valid.astype(x.dtype)], -2)[..., np.concatenate([i, j])]  # (..., 3, 2 pairs)
    xi, yi, xj, yj = ends[..., 0, :P], ends[..., 1, :P], ends[..., 0, P:], ends[..., 1, P:]
    dx, dy = xj - xi, yj - yi
    norm = jnp.sqrt(dx * dx + dy * dy)
    pair_ok = (ends[..., 2, :P] > 0) & (ends[..., 2, P:] > 0) & (norm > 1e-9)
    safe = jnp.where(pair_ok, norm, 1.0)
    nx, ny = -dy / safe, dx / safe
    proj = nx[..., :, None] * x[..., None, :] + ny[..., :, None] * y[..., None, :]
    dist = jnp.abs(proj - (nx * xi + ny * yi)[..., None])
    inl = (dist < tau_px) & valid[..., None, :] & pair_ok[..., None]
    best = jnp.argmax(inl.sum(-1), -1)  # the first pair of the most inliers
    inliers = jnp.take_along_axis(inl, best[..., None, None], -2)[..., 0, :]
    ok = inliers.sum(-1) >= max(2, min_inliers)
    inliers = inliers & ok[..., None]
    w = inliers.astype(float)
    cnt = jnp.maximum(w.sum(-1), 1.0)
    mx, my = (w * x).sum(-1) / cnt, (w * y).sum(-1) / cnt
    cx, cy = x - mx[..., None], y - my[..., None]
    vx, vy = _principal((w * cx * cx).sum(-1) / cnt, (w * cx * cy).sum(-1) / cnt, (w * cy * cy).sum(-1) / cnt)
    p = jnp.stack([jnp.where(ok, mx, 0.0), jnp.where(ok, my, 0.0)], -1)
    v = jnp.stack([jnp.where(ok, vx, 1.0), jnp.where(ok, vy, 0.0)], -1)
    return p, v, ok, inliers


def dot_jnp(a, b):
    """Row-wise dot products of (..., 2) arrays."""
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1]


def axial_line_jnp(p1, v1, p2, v2, det_eps):
    """The traced :func:`axial_line`."""
    plus, minus = v1 + v2, v1 - v2
    v = jnp.where((jnp.sqrt(dot_jnp(plus, plus)) >= jnp.sqrt(dot_jnp(minus, minus)))[..., None], plus, minus) / 2
    nv = jnp.sqrt(dot_jnp(v, v))[..., None]
    v = v / jnp.where(nv > 0, nv, 1.0)
    det = v1[..., 1] * v2[..., 0] - v1[..., 0] * v2[..., 1]
    cross = jnp.abs(det) > det_eps
    dp = p2 - p1
    k1 = (dp[..., 1] * v2[..., 0] - dp[..., 0] * v2[..., 1]) / jnp.where(cross, det, 1.0)
    return jnp.where(cross[..., None], p1 + k1[..., None] * v1, (p1 + p2) / 2), v


def line_params_jnp(p, v):
    """The traced :func:`line_params` without a reference."""
    nv = jnp.sqrt(dot_jnp(v, v))[..., None]
    v = v / jnp.where(nv > 0, nv, 1.0)
    n = jnp.stack([v[..., 1], -v[..., 0]], -1)
    return jnp.concatenate([n, dot_jnp(n, p)[..., None]], -1)


def offset_towards_jnp(p, v, target, distance):
    """The traced :func:`offset_towards`."""
    n = jnp.stack([-v[..., 1], v[..., 0]], -1)
    side = jnp.sign(dot_jnp(target - p, n))
    return p + (jnp.where(side == 0, 1.0, side) * distance)[..., None] * n


_ransac_pca = jax.jit(ransac_pca_jnp, static_argnums=(2, 3))
_axial_line = jax.jit(axial_line_jnp, static_argnums=4)
_offset_towards = jax.jit(offset_towards_jnp)
_line_params = jax.jit(line_params_jnp)
