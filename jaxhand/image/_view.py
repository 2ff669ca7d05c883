"""Steps 4-6 of the pipeline for one camera's observation: search every profile, fit the boundary
and axial lines of every link (thesis §4.4, DigitEyes §4), and find the tips (eq. 4.1, §11.1.1)."""

from __future__ import annotations

import dataclasses

import numpy as np

from ._context import CameraContext, Observation, against_background, off_other_links
from ._linefit import fit_rows
from ._sampling import sample_profiles
from ._trackers import LinkSamplers, TipSamplers, place_tip_samplers
from ._xy import all_last, along_xy, finite_xy, nan_to_num
from .searches import TEMPLATE_SEARCHES, Edges, Profiles
from .searches._common import gaussian_derivative, masked_argmax, simple_derivative

__all__ = ["LineFit", "TipFit", "View", "edges_to_px", "fit_links", "find_tips", "search_view"]


def edges_to_px(samplers: LinkSamplers, edges: Edges, centre: float) -> tuple[np.ndarray, np.ndarray]:
    """(links, samplers, 2, 2) boundary points in pixels (NaN where not found) and which were found."""
    off = (edges.pos - centre) * samplers.spacing_px[:, None, None]  # (links, samplers, 2), px along the normal
    pts = along_xy(samplers.centres[:, :, None, :], off, samplers.normal[:, None, None, :])
    ok = edges.valid & samplers.ok[:, None, None] & finite_xy(pts)
    pts[~ok] = np.nan
    return pts, ok


@dataclasses.dataclass(frozen=True)
class LineFit:
    """Every link's boundary lines and axial line (:func:`fit_links`).

    Attributes:
        lines: (links, 3) axial lines (a, b, rho); (1, 0, 0) where not valid.
        valid: (links,) the link's line was measured.
        weight: (links,) the slot's weight (0 where not valid).
        boundary: (links, 2, 3) both boundary lines.
        bvalid: (links, 2) the boundary line was fitted.
        inliers: (links, 2, samplers) RANSAC inliers of each boundary line.
        single: (links,) the valid line came from one boundary offset by the radius.
        p_ax, v_ax: (links, 2) the axial line as a point and a direction (start to end).
    """

    lines: np.ndarray
    valid: np.ndarray
    weight: np.ndarray
    boundary: np.ndarray
    bvalid: np.ndarray
    inliers: np.ndarray
    single: np.ndarray
    p_ax: np.ndarray
    v_ax: np.ndarray


def fit_links(obs: Observation, edge_px: np.ndarray, edge_ok: np.ndarray, config) -> LineFit:
    """Step 5: both boundary lines by RANSAC + PCA, the axial line between them, or a lone boundary
    offset by the radius towards the predicted axis (one compiled call, :mod:`._linefit`)."""
    s = obs.samplers
    mid = 0.5 * (nan_to_num(obs.start) + nan_to_num(obs.end))
    return LineFit(**fit_rows(edge_px, edge_ok, mid, s.radius_px, s.direction, s.ok, obs.visibility.visible_share,
                              config.lines))


@dataclasses.dataclass(frozen=True)
class TipFit:
    """Every tip's point (:func:`find_tips`): ``tips`` (tips, 2) px (0 where not valid), ``valid``,
    the samplers ``ts``, ``edge`` (tips, 2) the boundary points (NaN where none) and ``strength``."""

    tips: np.ndarray
    valid: np.ndarray
    ts: TipSamplers
    edge: np.ndarray
    strength: np.ndarray


def find_tips(ctx: CameraContext, obs: Observation, line_ok: np.ndarray, p_ax: np.ndarray, v_ax: np.ndarray
              ) -> TipFit:
    """Step 6: tip samplers on the terminal axial lines (or the predicted axes where no line was
    measured), the strongest falling edge along each, kept where background lies beyond it (or,
    with ``TipConfig.over_farther``, other fingers farther away)."""
    config = ctx.config
    tc = config.tips
    s = obs.samplers
    tl = np.asarray(ctx.model.tip_links, int)
    # The terminal axial line when it was measured, else the predicted link axis.
    p = np.where(line_ok[tl, None], p_ax[tl], nan_to_num(obs.start[tl]))
    v = np.where(line_ok[tl, None], v_ax[tl], s.direction[tl])
    ts = place_tip_samplers(nan_to_num(obs.tips), p, v, s.radius_px[tl], tc)
    values, usable = sample_profiles(ctx.grey, ts.points, config.samplers.interpolation)
    if tc.sigma > 0:
        d, d_ok, pos = gaussian_derivative(values, usable, tc.sigma)
    else:
        d, d_ok, pos = simple_derivative(values, usable)
    # Outwards past the tip a bright hand gives way to background: a falling edge.
    k, val, off = masked_argmax(-config.search.sign * d, d_ok, True)
    found = np.isfinite(val)
    strength = np.where(found & (ts.spacing_px > 0), val / np.where(ts.spacing_px > 0, ts.spacing_px, 1.0), 0.0)
    along = (pos[k] + off - (tc.points - 1) / 2) * ts.spacing_px
    centre = ts.refined + ts.radius_px[:, None] * ts.v0
    edge = centre + along[:, None] * ts.v0
    tip = edge - ts.radius_px[:, None] * ts.v0
    seen = obs.visibility.rows(tl).window_mask(tip[:, None, :])[:, 0]
    # Past the tip boundary there must be background (TipConfig.beyond).
    beyond = tip[:, None, :] + (ts.radius_px[:, None] * np.asarray(tc.beyond, float))[..., None] * ts.v0[:, None, :]
    clear = all_last(off_other_links(obs, beyond, tl))
    if tc.over_farther > 0:   # in front of another finger: its own occluding contour, on the measured line
        rows = np.flatnonzero(~clear & line_ok[tl] & (_shown_share(ctx, obs, tl) >= tc.over_farther))
        if len(rows):
            depth = obs.visibility.depth
            behind = (depth[None, :] > depth[tl[rows], None]) & ~np.asarray(ctx.chain, bool)[tl[rows]]
            clear[rows] = all_last(off_other_links(obs, beyond[rows], tl[rows], behind))
    seen &= clear
    valid = (s.ok[tl] & found & (strength >= tc.min_strength) & (strength > 0) & seen
             & (obs.visibility.visible_share[tl] >= config.lines.min_visible) & finite_xy(tip)
             & (line_ok[tl] | (not tc.need_line)))
    return TipFit(tips=np.where(valid[:, None], tip, 0.0), valid=valid, ts=ts,
                  edge=np.where(valid[:, None], edge, np.nan), strength=np.where(valid, strength, 0.0))


def _shown_share(ctx: CameraContext, obs: Observation, links: np.ndarray) -> np.ndarray:
    """(n,) the share of each link's length its projection shows (1: parallel to the image plane,
    0: seen end on), from its pixels per mm at its radius; 0 where the link has no radius in view."""
    length = np.linalg.norm(nan_to_num(obs.end[links]) - nan_to_num(obs.start[links]), axis=-1)
    full = (obs.samplers.radius_px[links] / np.asarray(ctx.model.link_radius_mm)[links]
            * np.asarray(ctx.model.link_length_mm)[links])
    return np.divide(length, full, out=np.zeros_like(length), where=full > 0)


@dataclasses.dataclass(frozen=True)
class View:
    """One camera's search, line fits and tips around one pose (:func:`search_view`); ``tips`` is
    None where the tips were not searched."""

    profiles: Profiles
    edges: Edges
    edge_px: np.ndarray
    fit: LineFit
    tips: TipFit | None


def search_view(ctx: CameraContext, obs: Observation, *, boundary_clear: np.ndarray | None = None,
                tips: bool = True) -> View:
    """Steps 4-6 for one camera's observation ``obs``, with ``ctx``'s search and templates.

    Every step but the tips' treats each link (row) on its own, given its profiles, samplers,
    visible share and (for the WSSD snap) ``boundary_clear``; so ``obs`` may also hold rows of
    different views (re-acquisition's batch of turns), with ``boundary_clear`` computed in each
    row's own view (None: :func:`against_background` of ``obs``) and ``tips=False`` (step 6 looks
    at every link's outline).
    """
    config, clock = ctx.config, ctx.clock
    sc = config.samplers
    snapping = config.method in TEMPLATE_SEARCHES and config.search.snap > 0
    if snapping and boundary_clear is None:
        boundary_clear = against_background(obs, config.visibility.background_reach)
    profiles = Profiles(values=obs.values, usable=obs.usable, window=obs.window, centre=sc.centre,
                        radius=sc.samples_per_radius, spacing_px=obs.samplers.spacing_px, templates=ctx.templates,
                        template_valid=ctx.template_mask.any(axis=(1, 2)) & obs.samplers.ok,
                        template_mask=ctx.template_mask,
                        boundary_clear=boundary_clear if snapping else None)
    clock.lap("search")  # template bookkeeping counts with the search
    edges = ctx.search(profiles, config.search)
    clock.lap("search")
    edge_px, edge_ok = edges_to_px(obs.samplers, edges, sc.centre)
    fit = fit_links(obs, edge_px, edge_ok, config)
    clock.lap("lines")
    tip_fit = None
    if tips:
        tip_fit = find_tips(ctx, obs, fit.valid, fit.p_ax, fit.v_ax)
        clock.lap("tips")
    return View(profiles=profiles, edges=edges, edge_px=edge_px, fit=fit, tips=tip_fit)
