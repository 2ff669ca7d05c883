"""The tracker: predict, extract features, solve, filter, once per frame (thesis chs. 4-6).

Per frame k (thesis fig. 1.2 / DESIGN.md data flow):

1. **predict** the state q̂_k with the g-h-k filter (thesis eqs. 5.4-5.6), clipped to the
   joint limits;
2. **extract features** from every camera around the prediction (image front end; visibility
   windows come from the predicted pose, templates from earlier unoccluded views);
3. **solve** for the pose q̃_k from those features starting at q̂_k (configurable solver and
   iterations, including the thesis's fast mode of one update per frame);
4. **filter**: refine q̃_k with the g-h-k update (eqs. 5.1-5.3) into the reported estimate;
5. score the frame: residual RMS (px) and the share of valid features give a confidence in
   [0, 1] and a loss-of-track flag. A failed or non-finite solve keeps the prediction.

The sequence loop is host Python (frames come from disk and the image front end is NumPy).
Steps 3-5 after the front end (the solve with its robust passes, the score and the filter)
run as one program, compiled once per model structure and settings, so a sequence never
recompiles, and each frame makes one call and one fetch (see :func:`_frame_jit`). Results are
written frame by frame.
"""

from __future__ import annotations

import dataclasses
import functools
import time
from collections.abc import Callable, Sequence
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float, Int

from ._errors import InputError
from .camera import as_rig
from .features import Features
from .filter import GHKState, ghk_init, ghk_predict, ghk_update
from .kinematics import clip_q, link_points, validate_q
from .kinematics import pose as pose_at
from .model import Model

__all__ = ["TrackConfig", "TrackState", "StepReport", "Tracker", "confidence_of", "exact_extractor",
           "feature_errors", "reweight"]


@dataclasses.dataclass(frozen=True)
class TrackConfig:
    """Tracker settings (host-side; numbers that enter jitted code are passed as arrays).

    Attributes:
        solver: solver name for :func:`jaxhand.fit` (e.g. "gn", "lm", "bounded"); the default
            "bounded" keeps every iterate inside the joint limits, which on the two-finger
            sequence keeps an occluded finger from being fitted into impossible poses.
        max_steps: solver iterations per frame (1 = the thesis's fast mode).
        theta: g-h-k discount factor in [0, 1] per frame at ``theta_rate_hz`` (thesis §6 uses 0.85).
        theta_rate_hz: the frame rate (Hz) at which ``theta`` is the discount per frame. The tracker
            uses ``theta ** (theta_rate_hz * dt_s)`` per frame, so the filter forgets the same share
            per second at any frame rate: 0.85 at 25 frames/s (the rate of the thesis sequences
            here) is 0.666 at DigitEyes' 10 frames/s. Taking 0.85 per frame at 10 frames/s keeps
            2.5 times as much history per second, and on the 10 frames/s two-camera hand (WSSD) the
            lagging prediction loses track by frame 30 where 0.666 tracks all 100 frames to about
            1 deg. None: ``theta`` is the discount per frame whatever the frame rate.
        filter: apply the g-h-k filter (False: report and predict the raw solve).
        rms_scale_px: residual RMS (px) at which the confidence halves.
        min_valid_share: below this share of valid feature slots the frame counts as lost (and,
            with ``hold_on_loss``, every joint is held, the well seen ones too). 0.15: on the
            two-finger sequence a hidden middle finger leaves 2-3 of 8 slots, and freezing the
            index with it then loses both (the faster runs of ``benchmarks/tracking.py --sweep``:
            9.9 -> 4.7 deg at 60 frames, 10.4 -> 2.5 deg at 70, the slower runs unchanged).
        max_rms_px: above this residual RMS (px) the frame counts as lost.
        robust_passes: re-solves after reweighting every feature by its residual at the last
            solution (iteratively reweighted least squares with Cauchy weights
            ``w / (1 + (e / robust_scale_px)^2)``), so a few wrong image features cannot pull the
            pose away. 0 solves once, as the thesis does.
        robust_scale_px: the Cauchy scale (px): a feature this far from the model halves its weight.
        refresh_templates: after a frame that is not lost, let the front end store the profiles
            seen at the solved pose as templates (when it keeps templates).
        hold_on_loss: on a lost frame, report the last good estimate and predict it standing
            still, rather than filtering the lost frame's solve into the state.
        jacobian: how the solver computes the residual Jacobian (:attr:`jaxhand.FitConfig.jacobian`):
            "geometric" (joint axes, DigitEyes eqs. 8-10; the default, several times cheaper on
            CPU) or "autodiff" (``jax.jacfwd``); they agree to rounding.
        gate_scale_px: the first solve weighs every feature by a Cauchy weight of its distance to
            the model at the pose it was searched around (the prediction), so a feature the search
            took from the wrong place (another finger, a misplaced window) cannot pull the first
            solve before the robust passes judge it; 0 starts from the front end's weights.
        reextract: after the solve, run the front end again around the solved pose and solve again
            from there, this many times: samplers and visibility windows then follow the measured
            pose rather than the prediction (not in the thesis; it matters where one finger
            occludes another and a few degrees move the window off the occluder).
    """

    solver: str = "bounded"
    max_steps: int = 20
    theta: float = 0.85
    theta_rate_hz: float | None = 25.0
    filter: bool = True
    rms_scale_px: float = 2.0
    min_valid_share: float = 0.15
    max_rms_px: float = 6.0
    robust_passes: int = 2
    robust_scale_px: float = 2.0
    refresh_templates: bool = True
    hold_on_loss: bool = True
    jacobian: str = "geometric"
    gate_scale_px: float = 2.0
    reextract: int = 1

    def __post_init__(self):
        if not 0.0 <= self.theta <= 1.0:
            raise InputError(f"theta must lie in [0, 1], got {self.theta}")
        if self.theta_rate_hz is not None and not self.theta_rate_hz > 0:
            raise InputError(f"theta_rate_hz must be > 0 Hz (or None), got {self.theta_rate_hz}")
        if self.max_steps < 1:
            raise InputError(f"max_steps must be >= 1, got {self.max_steps}")
        if self.robust_passes < 0 or self.robust_scale_px <= 0:
            raise InputError(f"robust_passes must be >= 0 and robust_scale_px > 0, got {self.robust_passes}, "
                             f"{self.robust_scale_px}")
        if self.gate_scale_px < 0 or self.reextract < 0:
            raise InputError(f"gate_scale_px and reextract must be >= 0, got {self.gate_scale_px}, {self.reextract}")
        from .solve._config import JACOBIANS

        if self.jacobian not in JACOBIANS:
            raise InputError(f"jacobian must be one of {', '.join(JACOBIANS)}, got {self.jacobian!r}")


@dataclasses.dataclass(frozen=True)
class TrackState:
    """What the tracker carries between frames: the filter state (whose x is the prediction for
    the next frame) and the image front end's state (templates, widths)."""

    ghk: GHKState
    image_state: Any
    frames_done: int = 0
    q_last: np.ndarray | None = None


@dataclasses.dataclass(frozen=True)
class StepReport:
    """Exactly what gets written for one frame."""

    frame: int
    time_s: float
    q_pred: np.ndarray
    q_solved: np.ndarray
    q_filtered: np.ndarray
    cost: float
    rms_px: float
    iterations: int
    status: str
    valid_share: float
    confidence: float
    lost: bool
    timings_s: dict[str, float]
    diagnostics: Any = None


def confidence_of(rms_px: float, valid_share: float, config: TrackConfig) -> tuple[float, bool]:
    """Confidence in [0, 1] (valid share times 1 / (1 + (rms / scale)^2)) and the loss flag."""
    conf = valid_share / (1.0 + (rms_px / config.rms_scale_px) ** 2)
    lost = valid_share < config.min_valid_share or rms_px > config.max_rms_px or not np.isfinite(rms_px)
    return float(conf if np.isfinite(conf) else 0.0), bool(lost)


def _filter_update(model: Model, ghk: GHKState, q_meas, theta, dt_s, use_filter: bool
                   ) -> tuple[Float[Array, " nq"], GHKState]:
    """g-h-k update with the measured q, then the prediction for the next frame (both clipped)."""
    if model.base_kind == "free":  # keep the measured quaternion in the prediction's hemisphere
        flip = jnp.sign(jnp.dot(q_meas[:4], ghk.x[:4]))
        q_meas = q_meas.at[:4].multiply(jnp.where(flip == 0, 1.0, flip))
    if use_filter:
        updated = ghk_update(ghk, q_meas, theta, dt_s)
    else:
        updated = GHKState(x=q_meas, v=jnp.zeros_like(q_meas), a=jnp.zeros_like(q_meas))
    filtered = clip_q(model, updated.x)
    updated = GHKState(x=filtered, v=updated.v, a=updated.a)
    nxt = ghk_predict(updated, dt_s)
    return filtered, GHKState(x=clip_q(model, nxt.x), v=nxt.v, a=nxt.a)


#: :func:`_filter_update` on its own (jitted), as the tracker ran it before its frame program was
#: fused; the tests compare the fused program with these separate calls.
_filter_step = eqx.filter_jit(_filter_update)


def _feature_errors(model: Model, cameras: tuple, features: tuple, q, fractions) -> tuple:
    pose = pose_at(model, q)
    out = []
    for cam, f in zip(cameras, features):
        tips_px, _ = cam.project(pose.tips)
        e_tip = jnp.linalg.norm(jnp.where(f.tip_valid[:, None], tips_px - jnp.where(f.tip_valid[:, None], f.tips, 0.0),
                                          0.0), axis=-1)
        pts, _ = cam.project(link_points(pose, fractions))
        lines = jnp.where(f.line_valid[:, None], f.lines, 0.0)
        e_link = jnp.max(jnp.abs(jnp.sum(lines[:, None, :2] * pts, -1) - lines[:, None, 2]), axis=-1)
        out.append((e_link, e_tip))
    return tuple(out)


@eqx.filter_jit
def feature_errors(model: Model, cameras: tuple, features: tuple, q, fractions) -> tuple:
    """Per camera, each link line's largest distance (px) to the model's link points and each tip's
    distance (px) to the model's tip at state q (0 where a feature is invalid)."""
    return _feature_errors(model, cameras, features, q, fractions)


def reweight(features: tuple, errors: tuple, scale_px) -> tuple:
    """Features with Cauchy weights ``w / (1 + (e / scale)^2)`` from their residual errors
    (host or jitted code alike)."""
    out = []
    for f, (e_link, e_tip) in zip(features, errors):
        out.append(eqx.tree_at(lambda g: (g.line_weight, g.tip_weight), f,
                               (f.line_weight / (1.0 + (e_link / scale_px) ** 2),
                                f.tip_weight / (1.0 + (e_tip / scale_px) ** 2))))
    return tuple(out)


class _StepNumbers(eqx.Module):
    """The :class:`TrackConfig` numbers the jitted frame step reads (traced: new values reuse the
    compiled program)."""

    theta: Float[Array, ""]
    dt_s: Float[Array, ""]
    robust_scale_px: Float[Array, ""]
    gate_scale_px: Float[Array, ""]
    min_valid_share: Float[Array, ""]
    max_rms_px: Float[Array, ""]


class _StepOut(eqx.Module):
    """Everything :meth:`Tracker.step` needs from one frame's solve and filter.

    ``q_solved`` is the measurement the filter took (the prediction when the solve was not
    finite); ``status`` is the last solve's :class:`~jaxhand.solve.Status` code.
    """

    q_solved: Float[Array, " nq"]
    solved_ok: Bool[Array, ""]
    cost: Float[Array, ""]
    iterations: Int[Array, ""]
    status: Int[Array, ""]
    q_filtered: Float[Array, " nq"]
    ghk: GHKState
    rms_px: Float[Array, ""]
    valid_share: Float[Array, ""]
    lost: Bool[Array, ""]
    features_ok: Bool[Array, ""]


#: The scalars of a :class:`_StepOut`, in the order :func:`_frame_jit` packs them.
_SCALARS = ("solved_ok", "cost", "iterations", "status", "rms_px", "valid_share", "lost", "features_ok")
#: The fields of a :class:`~jaxhand.features.Features`, in the order :func:`_frame_jit` takes them.
_FEATURE_FIELDS = ("lines", "line_valid", "line_weight", "tips", "tip_valid", "tip_weight")


def _robust_solve(model: Model, rig: tuple, feats: tuple, q0, build, fit_config, scale_px, passes: int,
                  gate_px=0.0):
    """Solve, then ``passes`` times reweight every feature by its error at the last solution
    (Cauchy weights of the *original* weights, :func:`reweight`) and solve again from there.

    The passes run in one ``lax.fori_loop`` so the solver is traced (and compiled) once. Pass 0
    weighs the features by their errors at ``q0`` with the scale ``gate_px`` (0 keeps the
    original weights). Only the last pass runs the rank test (an SVD) of its status.
    """
    from .solve._fit import _fit_core

    gated = reweight(feats, _feature_errors(model, rig, feats, q0, fit_config.link_fractions),
                     jnp.where(gate_px > 0, gate_px, 1.0))   # Guard: scale 0 means no gate
    first = jax.tree_util.tree_map(lambda a, b: jnp.where(gate_px > 0, b, a), feats, gated)

    def one_pass(i, result):
        errors = _feature_errors(model, rig, feats, result.q, fit_config.link_fractions)
        weighted = reweight(feats, errors, scale_px)
        weighted = jax.tree_util.tree_map(lambda a, b: jnp.where(i == 0, a, b), first, weighted)
        return _fit_core(model, rig, weighted, result.q, build, fit_config, rank_test=i == passes)

    start = jax.eval_shape(lambda: _fit_core(model, rig, feats, q0, build, fit_config))
    start = jax.tree_util.tree_map(lambda s: jnp.zeros(s.shape, s.dtype), start)
    start = eqx.tree_at(lambda r: r.q, start, q0)
    return jax.lax.fori_loop(0, passes + 1, one_pass, start)


def _features_ok(feats: tuple) -> Bool[Array, ""]:
    """The value checks of :func:`~jaxhand.features.validate_features` as one flag (valid lines
    and tips finite, valid line normals of unit length, weights finite and >= 0), so the
    tracker checks each frame's features inside its compiled step instead of on the host."""
    ok = jnp.array(True)
    for f in feats:
        norm = jnp.linalg.norm(jnp.where(f.line_valid[:, None], f.lines[:, :2], 0.0), axis=-1)
        ok = (ok & jnp.all(jnp.isfinite(f.lines) | ~f.line_valid[:, None])
              & jnp.all(jnp.isfinite(f.tips) | ~f.tip_valid[:, None])
              & jnp.all((jnp.abs(norm - 1.0) <= 1e-6 + 1e-5) | ~f.line_valid)   # np.allclose(norm, 1, atol=1e-6)
              & jnp.all(jnp.isfinite(f.line_weight) & (f.line_weight >= 0))
              & jnp.all(jnp.isfinite(f.tip_weight) & (f.tip_weight >= 0)))
    return ok


def _frame_step(model: Model, rig: tuple, feats: tuple, ghk: GHKState, q_last, q_start, build, fit_config,
                numbers: _StepNumbers, passes: int, use_filter: bool, hold: bool) -> _StepOut:
    """One frame after feature extraction, in one compiled program: the (robust) solve from
    ``q_start`` (the prediction ``ghk.x``, or an earlier solve of this frame that the features were
    searched around), the frame's score and loss flag, and the g-h-k update and prediction (or,
    with ``hold`` on a lost frame, ``q_last`` held still), and the features' value check."""
    q_pred = ghk.x
    result = _robust_solve(model, rig, feats, q_start, build, fit_config, numbers.robust_scale_px, passes,
                           numbers.gate_scale_px)
    ok = jnp.all(jnp.isfinite(result.q)) & jnp.isfinite(result.cost)
    q_meas = jnp.where(ok, result.q, q_pred)
    n_tips = sum(jnp.sum(f.tip_valid) for f in feats)
    n_lines = sum(jnp.sum(f.line_valid) for f in feats)
    n_res = jnp.maximum(1, 2 * n_tips + 2 * n_lines)
    # Guard: the unused branch of a failed solve must stay finite.
    rms = jnp.where(ok, jnp.sqrt(2.0 * jnp.where(ok, result.cost, 0.0) / n_res), jnp.inf)
    total = sum(f.line_valid.shape[-1] + f.tip_valid.shape[-1] for f in feats)
    share = (n_tips + n_lines) / max(total, 1)
    lost = (share < numbers.min_valid_share) | (rms > numbers.max_rms_px) | ~jnp.isfinite(rms)
    filtered, ghk_next = _filter_update(model, ghk, q_meas, numbers.theta, numbers.dt_s, use_filter)
    if hold:
        # A lost frame's solve fits stray features: hold the last good estimate still (zero
        # velocity and acceleration) instead of letting the filter extrapolate it.
        filtered = jnp.where(lost, q_last, filtered)
        ghk_next = GHKState(x=jnp.where(lost, q_last, ghk_next.x), v=jnp.where(lost, 0.0, ghk_next.v),
                            a=jnp.where(lost, 0.0, ghk_next.a))
    return _StepOut(q_solved=q_meas, solved_ok=ok, cost=result.cost, iterations=result.iterations,
                    status=result.status._value, q_filtered=filtered, ghk=ghk_next, rms_px=rms,
                    valid_share=share, lost=lost, features_ok=_features_ok(feats))


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


@functools.partial(jax.jit, static_argnums=0)
def _frame_jit(static: _Static, consts: tuple, feats: tuple, ghk: tuple, q_last, q_start):
    """:func:`_frame_step` with flat arguments and results, for the cheapest call from the host.

    The tracker's constant arguments (model, cameras, solver, config, settings) are split once
    into the leaves ``consts`` and ``static`` (their tree and static half); ``feats`` holds one
    tuple of :data:`_FEATURE_FIELDS` per camera, ``ghk`` the filter's (x, v, a) and ``q_start``
    where the solve starts. Returns
    ``(q_solved, q_filtered, scalars)``, the scalars of :data:`_SCALARS` packed in one float
    vector (all exact in float64), and the next filter state (x, v, a).

    Why not ``eqx.filter_jit``: it partitions the whole model on every call, which measured
    0.3 ms per frame (hand27, two cameras), more than a small model's solve.
    """
    treedef, static_half = static.value
    parts = eqx.combine(jax.tree_util.tree_unflatten(treedef, consts), static_half)
    model, rig, build, fit_config, numbers, passes, use_filter, hold = parts
    out = _frame_step(model, rig, tuple(Features(*f) for f in feats), GHKState(*ghk), q_last, q_start, build,
                      fit_config, numbers, passes, use_filter, hold)
    dtype = out.q_solved.dtype
    scalars = jnp.stack([jnp.asarray(getattr(out, name), dtype) for name in _SCALARS])
    return (out.q_solved, out.q_filtered, scalars), (out.ghk.x, out.ghk.v, out.ghk.a)


class Tracker:
    """Tracks one model through frames from one or more cameras.

    Args:
        model: the kinematic model.
        cameras: a camera or a rig (tuple of cameras), in the order images are passed.
        extract: the image front end, ``extract(images, q_pred, image_state) -> (features,
            image_state, diagnostics)``, optionally with ``extract.refresh(images, q, image_state)
            -> image_state`` to update templates at the solved pose;
            :class:`jaxhand.cli_track.image_extractor` wraps :func:`jaxhand.image.extract_features`.
        config: tracker settings.
        dt_s: frame interval (s).
    """

    def __init__(self, model: Model, cameras, extract: Callable, config: TrackConfig | None = None,
                 dt_s: float = 1 / 25):
        from .solve import FitConfig
        from .solve._fit import _program

        self.model, self.cameras, self.extract = model, as_rig(cameras), extract
        self.config = config = TrackConfig() if config is None else config
        if dt_s <= 0:
            raise InputError(f"dt_s must be > 0, got {dt_s}")
        self.dt_s = float(dt_s)
        #: the g-h-k discount per frame at this frame interval (see TrackConfig.theta_rate_hz)
        self.theta = float(config.theta if config.theta_rate_hz is None
                           else config.theta ** (config.theta_rate_hz * self.dt_s))
        self._fit_config = FitConfig(max_steps=config.max_steps, jacobian=config.jacobian)
        # The compiled program's solver and its (solver-adjusted) config, checked once here.
        self._build, self._program_config = _program(config.solver, self._fit_config)
        self._numbers = _StepNumbers(*(jnp.asarray(float(v)) for v in (
            self.theta, self.dt_s, config.robust_scale_px, config.gate_scale_px, config.min_valid_share,
            config.max_rms_px)))
        # The jitted step's constant arguments, split once into arrays and a static handle
        # (one per value of the hold flag).
        self._dtype = jnp.asarray(0.0).dtype   # float64 (jaxhand enables x64)
        self._lower, self._upper = np.asarray(model.q_lower), np.asarray(model.q_upper)
        self._ghk_tree = jax.tree_util.tree_structure(ghk_init(jnp.zeros(model.n_q)))
        self._consts, self._static = (), {}
        for hold in (False, True):
            consts, static = eqx.partition((model, self.cameras, self._build, self._program_config, self._numbers,
                                            config.robust_passes, config.filter, hold), eqx.is_array)
            leaves, treedef = jax.tree_util.tree_flatten(consts)
            self._consts, self._static[hold] = tuple(leaves), _Static((treedef, static))

    def _feature_arrays(self, features) -> tuple[tuple, ...]:
        """The front end's features as one tuple of :data:`_FEATURE_FIELDS` arrays per camera
        (float64, masks bool), after the cheap host-side count and shape checks; their values
        are checked inside the compiled step."""
        from .features import validate_features

        feats = (features,) if isinstance(features, Features) else tuple(features)
        nl, nt = self.model.n_links, self.model.n_tips
        shapes = ((nl, 3), (nl,), (nl,), (nt, 2), (nt,), (nt,))
        dtype = self._dtype
        out = []
        if len(feats) == len(self.cameras) and all(isinstance(f, Features) for f in feats):
            for f in feats:
                arrays = []
                for name, shape in zip(_FEATURE_FIELDS, shapes):
                    a = getattr(f, name)
                    if np.shape(a) != shape:
                        break
                    want = bool if name.endswith("valid") else dtype
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

    def init(self, q0, image_state=None) -> TrackState:
        """The state before the first frame: the filter sits at q0 with zero velocity."""
        q0 = validate_q(self.model, q0, name="initial pose", within_limits=True)
        return TrackState(ghk=ghk_init(jnp.asarray(q0)), image_state=image_state, q_last=q0)

    def step(self, state: TrackState, images: Sequence[np.ndarray], frame: int = 0, time_s: float = 0.0
             ) -> tuple[TrackState, StepReport]:
        """Process one frame (one image per camera).

        After the image front end, the solve (with its robust passes), the frame's score and the
        filter run as one compiled program whose results come back in one transfer; the timings
        ``solve`` (that program) and ``filter`` (scoring and report on the host) split it. With
        ``config.reextract`` the front end and the program run again from the solved pose (an
        extractor with ``reextract = False``, such as :func:`exact_extractor`, is asked once);
        ``features`` and ``solve`` then add up every round.
        """
        from .features import validate_features
        from .solve import STATUS_NAMES

        if len(images) != len(self.cameras):
            raise InputError(f"expected one image per camera ({len(self.cameras)}), got {len(images)}")
        q_pred = state.ghk.x
        hold = self.config.hold_on_loss and state.q_last is not None
        rounds = 1 + (self.config.reextract if getattr(self.extract, "reextract", True) else 0)
        t_features = t_solve = 0.0
        q_start, image_state = q_pred, state.image_state
        for _ in range(rounds):
            t0 = time.perf_counter()
            features, image_state, diag = self.extract(images, q_start, image_state)
            t1 = time.perf_counter()
            (q_meas, filtered, scalars), ghk_next = _frame_jit(
                self._static[hold], self._consts, self._feature_arrays(features),
                (state.ghk.x, state.ghk.v, state.ghk.a), state.q_last if hold else q_pred, q_start)
            q_meas, filtered = np.asarray(q_meas), np.asarray(filtered)
            out = dict(zip(_SCALARS, np.asarray(scalars).tolist()))
            t2 = time.perf_counter()
            t_features, t_solve = t_features + (t1 - t0), t_solve + (t2 - t1)
            if not out["features_ok"] or out["lost"]:  # nothing better to search around
                break
            q_start = np.clip(q_meas, self._lower, self._upper)
        if not out["features_ok"]:
            validate_features(self.model, self.cameras, features)   # raises, naming camera and field
            raise InputError("features: a value check failed (see jaxhand.features.validate_features)")
        ok, rms, share, lost = bool(out["solved_ok"]), out["rms_px"], out["valid_share"], bool(out["lost"])
        conf, _ = confidence_of(rms, share, self.config)
        cost = out["cost"] if ok else float("nan")
        t3 = time.perf_counter()
        timings = {"features": t_features, "solve": t_solve, "filter": t3 - t2}
        refresh = getattr(self.extract, "refresh", None)
        if refresh is not None and not lost and self.config.refresh_templates:
            t4 = time.perf_counter()
            image_state = refresh(images, q_meas, image_state)
            timings["templates"] = time.perf_counter() - t4
        if isinstance(diag, dict) and "timings_s" in diag:  # the front end's own split (e.g. visibility)
            timings.update({f"features.{k}": v for k, v in diag["timings_s"].items()})
        report = StepReport(frame=frame, time_s=time_s, q_pred=np.asarray(q_pred), q_solved=q_meas,
                            q_filtered=filtered, cost=cost, rms_px=rms, iterations=int(out["iterations"]),
                            status=STATUS_NAMES[int(out["status"])], valid_share=share, confidence=conf, lost=lost,
                            timings_s=timings, diagnostics=diag)
        ghk_next = jax.tree_util.tree_unflatten(self._ghk_tree, ghk_next)   # 1 us; GHKState(...) takes 9
        return TrackState(ghk=ghk_next, image_state=image_state, frames_done=state.frames_done + 1,
                          q_last=filtered), report


def exact_extractor(model: Model, cameras, truth, *, noise_px: float = 0.5, seed: int = 0) -> Callable:
    """An oracle front end for experiments: call k returns the exact features of ``truth[k]``
    (every camera) with Gaussian pixel noise of ``noise_px``, ignoring the images. Tracking with
    it measures what the solver and the filter can do with perfect image analysis."""
    from .features import features_from_pose

    rng = np.random.default_rng(seed)
    calls = [0]

    def extract(images, q_pred, state):
        k = calls[0]
        calls[0] += 1
        return features_from_pose(model, cameras, truth[k], noise_px=noise_px, rng=rng), state, {}

    extract.reextract = False  # one call per frame: a second look at the same frame gains nothing
    return extract
