"""Per-frame confidence and the loss flag, from the image score and the solve (issue 13 items 3, 7).

The one home of the loss rule. Three pieces of evidence, each mapped linearly onto [0, 1]
between a "lost" and a "good" level and clipped:

- the global image score (:func:`score_silhouette`), optionally relative to a reference score:
  high is good;
- the solve's residual RMS (px): low is good; a small residual alone proves little (a model
  that slid onto clutter fits its edges well), so this only ever lowers the confidence;
- the valid share of the feature slots (found / expected): high is good.

``confidence = min(c_score, c_rms, c_valid)``: the weakest evidence decides. A frame is **lost**
when any piece reaches its lost level (then its term, and the confidence, is 0). Non-finite
inputs count as lost. Works elementwise on scalars or arrays of frames (NumPy; host side).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from jaxtyping import Bool, Float

from .._errors import InputError

__all__ = ["ConfidenceConfig", "frame_confidence"]


@dataclass(frozen=True)
class ConfidenceConfig:
    """Levels of the confidence ramps (host values).

    The score levels were set on the MuJoCo dev set (``benchmarks/score.py``: its true poses,
    each perturbed 12 times by up to 30 deg, 1,144 poses on the five clean sequences): true
    poses score 0.90-0.95 with the palm drawn as an occluder (0.97 on jaxhand's own renders),
    and a score below 0.79 (the middle of the ramp, confidence 0.5) flagged 94 % of the poses
    whose tips were more than 8 px off and 0.4 % of those within 3 px. These levels are fitted to
    that set, not held out. A model without the palm scores its true poses lower (IoU 0.55-0.59
    instead of 0.98); there, drop the IoU term (``ScoreConfig(w_iou=0)``) and pass the score of a
    frame known to be right as ``score_reference`` (e.g. the first frame's, when tracking starts
    from a given pose), so the levels apply to the ratio (91 % / 0.4 % on the same poses).

    Attributes:
        score_lost, score_good: image score (over ``score_reference``) at which its term is 0
            (lost) and 1.
        score_reference: the score of a right pose with this model and foreground; scores are
            divided by it (and capped at 1) before the ramp. 1: use them as they are.
        rms_good_px, rms_lost_px: residual RMS (px) at which its term is 1 and 0 (lost).
        valid_lost, valid_good: valid share of the feature slots at which its term is 0 (lost) and 1.
    """

    score_lost: float = 0.7
    score_good: float = 0.88
    score_reference: float = 1.0
    rms_good_px: float = 1.5
    rms_lost_px: float = 6.0
    valid_lost: float = 0.2
    valid_good: float = 0.6

    def __post_init__(self):
        for lo, hi, name in ((self.score_lost, self.score_good, "score"), (self.rms_good_px, self.rms_lost_px, "rms"),
                             (self.valid_lost, self.valid_good, "valid")):
            if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
                raise InputError(f"ConfidenceConfig: the {name} levels need {lo!r} < {hi!r}")
        if not (np.isfinite(self.score_reference) and self.score_reference > 0):
            raise InputError(f"ConfidenceConfig.score_reference: need > 0, got {self.score_reference!r}")


def _ramp(x, lo, hi):
    return np.clip((x - lo) / (hi - lo), 0.0, 1.0)


def frame_confidence(score, residual_rms_px, valid_share, config: ConfidenceConfig = ConfidenceConfig()
                     ) -> tuple[Float[np.ndarray, "*frames"], Bool[np.ndarray, "*frames"]]:
    """Confidence in [0, 1] and the loss flag of each frame.

    Args:
        score: image score(s) in [0, 1].
        residual_rms_px: the solve's residual RMS (px) over its valid slots.
        valid_share: valid feature slots over all slots, in [0, 1].
        config: the ramp levels.

    Returns:
        (confidence, lost): float and bool arrays of the inputs' broadcast shape (0-d for scalars).
    """
    s, r, v = (np.asarray(a, float) for a in (score, residual_rms_px, valid_share))
    finite = np.isfinite(s) & np.isfinite(r) & np.isfinite(v)
    s, r, v = (np.where(finite, a, 0.0) for a in (s, r, v))
    s = np.minimum(s / config.score_reference, 1.0)
    c_score = _ramp(s, config.score_lost, config.score_good)
    c_rms = 1.0 - _ramp(r, config.rms_good_px, config.rms_lost_px)
    c_valid = _ramp(v, config.valid_lost, config.valid_good)
    lost = ~finite | (s <= config.score_lost) | (r >= config.rms_lost_px) | (v <= config.valid_lost)
    confidence = np.where(lost, 0.0, np.minimum(np.minimum(c_score, c_rms), c_valid))
    return confidence, np.asarray(lost)
