"""TrackConfig: every setting of a tracking run in one nested, frozen, documented tree.

One tree per run, no field declared at two levels (the solver's cap and Jacobian live in
:attr:`TrackConfig.fit`, the front end's settings in :attr:`TrackConfig.image`). Each field's
docstring gives its unit and whether it is *static* (part of the compiled frame program: a new
value compiles a new one) or *traced* (a new value reuses it); *host* fields never enter it.
Values are checked once, when the tree is built. :func:`config_to_dict` / :func:`config_from_dict`
(and :mod:`jaxhand.track._config_toml`'s TOML files) reproduce a tree exactly; unknown keys are
errors with a "did you mean" hint.
"""

from __future__ import annotations

import dataclasses
import difflib
import json

import numpy as np

from .._errors import InputError
from ..image import ImageConfig
from ..priors import DIP_PIP_RATIO
from ..solve import FitConfig, solver_named
from ..solve.internal import check_config
from ._config_checks import count, finite_number, flag, need
from ._config_hypotheses import HypothesisConfig
from ._presets import PRESETS
from ._support import SupportConfig

__all__ = ["TrackConfig", "FilterConfig", "RobustConfig", "LossConfig", "PriorConfig", "HypothesisConfig",
           "LandmarkConfig", "config_to_dict", "config_from_dict", "TRACK_CONFIG_VERSION"]

#: The ``format_version`` written into (and required of) saved tracking configs.
TRACK_CONFIG_VERSION = 1


@dataclasses.dataclass(frozen=True)
class FilterConfig:
    """The g-h-k filter between frames (thesis eqs. 5.1-5.6).

    Attributes:
        enabled: static. Filter the solves (False: report and predict the raw solve).
        theta: traced, per frame in [0, 1]. The discount factor at ``theta_rate_hz`` (thesis §6: 0.85).
        theta_rate_hz: host, Hz. The frame rate at which ``theta`` holds; the tracker uses
            ``theta ** (theta_rate_hz * dt_s)`` so the filter forgets the same share per second at
            any rate. 0 (or None): ``theta`` is the discount per frame at any rate.
        report_solve: static. Report the solve (with :class:`PriorConfig`'s priors) and predict
            from it with the filter's velocity and acceleration; False: the g-h-k update (thesis).
        damp_unseen: static. Damp each joint angle's velocity and acceleration by the share of its
            image information the frame's features give (:func:`jaxhand.filter.seen_share`), so a
            hidden joint's last velocity does not carry it to a limit. Off: a front end that misses
            visible links now and then lags with it (benchmarks/README.md, 2026-12-02).
        unseen_decay_s: traced, s. The time constant of an unseen joint's velocity decay
            (:func:`jaxhand.filter.damp_unseen`): a brief occlusion carries on, a long one holds.
        velocity_gain: traced, in [0, 2). With ``report_solve``, the share of each frame's
            observed velocity (the reported estimate's change against the prediction) taken into
            the filter's velocity, the acceleration dropped: a constant-velocity prediction from
            the reported estimates. 0: theta's h and k (the thesis's gains, made for a filter that
            keeps its own position: with the solve reported they forget a stop only over some 20 frames).
    """

    enabled: bool = True
    theta: float = 0.85
    theta_rate_hz: float | None = 25.0
    report_solve: bool = False
    damp_unseen: bool = False
    unseen_decay_s: float = 0.2
    velocity_gain: float = 0.0

    def __post_init__(self):
        if self.theta_rate_hz is None:
            object.__setattr__(self, "theta_rate_hz", 0.0)
        flag(self.enabled, "filter.enabled")
        flag(self.report_solve, "filter.report_solve")
        need(0.0 <= self.theta <= 1.0, "filter.theta", f"theta must lie in [0, 1], got {self.theta}")
        need(self.theta_rate_hz >= 0, "filter.theta_rate_hz",
              f"theta_rate_hz must be > 0 Hz (or 0: per frame), got {self.theta_rate_hz}")
        flag(self.damp_unseen, "filter.damp_unseen")
        value = self.unseen_decay_s
        need(finite_number(value) and value >= 0, "filter.unseen_decay_s",
              f"expected a finite number >= 0 (0: an unseen joint stops at once), got {value!r}")
        object.__setattr__(self, "unseen_decay_s", float(value))
        value = self.velocity_gain
        need(finite_number(value) and 0 <= value < 2, "filter.velocity_gain",
             f"expected a number in [0, 2) (0: theta's gains; 2 and above diverge), got {value!r}")
        object.__setattr__(self, "velocity_gain", float(value))
        need(not value or self.report_solve, "filter.velocity_gain",
             "acts on a filter that reports the solve: set filter.report_solve = true (or velocity_gain 0)")

    def theta_per_frame(self, dt_s: float) -> float:
        """The discount for one frame of ``dt_s`` seconds."""
        return float(self.theta if not self.theta_rate_hz else self.theta ** (self.theta_rate_hz * dt_s))


@dataclasses.dataclass(frozen=True)
class RobustConfig:
    """Iteratively reweighted least squares against wrong image features.

    Attributes:
        passes: static. Re-solves after reweighting each feature by ``w / (1 + (e / scale_px)^2)``
            of its distance e at the last solution (0: solve once, as the thesis does).
        scale_px: traced, px. The Cauchy scale: a feature this far from the model halves its weight.
        gate_scale_px: traced, px. The same Cauchy weight for the first solve, of each feature's
            distance at the pose it was searched around (0: the front end's weights).
    """

    passes: int = 2
    scale_px: float = 2.0
    gate_scale_px: float = 2.0

    def __post_init__(self):
        need(isinstance(self.passes, int) and self.passes >= 0, "robust.passes",
              f"expected an integer >= 0, got {self.passes!r}")
        need(self.scale_px > 0, "robust.scale_px", f"must be > 0, got {self.scale_px}")
        need(self.gate_scale_px >= 0, "robust.gate_scale_px", f"must be >= 0, got {self.gate_scale_px}")


@dataclasses.dataclass(frozen=True)
class LossConfig:
    """The frame's score and the loss-of-track rule (:func:`~jaxhand.track.frame_score`).

    Attributes:
        rms_scale_px: traced, px. The residual RMS at which the confidence halves.
        min_valid_share: traced, in [0, 1]. Below this share of valid feature slots the frame is lost.
        valid_share_good: traced, in (0, 1]. The share of valid feature slots at and above which
            the share does not lower the confidence (1: the share itself scales it). Hands
            crossing each other hide half their features on frames that are right.
        max_rms_px: traced, px. Above this residual RMS the frame is lost.
        min_term_merit: traced, in [0, 1]. The measured terms (``image.silhouette_term``) scale
            the confidence by their merit at the solve; below this merit the frame is lost.
        hold: static. On a lost frame report the last good estimate and predict it standing still.
        score_lost, score_good: host, in [0, 1]. The front end's image score (where it gives one:
            :attr:`jaxhand.image.ImageConfig.score`) of the estimate at which the frame is lost,
            and above which the image does not lower the confidence (:func:`~jaxhand.track.judge_frame`);
            fitted on the dev set's tracked frames (``benchmarks/score.py --tracked``).
        score_relative: host. Apply those levels to the score over the first scored frame's
            (tracking starts from a given pose): the score a right pose reaches differs with the
            view, the foreground model and what the model lacks (a palm, clutter).
        doubt_level: host, in (0, 1). The tracker's own confidence that is reported as 0.5
            (:func:`~jaxhand.track.reported_confidence`: piecewise linear, [0, doubt_level] onto
            [0, 0.5] and [doubt_level, 1] onto [0.5, 1]), so that a frame reported under 0.5 is one
            to doubt; 0.5 reports the confidence as it is. The tracker's own decisions (restarts,
            searches) keep using its own confidence.
    """

    rms_scale_px: float = 2.0
    min_valid_share: float = 0.15
    valid_share_good: float = 1.0
    max_rms_px: float = 6.0
    min_term_merit: float = 0.1
    hold: bool = True
    score_lost: float = 0.801
    score_good: float = 0.981
    score_relative: bool = True
    doubt_level: float = 0.5

    def __post_init__(self):
        need(self.rms_scale_px > 0, "loss.rms_scale_px", f"must be > 0, got {self.rms_scale_px}")
        need(0.0 <= self.min_valid_share <= 1.0, "loss.min_valid_share",
              f"must lie in [0, 1], got {self.min_valid_share}")
        need(0.0 < self.valid_share_good <= 1.0, "loss.valid_share_good",
             f"must lie in (0, 1], got {self.valid_share_good}")
        need(self.max_rms_px > 0, "loss.max_rms_px", f"must be > 0, got {self.max_rms_px}")
        need(0.0 <= self.min_term_merit <= 1.0, "loss.min_term_merit",
              f"must lie in [0, 1], got {self.min_term_merit}")
        flag(self.hold, "loss.hold")
        flag(self.score_relative, "loss.score_relative")
        need(0.0 <= self.score_lost < self.score_good <= 1.0, "loss.score_lost",
              f"need 0 <= score_lost < score_good <= 1, got {self.score_lost}, {self.score_good}")
        need(0.0 < self.doubt_level < 1.0, "loss.doubt_level", f"must lie in (0, 1), got {self.doubt_level}")


def _off(value) -> float:
    return 0.0 if value is None else value


@dataclasses.dataclass(frozen=True)
class PriorConfig:
    """Pose priors stacked under the image residuals of every solve (:mod:`jaxhand.priors`).

    Each prior's residual unit counts as one px of image residual. A value of 0 (or None) turns a
    prior off: whether each prior is on is static, its numbers are traced.

    Attributes:
        temporal_sigma_deg: traced, deg. Sigma of the temporal prior of each joint angle around
            the frame's prediction (0: none).
        temporal_sigma_mm: traced, mm. The same for length entries (base translation, prismatic).
        information_ratio: traced, unitless. Weigh the temporal prior by the image information of
            the frame's features at the start of the solve (:func:`~jaxhand.priors.information_weight`):
            along a direction in q that the images see with ``l`` times the prior's information its
            weight is ``ratio / (ratio + l)`` of the full one (0: the fixed sigmas everywhere).
        information_terms: traced, unitless. The share of the frame's measured terms' information
            (the silhouette's, fused landmarks') that counts in that weighting beside the features'
            (1: all of it; 0: the features' alone, so a direction only those terms see keeps the prior).
        temporal_merit: traced, unitless. With several starts (``hypotheses``), each start's merit
            also counts its pose's fixed-sigma temporal residuals ``(q - q_pred) / sigma`` times this,
            beside the feature residuals (:func:`~jaxhand.track._hypotheses.image_merit`): the choice
            then weighs the motion as the solves do, and a start that fits the image a little better
            far from the prediction does not win by it alone (0: the image alone chooses).
        temporal_min_confidence: host, in [0, 1]. The temporal prior (and its merit) hold only on a
            frame after one whose confidence reached this (0: on every frame): a prediction from
            a frame the tracker doubts is no motion to keep to, and a prior around it holds the
            solve, and the choice among the starts, to the wrong pose.
        restore_hidden_below: host, in [0, 1]. After a frame whose confidence fell under this, the
            joints the image did not show on it (those that move no link the front end's support
            judged) start again, still, from the last trusted pose (the estimate of the last frame
            whose confidence reached it): a doubtful frame's solve may move a hidden finger where
            the image cannot correct it, and a temporal prior would then hold it there (0: off;
            needs ``support.enabled``).
        hold_unseen_frames: host, frames. A joint none of whose links has had a feature line (in
            any camera) for this many frames in a row starts each frame, still, from its value on
            the last frame that measured one (0: off). Such a joint follows only the silhouette
            term and the priors, and drifts: a finger hidden behind the thumb curled on to its
            soft limit.
        thumb_rest_sigma_deg: traced, deg. A Gaussian prior of this sigma on the thumb's joints (those
            of every finger that is not planar: :func:`~jaxhand.track._flexion.thumb_joints`)
            towards the model's default pose, information-weighted as the temporal prior (needs
            ``information_ratio``): five hinges seen as two lines and a tip leave one camera a
            direction it hardly sees, along which small feature biases carry the thumb far off
            while the temporal prior only slows them (0: none). Not for the planar fingers: it
            would hold a finger that curls towards the camera straight.
        dip_pip_weight: traced, 1/rad. DIP-PIP coupling, ``w (q_dip - r q_pip)`` per finger (0: none).
        dip_pip_ratio: traced, unitless. That coupling's ``r``, the DIP's flexion over the PIP's
            (the common anatomical approximation 2/3 by default).
        soft_limit_weight: traced, 1/rad. Soft joint limits beyond ``soft_limit_margin_deg`` (0: none).
        soft_limit_margin_deg: traced, deg. Where each soft limit starts, past its hard limit (the
            ``bounded`` solver never goes there); negative: that far inside, as a pose at its limits is unlikely.
        hyperextension_weight: traced, 1/rad. A soft limit on the extension side of each planar
            finger's flexion hinges (the narrower side of the range), ``hyperextension_deg`` past
            straight (0: none): seen from the front, a finger flexing towards the camera and one
            bending back look alike, and a hand flexes far more often than it hyperextends.
        hyperextension_deg: traced, deg. Where that soft limit starts, past the straight finger.
    """

    temporal_sigma_deg: float | None = 0.0
    temporal_sigma_mm: float | None = 0.0
    information_ratio: float | None = 0.0
    information_terms: float | None = 1.0
    temporal_merit: float | None = 0.0
    temporal_min_confidence: float | None = 0.0
    restore_hidden_below: float | None = 0.0
    hold_unseen_frames: float | None = 0.0
    thumb_rest_sigma_deg: float | None = 0.0
    dip_pip_weight: float | None = 0.0
    dip_pip_ratio: float = DIP_PIP_RATIO
    soft_limit_weight: float | None = 0.0
    soft_limit_margin_deg: float | None = 0.0
    hyperextension_weight: float | None = 0.0
    hyperextension_deg: float | None = 15.0

    def __post_init__(self):
        for f in dataclasses.fields(self):
            value, signed = _off(getattr(self, f.name)), f.name == "soft_limit_margin_deg"
            need(finite_number(value) and (signed or value >= 0), f"prior.{f.name}",
                 f"expected a finite number >= 0 (0: off), got {value}")
            object.__setattr__(self, f.name, float(value))
        need(not self.information_ratio or bool(self.temporal_sigma_deg or self.temporal_sigma_mm),
              "prior.information_ratio", "weighs the temporal prior: set temporal_sigma_deg or temporal_sigma_mm")
        need(not self.thumb_rest_sigma_deg or bool(self.information_ratio), "prior.thumb_rest_sigma_deg",
             "is information-weighted: set information_ratio (and a temporal prior)")
        need(not self.temporal_merit or self.temporal,
             "prior.temporal_merit", "counts the temporal prior: set temporal_sigma_deg or temporal_sigma_mm")
        need(self.temporal_min_confidence <= 1.0, "prior.temporal_min_confidence",
             f"must lie in [0, 1], got {self.temporal_min_confidence}")
        need(not self.temporal_min_confidence or self.temporal, "prior.temporal_min_confidence",
             "gates the temporal prior: set temporal_sigma_deg or temporal_sigma_mm")
        need(self.restore_hidden_below <= 1.0, "prior.restore_hidden_below",
             f"must lie in [0, 1], got {self.restore_hidden_below}")

    @property
    def temporal(self) -> bool:
        """Whether there is a temporal prior (static)."""
        return bool(self.temporal_sigma_deg or self.temporal_sigma_mm)


@dataclasses.dataclass(frozen=True)
class LandmarkConfig:
    """Landmarks in the tracker (``jaxhand track --landmarks``; :mod:`jaxhand.track._landmarks`).

    Attributes:
        fuse_weight: traced, unitless (0: off; whether it is on is static). Every frame's
            landmarks enter its solve as 2-D residuals beside the edges, each point weighted by
            ``fuse_weight`` times its confidence: a landmark pixel counts ``sqrt(weight)`` image
            pixels. The frame's score stays on the image residuals alone.
        restart: host. When a frame is lost, solve it again from its landmark pose (filter and
            front end state started afresh there).
        restart_px: host, px. Also count a frame as lost (for the restart only) when the
            reported pose's 21 landmark points lie a median of more than this from the frame's
            landmarks (0: only the tracker's own loss flag).
        fit: host. How the landmark poses are fitted up front: ``"sequence"`` (the whole-sequence
            fit with smoothness) or ``"frames"`` (frame by frame only, each from the previous).
        propose: host. The frame's landmark pose joins its starts as a hypothesis
            (:attr:`TrackConfig.hypotheses`; the best start by residual and image score wins).
    """

    fuse_weight: float | None = 0.0
    restart: bool = True
    restart_px: float | None = 0.0
    fit: str = "sequence"
    propose: bool = True

    def __post_init__(self):
        value = _off(self.fuse_weight)
        need(finite_number(value) and value >= 0, "landmarks.fuse_weight",
             f"expected a finite number >= 0 (0: off), got {value!r}")
        object.__setattr__(self, "fuse_weight", float(value))
        px = _off(self.restart_px)
        need(finite_number(px) and px >= 0,
              "landmarks.restart_px", f"expected a finite number >= 0 (0: off), got {px!r}")
        object.__setattr__(self, "restart_px", float(px))
        for name in ("restart", "propose"):
            flag(getattr(self, name), f"landmarks.{name}")
        need(self.fit in ("sequence", "frames"), "landmarks.fit",
              f"expected 'sequence' or 'frames', got {self.fit!r}")


def _tracker_fit() -> FitConfig:
    # 20 iterations per frame, the geometric Jacobian (cheaper than autodiff; benchmarks/README.md)
    return FitConfig(max_steps=20, jacobian="geometric")


@dataclasses.dataclass(frozen=True, eq=False)
class TrackConfig:
    """Every setting of a tracking run (:class:`~jaxhand.Tracker`, :func:`~jaxhand.track_sequence`).

    Attributes:
        solver: static. The solver of :func:`jaxhand.fit` run per frame ("bounded": every iterate
            inside the joint limits, so an occluded finger is not fitted into impossible poses).
        fit: the solver's options (iterations per frame, Jacobian, tolerances; static and traced
            as :class:`~jaxhand.FitConfig` says).
        image: host. The image front end's settings (:class:`~jaxhand.ImageConfig`), used by the
            :class:`~jaxhand.ImageFrontEnd` that :func:`~jaxhand.track_sequence` builds.
        filter: the g-h-k filter (:class:`FilterConfig`).
        robust: the gate and robust passes (:class:`RobustConfig`).
        loss: the frame's score and the loss rule (:class:`LossConfig`).
        prior: pose priors in the solve (:class:`PriorConfig`; all off by default).
        hypotheses: several starts per frame and recovery after a loss (:class:`HypothesisConfig`;
            all off by default).
        reextract: host. Times the front end searches again around the solved pose, then the
            frame is solved again from there (for front ends whose ``reextracts`` is true).
        refresh_templates: host. After a frame that is not lost, let the front end refresh its
            state (templates, widths) at the solved pose.
        landmarks: landmarks as start, restart and solve term (:class:`LandmarkConfig`; used
            only when a run is given landmarks).
        support: the weakest finger's image support lowers the confidence (:class:`SupportConfig`; off).
    """

    solver: str = "bounded"
    fit: FitConfig = dataclasses.field(default_factory=_tracker_fit)
    image: ImageConfig = dataclasses.field(default_factory=ImageConfig)
    filter: FilterConfig = dataclasses.field(default_factory=FilterConfig)
    robust: RobustConfig = dataclasses.field(default_factory=RobustConfig)
    loss: LossConfig = dataclasses.field(default_factory=LossConfig)
    prior: PriorConfig = dataclasses.field(default_factory=PriorConfig)
    hypotheses: HypothesisConfig = dataclasses.field(default_factory=HypothesisConfig)
    reextract: int = 1
    refresh_templates: bool = True
    landmarks: LandmarkConfig = dataclasses.field(default_factory=LandmarkConfig)
    support: SupportConfig = dataclasses.field(default_factory=SupportConfig)

    def __post_init__(self):
        solver_named(self.solver)
        for name, kind in (("fit", FitConfig), ("image", ImageConfig), ("filter", FilterConfig),
                           ("robust", RobustConfig), ("loss", LossConfig), ("prior", PriorConfig),
                           ("hypotheses", HypothesisConfig), ("landmarks", LandmarkConfig), ("support", SupportConfig)):
            need(isinstance(getattr(self, name), kind), name,
                  f"expected a {kind.__name__}, got {type(getattr(self, name)).__name__}")
        try:
            check_config(self.fit)
        except InputError as err:
            raise InputError(f"fit.{str(err).removeprefix('config.')}") from None
        count(self.reextract, "reextract")
        flag(self.refresh_templates, "refresh_templates")
        need(not self.prior.restore_hidden_below or self.support.enabled or bool(self.hypotheses.finger_level),
             "prior.restore_hidden_below", "needs the image support to tell hidden joints: set support.enabled")
        for name in ("verify_below", "fold_passage_deg"):
            need(not getattr(self.hypotheses, name) or self.support.enabled, f"hypotheses.{name}",
                 "needs the image support to judge the fingers: set support.enabled")

    def __eq__(self, other) -> bool:   # by value: FitConfig holds arrays
        return isinstance(other, TrackConfig) and config_to_dict(self) == config_to_dict(other)

    def __hash__(self) -> int:
        return hash(json.dumps(config_to_dict(self), sort_keys=True))

    def merged(self, changes: dict) -> TrackConfig:
        """A copy with the nested mapping ``changes`` (as in :func:`config_to_dict`) applied."""
        return config_from_dict(_merge(config_to_dict(self), changes))

    def preset(self, name: str) -> TrackConfig:
        """A copy with the named :data:`PRESETS` entry applied (``TrackConfig().preset("robust")``).

        Raises:
            InputError: an unknown name (the message lists the presets).
        """
        need(name in PRESETS, "preset", f"unknown preset {name!r}; valid: {', '.join(PRESETS)}")
        return self.merged(PRESETS[name])


def _merge(base: dict, changes: dict) -> dict:
    return {**base, **{k: _merge(base[k], v) if isinstance(v, dict) and isinstance(base.get(k), dict) else v
                       for k, v in changes.items()}}


def _plain(value):
    """A config value as plain Python (dicts, lists, numbers, strings, bools)."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: _plain(getattr(value, f.name)) for f in dataclasses.fields(value) if f.init}
    if isinstance(value, (tuple, list)):
        return [_plain(v) for v in value]
    if isinstance(value, (bool, str, int, float)) or value is None:
        return value
    a = np.asarray(value)
    return a.tolist() if a.ndim else a.item()


def config_to_dict(config: TrackConfig) -> dict:
    """The whole tree as plain Python, with ``format_version`` (what ``summary.json`` holds)."""
    return {"format_version": TRACK_CONFIG_VERSION, **_plain(config)}


def _build(template, data, where: str):
    """``type(template)`` from ``data``, missing keys taken from ``template``."""
    if not isinstance(data, dict):
        raise InputError(f"{where or 'config'}: expected a table, got {data!r}")
    names = [f.name for f in dataclasses.fields(template) if f.init]
    values = {n: getattr(template, n) for n in names}
    for key, value in data.items():
        if key not in values:
            hint = difflib.get_close_matches(key, names, n=1)
            raise InputError(f"{where + '.' if where else ''}{key}: unknown key"
                             + (f"; did you mean {hint[0]!r}?" if hint else f"; valid keys: {', '.join(names)}"))
        values[key] = _value(values[key], value, f"{where + '.' if where else ''}{key}")
    try:
        return type(template)(**values)
    except (TypeError, ValueError) as err:
        if isinstance(err, InputError):
            raise
        raise InputError(f"{where or 'config'}: {err}") from err


def _value(template, value, where: str):
    if dataclasses.is_dataclass(template):
        return _build(template, value, where)
    if isinstance(template, bool):
        flag(value, where)
        return value
    if isinstance(template, tuple):
        need(isinstance(value, (list, tuple)), where, f"expected a list, got {value!r}")
        return tuple(value)
    if isinstance(template, float) and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    return value


def config_from_dict(data: dict) -> TrackConfig:
    """The :class:`TrackConfig` of :func:`config_to_dict`'s mapping; missing keys keep their
    defaults, unknown ones raise :class:`~jaxhand.InputError` with a "did you mean" hint."""
    data = dict(data)
    version = data.pop("format_version", TRACK_CONFIG_VERSION)
    need(version == TRACK_CONFIG_VERSION, "format_version",
          f"this jaxhand reads version {TRACK_CONFIG_VERSION}, got {version!r}")
    return _build(TrackConfig(), data, "")
