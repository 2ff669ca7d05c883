"""Reductions over a last axis of two (x, y) or three components, written out component-wise.

NumPy reduces a short last axis with a strided inner loop that costs far more per call than an
elementwise operation on the same array (benchmarks/README.md); these give the same bits (a sum of
two products is the same pair of roundings either way; ``np.linalg.norm`` squares and adds the same).
"""

from __future__ import annotations

import numpy as np

__all__ = ["finite_xy", "finite_last", "dot_xy", "norm_xy", "clip_index", "nan_to_num", "all_last", "along_xy"]


def finite_xy(p: np.ndarray | np.generic) -> np.ndarray | np.generic:
    """``np.all(np.isfinite(p), -1)`` for (..., 2) ``p``."""
    return np.isfinite(p[..., 0]) & np.isfinite(p[..., 1])


def finite_last(p: np.ndarray | np.generic) -> np.ndarray | np.generic:
    """``np.all(np.isfinite(p), -1)`` for any short last axis."""
    out = np.isfinite(p[..., 0])
    for k in range(1, p.shape[-1]):
        out &= np.isfinite(p[..., k])
    return out


def dot_xy(a: np.ndarray, b: np.ndarray) -> np.ndarray | np.generic:
    """``np.sum(a * b, -1)`` for (..., 2) ``a`` and ``b``."""
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1]


def norm_xy(a: np.ndarray) -> np.ndarray | np.generic:
    """``np.linalg.norm(a, axis=-1)`` for real (..., 2) ``a``."""
    return np.sqrt(a[..., 0] * a[..., 0] + a[..., 1] * a[..., 1])


def clip_index(k: np.ndarray, lo: int, hi: int) -> np.ndarray | np.generic:
    """``np.clip`` of integer indices (without its per-call dtype checks)."""
    return np.minimum(np.maximum(k, lo), hi)


def nan_to_num(x) -> np.ndarray | np.generic:
    """``np.nan_to_num(x)`` (a copy), skipping its per-call type inspection when every entry is finite."""
    x = np.asarray(x)
    return x.copy() if np.isfinite(x).all() else np.nan_to_num(x)


def all_last(b: np.ndarray) -> np.ndarray | np.generic:
    """``np.all(b, -1)`` for a short last axis of booleans."""
    out = b[..., 0].copy()
    for k in range(1, b.shape[-1]):
        out &= b[..., k]
    return out


def along_xy(origin: np.ndarray, step: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """``origin + step[..., None] * direction`` for (..., 2) ``origin`` and ``direction``, filled per
    component (broadcasting over a last axis of 2 runs NumPy's inner loop 2 wide; the same bits)."""
    shape = np.broadcast_shapes(origin.shape[:-1], np.shape(step), direction.shape[:-1])
    out = np.empty(shape + (2,))
    for c in range(2):
        np.add(origin[..., c], step * direction[..., c], out=out[..., c])
    return out
