"""Ray casting of pills (capsules) with a z-buffer, vectorised in NumPy over the pixels of each pill.

A pill is the set of points within ``radius`` of the segment ``[A, B]`` (thesis app. C: a cylinder
capped by two hemispheres). Every pixel casts one ray in the camera frame:

- orthographic: origin ``((x - cx) / scale, (y - cy) / scale, 0)``, direction ``(0, 0, 1)``;
- perspective: origin at the camera centre, direction ``K^-1 (x, y, 1)`` scaled so its z is 1.

With the direction's z equal to 1 the ray parameter ``t`` of a hit is ``p_cam.z - o.z``, so for both
kinds the depth of a hit (``p_cam.z``, the camera convention) is ``o.z + t`` with ``o.z = 0``.

The first hit of a ray on a pill is the smallest entry parameter over the pill's three convex parts
(the finite cylinder and the two end spheres); they are computed from six dot products shared by
all three. Only the pixels inside each pill's projected bounding box are evaluated, and a
z-buffer keeps the nearest pill per pixel. The loop runs over pills (a few dozen), never pixels.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..camera import Orthographic

__all__ = ["Pills", "RayGrid", "ZBuffer", "ray_grid", "pills_in_camera", "cast", "pill_normals"]

# Rays that meet a pill closer to a perspective camera than this (mm) are ignored: the camera
# centre sits inside or right next to that pill and the hit has no image.
_NEAR_MM = 1e-6
# A cylinder axis shorter than this (squared, mm^2) is a sphere; its cylinder part is skipped
# because the quadratic's leading coefficient vanishes.
_MIN_AXIS_SQ = 1e-18
# Rows choose lo (0) or hi (1) per axis: the 8 corners of a box.
_CORNERS = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)])


@dataclass(frozen=True)
class Pills:
    """Pills in the camera frame (mm): axis ends ``a``, ``b`` (n, 3) and radius (n,)."""

    a: np.ndarray
    b: np.ndarray
    radius: np.ndarray


@dataclass(frozen=True)
class RayGrid:
    """The rays of an image sampled ``k`` times per pixel along each axis (``k`` odd).

    Sample ``(X, Y)`` of the ``(k H, k W)`` grid sits at pixel ``((X - (k - 1) / 2) / k, ...)``, so the
    centre sample of every ``k x k`` block is the pixel centre. ``xs``/``ys`` are those pixel
    coordinates; the ray of a sample is ``origin + t * direction`` in camera coordinates. The camera's
    numbers are held as NumPy values (``scale``/``center`` for orthographic, ``K``/``kinv`` for
    perspective cameras), read once per frame rather than once per pill.
    """

    k: int
    xs: np.ndarray
    ys: np.ndarray
    perspective: bool
    scale: float = 1.0
    center: tuple[float, float] = (0.0, 0.0)
    K: np.ndarray | None = None
    kinv: np.ndarray | None = None

    @property
    def shape(self) -> tuple[int, int]:
        return (len(self.ys), len(self.xs))

    def rays(self, y0: int, y1: int, x0: int, x1: int):
        """Origin and direction components of the rays in rows y0:y1 and columns x0:x1.

        Each component is an array broadcastable to (y1 - y0, x1 - x0) or a float.
        """
        return self.rays_at(self.xs[x0:x1][None, :], self.ys[y0:y1][:, None])

    def rays_at(self, u, v):
        """Origin and direction components of the rays through pixel coordinates (u, v) (broadcastable)."""
        if not self.perspective:
            s = self.scale
            return ((u - self.center[0]) / s, (v - self.center[1]) / s, 0.0), (0.0, 0.0, 1.0)
        m = self.kinv
        if m[2, 0] == 0.0 and m[2, 1] == 0.0 and m[0, 1] == 0.0 and m[1, 0] == 0.0:
            # The usual K (no skew, last row 0 0 1): each direction component depends on one axis only.
            return (0.0, 0.0, 0.0), ((m[0, 0] * u + m[0, 2]) / m[2, 2], (m[1, 1] * v + m[1, 2]) / m[2, 2], 1.0)
        dz = m[2, 0] * u + m[2, 1] * v + m[2, 2]
        dx = (m[0, 0] * u + m[0, 1] * v + m[0, 2]) / dz
        dy = (m[1, 0] * u + m[1, 1] * v + m[1, 2]) / dz
        return (0.0, 0.0, 0.0), (dx, dy, 1.0)


def ray_grid(camera, k: int = 1) -> RayGrid:
    """The (supersampled) ray grid of a camera; ``k`` samples per pixel along each axis."""
    w, h = camera.size
    xs = (np.arange(k * w) - (k - 1) / 2) / k
    ys = (np.arange(k * h) - (k - 1) / 2) / k
    if isinstance(camera, Orthographic):
        c = np.asarray(camera.center, float)
        return RayGrid(k, xs, ys, False, scale=float(camera.scale), center=(float(c[0]), float(c[1])))
    K = np.asarray(camera.K, float)
    return RayGrid(k, xs, ys, True, K=K, kinv=np.linalg.inv(K))


def pills_in_camera(camera, link_start_world, link_end_world, radius_mm) -> Pills:
    """Move world-frame pill axes into the camera frame."""
    R = np.asarray(camera.R, float)
    t = np.asarray(camera.t, float)
    a = np.asarray(link_start_world, float) @ R.T + t
    b = np.asarray(link_end_world, float) @ R.T + t
    return Pills(a=a, b=b, radius=np.asarray(radius_mm, float).reshape(-1))


def _sample_range(lo_px: float, hi_px: float, k: int, n: int) -> tuple[int, int]:
    """Supersampled indices [i0, i1) whose pixel coordinates lie in [lo_px, hi_px], clipped to [0, n)."""
    c = (k - 1) / 2
    i0 = min(max(math.ceil(k * lo_px + c), 0), n)
    i1 = min(max(math.floor(k * hi_px + c) + 1, 0), n)
    return i0, max(i0, i1)


def _bbox(grid: RayGrid, a: np.ndarray, b: np.ndarray, r: float) -> tuple[int, int, int, int]:
    """Sample rows/columns (y0, y1, x0, x1) that can see the pill: its projected bounding box."""
    h, w = grid.shape
    if not grid.perspective:
        s, (cx, cy) = grid.scale, grid.center
        x_lo, x_hi = s * (min(a[0], b[0]) - r) + cx, s * (max(a[0], b[0]) + r) + cx
        y_lo, y_hi = s * (min(a[1], b[1]) - r) + cy, s * (max(a[1], b[1]) + r) + cy
    else:
        # The pill lies inside the axis-aligned box of its ends grown by r; project its 8 corners.
        lo3, hi3 = np.minimum(a, b) - r, np.maximum(a, b) + r
        if hi3[2] <= _NEAR_MM:
            return 0, 0, 0, 0  # entirely behind the camera
        if lo3[2] <= _NEAR_MM:
            return 0, h, 0, w  # straddles the camera plane: no finite box; test every ray
        corners = np.stack([lo3, hi3])[_CORNERS, [0, 1, 2]]
        uvw = corners @ grid.K.T
        px = uvw[:, :2] / uvw[:, 2:3]
        (x_lo, y_lo), (x_hi, y_hi) = px.min(0), px.max(0)
    x0, x1 = _sample_range(float(x_lo), float(x_hi), grid.k, w)
    y0, y1 = _sample_range(float(y_lo), float(y_hi), grid.k, h)
    return y0, y1, x0, x1


def _dot(u, v):
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]


def intersect(origin, direction, a: np.ndarray, b: np.ndarray, r: float, perspective: bool):
    """Ray parameter of the first hit of each ray on one pill (``inf`` where it misses).

    Args:
        origin, direction: ray components (3-tuples of arrays broadcastable to one shape, or floats).
        a, b: the pill's axis ends (3,) in camera coordinates (mm); r: its radius (mm).
        perspective: rays start at the camera centre, so hits must have t > 0; orthographic rays
            are whole lines (any t).

    Returns:
        t with the rays' broadcast shape; the hit point is ``origin + t * direction``.
    """
    ba = b - a
    oa = (origin[0] - a[0], origin[1] - a[1], origin[2] - a[2])
    baba = float(ba @ ba)
    bard = _dot(ba, direction)
    baoa = _dot(ba, oa)
    rdoa = _dot(direction, oa)
    oaoa = _dot(oa, oa)
    dd = _dot(direction, direction)
    rr = r * r
    with np.errstate(invalid="ignore", divide="ignore"):
        # Spheres at a and b: |o + t d - c|^2 = r^2, smaller root.
        ha = rdoa * rdoa - dd * (oaoa - rr)
        t = np.where(ha >= 0, (-rdoa - np.sqrt(np.maximum(ha, 0))) / dd, np.inf)
        rdob = rdoa - bard
        hb = rdob * rdob - dd * (oaoa - 2 * baoa + baba - rr)
        t = np.minimum(t, np.where(hb >= 0, (-rdob - np.sqrt(np.maximum(hb, 0))) / dd, np.inf))
        if baba > _MIN_AXIS_SQ:
            # Infinite cylinder: distance of o + t d from the axis line equals r; keep hits whose
            # axial coordinate falls between the ends (the rest are on the caps, handled above).
            qa = baba * dd - bard * bard
            qb = baba * rdoa - baoa * bard
            qc = baba * oaoa - baoa * baoa - rr * baba
            hc = qb * qb - qa * qc
            # Guard: qa == 0 for a ray parallel to the axis (seen end-on); the spheres cover it.
            ok = (hc >= 0) & (qa > 0)
            tc = (-qb - np.sqrt(np.where(ok, hc, 0.0))) / np.where(ok, qa, 1.0)
            axial = baoa + tc * bard
            ok &= (axial >= 0) & (axial <= baba)
            t = np.minimum(t, np.where(ok, tc, np.inf))
    t = np.broadcast_to(t, np.broadcast_shapes(np.shape(t), np.shape(oaoa), np.shape(dd)))
    if perspective:
        t = np.where(t > _NEAR_MM, t, np.inf)
    return t


@dataclass
class ZBuffer:
    """Result of :func:`cast` on the (supersampled) grid.

    ``depth`` (kH, kW): camera-frame z of the nearest hit (``inf`` on background); ``link_id``
    (kH, kW) int16: pill index (-1 on background); ``alone``: per pill, the number of pixel-centre
    samples it covers when rendered alone.
    """

    depth: np.ndarray
    link_id: np.ndarray
    alone: np.ndarray


def cast(grid: RayGrid, pills: Pills, *, use_bbox: bool = True) -> ZBuffer:
    """Z-buffered ray cast of all pills on a grid.

    Args:
        grid: the rays (:func:`ray_grid`).
        pills: pills in the camera frame (:func:`pills_in_camera`).
        use_bbox: evaluate only the pixels in each pill's projected bounding box (the fast path);
            False evaluates every pixel for every pill (the naive peer in ``benchmarks/render.py``).
    """
    h, w = grid.shape
    k = grid.k
    c = (k - 1) // 2  # offset of the pixel-centre sample in each k x k block
    depth = np.full((h, w), np.inf)
    link_id = np.full((h, w), -1, np.int16)
    alone = np.zeros(len(pills.radius), np.int64)
    for i in range(len(pills.radius)):  # a loop over pills; pixels are array axes
        r = float(pills.radius[i])
        if r <= 0:
            continue
        y0, y1, x0, x1 = _bbox(grid, pills.a[i], pills.b[i], r) if use_bbox else (0, h, 0, w)
        if y1 <= y0 or x1 <= x0:
            continue
        origin, direction = grid.rays(y0, y1, x0, x1)
        t = intersect(origin, direction, pills.a[i], pills.b[i], r, grid.perspective)
        hit = np.isfinite(t)
        # Pixel-centre samples of this box: supersampled rows/cols congruent to c modulo k.
        alone[i] = int(hit[(c - y0) % k::k, (c - x0) % k::k].sum())
        z = t + origin[2]  # depth = o.z + t (direction z is 1)
        zb = depth[y0:y1, x0:x1]  # views: writing through them updates the buffers
        win = hit & (z < zb)
        zb[win] = z[win]
        link_id[y0:y1, x0:x1][win] = i
    return ZBuffer(depth=depth, link_id=link_id, alone=alone)


def pill_normals(grid: RayGrid, pills: Pills, zbuf: ZBuffer):
    """Surface normals (camera frame, unit) and view directions at the foreground samples.

    The normal at a surface point p of a pill is (p - c) / r, with c the closest point of its axis.

    Returns:
        (mask, normal, view): mask (kH, kW) bool of foreground samples; normal (3, n) and view
        (3, n) or (3, 1) for the samples in ``mask`` (row-major order), view being the unit vector
        from the surface point towards the camera.
    """
    mask = zbuf.link_id >= 0
    ys, xs = np.nonzero(mask)  # (row, col) indices of foreground samples
    ids = zbuf.link_id[ys, xs]
    z = zbuf.depth[ys, xs]
    (ox, oy, _), (dx, dy, _) = grid.rays_at(grid.xs[xs], grid.ys[ys])
    if grid.perspective:
        px, py = dx * z, dy * z  # origin at the camera centre and d.z = 1
        inv = 1.0 / np.sqrt(dx * dx + dy * dy + 1.0)
        view = np.stack([-dx * inv, -dy * inv, -inv])
    else:
        px, py = ox, oy
        view = np.array([[0.0], [0.0], [-1.0]])
    ba = pills.b - pills.a
    baba = np.einsum("ij,ij->i", ba, ba)
    # Guard: a zero-length axis (a sphere) takes its single point (s = 0).
    inv_baba = np.where(baba > 0, 1.0 / np.where(baba > 0, baba, 1.0), 0.0)
    # One small table per quantity, gathered by link id (1-D gathers are the cheap kind).
    rx, ry, rz = px - pills.a[:, 0][ids], py - pills.a[:, 1][ids], z - pills.a[:, 2][ids]
    bx, by, bz = ba[:, 0][ids], ba[:, 1][ids], ba[:, 2][ids]
    s_ax = np.clip((rx * bx + ry * by + rz * bz) * inv_baba[ids], 0.0, 1.0)
    inv_r = (1.0 / pills.radius)[ids]
    n = np.stack([(rx - s_ax * bx) * inv_r, (ry - s_ax * by) * inv_r, (rz - s_ax * bz) * inv_r])
    return mask, n, view
