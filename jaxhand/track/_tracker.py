"""The tracker: predict, extract features, solve, filter, once per frame (thesis chs. 4-6).

Per frame k (thesis fig. 1.2):

1. **predict** the state q̂_k with the g-h-k filter (thesis eqs. 5.4-5.6), clipped to the
   joint limits;
2. **extract features** from every camera around the prediction (the front end,
   :class:`~jaxhand.track.AbstractFrontEnd`);
3. **solve** for the pose q̃_k from those features starting at q̂_k (configurable solver and
   iterations, including the thesis's fast mode of one update per frame), with robust passes;
4. **filter**: refine q̃_k with the g-h-k update (eqs. 5.1-5.3) into the reported estimate;
5. score the frame: residual RMS (px) and the share of valid features give a confidence in
   [0, 1] and a loss-of-track flag, lowered by the front end's image score of the estimate
   where it gives one (:func:`~jaxhand.track.judge_frame`). A failed or non-finite solve keeps
   the prediction. With :attr:`HypothesisConfig.verify_below`, a finger the image hardly
   supports is first searched again from starts of its own (:mod:`jaxhand.track._verify`); with
   :attr:`HypothesisConfig.fold_passage_deg`, a hinge that turned back at its fold is tried
   through it (:mod:`jaxhand.track._passage`).

Steps 3-5 run as one compiled program (:mod:`jaxhand.track._compiled`); the loop over frames is
host Python.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from typing import no_type_check

import jax
import jax.numpy as jnp
import numpy as np

from .._errors import InputError
from ..camera import as_rig
from ..features import Features, raise_on_values, validate_features
from ..filter import GHKState, ghk_init
from ..kinematics import validate_q
from ..model import Model
from ..solve import STATUS_NAMES
from ._compiled import FEATURE_FIELDS, SCALARS, FrameProgram
from ._config import TrackConfig
from ._flexion import flexion_hinges
from ._frontend import AbstractFrontEnd
from ._hypotheses import (
    HypothesisProgram,
    check_proposals,
    choose,
    extra_starts,
    fold_starts,
    fold_turns,
    joint_angles,
    runners_up,
    too_far,
)
from ._passage import crossed, push, turned_back
from ._score import held_filter, judge_frame, reported_confidence
from ._seen import SeenProgram
from ._state import StepReport, TrackState
from ._support import (
    finger_of_frame,
    finger_of_link,
    finger_supports,
    judge_weights,
    moved_links,
    support_confidence,
    tip_link_scores,
    unexplained_confidence,
    whole_finger_confidence,
)
from ._verify import beats, holds, verify_starts

__all__ = ["Tracker"]


@dataclasses.dataclass(frozen=True)
class _Picked:
    """The first round's choice among the starts: the winner's packed results, its label, the
    runners-up to carry, the number of starts, and the seconds the front end's score took."""

    results: tuple = ()
    label: str = "prediction"
    carried: np.ndarray | None = None
    starts: int = 1
    score_s: float = 0.0


class Tracker:
    """Tracks one model through frames from one or more cameras.

    Args:
        model: the kinematic model.
        cameras: a camera or a rig (tuple of cameras), in the order images are passed.
        frontend: what measures the features (:class:`~jaxhand.ImageFrontEnd`,
            :class:`~jaxhand.ExactFrontEnd`, or any :class:`~jaxhand.track.AbstractFrontEnd`).
        config: the run's settings (:class:`~jaxhand.TrackConfig`).
        dt_s: frame interval (s).
    """

    @no_type_check   # validates its arguments itself (InputError naming the argument), which a checker would preempt
    def __init__(self, model: Model, cameras, frontend: AbstractFrontEnd, config: TrackConfig | None = None,
                 dt_s: float = 1 / 25):
        if not isinstance(frontend, AbstractFrontEnd):
            raise InputError(f"frontend: expected an AbstractFrontEnd, got {type(frontend).__name__}")
        if model.n_links == 0:
            raise InputError(f"model {model.name!r} has no link pills: the tracker measures the edges and tips of "
                             "links, so give the moving frames a link (link = {{ axis, length_mm, radius_mm }})")
        if model.n_q == 0:
            raise InputError(f"model {model.name!r} has no moving joint and a fixed base: there is nothing to track "
                             "(make a joint revolute or prismatic, or the base planar or free)")
        self.model, self.cameras, self.frontend = model, as_rig(cameras), frontend
        self.config = config = TrackConfig() if config is None else config
        if not dt_s > 0:
            raise InputError(f"dt_s must be > 0, got {dt_s}")
        self.dt_s = float(dt_s)
        #: the g-h-k discount per frame at this frame interval (FilterConfig.theta_rate_hz)
        self.theta = config.filter.theta_per_frame(self.dt_s)
        self._program = FrameProgram(model, self.cameras, config, self.theta, self.dt_s)
        self._hypotheses = HypothesisProgram(model, self.cameras, config, self.theta, self.dt_s)
        # the same programs without the temporal prior, for a frame after a doubtful one
        self._untrusted = ((FrameProgram(model, self.cameras, config, self.theta, self.dt_s, temporal=False),
                            HypothesisProgram(model, self.cameras, config, self.theta, self.dt_s, temporal=False))
                           if config.prior.temporal_min_confidence else (self._program, self._hypotheses))
        # no host score to judge the starts by: the frame's choice is made in its compiled program
        self._choose_on_device = not (frontend.scores or config.support.judge_power > 0)
        self._rounds = 1 + (config.reextract if frontend.reextracts else 0)
        self._dtype = jnp.asarray(0.0).dtype   # the working precision of the compiled step
        self._lower, self._upper = np.asarray(model.q_lower), np.asarray(model.q_upper)
        self._ghk_tree = jax.tree_util.tree_structure(ghk_init(jnp.zeros(model.n_q)))
        nl, nt = model.n_links, model.n_tips
        self._shapes = ((nl, 3), (nl,), (nl,), (nt, 2), (nt,), (nt,))
        self._finger = finger_of_link(model)
        digit = finger_of_frame(model)
        self._flexion = flexion_hinges(model, digit)
        fingers = [f for f in range(model.n_frames) if digit[f] in self._flexion and model.q_index[f] >= model.n_base_q]
        self._rest_keep = None if config.hypotheses.rest_fingers else np.isin(
            np.arange(model.n_q), [model.q_index[f] for f in fingers])
        self._moves = moved_links(model)
        self._seen = SeenProgram(model, self.cameras, config.fit.link_fractions)
        self._is_angle = np.asarray(model.is_angle)
        self._joint_angle = joint_angles(model)
        # a doubtful finger's starts and a hinge tried through its fold, each solved without the
        # temporal prior (HypothesisConfig.verify_below, fold_passage_deg; the latter with one camera)
        hyp = config.hypotheses
        self._passes = bool(hyp.fold_passage_deg) and len(self.cameras) == 1
        self._verify_program = (FrameProgram(model, self.cameras, config, self.theta, self.dt_s, temporal=False)
                                if hyp.verify_below or self._passes else None)
        self._folds = jax.jit(lambda q: fold_starts(model, self.cameras[0], q, model.n_q)) if hyp.verify_below else None
        self._fold_turns = jax.jit(lambda q: fold_turns(model, self.cameras[0], q)[1:]) if self._passes else None
        self._fold_joints = (fold_turns(model, self.cameras[0], jnp.asarray(model.q_default))[0] if self._passes
                             else None)

    def _feature_arrays(self, features) -> tuple[tuple, ...]:
        """The front end's features as one tuple of :data:`FEATURE_FIELDS` arrays per camera,
        after the cheap host-side count and shape checks (values are checked in the program)."""
        feats = tuple(features)
        out = []
        if len(feats) == len(self.cameras) and all(isinstance(f, Features) for f in feats):
            for f in feats:
                arrays = []
                for name, shape in zip(FEATURE_FIELDS, self._shapes):
                    a = getattr(f, name)
                    if np.shape(a) != shape:
                        break
                    want = bool if name.endswith("valid") else self._dtype
                    if not (isinstance(a, jax.Array) and a.dtype == want and not a.weak_type):
                        a = jnp.asarray(np.asarray(a), dtype=want)
                    arrays.append(a)
                else:
                    out.append(tuple(arrays))
                    continue
                break
        if len(out) != len(self.cameras):
            validate_features(self.model, self.cameras, feats)   # raises, naming the problem
            raise InputError(f"features: expected one Features per camera ({len(self.cameras)})")
        return tuple(out)

    def init(self, q0, frontend_state=None) -> TrackState:
        """The state before the first frame: the filter sits at q0 with zero velocity."""
        q0 = validate_q(self.model, q0, name="initial pose", within_limits=True)
        return TrackState(ghk=ghk_init(jnp.asarray(q0)), frontend_state=frontend_state, q_last=q0, q_trusted=q0)

    def _extra_starts(self, state: TrackState, proposals, frame: int):
        """The host's extra starts of this frame (:func:`extra_starts`), or None when the frame has
        the prediction alone (the single-start program, as by default)."""
        hyp = self.config.hypotheses
        proposals = None if proposals is None else check_proposals(self.model, proposals, frame)
        if not (hyp.enabled or proposals is not None):
            return None
        extras = extra_starts(self.model, hyp, np.asarray(state.ghk.x), state.q_solved, state.carried, proposals,
                              state.q_last if state.lost else None, frame, self._flexion.get(state.weak_finger),
                              rest_ok=hyp.rest_below >= 1.0 or state.confidence < hyp.rest_below,
                              rest_keep=self._rest_keep)
        return extras if len(extras[0]) or hyp.flips or hyp.folds else None   # recovery alone: a frame after a good one

    def _solve_hypotheses(self, program: HypothesisProgram, feats, ghk, state: TrackState, extras, images, fe_state,
                          terms: tuple) -> _Picked:
        """Every start solved in one call of ``program``, the front end's score of the candidates,
        the winner committed (:mod:`jaxhand.track._hypotheses`); without a host score, all in one call."""
        rows, valid, labels = extras
        hyp = self.config.hypotheses
        rows, valid = np.asarray(rows, self._dtype), np.asarray(valid)   # jit takes NumPy arrays faster
        trusted = state.confidence >= hyp.step_trust   # the last frame's estimate may hold this one back
        max_step = float(np.radians(hyp.max_step_deg)) if trusted and hyp.max_step_deg else np.inf
        margin = hyp.prediction_margin if trusted else 0.0
        if self._choose_on_device:   # one call: the starts, the choice by merit and the commit
            (packed, ghk_next), chosen = program.chosen(feats, ghk, rows, valid, state.q_last, terms, max_step,
                                                        margin)
            packed, (qs, merit, winner) = jax.device_get((packed, chosen))   # one fetch; the filter state stays
            results, winner, t_score = (packed, ghk_next), int(winner), 0.0
            total = choose(merit)[1] if hyp.carry else merit   # the device favoured the prediction already
        else:
            cands = program.candidates(feats, ghk, rows, valid, terms)
            qs, merit = (np.asarray(a) for a in jax.device_get((cands.solved.q, cands.merit)))
            merit = np.where(too_far(qs, state.q_last, self._joint_angle, max_step), -1.0, merit)
            t0 = time.perf_counter()
            winner, total = choose(merit, self._scores(images, qs, merit, fe_state), margin)
            t_score = time.perf_counter() - t0
            results = program.commit(cands, winner, ghk, state.q_last)
        carried = runners_up(qs, total, winner, hyp.carry, hyp.carry_margin, float(np.radians(hyp.carry_min_deg)),
                             self._is_angle)
        labels = ("prediction",) + ("flip",) * self._hypotheses.n_flips + ("fold",) * self._hypotheses.n_folds + labels
        return _Picked(results, labels[winner], carried, len(merit), t_score)

    def _scores(self, images, qs: np.ndarray, merit: np.ndarray, fe_state) -> np.ndarray | None:
        """The front end's image score of the candidates that solved (0 for the others), times
        their finger support's judge weight (``support.judge_power``), or None when neither applies."""
        good = np.flatnonzero(merit >= 0)
        scores = self.frontend.score(images, qs[good], fe_state) if len(good) else None
        if scores is not None:
            scores = np.asarray(scores, float)
            if scores.shape != good.shape or not np.all((scores >= 0) & (scores <= 1)):
                raise InputError(f"{type(self.frontend).__name__}.score: expected {len(good)} scores in [0, 1] (one "
                                 f"per candidate pose), got {np.array2string(scores, precision=3)}")
        config = self.config.support
        if config.judge_power > 0 and len(good):
            measured = [self.frontend.support(images, q, fe_state, config.margin_px) for q in qs[good]]
            if all(m is not None for m in measured):
                weights = judge_weights([m.link_score for m in measured], self._finger, config.judge_power)
                scores = weights if scores is None else scores * weights
        if scores is None:
            return None
        full = np.zeros(len(merit))
        full[good] = scores
        return full

    def _support(self, images, q, fe_state) -> tuple[float, dict[int, float], np.ndarray, float]:
        """The image's support of ``q`` as a confidence, the lowest of the weakest finger's (by its
        tip's link alone with ``support.tip_links``), the weakest whole finger's
        (``support.whole_lost``) and the unexplained foreground's
        (:mod:`jaxhand.track._support`; 1 when the front end measures none), each finger's
        support (all its links), the q entries that move no judged link (hidden joints), and the
        confidence of the fingers' support alone (without the unexplained foreground)."""
        config = self.config.support
        measured = self.frontend.support(images, q, fe_state, config.margin_px)
        if measured is None:
            return 1.0, {}, np.zeros(0, int), 1.0
        fingers = finger_supports(measured.link_score, self._finger)
        judged = (finger_supports(tip_link_scores(measured.link_score, self.model.tip_links), self._finger)
                  if config.tip_links else fingers)
        weakest = min(judged.values(), default=float("nan"))
        finger_confidence = min(support_confidence(weakest, config), whole_finger_confidence(fingers, config))
        confidence = min(finger_confidence, unexplained_confidence(measured.unexplained_px, config))
        judged_link = np.isfinite(np.asarray(measured.link_score, float).reshape(-1, self.model.n_links)).any(0)
        hidden = np.flatnonzero(~(self._moves & judged_link).any(1) & self._moves.any(1))
        return confidence, fingers, hidden, finger_confidence

    def step(self, state: TrackState, images: Sequence[np.ndarray | None], frame: int = 0, time_s: float = 0.0,
             proposals=None, terms: tuple = (), learn: bool = True) -> tuple[TrackState, StepReport]:
        """Process one frame (one image per camera; ``frame`` is passed to the front end).

        After the front end, the compiled frame program runs and its results come back in one
        transfer; the timings ``features`` (front end), ``solve`` (the program) and ``filter``
        (the report on the host) split the frame. With ``config.reextract`` (and a front end
        whose ``reextracts`` is true) the front end and the program run again from the solved
        pose; ``features`` and ``solve`` then add up every round.

        With :attr:`TrackConfig.hypotheses` or ``proposals`` (a caller's (k, n_q) starting poses
        for this frame, e.g. a landmark fit), the first round solves every start in one call and
        keeps the best (:mod:`jaxhand.track._hypotheses`; the front end's ``score`` timed as
        ``score``); later rounds refine the winner. ``terms``: this frame's extra solve terms
        (e.g. :class:`~jaxhand.landmarks.LandmarkTerm`), outside the frame's score. ``learn``
        False: the front end does not learn from the frame (:meth:`AbstractFrontEnd.observe`),
        as when a frame is tracked again (:mod:`jaxhand.track._review`).
        """
        if len(images) != len(self.cameras):
            raise InputError(f"expected one image per camera ({len(self.cameras)}), got {len(images)}")
        if state.confidence < self.config.prior.restore_hidden_below and len(state.hidden):
            state = self._restore(state, np.asarray(state.hidden, int), state.q_trusted)
        hold = self.config.prior.hold_unseen_frames
        if hold and state.unseen is not None:
            state = self._restore(state, np.flatnonzero(state.unseen >= hold), state.q_seen)
        q_pred = state.ghk.x
        ghk = (state.ghk.x, state.ghk.v, state.ghk.a)
        t_features = t_solve = 0.0
        q_start, fe_state = q_pred, state.frontend_state
        extras = self._extra_starts(state, proposals, frame)
        trusted = state.confidence >= self.config.prior.temporal_min_confidence
        program, hypotheses = (self._program, self._hypotheses) if trusted else self._untrusted
        picked = _Picked()
        for r in range(self._rounds):
            t0 = time.perf_counter()
            extracted = self.frontend.extract(images, q_start, fe_state, frame)
            fe_state = extracted.state
            t1 = time.perf_counter()
            feats = self._feature_arrays(extracted.features)
            frame_terms = tuple(extracted.terms) + tuple(terms)
            if r == 0 and extras is not None:
                picked = self._solve_hypotheses(hypotheses, feats, ghk, state, extras, images, fe_state,
                                                frame_terms)
                (q_meas, filtered, scalars), ghk_next = picked.results
            else:
                (q_meas, filtered, scalars), ghk_next = program(feats, ghk, state.q_last, q_start, frame_terms)
            q_pred_host, q_meas, filtered, scalars = jax.device_get((q_pred, q_meas, filtered, scalars))  # one fetch
            out = dict(zip(SCALARS, scalars.tolist()))
            t2 = time.perf_counter()
            t_features, t_solve = t_features + (t1 - t0), t_solve + (t2 - t1) - (picked.score_s if r == 0 else 0.0)
            if not out["features_ok"] or out["lost"]:  # nothing better to search around
                break
            q_start = np.clip(q_meas, self._lower, self._upper)
        t_verify, measured, folds = None, None, state.fold_offsets
        if self._verify_program is not None and out["features_ok"] and not out["lost"]:
            t0 = time.perf_counter()
            measured = self._support(images, filtered, fe_state)
            found = (self._verify(images, state, ghk, filtered, measured, fe_state, frame, terms)
                     if self.config.hypotheses.verify_below else None)
            if found is not None:
                (q_meas, filtered, out, ghk_next, fe_state, extracted), measured = found, None
                feats = self._feature_arrays(extracted.features)
                picked = dataclasses.replace(picked, label="verify")
            if self._passes:
                found, folds = self._passage(images, state, ghk, filtered, measured, fe_state, frame, terms)
                if found is not None:
                    (q_meas, filtered, out, ghk_next, fe_state, extracted), measured = found, None
                    feats = self._feature_arrays(extracted.features)
                    picked = dataclasses.replace(picked, label="passage")
            t_verify = time.perf_counter() - t0
        if not out["features_ok"]:
            raise_on_values(tuple(extracted.features))   # raises, naming camera and field
            raise InputError("features: a value check failed (see jaxhand.features.feature_value_checks)")
        ok, lost = bool(out["solved_ok"]), bool(out["lost"])
        t3 = time.perf_counter()
        timings = {"features": t_features, "solve": t_solve, "filter": t3 - t2 - (t_verify or 0.0)}
        if t_verify is not None:   # the doubtful finger's and the passages' searches and solves, and their support
            timings["verify"] = t_verify
        confidence, lost, image_score, reference = judge_frame(self.frontend, images, filtered, fe_state,
                                                               out["confidence"], lost, self.config.loss,
                                                               state.score_reference)
        if lost and not out["lost"] and self.config.loss.hold:   # lost by the image score: hold still
            filtered, ghk_next = np.asarray(state.q_last), held_filter(state.q_last)
        weak, finger_level, hidden = -1, self.config.hypotheses.finger_level, np.zeros(0, int)
        if (self.config.support.enabled or finger_level) and not lost:
            support, fingers, hidden, finger_support = (measured if measured is not None
                                                        else self._support(images, filtered, fe_state))
            doubt = confidence   # the unexplained foreground names no finger to bend
            if self.config.support.enabled:
                confidence, doubt = min(confidence, support), min(confidence, finger_support)
            if doubt < finger_level and fingers:
                weak = min(fingers, key=fingers.get)
        if np.isfinite(image_score) or extras is not None:
            timings["score"] = picked.score_s + (time.perf_counter() - t3)
            t3 = time.perf_counter()
        if not lost and self.config.refresh_templates:
            fe_state = self.frontend.refresh(images, q_meas, fe_state)
            timings["templates"] = time.perf_counter() - t3
        if not lost and learn:
            self.frontend.observe(images, filtered)
        t4 = time.perf_counter()   # which joints the final features saw, at the reported pose
        seen = self._seen(feats, filtered)
        timings["seen"] = time.perf_counter() - t4
        diag = extracted.diagnostics
        timings.update({f"features.{k}": v for k, v in diag.timings_s.items()})
        report = StepReport(frame=frame, time_s=time_s, q_pred=np.asarray(q_pred_host), q_solved=q_meas,
                            q_filtered=filtered, cost=out["cost"] if ok else float("nan"), rms_px=out["rms_px"],
                            iterations=int(out["iterations"]), status=STATUS_NAMES[int(out["status"])],
                            valid_share=out["valid_share"], lost=lost,
                            confidence=reported_confidence(confidence, self.config.loss.doubt_level),
                            timings_s=timings, diagnostics=diag, image_score=image_score, hypothesis=picked.label,
                            starts=picked.starts, reinitialised=state.lost and not lost, seen=seen)
        ghk_next = jax.tree_util.tree_unflatten(self._ghk_tree, ghk_next)
        unseen, q_seen = self._unseen(state, extracted.features, filtered) if hold and not lost else (
            state.unseen, state.q_seen)
        return TrackState(ghk=ghk_next, frontend_state=fe_state, q_last=filtered, score_reference=reference,
                          q_solved=q_meas, carried=picked.carried, lost=lost, weak_finger=weak,
                          confidence=confidence, hidden=hidden,
                          q_trusted=filtered if confidence >= self.config.prior.restore_hidden_below
                          else state.q_trusted, unseen=unseen, q_seen=q_seen,
                          fold_offsets=None if lost else folds), report

    def _search_from(self, images, q0: np.ndarray, fe_state, frame: int, ghk: tuple, state: TrackState,
                     terms: tuple):
        """Features searched around ``q0`` and a solve from there without the temporal prior (a
        doubtful finger's start, a passage): ``(q_solved, q_filtered, scalars, filter state,
        extraction)``, the filter state left on the device."""
        extracted = self.frontend.extract(images, q0, fe_state, frame)
        feats = self._feature_arrays(extracted.features)
        (q_meas, filtered, scalars), ghk_next = self._verify_program(feats, ghk, state.q_last, q0,
                                                                     tuple(extracted.terms) + tuple(terms))
        q_meas, filtered, scalars = jax.device_get((q_meas, filtered, scalars))
        return q_meas, filtered, dict(zip(SCALARS, scalars.tolist())), ghk_next, extracted

    @staticmethod
    def _usable(out: dict) -> bool:
        """Whether a frame program's scalars say its features and solve are good and it is not lost."""
        return bool(out["features_ok"] and out["solved_ok"]) and not out["lost"]

    def _verify(self, images, state: TrackState, ghk: tuple, q: np.ndarray, measured: tuple, fe_state, frame: int,
                terms: tuple):
        """The best of the doubtful finger's starts (:mod:`jaxhand.track._verify`), each with its own
        features and solve, as ``(q_solved, q_filtered, scalars, filter state, front-end state,
        extraction)``, where one beats the finger supports of the estimate ``q`` (``measured``: its
        :meth:`_support`); else None. The filter forgets the finger's velocity: the jump is a
        correction, not motion."""
        hyp = self.config.hypotheses
        _, fingers, _, support = measured   # the fingers' own support: a speck of foreground is no finger's
        weak = min(fingers, key=fingers.get) if fingers else None
        if support >= hyp.verify_below or weak not in self._flexion:   # a thumb: no bends to try
            return None
        joints = self._flexion[weak]
        folds = np.unique(np.asarray(self._folds(jnp.asarray(q, self._dtype))), axis=0)
        starts = verify_starts(q, joints, hyp.finger_deg, self._lower, self._upper, folds, state.q_trusted)
        best, best_value = None, -np.inf
        for q0 in starts:
            q_meas, filtered, out, (x, v, a), extracted = self._search_from(images, q0, fe_state, frame, ghk,
                                                                             state, terms)
            if not self._usable(out):
                continue
            found = self._support(images, q_meas, extracted.state)[1]
            if beats(found, fingers, hyp.verify_margin) and min(found.values()) > best_value:
                ghk_next = (x, v.at[joints].set(0.0), a.at[joints].set(0.0))
                best, best_value = (q_meas, filtered, out, ghk_next, extracted.state, extracted), min(found.values())
        return best

    def _passage(self, images, state: TrackState, ghk: tuple, q: np.ndarray, measured: tuple | None, fe_state,
                 frame: int, terms: tuple):
        """The estimate ``q`` with each hinge that turned back at its fold reflected across it
        (:mod:`jaxhand.track._passage`; nearest its fold first), searched and solved from there,
        each kept where the solve stays beyond the fold and no finger's support (``measured``:
        :meth:`_support` of ``q``, None: measured here) drops by more than ``verify_margin``: as
        :meth:`_verify`'s result, or None where none was kept; and the fold offsets to carry on.
        The filter forgets the velocity of the hinges passed."""
        hyp = self.config.hypotheses
        fold, ok = (np.asarray(a) for a in jax.device_get(self._fold_turns(jnp.asarray(q, self._dtype))))
        history = push(state.fold_offsets, np.where(ok, -np.degrees(fold), np.nan))
        back = np.flatnonzero(turned_back(history, hyp.fold_passage_deg, hyp.fold_passage_speed_deg))
        best, passed, fingers = None, [], None
        for i in back[np.argsort(np.abs(history[-1, back]))]:
            history[:, i] = np.nan   # not judged again until the window has refilled
            if fingers is None:
                fingers = (self._support(images, q, fe_state) if measured is None else measured)[1]
            joint = self._fold_joints[i]
            q0 = np.asarray(q, float).copy()
            q0[joint] = np.clip(q0[joint] + 2 * fold[i], self._lower[joint], self._upper[joint])
            q_meas, filtered, out, (x, v, a), extracted = self._search_from(images, q0, fe_state, frame, ghk,
                                                                             state, terms)
            if not (self._usable(out) and crossed(q[joint], fold[i], q_meas[joint])):
                continue
            found = self._support(images, q_meas, extracted.state)[1]
            if not holds(found, fingers, hyp.verify_margin):
                continue
            passed.append(joint)
            idx = np.asarray(passed)
            best = (q_meas, filtered, out, (x, v.at[idx].set(0.0), a.at[idx].set(0.0)), extracted.state,
                    extracted)
            q, fingers = np.asarray(filtered), found
        return best, history

    def _unseen(self, state: TrackState, features, q) -> tuple[np.ndarray, np.ndarray]:
        """Per q entry, the frames in a row none of whose moved links had a feature line, and its
        value on the last frame one did (``q`` where this frame measured it)
        (:attr:`PriorConfig.hold_unseen_frames`); entries that move no link never count."""
        lined = np.any([np.asarray(f.line_valid, bool) for f in features], axis=0)
        seen = (self._moves & lined[None, :]).any(1) | ~self._moves.any(1)
        before = np.zeros(len(seen), int) if state.unseen is None else state.unseen
        q_seen = np.asarray(q) if state.q_seen is None else np.where(seen, q, state.q_seen)
        return np.where(seen, 0, before + 1), q_seen

    def _restore(self, state: TrackState, idx: np.ndarray, q_ref) -> TrackState:
        """``state`` with the filter's entries ``idx`` back at ``q_ref``, still: the hidden ones at
        the last trusted pose after a doubtful frame (:attr:`PriorConfig.restore_hidden_below`), whose
        solve may have moved them where the image cannot correct them, and those long unmeasured at
        their last measured value (:attr:`PriorConfig.hold_unseen_frames`)."""
        if not len(idx):
            return state
        x = state.ghk.x.at[idx].set(jnp.asarray(q_ref)[idx])
        ghk = GHKState(x=x, v=state.ghk.v.at[idx].set(0.0), a=state.ghk.a.at[idx].set(0.0))
        return dataclasses.replace(state, ghk=ghk)
