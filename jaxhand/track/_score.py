"""The frame's score and the loss rule: the residual rule, one pure function for the host and the
compiled step, and its combination with the front end's global image score (on the host)."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from ..score import ConfidenceConfig, frame_confidence
from ._config import LossConfig, TrackConfig

__all__ = ["frame_score", "confidence_of", "judge_frame", "held_filter", "reported_confidence"]


def frame_score(rms_px, valid_share, rms_scale_px, min_valid_share, max_rms_px, xp=jnp, share_good=1.0):
    """Confidence in [0, 1] and the loss flag of a frame from its residual RMS (px) and its share
    of valid feature slots: ``confidence = min(1, share / share_good) / (1 + (rms / rms_scale_px)^2)``
    (0 when not finite); lost when ``share < min_valid_share``, ``rms > max_rms_px`` or the RMS is
    not finite.

    ``xp`` is ``jax.numpy`` inside the compiled step and ``numpy`` on the host.
    """
    conf = xp.minimum(valid_share / share_good, 1.0) / (1.0 + (rms_px / rms_scale_px) ** 2)
    conf = xp.where(xp.isfinite(conf), conf, 0.0)
    lost = (valid_share < min_valid_share) | (rms_px > max_rms_px) | ~xp.isfinite(rms_px)
    return conf, lost


def reported_confidence(confidence: float, doubt_level: float = 0.5) -> float:
    """The confidence a frame reports: the tracker's own ``confidence`` (in [0, 1]) mapped
    piecewise linearly so that ``doubt_level`` becomes 0.5 (:attr:`LossConfig.doubt_level`);
    monotone, 0 and 1 kept, the identity at 0.5."""
    c = min(max(float(confidence), 0.0), 1.0)
    if c <= doubt_level:
        return 0.5 * c / doubt_level
    return 0.5 + 0.5 * (c - doubt_level) / (1.0 - doubt_level)


def confidence_of(rms_px: float, valid_share: float, config: LossConfig | TrackConfig) -> tuple[float, bool]:
    """:func:`frame_score` on the host with the settings of ``config`` (or ``config.loss``)."""
    loss = config.loss if isinstance(config, TrackConfig) else config
    conf, lost = frame_score(np.float64(rms_px), np.float64(valid_share), loss.rms_scale_px, loss.min_valid_share,
                             loss.max_rms_px, xp=np, share_good=loss.valid_share_good)
    return float(conf), bool(lost)


def judge_frame(frontend, images, q, frontend_state, confidence: float, lost: bool, loss: LossConfig,
                reference: float = float("nan")) -> tuple[float, bool, float, float]:
    """The frame's confidence and loss flag with the front end's image score of the estimate ``q``.

    The image term is :func:`jaxhand.score.frame_confidence` of the score alone (over
    ``reference`` with :attr:`LossConfig.score_relative`), a ramp from 0 at ``loss.score_lost``
    to 1 at ``loss.score_good``; the frame keeps the lower of it and the residual ``confidence``,
    and is lost when either rule says so. A frame the residual rule has already lost, or a front
    end without a score (None), is left as it is.

    Args:
        reference: the first scored frame's score (NaN: this frame's score becomes it, if > 0).

    Returns:
        (confidence, lost, score, reference); score is NaN where none was computed.
    """
    nan = float("nan")
    if lost:
        return confidence, lost, nan, reference
    scores = frontend.score(images, np.asarray(q)[None], frontend_state)
    if scores is None:
        return confidence, lost, nan, reference
    score = float(np.asarray(scores).reshape(-1)[0])
    if not reference > 0 and score > 0:   # NaN before the first scored frame
        reference = score
    scale = reference if loss.score_relative and reference > 0 else 1.0
    c_image, lost_image = frame_confidence(score, 0.0, 1.0, ConfidenceConfig(
        score_lost=loss.score_lost, score_good=loss.score_good, score_reference=scale))
    return min(confidence, float(c_image)), bool(lost_image), score, reference


def held_filter(q_last) -> tuple:
    """The filter state (x, v, a) that holds ``q_last`` still: what a lost frame predicts from
    under :attr:`LossConfig.hold` (as the compiled step does for a frame its residuals lose)."""
    x = jnp.asarray(q_last)
    return x, jnp.zeros_like(x), jnp.zeros_like(x)
