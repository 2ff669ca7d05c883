"""Several starts per frame (thesis ch. 7, "a bank of filters"; Cham and Rehg 1998).

A frame's features are extracted once, around the prediction; every start is then solved in one
vectorised call (``jax.vmap`` of :func:`~jaxhand.track._compiled.solve_frame`), each candidate
is judged by a robust image residual (:func:`image_merit`) times the front end's global image
score when it has one (:meth:`AbstractFrontEnd.score`), and the winner goes through the loss rule
and the filter (:func:`~jaxhand.track._compiled.finish_frame`).

The host/jit split: where the front end scores poses on the host, :class:`HypothesisProgram`
makes two calls per frame, the candidates (:func:`_candidates_jit`) and, after the host has
scored them and chosen (:func:`choose`), the commit of the winner (:func:`_commit_jit`), whose
results pack like the single-start program's. Where the merit alone chooses, one call does all
three (:func:`_chosen_jit`), and with :attr:`HypothesisConfig.coarse_steps` it runs every start a
few iterations and finishes only the best: a vmapped lane costs about what a single solve
costs on a CPU. The default tracker (one start) never comes here.

The starts, in order (their labels in :data:`LABELS`): the prediction; ``flips`` of it with the
most poorly observed joints pushed either way (:func:`flip_starts`); then the host's extra starts
(:func:`extra_starts`): the last solve, the runners-up carried from the frame before, the
caller's proposals, on the frames after a lost one, starts around the last good pose
(:func:`recovery_starts`) and, after a frame of low confidence, the finger the image supports least
bent either way (:func:`finger_starts`).
"""

from __future__ import annotations

import dataclasses
import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float

from .._errors import InputError
from ..camera import Perspective
from ..features import Features
from ..filter import GHKState
from ..kinematics import clip_q, pose
from ..model import Model
from ..residuals import ResidualArgs, feature_distances, residuals_and_jacobian
from ._compiled import (
    SCALARS,
    _Solved,
    _Static,
    features_ok,
    finish_frame,
    join_constants,
    solve_frame,
    split_constants,
    step_constants,
)
from ._config import HypothesisConfig, TrackConfig

__all__ = ["HypothesisProgram", "flip_starts", "fold_starts", "fold_turns", "image_merit", "choose", "runners_up",
           "recovery_starts", "extra_starts", "finger_starts", "too_far", "favour_prediction", "joint_angles", "LABELS"]

#: The kinds of start, as :attr:`StepReport.hypothesis` names the winner's.
LABELS = ("prediction", "flip", "fold", "last_solve", "rest", "carried", "proposal", "recover", "finger", "verify",
          "passage")


def _flippable(model: Model) -> np.ndarray:
    """Indices of the joint angles a flip may push (not the base's entries)."""
    return np.array([i for i, k in enumerate(model.q_kinds) if k == "angle" and i >= model.n_base_q], int)


def flip_starts(model: Model, rig: tuple, feats: tuple, q_pred, n: int, flip_rad, fractions
                ) -> Float[Array, "n nq"]:
    """``n`` starts from ``q_pred`` with its most poorly observed joints (the smallest columns of
    the image Jacobian at ``q_pred``, with the front end's weights) pushed by ``+flip_rad`` then
    ``-flip_rad``, worst joint first, clipped into the limits."""
    joints = _flippable(model)
    if n == 0 or len(joints) == 0:
        return jnp.broadcast_to(q_pred, (n,) + q_pred.shape)
    _, J = residuals_and_jacobian(q_pred, ResidualArgs(model=model, cameras=rig, features=feats,
                                                       fractions=fractions))
    norms = jnp.sqrt(jnp.sum(J[:, joints] ** 2, axis=0))
    order = jnp.asarray(joints)[jnp.argsort(norms)]
    pick = np.arange(n) // 2 % len(joints)
    sign = jnp.asarray(np.where(np.arange(n) % 2 == 0, 1.0, -1.0), q_pred.dtype)
    starts = jnp.broadcast_to(q_pred, (n,) + q_pred.shape)
    starts = starts.at[np.arange(n), order[pick]].add(sign * flip_rad)
    return jax.vmap(lambda q: clip_q(model, q))(starts)


def _fold_joints(model: Model) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For every flippable hinge: its q entry, its frame, and the first link it moves (the link
    of its own frame, else of its nearest descendant frame)."""
    children = {f: [c for c, p in enumerate(model.parents) if p == f] for f in range(len(model.parents))}
    rows = []
    for i in _flippable(model):
        frame = model.q_index.index(i)
        if model.joint_kinds[frame] != "revolute":
            continue
        queue = [frame]
        while queue:
            f = queue.pop(0)
            if f in model.link_frame:
                rows.append((i, frame, model.link_frame.index(f)))
                break
            queue.extend(children[f])
    return tuple(np.array(c, int) for c in zip(*rows)) if rows else (np.zeros(0, int),) * 3


def fold_turns(model: Model, camera, q) -> tuple[np.ndarray, Float[Array, " m"], Bool[Array, " m"]]:
    """For every flippable hinge (:func:`_fold_joints`): its q entry, the turn (rad, signed, the
    smaller of two) that brings the link it moves across the viewing ray at ``q`` (its fold), and
    whether the link ever lies across the ray (else the turn is meaningless)."""
    joints, frames, links = _fold_joints(model)
    if len(joints) == 0:
        return joints, jnp.zeros(0, q.dtype), jnp.zeros(0, bool)
    p = pose(model, q)
    omega, origin = p.frames[frames, :3, 2], p.frames[frames, :3, 3]
    d = p.link_end[links] - p.link_start[links]
    d = d / jnp.linalg.norm(d, axis=-1, keepdims=True)
    if isinstance(camera, Perspective):
        ray = origin + camera.R.T @ camera.t     # from the camera centre -R^T t to the joint
        ray = ray / jnp.linalg.norm(ray, axis=-1, keepdims=True)
    else:
        ray = jnp.broadcast_to(camera.R[2], origin.shape)
    # depth of the turned link: A cos(x) + B sin(x) + C; the fold is where it is 0
    wd, wv = jnp.sum(omega * d, -1), jnp.sum(omega * ray, -1)
    A = jnp.sum(ray * d, -1) - wd * wv
    B = jnp.sum(ray * jnp.cross(omega, d), -1)
    C = wd * wv
    R = jnp.sqrt(A * A + B * B) + 1e-12          # Guard: a link along its own axis
    ok = jnp.abs(C) < R
    phi, half = jnp.arctan2(B, A), jnp.arccos(jnp.clip(-C / R, -1.0, 1.0))
    turns = jnp.stack([phi + half, phi - half], -1)
    turns = jnp.arctan2(jnp.sin(turns), jnp.cos(turns))
    fold = jnp.take_along_axis(turns, jnp.argmin(jnp.abs(turns), -1)[:, None], -1)[:, 0]
    return joints, fold, ok


def fold_starts(model: Model, camera, q_pred, n: int) -> Float[Array, "n nq"]:
    """``n`` starts from ``q_pred``, each with one hinge reflected across its fold: the angle at
    which the link it moves lies across the viewing ray (:func:`fold_turns`). Both sides of the
    fold show the link at nearly the same place in the image with its depth reversed (exactly so
    for an orthographic camera and a hinge axis across the ray): the ambiguity a single view leaves
    (Sminchisescu and Triggs 2003, kinematic jumps). The hinges closest to their fold go first;
    a hinge whose link never lies across the ray gives the prediction itself."""
    joints, fold, ok = fold_turns(model, camera, q_pred)
    if n == 0 or len(joints) == 0:
        return jnp.broadcast_to(q_pred, (n,) + q_pred.shape)
    target = jnp.clip(q_pred[joints] + 2 * fold, model.q_lower[joints], model.q_upper[joints])
    order = jnp.argsort(jnp.where(ok, jnp.abs(fold), jnp.inf))[np.arange(n) % len(joints)]
    value = jnp.where(ok[order], target[order], q_pred[jnp.asarray(joints)[order]])
    starts = jnp.broadcast_to(q_pred, (n,) + q_pred.shape)
    return starts.at[np.arange(n), jnp.asarray(joints)[order]].set(value)


def image_merit(model: Model, rig: tuple, feats: tuple, q, fractions, scale_px, rms_scale_px, extra_sq=0.0
                ) -> Float[Array, ""]:
    """A candidate pose's merit in (0, 1] from its image residuals, comparable across starts: the
    robust RMS ``e_r = sqrt((sum w s^2 log(1 + (e/s)^2) + extra_sq) / sum w)`` of the feature
    distances ``e`` at ``q`` with the front end's weights ``w`` and the Cauchy scale ``s``, as
    ``1 / (1 + (e_r / rms_scale_px)^2)``; ``extra_sq`` (px^2) adds other squared residuals, the
    temporal prior's (:attr:`~jaxhand.track.PriorConfig.temporal_merit`). (The solves' own costs
    carry each start's reweighting.)"""
    total, weight = 0.0, 0.0
    for f, (e_link, e_tip) in zip(feats, feature_distances(model, rig, feats, q, fractions)):
        for e, w, valid in ((e_link, f.line_weight, f.line_valid), (e_tip, f.tip_weight, f.tip_valid)):
            w = jnp.where(valid, w, 0.0)
            total = total + jnp.sum(w * scale_px ** 2 * jnp.log1p((e / scale_px) ** 2))
            weight = weight + jnp.sum(w)
    rms = jnp.sqrt((total + extra_sq) / jnp.maximum(weight, 1e-12))   # Guard: no valid feature gives 0, not NaN
    return 1.0 / (1.0 + (rms / rms_scale_px) ** 2)


class _Candidates(eqx.Module):
    """Every start's solve (batched :class:`_Solved`), its merit (-1: a padding slot or a failed
    solve), the features' value check and the starts."""

    solved: _Solved
    merit: Float[Array, " k"]
    features_ok: Bool[Array, ""]
    starts: Float[Array, "k nq"]


def candidates(model: Model, rig: tuple, feats: tuple, ghk: GHKState, extras, extra_valid, build, fit_config,
               numbers, passes: int, priors, n_flips: int, flip_rad, n_folds: int = 0, terms: tuple = (),
               coarse_steps: int = 0) -> _Candidates:
    """The prediction, its flips and the ``extras`` (where ``extra_valid``) solved in one vmapped
    call, each with the frame's extra solve ``terms``; with ``coarse_steps`` only that many
    iterations of the first (gated) pass, to choose by (:func:`_chosen_jit`)."""
    fractions = fit_config.link_fractions
    q_pred = ghk.x
    starts = jnp.concatenate([q_pred[None], flip_starts(model, rig, feats, q_pred, n_flips, flip_rad, fractions),
                              fold_starts(model, rig[0], q_pred, n_folds), extras])
    valid = jnp.concatenate([jnp.ones(1 + n_flips + n_folds, bool), extra_valid])
    if coarse_steps:
        fit_config, passes = dataclasses.replace(fit_config, max_steps=coarse_steps), 0
    solved = jax.vmap(lambda q0: solve_frame(model, rig, feats, q_pred, q0, build, fit_config, numbers, passes,
                                             priors, terms))(starts)
    merit = jax.vmap(lambda q: image_merit(model, rig, feats, q, fractions, numbers.robust_scale_px,
                                           numbers.rms_scale_px, priors.merit_sq(q, q_pred)))(solved.q)
    merit = merit * solved.term_merit   # the measured terms judge too (solve_frame: 1 for the others)
    return _Candidates(solved=solved, merit=jnp.where(valid & solved.ok, merit, -1.0), features_ok=features_ok(feats),
                       starts=starts)


@functools.partial(jax.jit, static_argnums=0)
def _candidates_jit(static: _Static, consts: tuple, feats: tuple, ghk: tuple, extras, extra_valid, terms: tuple = ()):
    (model, rig, build, fit_config, numbers, passes, _, _, priors, _), (n_flips, flip_rad, n_folds, _) = \
        join_constants(static, consts)
    return candidates(model, rig, tuple(Features(*f) for f in feats), GHKState(*ghk), extras, extra_valid, build,
                      fit_config, numbers, passes, priors, n_flips, flip_rad, n_folds, terms)


def _pack(out):
    """:func:`finish_frame`'s results packed as :func:`_frame_jit` packs them."""
    dtype = out.q_solved.dtype
    scalars = jnp.stack([jnp.asarray(getattr(out, name), dtype) for name in SCALARS])
    return (out.q_solved, out.q_filtered, scalars), (out.ghk.x, out.ghk.v, out.ghk.a)


@functools.partial(jax.jit, static_argnums=0)
def _commit_jit(static: _Static, consts: tuple, cands: _Candidates, index, ghk: tuple, q_last):
    """The candidate ``index`` through :func:`finish_frame`, packed as :func:`_frame_jit` packs."""
    (model, _, _, _, numbers, _, use_filter, hold, _, report_solve), _ = join_constants(static, consts)
    solved = jax.tree_util.tree_map(lambda a: a[index], cands.solved)
    return _pack(finish_frame(model, GHKState(*ghk), q_last, solved, cands.features_ok, numbers, use_filter, hold,
                              report_solve))


@functools.partial(jax.jit, static_argnums=0)
def _chosen_jit(static: _Static, consts: tuple, feats: tuple, ghk: tuple, extras, extra_valid, q_last,
                terms: tuple = (), max_step=jnp.inf, margin=0.0):
    """The whole frame in one call where the merit alone chooses (no host score): the candidates,
    the winner (the first best merit, as :func:`choose` picks) and its commit; also every
    candidate's q and merit, and the winner's index. With ``coarse_steps`` the candidates are
    the coarse solves, and the winner's start is solved again in full: a frame whose coarse
    choice is the full one gives the full path's numbers. A candidate other than the prediction's
    that moves a joint more than ``max_step`` (rad) from ``q_last`` cannot win (:func:`too_far`),
    and the prediction's merit counts ``1 + margin`` times (:func:`favour_prediction`)."""
    (model, rig, build, fit_config, numbers, passes, use_filter, hold, priors, report_solve), \
        (n_flips, flip_rad, n_folds, coarse_steps) = join_constants(static, consts)
    feats, ghk = tuple(Features(*f) for f in feats), GHKState(*ghk)
    cands = candidates(model, rig, feats, ghk, extras, extra_valid, build, fit_config, numbers, passes, priors,
                       n_flips, flip_rad, n_folds, terms, coarse_steps)
    merit = jnp.where(too_far(cands.solved.q, q_last, joint_angles(model), max_step, xp=jnp), -1.0, cands.merit)
    merit = favour_prediction(merit, margin, xp=jnp)
    index = jnp.argmax(merit)
    if coarse_steps:
        solved = solve_frame(model, rig, feats, ghk.x, cands.starts[index], build, fit_config, numbers, passes,
                             priors, terms)
    else:
        solved = jax.tree_util.tree_map(lambda a: a[index], cands.solved)
    out = finish_frame(model, ghk, q_last, solved, cands.features_ok, numbers, use_filter, hold, report_solve)
    return _pack(out), (cands.solved.q, merit, index)


class HypothesisProgram:
    """The multiple-start frame program of one tracker (its constants split once, like
    :class:`~jaxhand.track._compiled.FrameProgram`, ``temporal`` as there). Each number of extra
    starts compiles once."""

    def __init__(self, model: Model, rig: tuple, config: TrackConfig, theta: float, dt_s: float,
                 temporal: bool = True):
        hyp = config.hypotheses
        parts = (step_constants(model, rig, config, theta, dt_s, temporal),
                 (hyp.flips, jnp.asarray(float(np.radians(hyp.flip_deg))), hyp.folds, hyp.coarse_steps))
        self._consts, self._static = split_constants(parts)
        self.n_flips, self.n_folds = hyp.flips, hyp.folds

    def candidates(self, feats: tuple, ghk: tuple, extras, extra_valid, terms: tuple = ()) -> _Candidates:
        """Every start's solve and merit (device arrays)."""
        return _candidates_jit(self._static, self._consts, feats, ghk, extras, extra_valid, terms)

    def commit(self, cands: _Candidates, index: int, ghk: tuple, q_last):
        """``(q_solved, q_filtered, scalars), (x, v, a)`` of the chosen candidate."""
        return _commit_jit(self._static, self._consts, cands, jnp.asarray(index), ghk, q_last)

    def chosen(self, feats: tuple, ghk: tuple, extras, extra_valid, q_last, terms: tuple = (), max_step=np.inf,
               margin: float = 0.0):
        """``(packed results as commit's), (qs, merit, winner)`` of the frame in one call, the
        winner chosen by the merit alone among the candidates within ``max_step`` (rad) of
        ``q_last``, the prediction's merit favoured by ``margin`` (:func:`_chosen_jit`; device arrays)."""
        dtype = jnp.asarray(q_last).dtype
        return _chosen_jit(self._static, self._consts, feats, ghk, extras, extra_valid, q_last, terms,
                           jnp.asarray(max_step, dtype), jnp.asarray(margin, dtype))


def choose(merit: np.ndarray, scores: np.ndarray | None = None, margin: float = 0.0) -> tuple[int, np.ndarray]:
    """The winner's index and every candidate's total merit: the residual merit times the image
    score (when there is one), the prediction's favoured by ``margin`` (:func:`favour_prediction`);
    a tie goes to the earlier start (the prediction first)."""
    total = np.asarray(merit, float) * (1.0 if scores is None else np.asarray(scores, float))
    total = np.where(np.asarray(merit) < 0, -1.0, total)   # padding slots and failed solves never win
    total = favour_prediction(total, margin)
    return int(np.argmax(total)), total


def favour_prediction(merit, margin, xp=np):
    """``merit`` (k,) with the first candidate's (the prediction's) times ``1 + margin`` where it
    solved: another start must beat it by that share to win
    (:attr:`~jaxhand.track.HypothesisConfig.prediction_margin`). ``xp`` as :func:`too_far`'s."""
    merit = xp.asarray(merit)
    first = xp.arange(merit.shape[0]) == 0
    return xp.where(first & (merit > 0), merit * (1.0 + margin), merit)


def joint_angles(model: Model) -> np.ndarray:
    """(n_q,) bool: the joint angles of ``model`` (angle entries that are not the base's)."""
    return np.asarray(model.is_angle) & (np.arange(model.n_q) >= model.n_base_q)


def too_far(qs, q_last, joints: np.ndarray, max_rad, xp=np):
    """(k,) bool: which candidates (k, n_q) move some of ``joints`` (a mask) more than ``max_rad``
    from ``q_last``; the first (the prediction's) never is. ``xp``: NumPy on the host,
    ``jax.numpy`` in the compiled frame."""
    far = xp.max(xp.abs(xp.asarray(qs) - xp.asarray(q_last))[:, joints], axis=1, initial=0.0) > max_rad
    return far & (xp.arange(far.shape[0]) > 0)


def runners_up(qs: np.ndarray, total: np.ndarray, winner: int, n: int, margin: float, min_rad: float,
               angle: np.ndarray) -> np.ndarray:
    """Up to ``n`` candidates the merit could not tell from the winner (at least ``margin`` of its
    merit) that differ from it (and from each other) by more than ``min_rad`` in some joint angle,
    best first: the starts carried to the next frame, (m, n_q)."""
    kept: list[np.ndarray] = [qs[winner]]
    if n == 0 or total[winner] <= 0:
        return qs[:0]
    for i in np.argsort(-total, kind="stable"):
        if len(kept) > n or total[i] < margin * total[winner]:
            break
        if all(np.max(np.abs(qs[i] - k)[angle]) > min_rad for k in kept):
            kept.append(qs[i])
    return np.asarray(kept[1:]).reshape(-1, qs.shape[1])


def recovery_starts(model: Model, q_good: np.ndarray, hyp: HypothesisConfig, frame: int) -> np.ndarray:
    """``hyp.recover`` starts around the last good pose: Gaussian in every joint angle
    (``recover_deg``) and length (``recover_mm``), the quaternion kept, drawn from
    ``(hyp.seed, frame)`` and clipped into the limits."""
    kinds = np.array(model.q_kinds)
    sigma = np.where(kinds == "angle", np.radians(hyp.recover_deg), np.where(kinds == "length", hyp.recover_mm, 0.0))
    rng = np.random.default_rng((hyp.seed, frame))
    starts = q_good + sigma * rng.standard_normal((hyp.recover, model.n_q))
    return np.clip(starts, np.asarray(model.q_lower), np.asarray(model.q_upper))


def finger_starts(q_pred: np.ndarray, joints: np.ndarray, bends_deg, lower: np.ndarray, upper: np.ndarray
                  ) -> np.ndarray:
    """(len(bends_deg), n_q) starts: ``q_pred`` with each of ``joints`` moved by each bend towards
    the wider side of its range (a hand's flexion; a negative bend the other way), clipped into the limits."""
    toward = np.where(np.abs(upper[joints]) >= np.abs(lower[joints]), 1.0, -1.0)
    starts = np.tile(np.asarray(q_pred, float), (len(bends_deg), 1))
    starts[:, joints] += np.radians(np.asarray(bends_deg, float))[:, None] * toward
    return np.clip(starts, lower, upper)


def check_proposals(model: Model, proposals, frame: int) -> np.ndarray:
    """A caller's starting poses as a (k, n_q) array clipped into the limits (k may be 0).

    Raises:
        InputError: not (k, n_q) numbers, or not finite.
    """
    try:
        p = np.asarray(proposals, float)
    except (TypeError, ValueError) as err:
        raise InputError(f"proposals: frame {frame}: cannot read as numbers ({err})") from None
    if p.ndim == 1 and p.shape[0] == model.n_q:
        p = p[None]
    if p.ndim != 2 or p.shape[1] != model.n_q:
        raise InputError(f"proposals: frame {frame}: expected (k, {model.n_q}) starting poses for {model.name!r}, "
                         f"got shape {p.shape}")
    if not np.all(np.isfinite(p)):
        raise InputError(f"proposals: frame {frame}: a starting pose is not finite")
    return np.clip(p, np.asarray(model.q_lower), np.asarray(model.q_upper))


def extra_starts(model: Model, hyp: HypothesisConfig, q_pred: np.ndarray, q_solved: np.ndarray | None,
                 carried: np.ndarray | None, proposals: np.ndarray | None, q_good: np.ndarray | None, frame: int,
                 finger: np.ndarray | None = None, rest_ok: bool = True, rest_keep: np.ndarray | None = None
                 ) -> tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
    """The host's extra starts of a frame, their validity and labels: the last solve, the rest pose, the carried
    runners-up (padded to ``hyp.carry`` slots with the prediction, not valid, so the program's
    shape does not change), the proposals, the recovery starts around ``q_good`` (None: the
    frame before was not lost) and the weakest finger's bends of the prediction (``finger``: its
    flexion hinges' q entries; None: the frame before was confident). The rest start is kept
    (not valid, so the program's shape does not change) unless ``rest_ok``; the entries of the
    mask ``rest_keep`` stay at the prediction in it."""
    rows, valid, labels = [], [], []

    def add(qs, label, ok=True):
        for q in np.asarray(qs, float).reshape(-1, model.n_q):
            rows.append(q)
            valid.append(ok)
            labels.append(label)

    if hyp.last_solve:
        add(q_pred if q_solved is None else q_solved, "last_solve", q_solved is not None)
    if hyp.rest:   # the model's default joint angles, the base where the prediction has it
        rest = np.asarray(model.q_default, float).copy()
        rest[:model.n_base_q] = q_pred[:model.n_base_q]
        if rest_keep is not None:
            rest[rest_keep] = q_pred[rest_keep]
        add(rest, "rest", rest_ok)
    if hyp.carry:
        have = np.zeros((0, model.n_q)) if carried is None else carried[:hyp.carry]
        add(have, "carried")
        add(np.tile(q_pred, (hyp.carry - len(have), 1)), "carried", ok=False)
    if proposals is not None:
        add(proposals, "proposal")
    if q_good is not None and hyp.recover:
        add(recovery_starts(model, q_good, hyp, frame), "recover")
    if finger is not None and len(finger) and hyp.finger_level:
        add(finger_starts(q_pred, finger, hyp.finger_deg, np.asarray(model.q_lower), np.asarray(model.q_upper)),
            "finger")
    return np.asarray(rows).reshape(-1, model.n_q), np.asarray(valid, bool), tuple(labels)
