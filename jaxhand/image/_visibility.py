"""Visibility ordering and window functions (thesis §4.3.3, figs. 4.12-4.18).

Each link's pill is outlined in the image as the convex hull of its two end circles (the
projected hemisphere outlines; equal radii give a stadium, a perspective camera gives each end its
own radius), simplified (Douglas-Peucker). Every pill gets the mean depth of its two ends, and
every pill is cut where nearer pills cover it (Boolean difference, shapely), which leaves the
truncated polygons of fig. 4.17. Phalanges of one finger (links on one kinematic chain) never cut
each other, as in the thesis. The window function of a profile is 1 where its samples fall inside
its link's window polygon: the link's outline grown by ``window_pad`` radii (a strip of
background), less the nearer pills grown by ``occluder_margin_px``. The polygons (for the visible
shares and overlays) come from shapely 2's vectorised array functions; which samples lie inside a
window is decided from each point's distance to the pills themselves, which bound the polygons
from both sides, and by shapely only for the few points between those bounds.
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np
import shapely

from ._config import VisibilityConfig
from ._xy import dot_xy, finite_xy, nan_to_num

__all__ = ["Visibility", "pill_outlines", "same_chain", "compute_visibility", "window_masks", "convex_edges",
           "inside_polygons"]


@dataclasses.dataclass(frozen=True)
class Visibility:
    """The visibility of every link in one view.

    Attributes:
        outlines: (links,) shapely polygons, the simplified convex hull of each projected pill.
        depth: (links,) mean depth of each pill (mm; larger is farther).
        order: (links,) link indices from the farthest to the nearest (thesis fig. 4.15).
        visible: (links,) truncated polygons: outline less the nearer pills of other chains.
        visible_share: (links,) area of the truncated polygon inside the image over the outline's
            area (0 for an empty outline).
        pad_px: (links,) how far each outline is grown for its window (``window_pad`` radii).
        nearer: (links, pills) the pills that cut each link's window (all False: none, or no
            occlusion); its columns index ``covers``.
        covers: (pills,) the occluding pills grown by ``occluder_margin_px`` (built only for the
            pills that can cut a window, None for the others, which no row of ``nearer`` names).
        cut: whether windows are cut at all (occlusion on, more than one link).
        pills: (links, 11) each pill as start (x, y), end - start, start radius, end - start
            radius, 1 / length, 1 / length², the cone's slope term, the slack (px) by which its
            simplified outline may lie inside the pill, and whether one end circle holds the
            other (:func:`pill_distance`); an empty outline's pill lies far off the image.
        cover_pills: (pills, 7) the same for ``covers``' pills.
        margin_px: how far ``covers`` are grown (``occluder_margin_px``).

    ``grown`` (the grown outlines) and ``windows`` (grown outline less the union of its nearer
    covers) are shapely polygons built on first use (a batch of turns needs the searched links'
    windows only).
    """

    outlines: np.ndarray
    depth: np.ndarray
    order: np.ndarray | None
    visible: np.ndarray
    visible_share: np.ndarray
    pad_px: np.ndarray
    nearer: np.ndarray
    covers: np.ndarray
    cut: bool
    pills: np.ndarray
    cover_pills: np.ndarray
    margin_px: float

    @functools.cached_property
    def grown(self) -> np.ndarray:
        """(links,) the outlines grown by ``pad_px`` (the outlines themselves where it is 0)."""
        return _grow(self.outlines, self.pad_px)

    @functools.cached_property
    def windows(self) -> np.ndarray:
        """(links,) window polygons: grown outline less the union of its nearer covers."""
        if not self.cut:
            return self.grown
        none = _EMPTY
        # Links with the same occluders (the phalanges of one finger behind another, often) share
        # one union of them.
        unions: dict[bytes, object] = {}
        occl = np.empty(len(self.outlines), dtype=object)
        for i, row in enumerate(self.nearer):
            key = row.tobytes()
            if key not in unions:
                unions[key] = shapely.union_all(self.covers[row]) if row.any() else none
            occl[i] = unions[key]
        return shapely.difference(self.grown, occl)

    def rows(self, at: np.ndarray) -> Visibility:
        """The visibility of the links ``at`` only (their windows still cut by every cover)."""
        return Visibility(outlines=self.outlines[at], depth=self.depth[at], order=None, visible=self.visible[at],
                          visible_share=self.visible_share[at], pad_px=self.pad_px[at], nearer=self.nearer[at],
                          covers=self.covers, cut=self.cut, pills=self.pills[at], cover_pills=self.cover_pills,
                          margin_px=self.margin_px)

    def window_mask(self, points: np.ndarray) -> np.ndarray:
        """(links, ...) True where ``points[i, ...]`` (NaN: False) lies inside link i's window, the
        same as ``window_masks(self.windows, points)`` without building the windows: inside the
        grown outline and off the closure of every nearer cover, decided from each pill's
        distance, and by shapely only within the band where the polygon and the pill differ."""
        pts = np.asarray(points, float)
        lead = pts.shape[:-1]
        flat = pts.reshape(len(pts), -1, 2)
        finite = finite_xy(flat)
        x = np.where(finite, flat[..., 0], 0.0)
        y = np.where(finite, flat[..., 1], 0.0)
        pad = self.pad_px[:, None]
        lo = np.where(pad > 0, pad * _ARC_COS, 0.0) - self.pills[:, None, 9]
        own = _decide(pill_distance(x, y, self.pills[:, None, :]), lo, pad * _BUFFER_OVER,
                      lambda i, k: shapely.contains_xy(_prepared(self.grown)[i], x[i, k], y[i, k]))
        if self.cut and self.nearer.any():
            i, j = np.nonzero(self.nearer)  # rows sorted, so each row's pairs are contiguous
            m = self.margin_px
            lo = (m * _ARC_COS if m > 0 else 0.0) - self.cover_pills[j, None, 9]
            covered = _decide(pill_distance(x[i], y[i], self.cover_pills[j, None, :]), lo, m * _BUFFER_OVER,
                              lambda a, k: shapely.intersects_xy(_prepared(self.covers)[j[a]], x[i[a], k],
                                                                 y[i[a], k]))
            first = np.flatnonzero(np.concatenate([[True], i[1:] != i[:-1]]))
            own[i[first]] &= ~np.logical_or.reduceat(covered, first, axis=0)
        return (own & finite).reshape(lead)


# One empty polygon for every empty outline (geometries are immutable; building one parses WKT).
_EMPTY = shapely.Polygon()
# A buffer of quad_segs=4 reaches at least this share of its distance (chords of 22.5-degree arcs).
_ARC_COS = float(np.cos(np.pi / 8))
# ... and at most this share past it (GEOS may drop an input vertex within 1 % of the distance).
_BUFFER_OVER = 1.02
# Distances within this (px) of a bound are left to shapely (rounding of the distance itself).
_BAND_EPS = 1e-6


def _prepared(geoms: np.ndarray) -> np.ndarray:
    shapely.prepare(geoms)
    return geoms


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
    h = np.abs(wx * dy - wy * dx) * pills[..., 6]
    t = (wx * dx + wy * dy) * pills[..., 7] + pills[..., 8] * h
    t = np.minimum(np.maximum(t, 0.0, out=t), 1.0, out=t)
    d = np.hypot(wx - t * dx, wy - t * dy) - (pills[..., 4] + t * pills[..., 5])
    if pills[..., 10].any():  # one end circle holds the other (or a point-like segment): the larger one
        ends = np.minimum(np.hypot(wx, wy) - pills[..., 4], np.hypot(wx - dx, wy - dy) - pills[..., 4] - pills[..., 5])
        d = np.where(pills[..., 10] > 0, ends, d)
    return d


def _decide(d: np.ndarray, lo, hi, exact) -> np.ndarray:
    """``d < lo``: inside; ``d > hi``: outside; in between (within ``_BAND_EPS``) ``exact(*index)``."""
    inside = d < lo - _BAND_EPS
    band = (d <= hi + _BAND_EPS) & ~inside
    if band.any():
        index = np.nonzero(band)
        inside[index] = exact(*index)
    return inside


def _grow(outlines: np.ndarray, pad_px: np.ndarray) -> np.ndarray:
    """``shapely.buffer(outlines, pad_px)``, skipped where ``pad_px`` is 0 (a zero buffer only
    rewrites the same ring)."""
    if not np.any(pad_px):
        return outlines
    return shapely.buffer(outlines, pad_px, quad_segs=4)


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
    k = 2 * arc_points
    a = 2 * np.pi * np.arange(k) / k
    circle = np.stack([np.cos(a), np.sin(a)], -1)  # (k, 2)
    s = np.asarray(start_px, float)
    e = np.asarray(end_px, float)
    rs = np.asarray(radius_start, float)
    re = np.asarray(radius_end, float)
    ok = (finite_xy(s) & finite_xy(e) & np.isfinite(rs) & np.isfinite(re)
          & (rs > 0) & (re > 0))
    cloud = np.concatenate([s[:, None] + rs[:, None, None] * circle, e[:, None] + re[:, None, None] * circle], 1)
    cloud = np.where(ok[:, None, None], cloud, 0.0)
    # GEOS takes the hull of the coordinates in their order whatever the geometry type; a line
    # string is built straight from the array (a multipoint first makes one Point per vertex).
    hulls = shapely.convex_hull(shapely.linestrings(cloud))
    hulls = shapely.simplify(hulls, simplify_px) if simplify_px > 0 else hulls
    return np.where(ok, hulls, _EMPTY) if not ok.all() else hulls


def _pills(start_px, end_px, radius_start, radius_end, config: VisibilityConfig) -> np.ndarray:
    """(links, 11) :attr:`Visibility.pills`. The outline's hull vertices lie on the end circles, so
    its edges cut into the pill by at most the chord depth ``r (1 - cos(pi / (2 arc_points)))``,
    and the simplification moves them in by at most ``simplify_px`` more: the slack."""
    s, e = np.asarray(start_px, float), np.asarray(end_px, float)
    rs, re = np.asarray(radius_start, float), np.asarray(radius_end, float)
    ok = finite_xy(s) & finite_xy(e) & np.isfinite(rs) & np.isfinite(re) & (rs > 0) \
        & (re > 0)
    far = np.array([1e12, 1e12])  # an empty pill: far from every point
    s, e = np.where(ok[:, None], s, far), np.where(ok[:, None], e, far)
    rs, re = np.where(ok, rs, 0.0), np.where(ok, re, 0.0)
    d, dr = e - s, re - rs
    L2 = dot_xy(d, d)
    steep2 = L2 - dr * dr
    ends = ~(steep2 > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv_len = np.where(ends, 0.0, 1.0 / np.sqrt(L2))
        inv_L2 = np.where(ends, 0.0, 1.0 / L2)
        ratio = np.where(ends, 0.0, dr * inv_len / np.sqrt(steep2))
    slack = np.where(ok, np.maximum(rs, re) * (1.0 - np.cos(np.pi / (2 * config.arc_points))) + config.simplify_px,
                     0.0)
    return np.stack([s[:, 0], s[:, 1], d[:, 0], d[:, 1], rs, dr, inv_len, inv_L2, ratio, slack, ends.astype(float)],
                    -1)


def same_chain(link_frame, ancestors: np.ndarray) -> np.ndarray:
    """(links, links) True where two links lie on one kinematic chain (one is above the other)."""
    f = np.asarray(link_frame, int)
    a = np.asarray(ancestors, bool)[np.ix_(f, f)]
    return a | a.T


def compute_visibility(start_px: np.ndarray, end_px: np.ndarray, depth: np.ndarray, radius_start: np.ndarray,
                       radius_end: np.ndarray, chain: np.ndarray, image_size: tuple[int, int],
                       config: VisibilityConfig) -> Visibility:
    """Depth-sort the pills and cut each by the nearer pills of other chains (thesis §4.3.3).

    Args:
        start_px, end_px: (links, 2) projected link ends.
        depth: (links, 2) depth of the two ends (mm).
        radius_start, radius_end: (links,) radius in pixels at each end.
        chain: (links, links) :func:`same_chain`.
        image_size: (width, height), for the share of each link inside the image.
        config: visibility settings.
    """
    outlines = pill_outlines(start_px, end_px, radius_start, radius_end, config.arc_points, config.simplify_px)
    mean_depth = np.nan_to_num(np.asarray(depth, float).mean(-1), nan=np.inf, posinf=np.inf, neginf=np.inf)
    order = np.argsort(-mean_depth, kind="stable")
    radius = 0.5 * (nan_to_num(radius_start) + nan_to_num(radius_end))
    pad = config.window_pad * radius
    L = len(outlines)
    empty = shapely.is_empty(outlines)
    cut = bool(config.occlusion and L > 1)
    nearer = np.zeros((L, L), bool)
    covers = outlines
    grown = None
    if cut:
        grown = _grow(outlines, pad)
        b = nan_to_num(shapely.bounds(grown))
        candidate = (mean_depth[None, :] < mean_depth[:, None]) & ~np.asarray(chain, bool) & ~empty[None, :]
        m = config.occluder_margin_px
        if m > 0:
            # A cover lies within its outline's box grown by the margin: only the pills whose grown
            # box meets a candidate's box are buffered (the others cut no window).
            o = nan_to_num(shapely.bounds(outlines)) + np.array([-1.0, -1.0, 1.0, 1.0]) * (m * _BUFFER_OVER + 1e-9)
            candidate &= _boxes_meet(b, o)
            used = np.flatnonzero(candidate.any(0))
            covers = np.full(L, None, dtype=object)
            covers[used] = shapely.buffer(outlines[used], m, quad_segs=4)
            c = np.zeros((L, 4))
            c[used] = nan_to_num(shapely.bounds(covers[used]))
        else:
            c = nan_to_num(shapely.bounds(covers))
        # Only nearer pills of other chains whose bounding boxes meet this one's can cut it.
        nearer = candidate & _boxes_meet(b, c)
        # Links with the same occluders (the phalanges of one finger behind another, often) share
        # one union of them; a link without occluders keeps its outline (what the difference with
        # an empty polygon returns).
        cut_rows = np.flatnonzero(nearer.any(1))
        unions: dict[bytes, object] = {}
        occl = np.empty(len(cut_rows), dtype=object)
        for n, i in enumerate(cut_rows):
            key = nearer[i].tobytes()
            if key not in unions:
                unions[key] = shapely.union_all(outlines[nearer[i]])
            occl[n] = unions[key]
        visible = outlines.copy()
        if len(cut_rows):
            visible[cut_rows] = shapely.difference(outlines[cut_rows], occl)
    else:
        visible = outlines.copy()
    w, h = image_size
    area = shapely.area(outlines)
    # Only a pill that reaches past the image border is clipped by it (GEOS's overlay is the
    # slowest step here); inside the image the visible area is the truncated polygon's own.
    b = shapely.bounds(outlines)
    inside = (b[:, 0] >= -0.5) & (b[:, 1] >= -0.5) & (b[:, 2] <= w - 0.5) & (b[:, 3] <= h - 0.5)
    seen_area = shapely.area(visible)
    if not inside.all():
        out = ~inside
        frame = shapely.box(-0.5, -0.5, w - 0.5, h - 0.5)
        seen_area[out] = shapely.area(shapely.intersection(visible[out], frame))
    share = np.where(area > 0, seen_area / np.where(area > 0, area, 1.0), 0.0)
    pills = _pills(start_px, end_px, radius_start, radius_end, config)
    vis = Visibility(outlines=outlines, depth=mean_depth, order=order, visible=visible,
                     visible_share=np.clip(share, 0.0, 1.0), pad_px=pad, nearer=nearer, covers=covers, cut=cut,
                     pills=pills, cover_pills=pills, margin_px=float(config.occluder_margin_px))
    if grown is not None:
        vis.__dict__["grown"] = grown  # already built for the bounds (the cached property's slot)
    return vis


def _boxes_meet(b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """(len(b), len(c)) True where box b[i] meets box c[j] (xmin, ymin, xmax, ymax; closed)."""
    return ((c[None, :, 0] <= b[:, None, 2]) & (c[None, :, 2] >= b[:, None, 0])
            & (c[None, :, 1] <= b[:, None, 3]) & (c[None, :, 3] >= b[:, None, 1]))


def window_masks(polygons: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Window functions: True where a sample lies inside its link's polygon (thesis fig. 4.18).

    Args:
        polygons: (links,) window polygons.
        points: (links, ..., 2) sample positions of each link's profiles (NaN gives False).

    Returns:
        (links, ...) boolean windows, from one vectorised ``shapely.contains_xy`` call.
    """
    pts = np.asarray(points, float)
    geoms = np.asarray(polygons, dtype=object).reshape((-1,) + (1,) * (pts.ndim - 2))
    shapely.prepare(geoms)
    finite = finite_xy(pts)
    x = np.where(finite, pts[..., 0], 0.0)
    y = np.where(finite, pts[..., 1], 0.0)
    return shapely.contains_xy(geoms, x, y) & finite


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

