"""Pills (the convex hull of two end circles) in the image: their simplified outline polygons, their
parameters as a table, and the exact distance of points from their edge, which decides most
point-in-outline questions without shapely (thesis §4.3.3's outlines, fig. 4.13)."""

from __future__ import annotations

import functools

import numpy as np
import shapely

from ._config import VisibilityConfig
from ._xy import dot_xy, finite_xy

__all__ = ["EMPTY", "pill_distance", "decide_band", "pill_outlines", "pill_table"]

# One empty polygon for every empty outline (geometries are immutable; building one parses WKT).
EMPTY = shapely.Polygon()
# Distances within this (px) of a bound are left to shapely (rounding of the distance itself).
_BAND_EPS = 1e-6
# Plain Douglas-Peucker results with at most this many coordinates are redone topology-preserving
# (the two differ only below 7; a margin).
_FEW_COORDS = 8


def pill_distance(x: np.ndarray, y: np.ndarray, pills: np.ndarray) -> np.ndarray:
    """Distance of points (x, y) from the edge of pills (negative inside; about 1e12 for an empty one).

    A pill is the convex hull of its two end circles, the union of the circles centred on the
    segment with the radius interpolated linearly, so the distance is the minimum over t of
    ``|p - c(t)| - r(t)``, a convex function of t minimised in closed form.

    Args:
        x, y: point coordinates, broadcasting against ``pills[..., 0]``.
        pills: (..., 11) :attr:`Visibility.pills`.
    """
    wx, wy = x - pills[..., 0], y - pills[..., 1]
    dx, dy = pills[..., 2], pills[..., 3]
    h = wx * dy
    h -= wy * dx
    np.abs(h, out=h)
    h *= pills[..., 8] * pills[..., 6]
    t = wx * dx
    t += wy * dy
    t *= pills[..., 7]
    t += h
    t = np.minimum(np.maximum(t, 0.0, out=t), 1.0, out=t)
    # The distance to the nearest circle's centre; sqrt of the sum of squares, not np.hypot (several
    # times slower): the two differ in the last bit, far inside the band that shapely decides.
    ex, ey = wx - t * dx, wy - t * dy
    ex *= ex
    ey *= ey
    ex += ey
    d = np.sqrt(ex, out=ex)
    d -= pills[..., 4] + t * pills[..., 5]
    if pills[..., 10].any():  # one end circle holds the other (or a point-like segment): the larger one
        ends = np.minimum(np.hypot(wx, wy) - pills[..., 4], np.hypot(wx - dx, wy - dy) - pills[..., 4] - pills[..., 5])
        d = np.where(pills[..., 10] > 0, ends, d)
    return d


def decide_band(d: np.ndarray, lo, hi, exact) -> np.ndarray:
    """``d < lo``: inside; ``d > hi``: outside; in between (within ``_BAND_EPS``) ``exact(*index)``."""
    inside = d < lo - _BAND_EPS
    band = (d <= hi + _BAND_EPS) & ~inside
    if band.any():
        index = np.nonzero(band)
        inside[index] = exact(*index)
    return inside


def pill_outlines(start_px: np.ndarray, end_px: np.ndarray, radius_start: np.ndarray, radius_end: np.ndarray,
                  arc_points: int, simplify_px: float) -> np.ndarray:
    """Convex hulls of the projected pills, simplified (thesis figs. 4.13-4.14).

    Args:
        start_px, end_px: (links, 2) projected link ends.
        radius_start, radius_end: (links,) radius in pixels at each end.
        arc_points: vertices per half circle.
        simplify_px: simplification tolerance.

    Returns:
        (links,) polygons; links with non-finite input or zero radius give empty polygons.
    """
    circle = _unit_circle(2 * arc_points)  # (k, 2)
    s = np.asarray(start_px, float)
    e = np.asarray(end_px, float)
    rs = np.asarray(radius_start, float)
    re = np.asarray(radius_end, float)
    ok = (finite_xy(s) & finite_xy(e) & np.isfinite(rs) & np.isfinite(re)
          & (rs > 0) & (re > 0))
    k = len(circle)
    cloud = np.empty((len(s), 2 * k, 2))   # start + r u_j, then end + r u_j, filled in place
    np.multiply(rs[:, None, None], circle, out=cloud[:, :k])
    np.multiply(re[:, None, None], circle, out=cloud[:, k:])
    cloud[:, :k] += s[:, None]
    cloud[:, k:] += e[:, None]
    if not ok.all():
        cloud[~ok] = 0.0
    # GEOS takes the hull of the coordinates in their order whatever the geometry type; a line
    # string is built straight from the array (a multipoint first makes one Point per vertex).
    hulls = shapely.convex_hull(shapely.linestrings(cloud))
    if simplify_px > 0:
        hulls = _simplify_convex(hulls, simplify_px)
    return np.where(ok, hulls, EMPTY) if not ok.all() else hulls


def _simplify_convex(hulls: np.ndarray, tolerance: float) -> np.ndarray:
    """``shapely.simplify(hulls, tolerance)`` (topology-preserving) for convex polygons: on a convex
    ring GEOS's plain Douglas-Peucker keeps the same vertices, starting the ring elsewhere, several
    times faster; only where it shrinks a ring to a few vertices (the topology-preserving simplifier
    keeps a minimum) is the topology-preserving result taken (tests/test_image_speed.py)."""
    simple = shapely.simplify(hulls, tolerance, preserve_topology=False)
    few = shapely.get_num_coordinates(simple) <= _FEW_COORDS
    if few.any():
        simple[few] = shapely.simplify(hulls[few], tolerance)
    return simple


@functools.lru_cache(maxsize=8)
def _unit_circle(k: int) -> np.ndarray:
    """(k, 2) points evenly spaced on the unit circle, from angle 0 (kept per k, read-only)."""
    a = 2 * np.pi * np.arange(k) / k
    circle = np.stack([np.cos(a), np.sin(a)], -1)
    circle.setflags(write=False)
    return circle


def pill_table(start_px, end_px, radius_start, radius_end, config: VisibilityConfig) -> np.ndarray:
    """(links, 11) :attr:`Visibility.pills`. The outline's hull vertices lie on the end circles, so
    its edges cut into the pill by at most the chord depth ``r (1 - cos(pi / (2 arc_points)))``,
    and the simplification moves them in by at most ``simplify_px`` more: the slack."""
    s, e = np.asarray(start_px, float), np.asarray(end_px, float)
    rs, re = np.asarray(radius_start, float), np.asarray(radius_end, float)
    ok = finite_xy(s) & finite_xy(e) & np.isfinite(rs) & np.isfinite(re) & (rs > 0) \
        & (re > 0)
    if not ok.all():
        far = np.array([1e12, 1e12])  # an empty pill: far from every point
        s, e = np.where(ok[:, None], s, far), np.where(ok[:, None], e, far)
        rs, re = np.where(ok, rs, 0.0), np.where(ok, re, 0.0)
    out = np.empty((len(s), 11))  # filled column by column (no np.stack)
    out[:, 0:2] = s
    d = np.subtract(e, s, out=out[:, 2:4])
    out[:, 4] = rs
    dr = np.subtract(re, rs, out=out[:, 5])
    L2 = dot_xy(d, d)
    steep2 = L2 - dr * dr
    ends = ~(steep2 > 0)
    # Guard: the ends' rows divide by 1 and are then zeroed (no warnings to silence).
    inv_len = 1.0 / np.sqrt(np.where(ends, 1.0, L2))
    out[:, 6] = np.where(ends, 0.0, inv_len)
    out[:, 7] = np.where(ends, 0.0, 1.0 / np.where(ends, 1.0, L2))
    out[:, 8] = np.where(ends, 0.0, dr * inv_len / np.sqrt(np.where(ends, 1.0, steep2)))
    out[:, 9] = np.maximum(rs, re) * (1.0 - np.cos(np.pi / (2 * config.arc_points))) + config.simplify_px
    if not ok.all():
        out[~ok, 9] = 0.0
    out[:, 10] = ends
    return out
