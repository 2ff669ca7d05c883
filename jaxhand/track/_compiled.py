"""The tracker's compiled frame program: everything after the front end, in one call.

Per frame the host makes one call and one fetch. :func:`frame_step` runs, traced once per model
structure and settings: the gate and the robust solve (:func:`robust_solve`, its passes in one
``lax.fori_loop``) with the pose priors of :class:`~jaxhand.track.PriorConfig` (the temporal
one around the frame's prediction, a traced input), the frame's score of the image residuals
(:func:`~jaxhand.track.frame_score`), the g-h-k update and prediction (held still on a lost
frame when :attr:`LossConfig.hold`), and the features' value checks
(:func:`jaxhand.features.feature_value_checks`), so bad features are found without a host-side
pass over them.

Calling it cheaply from the host: :class:`FrameProgram` splits its constant arguments (model,
cameras, solver, settings) once into array leaves and a :class:`_Static` handle on the rest,
hashed once; :func:`_frame_jit` takes those plus flat tuples of arrays and returns the
scalars packed in one vector. ``eqx.filter_jit`` would partition the whole model on every call,
which costs more than a small model's solve (benchmarks/README.md).
"""

from __future__ import annotations

import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float, Int

from ..features import Features, feature_value_checks, line_through
from ..filter import GHKState, damp_unseen, ghk_follow, ghk_predict, ghk_update, seen_share
from ..kinematics import clip_q, pose
from ..model import Model
from ..priors import TemporalPrior, dip_pip_coupling, information_weight, soft_limits, stack_priors, temporal_weight
from ..residuals import ResidualArgs, feature_distances, residuals_and_jacobian
from ..solve.internal import fit_traced, solver_program
from ._config import TrackConfig
from ._flexion import hyperextension_limits, thumb_joints
from ._score import frame_score

__all__ = ["FrameProgram", "frame_step", "solve_frame", "seen_at", "finish_frame", "step_constants", "split_constants",
           "join_constants", "robust_solve",
           "gate", "reweight", "filter_update", "SCALARS", "FEATURE_FIELDS"]

#: The scalars of a :class:`_StepOut`, in the order :func:`_frame_jit` packs them.
SCALARS = ("solved_ok", "cost", "iterations", "status", "rms_px", "valid_share", "confidence", "lost",
           "features_ok")
#: The fields of a :class:`~jaxhand.features.Features`, in the order :func:`_frame_jit` takes them.
FEATURE_FIELDS = ("lines", "line_valid", "line_weight", "tips", "tip_valid", "tip_weight")


def filter_update(model: Model, ghk: GHKState, q_meas, theta, dt_s, use_filter: bool, report_solve: bool = False,
                  seen=None, keep_unseen=0.0, velocity_gain=0.0) -> tuple[Float[Array, " nq"], GHKState]:
    """g-h-k update with the measured q, then the prediction for the next frame (both clipped).
    With ``report_solve`` the estimate is the measurement itself; the filter's velocity and
    acceleration still carry the prediction from it. With ``seen`` (per entry, in [0, 1]) the
    velocity and acceleration of the joint angles the frame does not see decay before the
    prediction, each keeping ``seen + (1 - seen) keep_unseen`` (:func:`jaxhand.filter.damp_unseen`).
    With ``report_solve`` and ``velocity_gain`` > 0 (traced) the velocity takes that share of the
    innovation over the frame and the acceleration is dropped (:class:`FilterConfig`)."""
    if model.base_kind == "free":  # keep the measured quaternion in the prediction's hemisphere
        flip = jnp.sign(jnp.dot(q_meas[:4], ghk.x[:4]))
        q_meas = q_meas.at[:4].multiply(jnp.where(flip == 0, 1.0, flip))
    if use_filter:
        updated = ghk_update(ghk, q_meas, theta, dt_s)
        if report_solve:   # the solve itself, its velocity by theta's gains or its own (velocity_gain > 0)
            own = ghk_follow(ghk, q_meas, velocity_gain, dt_s)
            updated = jax.tree_util.tree_map(lambda o, u: jnp.where(velocity_gain > 0, o, u), own,
                                             GHKState(x=q_meas, v=updated.v, a=updated.a))
        if seen is not None:   # angles only: a base translation or quaternion is not a joint a finger hides
            updated = damp_unseen(updated, jnp.where(model.is_angle, seen, 1.0), keep_unseen)
    else:
        updated = GHKState(x=q_meas, v=jnp.zeros_like(q_meas), a=jnp.zeros_like(q_meas))
    filtered = clip_q(model, updated.x)
    updated = GHKState(x=filtered, v=updated.v, a=updated.a)
    nxt = ghk_predict(updated, dt_s)
    return filtered, GHKState(x=clip_q(model, nxt.x), v=nxt.v, a=nxt.a)


def reweight(features: tuple, errors: tuple, scale_px) -> tuple:
    """Features with Cauchy weights ``w / (1 + (e / scale)^2)`` from their distances
    (:func:`jaxhand.residuals.feature_distances`), on the host or in jitted code alike."""
    out = []
    for f, (e_link, e_tip) in zip(features, errors):
        out.append(eqx.tree_at(lambda g: (g.line_weight, g.tip_weight), f,
                               (f.line_weight / (1.0 + (e_link / scale_px) ** 2),
                                f.tip_weight / (1.0 + (e_tip / scale_px) ** 2))))
    return tuple(out)


class _StepNumbers(eqx.Module):
    """The :class:`TrackConfig` numbers the frame program reads (traced: new values reuse it)."""

    theta: Float[Array, ""]
    dt_s: Float[Array, ""]
    robust_scale_px: Float[Array, ""]
    gate_scale_px: Float[Array, ""]
    rms_scale_px: Float[Array, ""]
    min_valid_share: Float[Array, ""]
    max_rms_px: Float[Array, ""]
    min_term_merit: Float[Array, ""]
    valid_share_good: Float[Array, ""]
    keep_unseen: Float[Array, ""]    # exp(-dt_s / FilterConfig.unseen_decay_s)
    velocity_gain: Float[Array, ""]
    damp_unseen: bool = eqx.field(static=True, default=False)


class _Priors(eqx.Module):
    """The priors of :class:`~jaxhand.track.PriorConfig`, built once: the fixed ones (DIP-PIP,
    soft limits), the temporal prior's per-entry weight (its ``q_pred`` is the frame's
    prediction) and the thumb's rest prior's (around the default pose). Which are present is
    static; their numbers are traced."""

    fixed: tuple
    temporal_weight: Float[Array, " nq"] | None
    information_ratio: Float[Array, ""] | None
    information_terms: Float[Array, ""] | None = None
    temporal_merit: Float[Array, ""] | None = None
    rest_weight: Float[Array, " nq"] | None = None
    rest_pose: Float[Array, " nq"] | None = None

    @staticmethod
    def of(model: Model, config) -> _Priors:
        dtype = model.q_lower.dtype
        fixed = []
        if config.dip_pip_weight:
            fixed.append(dip_pip_coupling(model, weight=config.dip_pip_weight, ratio=config.dip_pip_ratio))
        if config.soft_limit_weight:
            fixed.append(soft_limits(model, weight=config.soft_limit_weight,
                                     margin=float(np.radians(config.soft_limit_margin_deg))))
        if config.hyperextension_weight:
            fixed.append(hyperextension_limits(model, config.hyperextension_weight, config.hyperextension_deg))
        weight = (jnp.asarray(temporal_weight(model, config.temporal_sigma_deg, config.temporal_sigma_mm), dtype)
                  if config.temporal else None)
        ratio = jnp.asarray(config.information_ratio, dtype) if config.information_ratio else None
        merit = jnp.asarray(config.temporal_merit, dtype) if config.temporal_merit else None
        rest, thumb = None, thumb_joints(model) if config.thumb_rest_sigma_deg else ()
        if len(thumb):   # a model without a thumb gets none
            rest = np.zeros(model.n_q)
            rest[thumb] = 1.0 / np.radians(config.thumb_rest_sigma_deg)
            rest = jnp.asarray(rest, dtype)
        terms = jnp.asarray(config.information_terms, dtype) if ratio is not None else None
        return _Priors(fixed=tuple(fixed), temporal_weight=weight, information_ratio=ratio, information_terms=terms,
                       temporal_merit=merit,
                       rest_weight=rest, rest_pose=None if rest is None else jnp.asarray(model.q_default, dtype))

    def without_temporal(self) -> _Priors:
        """These priors with the temporal weight zeroed (its residuals and merit vanish): the same
        compiled program, for a frame whose prediction is not trusted."""
        if self.temporal_weight is None:
            return self
        return eqx.tree_at(lambda p: p.temporal_weight, self, jnp.zeros_like(self.temporal_weight))

    def merit_sq(self, q, q_pred) -> Float[Array, ""]:
        """The squared fixed-sigma temporal residuals of ``q`` times :attr:`PriorConfig.temporal_merit`,
        for a start's merit (0 where that is off)."""
        if self.temporal_merit is None:
            return jnp.zeros((), q.dtype)
        return self.temporal_merit * jnp.sum((self.temporal_weight * (q - q_pred)) ** 2)

    def at(self, model: Model, rig: tuple, feats: tuple, q_pred, q_start, fractions, measured: tuple = ()) -> tuple:
        """The priors of one frame: the temporal prior around ``q_pred`` and the thumb's rest
        prior, each information-weighted by the features (with the front end's weights) and the
        frame's ``measured`` terms (bound priors of measurements: the silhouette, fused landmarks)
        at ``q_start`` when :attr:`information_ratio` is set: what a term sees (a finger's length,
        a folded thumb's landmarks) is the measurement's to say, as far as
        :attr:`information_terms` counts it."""
        weighted = [(self.temporal_weight, q_pred), (self.rest_weight, self.rest_pose)]
        weighted = [(w, centre) for w, centre in weighted if w is not None]
        if not weighted:
            return self.fixed
        if self.information_ratio is not None:
            args = ResidualArgs(model=model, cameras=rig, features=feats, fractions=fractions)
            _, J = residuals_and_jacobian(q_start, args)
            information = J.T @ J
            for term in measured:
                J_term = jax.jacfwd(term)(q_start)
                information = information + self.information_terms * (J_term.T @ J_term)
            roots = information_weight(jnp.stack([w for w, _ in weighted]), information, self.information_ratio)
            weighted = [(root, centre) for root, (_, centre) in zip(roots, weighted)]
        return tuple(TemporalPrior(q_pred=centre, weight=w) for w, centre in weighted) + self.fixed


class _StepOut(eqx.Module):
    """One frame's solve, score and filter. ``q_solved`` is the measurement the filter took (the
    prediction when the solve was not finite); ``status`` the last solve's Status code."""

    q_solved: Float[Array, " nq"]
    solved_ok: Bool[Array, ""]
    cost: Float[Array, ""]
    iterations: Int[Array, ""]
    status: Int[Array, ""]
    q_filtered: Float[Array, " nq"]
    ghk: GHKState
    rms_px: Float[Array, ""]
    valid_share: Float[Array, ""]
    confidence: Float[Array, ""]
    lost: Bool[Array, ""]
    features_ok: Bool[Array, ""]


def gate(model: Model, rig: tuple, feats: tuple, q0, fractions, gate_px) -> tuple:
    """The features weighed by their distances at ``q0`` with the Cauchy scale ``gate_px``
    (:func:`reweight`; 0 keeps the original weights): what the first solve of a frame uses."""
    gated = reweight(feats, feature_distances(model, rig, feats, q0, fractions),
                     jnp.where(gate_px > 0, gate_px, 1.0))   # Guard: scale 0 means no gate
    return jax.tree_util.tree_map(lambda a, b: jnp.where(gate_px > 0, b, a), feats, gated)


def robust_solve(model: Model, rig: tuple, feats: tuple, q0, build, fit_config, scale_px, passes: int,
                 gate_px=0.0, priors: tuple = ()):
    """Solve, then ``passes`` times reweight every feature by its distance at the last solution
    (Cauchy weights of the *original* weights, :func:`reweight`) and solve again from there.

    The passes run in one ``lax.fori_loop`` so the solver is traced (and compiled) once. Pass 0
    weighs the features by their distances at ``q0`` with the scale ``gate_px`` (:func:`gate`).
    Only the last pass runs the rank test (an SVD) of its status. ``priors`` are stacked under
    the image residuals of every pass (the result's cost includes them).
    """
    fractions = fit_config.link_fractions
    first = gate(model, rig, feats, q0, fractions, gate_px)

    def one_pass(i, result):
        weighted = reweight(feats, feature_distances(model, rig, feats, result.q, fractions), scale_px)
        weighted = jax.tree_util.tree_map(lambda a, b: jnp.where(i == 0, a, b), first, weighted)
        return fit_traced(model, rig, weighted, result.q, build, fit_config, rank_test=i == passes, priors=priors)

    start = jax.eval_shape(lambda: fit_traced(model, rig, feats, q0, build, fit_config, priors=priors))
    start = jax.tree_util.tree_map(lambda s: jnp.zeros(s.shape, s.dtype), start)
    start = eqx.tree_at(lambda r: r.q, start, q0)
    return jax.lax.fori_loop(0, passes + 1, one_pass, start)


class _Solved(eqx.Module):
    """One start's robust solve of a frame, judged by its image residuals alone: ``q`` is the
    measurement the filter takes (the prediction when the solve was not finite)."""

    q: Float[Array, " nq"]
    ok: Bool[Array, ""]
    cost: Float[Array, ""]
    iterations: Int[Array, ""]
    status: Int[Array, ""]
    rms_px: Float[Array, ""]
    valid_share: Float[Array, ""]
    term_merit: Float[Array, ""]
    seen: Float[Array, " nq"] | None = None


def seen_at(model: Model, rig: tuple, feats: tuple, q, fractions) -> Float[Array, " nq"]:
    """Each q entry's share of being seen by the frame's features at ``q``
    (:func:`jaxhand.filter.seen_share`): the image information of the features' valid slots,
    against every slot valid, both on the model's own projection at
    ``q`` (so the share depends on what is seen, not on where the features lie)."""
    p = pose(model, q)
    own, every = [], []
    for cam, f in zip(rig, feats):
        lines, tips = line_through(cam.project(p.link_start)[0], cam.project(p.link_end)[0]), cam.project(p.tips)[0]
        # valid slots at weight 1: the front end's weights (visibility, strength) scale every
        # frame's information alike and would count a well-seen joint as partly hidden
        own.append(Features(lines=lines, line_valid=f.line_valid, line_weight=jnp.ones_like(f.line_weight), tips=tips,
                            tip_valid=f.tip_valid, tip_weight=jnp.ones_like(f.tip_weight)))
        every.append(Features(lines=lines, line_valid=jnp.ones_like(f.line_valid), line_weight=jnp.ones_like(
            f.line_weight), tips=tips, tip_valid=jnp.ones_like(f.tip_valid), tip_weight=jnp.ones_like(f.tip_weight)))

    def information(features):
        args = ResidualArgs(model=model, cameras=rig, features=tuple(features), fractions=fractions)
        _, J = residuals_and_jacobian(q, args)
        return J.T @ J

    return seen_share(information(own), information(every))


def solve_frame(model: Model, rig: tuple, feats: tuple, q_pred, q_start, build, fit_config, numbers: _StepNumbers,
                passes: int, priors: _Priors | None = None, terms: tuple = ()) -> _Solved:
    """The robust solve of one frame from ``q_start`` with the ``priors`` (the temporal one
    around the prediction ``q_pred``) and the frame's extra solve ``terms`` (``term.bind(model,
    rig)`` gives a prior, e.g. :class:`~jaxhand.landmarks.LandmarkTerm`), its image cost and
    residual RMS (px) and the share of valid feature slots: what :func:`frame_step` runs once,
    and the hypotheses once per start."""
    fractions = fit_config.link_fractions
    # the information of the front end's own weights: the gate would shrink it wherever the
    # prediction is off, and so hold the solve back exactly where it has to move
    bound = tuple(term.bind(model, rig) for term in terms)
    frame_priors = () if priors is None else priors.at(model, rig, feats, q_pred, q_start, fractions, bound)
    frame_priors = frame_priors + bound
    result = robust_solve(model, rig, feats, q_start, build, fit_config, numbers.robust_scale_px, passes,
                          numbers.gate_scale_px, frame_priors)
    ok = jnp.all(jnp.isfinite(result.q)) & jnp.isfinite(result.cost)
    q_meas = jnp.where(ok, result.q, q_pred)
    cost = result.cost
    if frame_priors:   # the frame is judged by its image residuals alone
        r_prior = stack_priors(frame_priors, result.q)
        cost = jnp.maximum(cost - 0.5 * jnp.sum(r_prior * r_prior), 0.0)
    n_tips = sum(jnp.sum(f.tip_valid) for f in feats)
    n_lines = sum(jnp.sum(f.line_valid) for f in feats)
    dtype = result.cost.dtype
    n_res = jnp.maximum(1, 2 * n_tips + 2 * n_lines).astype(dtype)
    # Guard: the unused branch of a failed solve must stay finite.
    rms = jnp.where(ok, jnp.sqrt(2.0 * jnp.where(ok, cost, 0.0) / n_res), jnp.inf)
    total = sum(f.line_valid.shape[-1] + f.tip_valid.shape[-1] for f in feats)
    share = (n_tips + n_lines).astype(dtype) / max(total, 1)
    merit = jnp.ones((), dtype)
    for term in terms:   # the measured terms' agreement with the solve (1 for the others)
        merit = merit * term.merit(model, rig, q_meas)
    seen = seen_at(model, rig, feats, q_meas, fractions) if numbers.damp_unseen else None
    return _Solved(q=q_meas, ok=ok, cost=cost, iterations=result.iterations, status=result.status._value,
                   rms_px=rms, valid_share=share, term_merit=merit, seen=seen)


def features_ok(feats: tuple) -> Bool[Array, ""]:
    """Whether every feature passes its value checks (:func:`jaxhand.features.feature_value_checks`)."""
    return functools.reduce(jnp.logical_and, [c for f in feats for c in feature_value_checks(f)])


def finish_frame(model: Model, ghk: GHKState, q_last, solved: _Solved, checks_ok, numbers: _StepNumbers,
                 use_filter: bool, hold: bool, report_solve: bool = False) -> _StepOut:
    """The frame's score and loss flag from the chosen solve, then the g-h-k update and prediction
    (with ``report_solve`` the solve is reported and predicted from; with ``hold``, a lost frame
    holds ``q_last`` still)."""
    conf, lost = frame_score(solved.rms_px, solved.valid_share, numbers.rms_scale_px, numbers.min_valid_share,
                             numbers.max_rms_px, share_good=numbers.valid_share_good)
    # the measured terms (the silhouette) judge the frame too: their merit scales the confidence
    conf = conf * solved.term_merit
    lost = lost | (solved.term_merit < numbers.min_term_merit)
    filtered, ghk_next = filter_update(model, ghk, solved.q, numbers.theta, numbers.dt_s, use_filter,
                                       report_solve, solved.seen, numbers.keep_unseen, numbers.velocity_gain)
    if hold:
        # A lost frame's solve fits stray features: hold the last good estimate still (zero
        # velocity and acceleration) instead of letting the filter extrapolate it.
        filtered = jnp.where(lost, q_last, filtered)
        ghk_next = GHKState(x=jnp.where(lost, q_last, ghk_next.x), v=jnp.where(lost, 0.0, ghk_next.v),
                            a=jnp.where(lost, 0.0, ghk_next.a))
    return _StepOut(q_solved=solved.q, solved_ok=solved.ok, cost=solved.cost, iterations=solved.iterations,
                    status=solved.status, q_filtered=filtered, ghk=ghk_next, rms_px=solved.rms_px,
                    valid_share=solved.valid_share, confidence=conf, lost=lost, features_ok=checks_ok)


def frame_step(model: Model, rig: tuple, feats: tuple, ghk: GHKState, q_last, q_start, build, fit_config,
               numbers: _StepNumbers, passes: int, use_filter: bool, hold: bool, priors: _Priors | None = None,
               report_solve: bool = False, terms: tuple = ()) -> _StepOut:
    """One frame after feature extraction: the robust solve from ``q_start`` (the prediction
    ``ghk.x``, or an earlier solve of this frame that the features were searched around) with
    the ``priors`` (the temporal one around ``ghk.x``; :func:`solve_frame`), the score and loss
    flag (of the image residuals alone), the g-h-k update and prediction (:func:`finish_frame`),
    and the features' value check. ``terms``: the frame's extra solve terms (:func:`solve_frame`)."""
    solved = solve_frame(model, rig, feats, ghk.x, q_start, build, fit_config, numbers, passes, priors, terms)
    return finish_frame(model, ghk, q_last, solved, features_ok(feats), numbers, use_filter, hold, report_solve)


class _Static:
    """A hashable handle on the static half of a pytree, hashed once: as a ``jax.jit`` static
    argument it costs no tree traversal per call, and equal halves (trackers of the same model
    structure and settings) share one compiled program."""

    __slots__ = ("value", "_hash")

    def __init__(self, value):
        self.value = value
        self._hash = hash(value)

    def __hash__(self) -> int:
        return self._hash

    def __eq__(self, other) -> bool:
        return isinstance(other, _Static) and (other.value is self.value or other.value == self.value)


def split_constants(tree) -> tuple[tuple, _Static]:
    """A program's constant arguments split once: their array leaves, and a :class:`_Static`
    handle on the rest (the tree structure and the static half) for ``jax.jit``'s static argument."""
    consts, static = eqx.partition(tree, eqx.is_array)
    leaves, treedef = jax.tree_util.tree_flatten(consts)
    return tuple(leaves), _Static((treedef, static))


def join_constants(static: _Static, consts: tuple):
    """The constant arguments again from :func:`split_constants`' halves (inside the jitted program)."""
    treedef, static_half = static.value
    return eqx.combine(jax.tree_util.tree_unflatten(treedef, consts), static_half)


@functools.partial(jax.jit, static_argnums=0)
def _frame_jit(static: _Static, consts: tuple, feats: tuple, ghk: tuple, q_last, q_start, terms: tuple = ()):
    """:func:`frame_step` with flat arguments and results: ``consts`` and ``static`` are the
    leaves and the (tree, static half) of the constant arguments; ``feats`` one tuple of
    :data:`FEATURE_FIELDS` per camera; ``ghk`` the filter's (x, v, a). Returns
    ``(q_solved, q_filtered, scalars)`` with the :data:`SCALARS` packed in one float vector (all
    exact in float64), and the next filter state (x, v, a)."""
    model, rig, build, fit_config, numbers, passes, use_filter, hold, priors, report_solve = join_constants(
        static, consts)
    out = frame_step(model, rig, tuple(Features(*f) for f in feats), GHKState(*ghk), q_last, q_start, build,
                     fit_config, numbers, passes, use_filter, hold, priors, report_solve, terms)
    dtype = out.q_solved.dtype
    scalars = jnp.stack([jnp.asarray(getattr(out, name), dtype) for name in SCALARS])
    return (out.q_solved, out.q_filtered, scalars), (out.ghk.x, out.ghk.v, out.ghk.a)


def step_constants(model: Model, rig: tuple, config: TrackConfig, theta: float, dt_s: float,
                   temporal: bool = True) -> tuple:
    """The constant arguments of :func:`frame_step` after the frame's own, in its order (model, rig,
    build, fit_config, numbers, passes, use_filter, hold, priors, report_solve), the solver and its
    options checked once here: what :class:`FrameProgram` (and the hypotheses' program) split.
    ``temporal`` False: the temporal prior's weight zeroed (:meth:`_Priors.without_temporal`)."""
    build, fit_config = solver_program(config.solver, config.fit)
    fc = config.filter
    keep_unseen = float(np.exp(-dt_s / fc.unseen_decay_s)) if fc.unseen_decay_s > 0 else 0.0
    numbers = _StepNumbers(*(jnp.asarray(float(v)) for v in (
        theta, dt_s, config.robust.scale_px, config.robust.gate_scale_px, config.loss.rms_scale_px,
        config.loss.min_valid_share, config.loss.max_rms_px, config.loss.min_term_merit, config.loss.valid_share_good,
        keep_unseen, fc.velocity_gain)),
        damp_unseen=fc.enabled and fc.damp_unseen)
    priors = _Priors.of(model, config.prior)
    priors = priors if temporal else priors.without_temporal()
    return (model, rig, build, fit_config, numbers, config.robust.passes, config.filter.enabled, config.loss.hold,
            priors, config.filter.report_solve)


class FrameProgram:
    """The frame program of one tracker: its constant arguments split once, called per frame.

    Args:
        model, rig: the model and the cameras.
        config: the run's settings (the solver and its options checked once here).
        theta: the g-h-k discount per frame at this frame interval; dt_s: the interval (s).
        temporal: False: without the temporal prior (:meth:`_Priors.without_temporal`).
    """

    def __init__(self, model: Model, rig: tuple, config: TrackConfig, theta: float, dt_s: float,
                 temporal: bool = True):
        self._consts, self._static = split_constants(step_constants(model, rig, config, theta, dt_s, temporal))

    def __call__(self, feats: tuple, ghk: tuple, q_last, q_start, terms: tuple = ()):
        """``(q_solved, q_filtered, scalars), (x, v, a)`` of one frame (see :func:`_frame_jit`)."""
        return _frame_jit(self._static, self._consts, feats, ghk, q_last, q_start, terms)
