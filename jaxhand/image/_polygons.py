"""Point-in-polygon tests for convex polygons in NumPy (the pill outlines are simplified convex
hulls), with shapely deciding the points within rounding of an edge and any non-convex input."""

from __future__ import annotations

import numpy as np
import shapely

from ._xy import finite_xy

__all__ = ["convex_edges", "inside_polygons"]


def convex_edges(polygons: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Edges of convex polygons padded to one length, oriented so the interior lies to the left.

    Returns:
        (start, vector, present): (n, V, 2) edge starts and vectors (padding repeats edge 0), and
        (n,) the polygon is non-empty; None when a polygon is neither empty nor a convex polygon
        without holes (then the caller falls back to shapely).
    """
    geoms = np.asarray(polygons, dtype=object).reshape(-1)
    n = len(geoms)
    present = ~shapely.is_empty(geoms)
    if not present.any():
        return np.zeros((n, 1, 2)), np.zeros((n, 1, 2)), present
    if np.any(shapely.get_type_id(geoms[present]) != 3) or np.any(shapely.get_num_interior_rings(geoms[present]) > 0):
        return None
    coords, index = shapely.get_coordinates(shapely.get_exterior_ring(geoms), return_index=True)
    counts = np.bincount(index, minlength=n) - 1  # rings are closed: edges = coordinates - 1
    if np.any(counts[present] < 3):
        return None
    V = int(counts.max())
    first = np.concatenate([[0], np.cumsum(counts + 1)[:-1]])
    k = np.arange(V)
    # Edge k of polygon i runs from coordinate first[i] + k to first[i] + k + 1; padding repeats edge 0.
    kk = np.where(k[None, :] < counts[:, None], k[None, :], 0)
    a_idx = np.where(present[:, None], first[:, None] + kk, 0)
    a = coords[a_idx]
    e = coords[np.where(present[:, None], a_idx + 1, 0)] - a
    # Orientation from the signed area; a clockwise ring is flipped to counter-clockwise.
    cross_ae = a[..., 0] * e[..., 1] - a[..., 1] * e[..., 0]
    valid_edge = k[None, :] < counts[:, None]
    area2 = np.where(valid_edge, cross_ae, 0.0).sum(-1)
    if np.any(area2[present] == 0):
        return None
    sign = np.where(area2 < 0, -1.0, 1.0)[:, None, None]
    # Convex: every turn between consecutive edges, in the ring's own order, is to the side of
    # its orientation (or straight, within rounding: a point near such a vertex is within the
    # callers' tolerance of both edges' lines and is decided by shapely).
    nxt = np.roll(e, -1, axis=1)
    nxt = np.where((k[None, :] == counts[:, None] - 1)[..., None], e[:, :1], nxt)
    turn = sign[..., 0] * (e[..., 0] * nxt[..., 1] - e[..., 1] * nxt[..., 0])
    slack = 1e-12 * np.linalg.norm(e, axis=-1) * np.linalg.norm(nxt, axis=-1)
    if np.any((turn < -slack) & valid_edge & present[:, None]):
        return None
    a = np.where(sign < 0, a + e, a)
    e = e * sign
    return a, e, present


def inside_polygons(polygons: np.ndarray, points: np.ndarray, *, tol: float = 1e-9, edges=False) -> np.ndarray:
    """(..., n) True where each point lies strictly inside each of ``n`` convex polygons.

    The same predicate as ``shapely.contains_xy`` (boundary points are outside, NaN points are
    outside every polygon), computed in NumPy from edge cross products for convex polygons
    (pill outlines are simplified convex hulls); points within ``tol`` (relative) of an edge line
    and non-convex input are decided by shapely itself.

    Args:
        polygons: (n,) polygons (empty ones contain nothing).
        points: (..., 2) positions (x, y).
        edges: ``convex_edges(polygons)`` when already computed (False: compute them here).
    """
    geoms = np.asarray(polygons, dtype=object).reshape(-1)
    pts = np.asarray(points, float)
    lead = pts.shape[:-1]
    flat = pts.reshape(-1, 2)
    finite = finite_xy(flat)
    x = np.where(finite, flat[:, 0], 0.0)
    y = np.where(finite, flat[:, 1], 0.0)
    edges = convex_edges(geoms) if edges is False else edges
    if edges is None:
        # Only the pairs whose point lies within the polygon's bounding box are asked of shapely;
        # a point outside it is outside the polygon (and an empty polygon's NaN box holds none).
        b = shapely.bounds(geoms)
        cand = ((x[:, None] >= b[None, :, 0]) & (x[:, None] <= b[None, :, 2]) & (y[:, None] >= b[None, :, 1])
                & (y[:, None] <= b[None, :, 3]) & finite[:, None])
        out = np.zeros(cand.shape, bool)
        p, g = np.nonzero(cand)
        if len(p):
            shapely.prepare(geoms)
            out[p, g] = shapely.contains_xy(geoms[g], x[p], y[p])
        return out.reshape(lead + (len(geoms),))
    a, e, present = edges
    # cross(e, p - a) > 0 on the interior side of every edge: (points, n, V).
    c = (e[None, :, :, 0] * (y[:, None, None] - a[None, :, :, 1])
         - e[None, :, :, 1] * (x[:, None, None] - a[None, :, :, 0]))
    m = c.min(-1)
    out = (m > 0) & present[None, :] & finite[:, None]
    # Near an edge, rounding could differ from GEOS's robust predicate: ask shapely there.
    extent = np.abs(a).max((1, 2))[None, :] + 1.0
    scale = np.abs(e).max((1, 2))[None, :] * (np.abs(x)[:, None] + np.abs(y)[:, None] + extent)
    near = (np.abs(m) <= tol * scale) & present[None, :] & finite[:, None]
    if near.any():
        p, g = np.nonzero(near)
        shapely.prepare(geoms)
        out[p, g] = shapely.contains_xy(geoms[g], x[p], y[p])
    return out.reshape(lead + (len(geoms),))

