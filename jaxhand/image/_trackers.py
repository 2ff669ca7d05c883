"""Tracker placement (thesis §4.1): link samplers across each projected link, tip samplers along
the terminal axial line.

Link samplers (fig. 4.2) are segments perpendicular to the projected link axis, spread evenly
along it; each holds ``points`` samples spanning ``±scope · r`` about the axis (``r`` the
predicted radius in pixels), so it reaches past both predicted boundaries. Sample ``j`` of a
sampler centred on axis point ``c`` is ``c + (j - (points - 1) / 2) · spacing · n``, where ``n`` is
the link's unit normal ``(u_y, -u_x)`` for the unit direction ``u`` from the link's start to its end
(the normal of :func:`jaxhand.features.line_through`).

The tip sampler (fig. 4.3) lies on the terminal axial line: the predicted tip is projected onto
that line (eq. 4.1) and the sampler runs along it, centred one radius beyond the refined tip
centre, where the tip's boundary should be.
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np

from ._config import SamplerConfig, TipConfig
from ._xy import along_xy, dot_xy, finite_xy, nan_to_num, norm_xy

__all__ = ["LinkSamplers", "TipSamplers", "place_link_samplers", "refine_tip", "place_tip_samplers"]


@dataclasses.dataclass(frozen=True)
class LinkSamplers:
    """Where every link profile is sampled (pixels).

    Attributes:
        direction: (links, 2) unit direction of the predicted link, start to end.
        normal: (links, 2) unit normal, the direction in which profile indices grow.
        radius_px: (links,) predicted radius.
        length_px: (links,) projected length.
        ok: (links,) the link has samplers (finite, long enough, positive radius).
        centres: (links, samplers, 2) sampler centres on the predicted axis.
        spacing_px: (links,) distance between neighbouring samples.
        points: (links, samplers, points, 2) sample positions (NaN where the link is not ok).
    """

    direction: np.ndarray
    normal: np.ndarray
    radius_px: np.ndarray
    length_px: np.ndarray
    ok: np.ndarray
    centres: np.ndarray
    spacing_px: np.ndarray
    points: np.ndarray

    @property
    def ends(self) -> np.ndarray:
        """(links, samplers, 2, 2) first and last sample of every sampler (for drawing)."""
        return self.points[:, :, [0, -1]]


def place_link_samplers(start_px: np.ndarray, end_px: np.ndarray, radius_px: np.ndarray, config: SamplerConfig
                        ) -> LinkSamplers:
    """Samplers perpendicular to every projected link (thesis §4.1, table 4.1).

    Args:
        start_px, end_px: (links, 2) projected link ends.
        radius_px: (links,) predicted radius in pixels.
        config: sampler layout.
    """
    start = np.asarray(start_px, float)
    end = np.asarray(end_px, float)
    radius = np.asarray(radius_px, float)
    d = end - start
    length = norm_xy(d)
    ok = (finite_xy(start) & finite_xy(end) & np.isfinite(radius)
          & (radius > 0) & (length >= max(config.min_length_px, 1e-9)))
    # Guard: a link that is not ok gets a dummy direction so every array stays finite; its
    # sample positions are NaN below, which the sampler reports as unusable.
    u = np.where(ok[:, None], d / np.where(ok, length, 1.0)[:, None], np.array([1.0, 0.0]))
    n = np.empty_like(u)  # (u_y, -u_x), filled in place (np.stack costs more than the values)
    n[:, 0], n[:, 1] = u[:, 1], -u[:, 0]
    f = _along(tuple(config.along), config.per_link)
    centres = np.where(ok[:, None, None], start[:, None] + f[None, :, None] * d[:, None], np.nan)
    spacing = np.where(ok, 2 * config.scope * np.where(ok, radius, 0.0) / (config.points - 1), 0.0)
    step = _offsets(config.points, config.centre)[None, :] * spacing[:, None]  # (links, points)
    pts = along_xy(centres[:, :, None, :], step[:, None, :], n[:, None, None, :])
    return LinkSamplers(direction=u, normal=n, radius_px=np.where(ok, radius, 0.0), length_px=nan_to_num(length),
                        ok=ok, centres=centres, spacing_px=spacing, points=pts)


@functools.lru_cache(maxsize=8)
def _offsets(points: int, centre: float) -> np.ndarray:
    """Each sample's index relative to the profile's centre (read-only)."""
    j = np.arange(points) - centre
    j.setflags(write=False)
    return j


@functools.lru_cache(maxsize=8)
def _along(along: tuple, per_link: int) -> np.ndarray:
    """Where the samplers sit along the link, as fractions of its length (read-only)."""
    f = np.linspace(along[0], along[1], per_link)
    f.setflags(write=False)
    return f


def refine_tip(tip_px: np.ndarray, p_ax: np.ndarray, v_ax: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Project the predicted tip onto the terminal axial line (thesis eq. 4.1).

    ``p~ = p_ax + ((p_tip - p_ax)^T v0) v0`` with ``v0 = v_ax / |v_ax|``.

    Args:
        tip_px: (..., 2) predicted tip centre.
        p_ax, v_ax: (..., 2) a point on the terminal axial line and its direction (towards the tip).

    Returns:
        (refined tip, v0).
    """
    nv = norm_xy(v_ax)[..., None]
    v0 = v_ax / np.where(nv > 0, nv, 1.0)  # Guard: a zero direction stays zero, giving p~ = p_ax.
    return p_ax + dot_xy(tip_px - p_ax, v0)[..., None] * v0, v0


@dataclasses.dataclass(frozen=True)
class TipSamplers:
    """Tip samplers (pixels).

    Attributes:
        refined: (tips, 2) predicted tip projected onto the terminal axial line (eq. 4.1).
        v0: (tips, 2) unit direction of the terminal axial line, towards the tip.
        radius_px: (tips,) predicted radius of the tip link.
        spacing_px: (tips,) distance between neighbouring samples.
        points: (tips, points, 2) sample positions, running outwards past the tip.
    """

    refined: np.ndarray
    v0: np.ndarray
    radius_px: np.ndarray
    spacing_px: np.ndarray
    points: np.ndarray


def place_tip_samplers(tip_px: np.ndarray, p_ax: np.ndarray, v_ax: np.ndarray, radius_px: np.ndarray,
                       config: TipConfig) -> TipSamplers:
    """Tip samplers on the terminal axial lines, centred on the predicted tip boundary."""
    refined, v0 = refine_tip(np.asarray(tip_px, float), np.asarray(p_ax, float), np.asarray(v_ax, float))
    r = np.asarray(radius_px, float)
    spacing = 2 * config.scope * r / (config.points - 1)
    step = _offsets(config.points, (config.points - 1) / 2)[None, :] * spacing[:, None]  # (tips, points)
    centre = refined + r[:, None] * v0
    pts = along_xy(centre[:, None, :], step, v0[:, None, :])
    return TipSamplers(refined=refined, v0=v0, radius_px=r, spacing_px=spacing, points=pts)
