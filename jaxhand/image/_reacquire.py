"""Re-acquisition (``ImageConfig.reacquire_deg``; not in the documents): where the prediction
shows a link but the search found no line for it, search again with the link's joint turned."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence

import numpy as np

from ._context import CameraContext, Observation, against_background, end_radii, observe
from ._geometry import predicted_geometry
from ._sampling import sample_profiles
from ._trackers import place_link_samplers
from ._view import View, find_tips, search_view
from ._visibility import compute_visibility
from .searches import TEMPLATE_SEARCHES

__all__ = ["reacquire", "reacquire_full", "turns_to_try", "search_turns", "parent_links", "Turns"]

#: The per-link fields of a :class:`LineFit` a winning turn replaces (its tip aside).
TURN_FIELDS = ("lines", "valid", "weight", "single")


def parent_links(model) -> np.ndarray:
    """(links,) the link on the nearest frame above each link's frame (-1: none)."""
    by_frame = {f: k for k, f in enumerate(model.link_frame)}
    out = np.full(model.n_links, -1)
    for k, f in enumerate(model.link_frame):
        j = model.parents[f]
        while j >= 0 and j not in by_frame:
            j = model.parents[j]
        out[k] = by_frame.get(j, -1)
    return out


def _same_bits(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(links,) row ``k`` of ``a`` and of ``b`` hold the same bits (NaNs, signed zeros and all)."""
    a, b = np.ascontiguousarray(a, float), np.ascontiguousarray(b, float)
    return np.all((a.view(np.uint64) == b.view(np.uint64)).reshape(len(a), -1), axis=-1)


def _rows(tree, at):
    """A samplers dataclass with the rows ``at`` of each array field."""
    return type(tree)(**{f.name: (None if getattr(tree, f.name) is None else getattr(tree, f.name)[at])
                         for f in dataclasses.fields(tree)})


@dataclasses.dataclass(frozen=True)
class Turns:
    """Links searched again with their joints turned (:func:`search_turns`).

    Attributes:
        links: (turns,) the link searched at each turn.
        view: the search and line fits, row ``i`` for link ``links[i]`` at turn ``i`` (no tips).
        observe: ``observe(i)`` gives turn ``i``'s :class:`Observation` for the tip search: its
            link geometry, samplers, tips and outlines are every link's at that turn; its
            windows and visible shares are right for ``links[i]`` only (the others are not cut
            by nearer pills), and it holds no profiles.
    """

    links: np.ndarray
    view: View
    observe: Callable[[int], Observation]


def search_turns(ctx: CameraContext, links: np.ndarray, qs: Sequence[np.ndarray]) -> Turns:
    """Link ``links[i]`` searched and fitted in the view at pose ``qs[i]``, for every turn ``i`` at once.

    Row ``i`` is, bit for bit, row ``links[i]`` of ``search_view(ctx, observe(ctx, qs[i]))``:
    steps 2-5 of the pipeline treat each link on its own except where one link's outline meets
    another's, so the turns' searched links are stacked as the rows of one batch. Each turn takes
    one jitted kinematics call; then the link poses of all turns (each distinct one once: a turn
    moves only its link and the links below it) are placed in one call and outlined in one
    :func:`compute_visibility` call, in which only the searched links are cut, each by the nearer
    pills of its own turn's other chains, as in its own view; only the searched links' profiles
    are sampled (one remap), searched (one search call) and fitted (one RANSAC call). The WSSD
    snap (whether a boundary lies against the background) looks at each turn's own outlines.
    Tips are left to the caller: only the winning turn's is needed.
    """
    model, config, clock = ctx.model, ctx.config, ctx.clock
    n, L = len(qs), model.n_links
    links = np.asarray(links, int)
    views = [predicted_geometry(model, ctx.camera, qc) for qc in qs]
    geometry = [(v.start, v.end, v.depth, v.radius) for v in views]
    tips = [v.tips for v in views]
    clock.lap("kinematics")
    # One row per distinct link pose: the first turn's links, then each later turn's links that
    # moved (bit for bit), and each turn's searched link in a row of its own; rows[i, k] holds
    # link k at turn i.
    rows = np.tile(np.arange(L), (n, 1))
    parts, count = [geometry[0]], L
    for i in range(1, n):
        moved = ~np.all([_same_bits(a, b) for a, b in zip(geometry[i], geometry[0])], axis=0)
        moved[links[i]] = True
        new = np.flatnonzero(moved)
        rows[i, new] = count + np.arange(len(new))
        parts.append(tuple(a[new] for a in geometry[i]))
        count += len(new)
    start, end, depth, radius = (np.concatenate(a) for a in zip(*parts))
    samplers = place_link_samplers(start, end, radius, config.samplers)
    clock.lap("samplers")
    r_ends = end_radii(ctx.camera, depth, radius, samplers.ok)
    searched = rows[np.arange(n), links]
    # compute_visibility cuts row a by a nearer pill b only where not keep[a, b]: each turn's
    # searched link by its own turn's other chains, nothing else.
    keep = np.ones((count, count), bool)
    for i, k in enumerate(links):
        keep[searched[i], rows[i]] = ctx.chain[k]
    vis = compute_visibility(start, end, depth, r_ends[:, 0], r_ends[:, 1], keep, ctx.camera.size, config.visibility)
    clock.lap("visibility")
    pts = samplers.points[searched]
    values, usable = sample_profiles(ctx.grey, pts, config.samplers.interpolation)
    clock.lap("sampling")
    window = vis.rows(searched).window_mask(pts) & usable
    clock.lap("visibility")

    def observe_turn(i: int) -> Observation:
        at = rows[i]
        return Observation(start=start[at], end=end[at], tips=tips[i], samplers=_rows(samplers, at),
                           visibility=vis.rows(at), values=None, usable=None,
                           window=None)

    clear = None
    if config.method in TEMPLATE_SEARCHES and config.search.snap > 0:
        reach = config.visibility.background_reach
        clear = np.stack([against_background(observe_turn(i), reach)[k] for i, k in enumerate(links)])
    batch = Observation(start=start[searched], end=end[searched], tips=None, samplers=_rows(samplers, searched),
                        visibility=vis.rows(searched), values=values,
                        usable=usable, window=window)
    sub = dataclasses.replace(ctx, templates=ctx.templates[links], template_mask=ctx.template_mask[links])
    return Turns(links=links, view=search_view(sub, batch, boundary_clear=clear, tips=False), observe=observe_turn)


def turns_to_try(ctx: CameraContext, q: np.ndarray, obs: Observation, view: View) -> list[tuple[int, np.ndarray]]:
    """(link, turned pose) of every turn :func:`reacquire` tries, link by link in order: the
    links that qualify (see there), each with its joint turned by ``config.reacquire_deg``
    both ways within the joint limits (a turn the limits cancel is left out)."""
    model, config = ctx.model, ctx.config
    valid = view.fit.valid
    parent = parent_links(model)
    frame_q = np.array([model.q_index[f] for f in model.link_frame])
    anchored = np.where(parent >= 0, valid[np.maximum(parent, 0)], True)
    todo = np.flatnonzero(~valid & anchored & (obs.visibility.visible_share >= config.reacquire_min_visible)
                          & obs.samplers.ok & (frame_q >= 0)
                          & np.array([model.joint_kinds[f] == "revolute" for f in model.link_frame]))
    lo, hi = np.asarray(model.q_lower, float), np.asarray(model.q_upper, float)
    turns = []
    for link in todo:
        j = frame_q[link]
        for turn in np.radians([a * sign for a in config.reacquire_deg for sign in (1.0, -1.0)]):
            qc = q.copy()
            qc[j] = np.clip(q[j] + turn, lo[j], hi[j])
            if qc[j] != q[j]:
                turns.append((int(link), qc))
    return turns


def reacquire(ctx: CameraContext, q: np.ndarray, obs: Observation, view: View) -> tuple[View, np.ndarray]:
    """Search again for the links the prediction shows but the search did not find.

    A link qualifies when it has samplers, is predicted in full view (visible share of at least
    ``config.reacquire_min_visible``), no line was found for it and its parent link's line was
    (so its joint is where the model says): its own joint is then turned by each of
    ``config.reacquire_deg`` both ways (within the joint limits) and the view searched again; the
    turn whose search finds the link's line with the most boundary inliers, at least one per
    sampler, gives that link's line (and tip): a turn that only grazes the phalanx finds fewer
    inliers on a line several degrees off. A distal phalanx that moves faster than the filter
    predicts otherwise leaves its profiles and is not found again while the prediction lags.

    All turns of all qualifying links are searched as one batch (:func:`search_turns`) and only
    the winning turn's tip is searched for: the results are, bit for bit, those of observing and
    searching each turn's whole view (:func:`reacquire_full`). The turns' work is timed under the
    stages it belongs to (kinematics, visibility, ..., tips).
    """
    model = ctx.model
    if model.n_links == 1:  # a one-link view skips the cutting; the batch would cut by an empty pill
        return reacquire_full(ctx, q, obs, view)
    tried = turns_to_try(ctx, q, obs, view)
    if not tried:
        return view, np.zeros(model.n_links, bool)
    links = np.array([k for k, _ in tried])
    turns = search_turns(ctx, links, [qc for _, qc in tried])
    found = turns.view.fit

    def tip(i: int, link: int) -> tuple[np.ndarray, bool]:
        # The tip of the winning turn's link, from its line alone (the other links' lines only
        # place their own tips).
        line_ok = np.zeros(model.n_links, bool)
        p_ax, v_ax = np.zeros((model.n_links, 2)), np.tile([1.0, 0.0], (model.n_links, 1))
        line_ok[link], p_ax[link], v_ax[link] = found.valid[i], found.p_ax[i], found.v_ax[i]
        tf = find_tips(ctx, turns.observe(i), line_ok, p_ax, v_ax)
        ctx.clock.lap("tips")
        t = model.tip_links.index(link)
        return tf.tips[t], bool(tf.valid[t])

    return take_best_turns(ctx, view, links, found.valid, found.inliers.sum(axis=(1, 2)),
                           lambda i: {k: getattr(found, k)[i] for k in TURN_FIELDS}, tip)


def reacquire_full(ctx: CameraContext, q: np.ndarray, obs: Observation, view: View) -> tuple[View, np.ndarray]:
    """:func:`reacquire` the straightforward way, each turn's whole view observed and searched
    (the reference the batch is tested against; also a one-link model's)."""
    tried = turns_to_try(ctx, q, obs, view)
    links = np.array([k for k, _ in tried], int)
    views = [search_view(ctx, observe(ctx, qc)) for _, qc in tried]

    def tip(i: int, link: int) -> tuple[np.ndarray, bool]:
        t = ctx.model.tip_links.index(link)
        return views[i].tips.tips[t], bool(views[i].tips.valid[t])

    return take_best_turns(ctx, view, links, np.array([v.fit.valid[k] for v, k in zip(views, links)], bool),
                           np.array([v.fit.inliers[k].sum() for v, k in zip(views, links)], int),
                           lambda i: {f: getattr(views[i].fit, f)[links[i]] for f in TURN_FIELDS}, tip)


def take_best_turns(ctx: CameraContext, view: View, links: np.ndarray, valid: np.ndarray, score: np.ndarray,
                    row: Callable[[int], dict], tip: Callable[[int, int], tuple]) -> tuple[View, np.ndarray]:
    """``view`` with each turned link's fields from its best turn: turn ``i`` searched link
    ``links[i]``, found it (``valid[i]``) with ``score[i]`` boundary inliers; the turn with the
    most, at least one per sampler (the first of equals), gives ``row(i)`` and, for a tip link,
    ``tip(i, link)``. Returns the view and which links were re-acquired."""
    model = ctx.model
    fit = {k: getattr(view.fit, k).copy() for k in TURN_FIELDS}
    tips, tip_valid = view.tips.tips.copy(), view.tips.valid.copy()
    reacquired = np.zeros(model.n_links, bool)
    for link in dict.fromkeys(links.tolist()):
        best, best_score = None, view.profiles.values.shape[1] - 1   # at least one inlier per sampler
        for i in np.flatnonzero(links == link):  # in the order the turns were made
            if valid[i] and score[i] > best_score:
                best, best_score = int(i), score[i]
        if best is None:
            continue
        reacquired[link] = True
        for k, v in row(best).items():
            fit[k][link] = v
        if link in model.tip_links:
            t = model.tip_links.index(link)
            tips[t], tip_valid[t] = tip(best, link)
    return dataclasses.replace(view, fit=dataclasses.replace(view.fit, **fit),
                               tips=dataclasses.replace(view.tips, tips=tips, valid=tip_valid)), reacquired
