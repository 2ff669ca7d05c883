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
from ._pills import EMPTY, decide_band, pill_distance, pill_outlines, pill_table
from ._xy import finite_xy, nan_to_num

__all__ = ["Visibility", "OccluderPills", "pill_outlines", "same_chain", "compute_visibility", "window_masks",
           "row_unions"]


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
        nearer: (links, pills) the pills that may cut each link's window (nearer, of another chain,
            within the margin of its box; all False: none, or no occlusion); its columns index
            ``cutters`` and ``covers``.
        cutters: (pills,) the outlines of every pill that may cut a window: the links', then the
            occluders'.
        covers: (pills,) ``cutters`` grown by ``occluder_margin_px``, each built on first use
            (:meth:`cover_polygons`; None until then).
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
    cutters: np.ndarray
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
        occl = np.full(len(self.outlines), EMPTY, dtype=object)
        rows = np.flatnonzero(self.nearer.any(1))
        if len(rows):
            self.cover_polygons(np.flatnonzero(self.nearer[rows].any(0)))
            occl[rows] = row_unions(self.covers, self.nearer[rows])
        return shapely.difference(self.grown, occl)

    def rows(self, at: np.ndarray) -> Visibility:
        """The visibility of the links ``at`` only (their windows still cut by every cover)."""
        return Visibility(outlines=self.outlines[at], depth=self.depth[at], order=None, visible=self.visible[at],
                          visible_share=self.visible_share[at], pad_px=self.pad_px[at], nearer=self.nearer[at],
                          cutters=self.cutters, covers=self.covers, cut=self.cut, pills=self.pills[at],
                          cover_pills=self.cover_pills, margin_px=self.margin_px)

    def cover_polygons(self, at: np.ndarray) -> np.ndarray:
        """``covers[at]``, the missing ones buffered now, all prepared for point tests."""
        at = np.asarray(at, int)
        missing = at[np.equal(self.covers[at], None)]
        if len(missing):
            missing = np.unique(missing)
            self.covers[missing] = shapely.buffer(self.cutters[missing], self.margin_px, quad_segs=4)
        return _prepared(self.covers[at])

    def inside_others(self, points: np.ndarray, links: np.ndarray, ignore: np.ndarray | None = None) -> np.ndarray:
        """(n, ...) True where ``points[i, ...]`` (NaN: False) lies inside the outline of a link other
        than ``links[i]`` (and, with ``ignore`` (n, links) bool, not one that ``ignore[i]`` marks):
        ``shapely.contains_xy`` against every other outline, decided from the pills' distances and
        by shapely only within the band where outline and pill differ."""
        pts = np.asarray(points, float)
        flat = pts.reshape(len(pts), -1, 2)
        x, y = flat[:, None, :, 0], flat[:, None, :, 1]
        pills = self.pills[None, :, None, :]
        inside = decide_band(pill_distance(x, y, pills), -pills[..., 9], 0.0,
                             lambda a, g, k: shapely.contains_xy(_prepared(self.outlines)[g], flat[a, k, 0],
                                                                 flat[a, k, 1]))
        inside[np.arange(len(flat)), links] = False
        if ignore is not None:
            inside &= ~np.asarray(ignore, bool)[..., None]
        return inside.any(1).reshape(pts.shape[:-1])

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
        own = decide_band(pill_distance(x, y, self.pills[:, None, :]), lo, pad * _BUFFER_OVER,
                      lambda i, k: shapely.contains_xy(_prepared(self.grown)[i], x[i, k], y[i, k]))
        own &= finite
        if self.cut and self.nearer.any():
            # Only the points inside their own outline can be covered: each (cover, point) pair once.
            i, j = np.nonzero(self.nearer)
            a, k = np.nonzero(own[i])
            r, c = i[a], j[a]
            m = self.margin_px
            lo = (m * _ARC_COS if m > 0 else 0.0) - self.cover_pills[c, 9]
            covered = decide_band(pill_distance(x[r, k], y[r, k], self.cover_pills[c]), lo, m * _BUFFER_OVER,
                              lambda n: shapely.intersects_xy(self.cover_polygons(c[n]), x[r[n], k[n]],
                                                              y[r[n], k[n]]))
            own[r[covered], k[covered]] = False
        return own.reshape(lead)


# A buffer of quad_segs=4 reaches at least this share of its distance (chords of 22.5-degree arcs).
_ARC_COS = float(np.cos(np.pi / 8))
# ... and at most this share past it (GEOS may drop an input vertex within 1 % of the distance).
_BUFFER_OVER = 1.02
def _prepared(geoms: np.ndarray) -> np.ndarray:
    shapely.prepare(geoms)
    return geoms


def _grow(outlines: np.ndarray, pad_px: np.ndarray) -> np.ndarray:
    """``shapely.buffer(outlines, pad_px)``, skipped where ``pad_px`` is 0 (a zero buffer only
    rewrites the same ring)."""
    if not np.any(pad_px):
        return outlines
    return shapely.buffer(outlines, pad_px, quad_segs=4)


def same_chain(link_frame, ancestors: np.ndarray) -> np.ndarray:
    """(links, links) True where two links lie on one kinematic chain (one is above the other)."""
    f = np.asarray(link_frame, int)
    a = np.asarray(ancestors, bool)[np.ix_(f, f)]
    return a | a.T


@dataclasses.dataclass(frozen=True)
class OccluderPills:
    """Occluder-only pills (a palm, a forearm) seen by one camera: they cut the windows and visible
    polygons of the links behind them, like the links of other chains, and have no window.

    Attributes:
        start_px, end_px: (occluders, 2) projected segment ends.
        depth: (occluders, 2) depth of the two ends (mm).
        radius_start, radius_end: (occluders,) radius in pixels at each end.
    """

    start_px: np.ndarray
    end_px: np.ndarray
    depth: np.ndarray
    radius_start: np.ndarray
    radius_end: np.ndarray


def compute_visibility(start_px: np.ndarray, end_px: np.ndarray, depth: np.ndarray, radius_start: np.ndarray,
                       radius_end: np.ndarray, chain: np.ndarray, image_size: tuple[int, int],
                       config: VisibilityConfig, occluders: OccluderPills | None = None) -> Visibility:
    """Depth-sort the pills and cut each by the nearer pills of other chains (thesis §4.3.3).

    Args:
        start_px, end_px: (links, 2) projected link ends.
        depth: (links, 2) depth of the two ends (mm).
        radius_start, radius_end: (links,) radius in pixels at each end.
        chain: (links, links) :func:`same_chain`.
        image_size: (width, height), for the share of each link inside the image.
        config: visibility settings.
        occluders: occluder-only pills, which cut every link they lie nearer than (None or empty:
            none, and the result is that of the links alone).
    """
    outlines = pill_outlines(start_px, end_px, radius_start, radius_end, config.arc_points, config.simplify_px)
    mean_depth = _mean_depth(depth)
    order = np.argsort(-mean_depth, kind="stable")
    radius = 0.5 * (nan_to_num(radius_start) + nan_to_num(radius_end))
    pad = config.window_pad * radius
    L = len(outlines)
    chain = np.asarray(chain, bool)
    # Every pill that may cut a window: the links, then the occluders (the columns of ``nearer``).
    cutters, cutter_depth, cover_pills = outlines, mean_depth, None
    if occluders is not None and len(occluders.start_px):
        o = occluders
        cutters = np.concatenate([outlines, pill_outlines(o.start_px, o.end_px, o.radius_start, o.radius_end,
                                                          config.arc_points, config.simplify_px)])
        cutter_depth = np.concatenate([mean_depth, _mean_depth(o.depth)])
        chain = np.hstack([chain, np.zeros((L, len(o.start_px)), bool)])  # an occluder is on no link's chain
        cover_pills = pill_table(np.concatenate([start_px, o.start_px]), np.concatenate([end_px, o.end_px]),
                             np.concatenate([radius_start, o.radius_start]),
                             np.concatenate([radius_end, o.radius_end]), config)
    P = len(cutters)
    empty = shapely.is_empty(cutters)
    cut = bool(config.occlusion and P > 1)
    nearer = np.zeros((L, P), bool)
    covers = cutters
    grown = None
    if cut:
        grown = _grow(outlines, pad)
        b = nan_to_num(shapely.bounds(grown))
        candidate = (cutter_depth[None, :] < mean_depth[:, None]) & ~chain & ~empty[None, :]
        m = config.occluder_margin_px
        if m > 0:
            # A cover lies within its outline's box grown by the margin: only the pills whose grown
            # box meets a candidate's box are buffered (the others cut no window).
            # A cover lies within its outline's box grown by the margin (and a pill that only
            # comes that near cuts nothing, decided by the pills' distances in window_mask).
            c = nan_to_num(shapely.bounds(cutters)) + np.array([-1.0, -1.0, 1.0, 1.0]) * (m * _BUFFER_OVER + 1e-9)
            covers = np.full(P, None, dtype=object)
        else:
            c = nan_to_num(shapely.bounds(covers))
        # Only nearer pills of other chains whose bounding boxes meet this one's can cut it.
        nearer = candidate & _boxes_meet(b, c)
        visible = _cut_outlines(outlines, cutters, nearer)
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
    pills = pill_table(start_px, end_px, radius_start, radius_end, config)
    vis = Visibility(outlines=outlines, depth=mean_depth, order=order, visible=visible,
                     visible_share=np.clip(share, 0.0, 1.0), pad_px=pad, nearer=nearer, cutters=cutters, covers=covers,
                     cut=cut, pills=pills, cover_pills=pills if cover_pills is None else cover_pills,
                     margin_px=float(config.occluder_margin_px))
    if grown is not None:
        vis.__dict__["grown"] = grown  # already built for the bounds (the cached property's slot)
    return vis


def _mean_depth(depth) -> np.ndarray:
    """(pills,) mean depth of each pill's two ends (mm); not finite: infinitely far."""
    d = np.asarray(depth, float)
    mean = (d[..., 0] + d[..., 1]) / 2  # the same bits as mean(-1) over two entries
    return np.where(np.isfinite(mean), mean, np.inf)


def _cut_outlines(outlines: np.ndarray, cutters: np.ndarray, nearer: np.ndarray) -> np.ndarray:
    """(links,) each outline less the union of its ``nearer`` cutters. Only the cutters that meet an
    outline take part (most nearer pills only come within the covers' margin), and a single one is
    subtracted without a union: the same areas to rounding; an outline that none meets is kept."""
    out = outlines.copy()
    i, j = np.nonzero(nearer)
    if not len(i):
        return out
    meets = shapely.intersects(outlines[i], cutters[j])
    i, j = i[meets], j[meets]
    if not len(i):
        return out
    count = np.bincount(i, minlength=len(outlines))
    rows = np.flatnonzero(count)
    others = cutters[j[np.searchsorted(i, rows)]]   # each row's first cutter (i is sorted)
    multi = count[rows] > 1
    if multi.any():
        take = np.zeros(nearer.shape, bool)
        take[i, j] = True
        others[multi] = row_unions(cutters, take[rows[multi]])
    out[rows] = shapely.difference(outlines[rows], others)
    return out


def row_unions(geoms: np.ndarray, take: np.ndarray) -> np.ndarray:
    """(rows,) the union of ``geoms[take[i]]`` for each row i (each row takes at least one), in one
    vectorised ``shapely.union_all`` over a grid padded with None (the same geometry, bit for bit,
    as one ``union_all`` per row)."""
    order = np.argsort(~take, axis=1, kind="stable")[:, :int(take.sum(1).max())]
    grid = np.where(np.take_along_axis(take, order, 1), geoms[order], None)
    return shapely.union_all(grid, axis=1)


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
