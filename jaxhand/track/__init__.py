"""Tracking: a model through frames, one front end, one compiled solve-and-filter step per frame.

- :class:`TrackConfig` (with :class:`FilterConfig`, :class:`RobustConfig`, :class:`LossConfig`, :class:`PriorConfig`,
  :class:`HypothesisConfig`, :class:`LandmarkConfig`, :class:`SupportConfig`, a :class:`~jaxhand.FitConfig` and an
  :class:`~jaxhand.ImageConfig`): every setting of a run, saved to and loaded from TOML
  (:func:`save_track_config`, :func:`load_track_config`);
- :class:`AbstractFrontEnd` and its final implementations :class:`ImageFrontEnd` (the image
  analysis) and :class:`ExactFrontEnd` (exact features of a known truth, for experiments);
- :class:`Tracker` (``init``, ``step``), :class:`TrackState`, :class:`StepReport`; :class:`Review`,
  which tracks the frames before a jump again backward and keeps what explains them better;
- :func:`track_sequence` (frames from disk to ``angles.csv``, ``summary.json``, overlay video)
  and :func:`accuracy_summary`; :func:`seen_summary`, which joints the frames saw
  (:attr:`StepReport.seen`) and how far off the unseen ones were; :func:`frame_score`, the loss
  rule, :func:`judge_frame`, its combination with the front end's image score, and
  :func:`reported_confidence`, the confidence as a frame reports it.
"""

from ._compiled import reweight
from ._config import (
    TRACK_CONFIG_VERSION,
    FilterConfig,
    HypothesisConfig,
    LandmarkConfig,
    LossConfig,
    PriorConfig,
    RobustConfig,
    TrackConfig,
    config_from_dict,
    config_to_dict,
)
from ._config_toml import config_to_toml, load_track_config, save_track_config
from ._frontend import (
    AbstractFrontEnd,
    ExactFrontEnd,
    FrontEndDiagnostics,
    FrontEndResult,
    ImageFrontEnd,
    image_front_end,
)
from ._presets import PRESETS
from ._review import Review
from ._score import confidence_of, frame_score, judge_frame, reported_confidence
from ._seen import seen_summary
from ._sequence import accuracy_summary, frame_tip_error_px, loss_flag_quality, track_sequence
from ._state import StepReport, TrackState
from ._support import ImageSupport, SupportConfig
from ._tracker import Tracker

__all__ = [
    "TrackConfig", "FilterConfig", "RobustConfig", "LossConfig", "PriorConfig", "HypothesisConfig", "LandmarkConfig",
    "SupportConfig", "ImageSupport", "TRACK_CONFIG_VERSION", "PRESETS",
    "config_to_dict", "config_from_dict", "config_to_toml", "save_track_config", "load_track_config",
    "AbstractFrontEnd", "FrontEndResult", "FrontEndDiagnostics", "ImageFrontEnd", "ExactFrontEnd", "image_front_end",
    "Tracker", "TrackState", "StepReport", "Review", "track_sequence", "accuracy_summary", "frame_tip_error_px",
    "loss_flag_quality", "seen_summary",
    "frame_score", "confidence_of", "judge_frame", "reported_confidence", "reweight",
]
