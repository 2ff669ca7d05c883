"""The frame's score and the loss rule, one pure function for the host and the compiled step."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from ._config import LossConfig, TrackConfig

__all__ = ["frame_score", "confidence_of"]


def frame_score(rms_px, valid_share, rms_scale_px, min_valid_share, max_rms_px, xp=jnp):
    """Confidence in [0, 1] and the loss flag of a frame from its residual RMS (px) and its share
    of valid feature slots: ``confidence = share / (1 + (rms / rms_scale_px)^2)`` (0 when not
    finite); lost when ``share < min_valid_share``, ``rms > max_rms_px`` or the RMS is not finite.

    ``xp`` is ``jax.numpy`` inside the compiled step and ``numpy`` on the host.
    """
    conf = valid_share / (1.0 + (rms_px / rms_scale_px) ** 2)
    conf = xp.where(xp.isfinite(conf), conf, 0.0)
    lost = (valid_share < min_valid_share) | (rms_px > max_rms_px) | ~xp.isfinite(rms_px)
    return conf, lost


def confidence_of(rms_px: float, valid_share: float, config: LossConfig | TrackConfig) -> tuple[float, bool]:
    """:func:`frame_score` on the host with the settings of ``config`` (or ``config.loss``)."""
    loss = config.loss if isinstance(config, TrackConfig) else config
    conf, lost = frame_score(np.float64(rms_px), np.float64(valid_share), loss.rms_scale_px, loss.min_valid_share,
                             loss.max_rms_px, xp=np)
    return float(conf), bool(lost)
