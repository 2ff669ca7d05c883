"""What the tracker carries between frames and what it reports per frame."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

import numpy as np

from ..filter import GHKState
from ._frontend import FrontEndDiagnostics

__all__ = ["TrackState", "StepReport"]


@dataclasses.dataclass(frozen=True)
class TrackState:
    """What the tracker carries between frames.

    Attributes:
        ghk: the filter state, whose x is the prediction for the next frame.
        frontend_state: the front end's state (templates, widths; None before the first frame).
        q_last: the last reported estimate (held on a lost frame).
        score_reference: the image score of the first scored frame (NaN before it; see
            :attr:`~jaxhand.track.LossConfig.score_relative`).
        q_solved: the last frame's solve (a start with :attr:`HypothesisConfig.last_solve`).
        carried: the runners-up carried as extra starts (:attr:`HypothesisConfig.carry`), (m, n_q).
        lost: whether the last frame was lost (the next frames then recover, :attr:`HypothesisConfig.recover`).
        weak_finger: the finger the image supported least on the last frame, when its confidence was
            under :attr:`HypothesisConfig.finger_level` (the next frame bends it); -1: none.
        confidence: the last frame's confidence, the tracker's own (before
            :attr:`LossConfig.doubt_level`'s mapping; :attr:`PriorConfig.temporal_min_confidence`).
        q_trusted: the estimate of the last frame whose confidence reached
            :attr:`PriorConfig.restore_hidden_below` (the initial pose before one did).
        hidden: the q entries the image did not show on the last frame (they move no link the
            front end's support judged; empty when it was not measured).
        unseen: per q entry, the frames in a row none of whose links had a feature line (None
            unless :attr:`PriorConfig.hold_unseen_frames`).
        q_seen: per q entry, its estimate on the last frame that measured one of its links.
        fold_offsets: the last frames' signed offsets (deg) of each hinge from its fold, oldest
            first (None unless :attr:`HypothesisConfig.fold_passage_deg`; :mod:`jaxhand.track._passage`).
    """

    ghk: GHKState
    frontend_state: Any
    q_last: np.ndarray
    score_reference: float = float("nan")
    q_solved: np.ndarray | None = None
    carried: np.ndarray | None = None
    lost: bool = False
    weak_finger: int = -1
    confidence: float = 1.0
    q_trusted: np.ndarray | None = None
    hidden: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0, int))
    unseen: np.ndarray | None = None
    q_seen: np.ndarray | None = None
    fold_offsets: np.ndarray | None = None


@dataclasses.dataclass(frozen=True)
class StepReport:
    """Exactly what gets written for one frame (angles in rad, pixels, seconds)."""

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
    confidence: float   # as reported (LossConfig.doubt_level at 0.5); TrackState.confidence is the tracker's own
    lost: bool
    timings_s: Mapping[str, float]
    diagnostics: FrontEndDiagnostics
    image_score: float = float("nan")   # the front end's score of q_filtered (NaN: none)
    hypothesis: str = "prediction"   # the kind of start that won (_hypotheses.LABELS); "review": tracked back (_review)
    starts: int = 1                  # the starts solved
    reinitialised: bool = False      # the first frame not lost after a lost one
    seen: np.ndarray | None = None   # per q entry, the share of image information the features give it (_seen)
