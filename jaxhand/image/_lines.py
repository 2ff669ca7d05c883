"""Line fitting (thesis §4.4): boundary lines by deterministic RANSAC and PCA, the axial line from
two boundary lines, the single-boundary fallback (DigitEyes §4), and (a, b, rho) conversion.

Everything is vectorised over leading axes (all links, both boundaries, at once).
"""

from __future__ import annotations

import functools

import numpy as np

from ._xy import dot_xy, norm_xy

__all__ = ["ransac_pca", "axial_line", "offset_towards", "line_params", "line_point_direction"]


def ransac_pca(points: np.ndarray, valid: np.ndarray, tau_px: float, min_inliers: int
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Fit a line to each group of points: exhaustive RANSAC over all pairs, then PCA of the inliers.

    Every pair of valid, distinct points defines a line; a point is an inlier of it when its
    Euclidean distance is below ``tau_px``. The pair with the most inliers wins (the first such
    pair in the order (0, 1), (0, 2), ..., (1, 2), ... on ties, so the result is deterministic), and
    its inliers are refined by PCA: the line passes through their centre of mass along the
    eigenvector of their 2x2 covariance with the largest eigenvalue (total least squares).

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
    pts = np.where(valid[..., None], np.asarray(points, float), 0.0)
    m = pts.shape[-2]
    i, j = _pairs(m)  # every pair, in a fixed order
    d = pts[..., j, :] - pts[..., i, :]  # (..., P, 2)
    norm = norm_xy(d)
    pair_ok = valid[..., i] & valid[..., j] & (norm > 1e-9)
    nrm = np.stack([-d[..., 1], d[..., 0]], -1) / np.where(pair_ok, norm, 1.0)[..., None]
    # distance of every point to every pair's line: (..., P, m)
    # (the same products and sum as einsum("...pk,...mk->...pm"), without its per-call parsing)
    proj = nrm[..., :, None, 0] * pts[..., None, :, 0] + nrm[..., :, None, 1] * pts[..., None, :, 1]
    dist = np.abs(proj - dot_xy(nrm, pts[..., i, :])[..., None])
    inl = (dist < tau_px) & valid[..., None, :] & pair_ok[..., None]
    counts = inl.sum(-1) if m > 1 else np.zeros(pts.shape[:-2] + (0,), int)
    if counts.shape[-1] == 0:
        zeros = np.zeros(pts.shape[:-2] + (2,))
        return zeros, zeros + [1.0, 0.0], np.zeros(pts.shape[:-2], bool), np.zeros(valid.shape, bool)
    best = np.argmax(counts, -1)
    P = inl.shape[-2]
    inliers = inl.reshape(-1, P, m)[np.arange(best.size), best.reshape(-1)].reshape(valid.shape)  # the best pair's
    n_in = inliers.sum(-1)
    ok = n_in >= max(2, min_inliers)
    inliers = inliers & ok[..., None]
    w = inliers.astype(float)
    cnt = np.maximum(w.sum(-1), 1.0)[..., None]
    mu = np.sum(w[..., None] * pts, -2) / cnt
    c = (pts - mu[..., None, :]) * w[..., None]
    cov = np.einsum("...mi,...mj->...ij", c, pts - mu[..., None, :]) / cnt[..., None]
    cov = np.where(ok[..., None, None], cov, np.eye(2))  # Guard: dummy covariance where there is no line.
    _, vecs = np.linalg.eigh(cov)
    v = vecs[..., :, 1]  # eigh sorts eigenvalues ascending: the last column is the main direction
    return np.where(ok[..., None], mu, 0.0), np.where(ok[..., None], v, [1.0, 0.0]), np.asarray(ok), inliers


@functools.lru_cache(maxsize=8)
def _pairs(m: int) -> tuple[np.ndarray, np.ndarray]:
    """``np.triu_indices(m, k=1)``, kept per group size (read-only)."""
    i, j = np.triu_indices(m, k=1)
    i.setflags(write=False)
    j.setflags(write=False)
    return i, j


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
    plus, minus = v1 + v2, v1 - v2
    use_plus = norm_xy(plus) >= norm_xy(minus)
    v = np.where(use_plus[..., None], plus, minus) / 2
    nv = norm_xy(v)[..., None]
    v = v / np.where(nv > 0, nv, 1.0)  # |v1 + v2| >= sqrt(2) for the chosen sign, so nv > 0 for unit input
    det = v1[..., 0] * (-v2[..., 1]) - (-v2[..., 0]) * v1[..., 1]
    cross = np.abs(det) > det_eps
    safe = np.where(cross, det, 1.0)  # Guard: near-parallel lines use the midpoint instead.
    dp = p2 - p1
    k1 = (dp[..., 0] * (-v2[..., 1]) - (-v2[..., 0]) * dp[..., 1]) / safe
    p_int = p1 + k1[..., None] * v1
    return np.where(cross[..., None], p_int, (p1 + p2) / 2), v


def offset_towards(p: np.ndarray, v: np.ndarray, target: np.ndarray, distance: np.ndarray) -> np.ndarray:
    """Move a line (point ``p``, unit direction ``v``) by ``distance`` along its normal, towards the side
    where ``target`` lies (DigitEyes §4: a single boundary offset by the radius towards the axis)."""
    n = np.stack([-v[..., 1], v[..., 0]], -1)
    side = np.sign(dot_xy(target - p, n))
    side = np.where(side == 0, 1.0, side)
    return p + (side * distance)[..., None] * n


def line_params(p: np.ndarray, v: np.ndarray, reference: np.ndarray | None = None) -> np.ndarray:
    """(a, b, rho) of the line through ``p`` along ``v``: unit normal ``(a, b) = (v_y, -v_x)`` and
    ``rho = a p_x + b p_y``, so ``a x + b y = rho`` on the line.

    With ``reference`` (..., 2), ``v`` is first flipped to point the same way as it, so the normal
    matches :func:`jaxhand.features.line_through` of a segment running along ``reference``.
    """
    v = np.asarray(v, float)
    if reference is not None:
        v = np.where((dot_xy(v, reference) < 0)[..., None], -v, v)
    nv = norm_xy(v)[..., None]
    v = v / np.where(nv > 0, nv, 1.0)
    n = np.stack([v[..., 1], -v[..., 0]], -1)
    return np.concatenate([n, dot_xy(n, p)[..., None]], -1)


def line_point_direction(lines: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A point (the foot of the perpendicular from the origin) and the direction of (a, b, rho) lines;
    the direction is the one :func:`line_params` turns back into the same normal."""
    n = lines[..., :2]
    return n * lines[..., 2:3], np.stack([-n[..., 1], n[..., 0]], -1)
