"""Per-finger image support: the confidence a frame loses when one finger of the estimate is not
backed by the image, even though the whole model stays inside the foreground (issue 13).

A link's support is its :func:`jaxhand.score.score_silhouette` link score at the reported pose
(the mean of its visible pixels' foreground share and its own contour's closeness to the image's
edges). A *finger* is a chain of links under one child of the base frame; its support is the
mean over its judged links (a hidden link gives no evidence either way), and the frame's is the
weakest finger's. With ``tip_links`` only the links that carry a fingertip are judged
(:func:`tip_link_scores`), optionally with each whole finger's support ramped too
(:func:`whole_finger_confidence`). :func:`support_confidence` maps it onto [0, 1] with a ramp.

The converse evidence: foreground the estimate leaves unexplained (:func:`largest_unexplained_px`,
the largest blob of foreground outside the grown silhouette), e.g. the tip of a finger the model
has put somewhere else; :func:`unexplained_confidence` maps its area onto [0, 1]. The tracker
keeps the lowest of these and the frame's other confidence (host side, NumPy and OpenCV).
"""

from __future__ import annotations

import dataclasses
import math

import cv2
import numpy as np

from .._errors import InputError
from ..model import Model

__all__ = ["SupportConfig", "ImageSupport", "finger_of_frame", "finger_of_link", "moved_links", "finger_supports",
           "weakest_finger", "tip_link_scores", "judge_weights", "support_confidence", "whole_finger_confidence",
           "largest_unexplained_px", "unexplained_confidence"]


@dataclasses.dataclass(frozen=True)
class SupportConfig:
    """The per-finger support rule (:mod:`jaxhand.track._support`). Off by default (the thesis'
    confidence alone); on in the "robust" preset.

    Attributes:
        enabled: host. Lower the confidence by the weakest finger's image support.
        lost: host, in [0, 1]. The finger support at which this term's confidence is 0.
        good: host, in [0, 1]. ...and at which it is 1 (the midpoint is where a frame is flagged).
        unexplained_px: host, px. The area of unexplained foreground at which that term's
            confidence is 0.5 (0 at twice it); 0: the term is off.
        margin_px: host, px. The silhouette is grown by this before the foreground outside it
            counts as unexplained (the outline's rounding and antialiasing).
        judge_power: host, >= 0. Each hypothesis's merit is also multiplied by its weakest
            finger's support to this power, so that of two starts the silhouette cannot tell
            apart (a finger lying on another's image) the one whose fingers the image backs
            wins; 0: off. Works whether or not ``enabled`` is.
        tip_links: host. Judge each finger by the link that carries its tip alone (its distal
            phalanx): a finger whose tip lies on its image while a proximal phalanx strays off
            its edges still has its tip right, and the tips are what the loss flag is about.
        whole_lost: host, in [0, 1]. Each finger's support over all its links also lowers the
            confidence, ramped from this (0) to ``whole_good`` (1). With ``tip_links`` a finger
            whose tip link happens to lie on edges while the rest of it lies wrong (folded the
            other way over the palm) is then doubtful too. Both 0: off.
        whole_good: host, in [0, 1]. ...and at which it is 1.
    """

    enabled: bool = False
    lost: float = 0.80
    good: float = 0.96
    unexplained_px: float = 8.0
    margin_px: int = 1
    judge_power: float = 0.0
    tip_links: bool = False
    whole_lost: float = 0.0
    whole_good: float = 0.0

    def __post_init__(self):
        for name in ("enabled", "tip_links"):
            if not isinstance(getattr(self, name), bool):
                raise InputError(f"support.{name}: expected true or false, got {getattr(self, name)!r}")
        for name in ("lost", "good"):
            if not _finite(getattr(self, name)):
                raise InputError(f"support.{name}: expected a finite number, got {getattr(self, name)!r}")
        if not 0.0 <= self.lost < self.good <= 1.0:
            raise InputError(f"support.lost: need 0 <= lost < good <= 1, got {self.lost}, {self.good}")
        for name in ("whole_lost", "whole_good"):
            if not _finite(getattr(self, name)):
                raise InputError(f"support.{name}: expected a finite number, got {getattr(self, name)!r}")
        if (self.whole_lost, self.whole_good) != (0.0, 0.0) and not 0.0 <= self.whole_lost < self.whole_good <= 1.0:
            raise InputError(f"support.whole_lost: need 0 <= whole_lost < whole_good <= 1 (both 0: off), got "
                             f"{self.whole_lost}, {self.whole_good}")
        for name in ("unexplained_px", "judge_power"):
            if not (_finite(getattr(self, name)) and getattr(self, name) >= 0):
                raise InputError(f"support.{name}: expected a finite number >= 0, got {getattr(self, name)!r}")
        if isinstance(self.margin_px, bool) or not isinstance(self.margin_px, int) or self.margin_px < 0:
            raise InputError(f"support.margin_px: expected a whole number >= 0, got {self.margin_px!r}")


def _finite(value) -> bool:
    """A finite int or float (true/false do not count as numbers)."""
    return not isinstance(value, bool) and isinstance(value, (int, float)) and math.isfinite(value)


@dataclasses.dataclass(frozen=True)
class ImageSupport:
    """What a front end measures of one pose against one frame (:meth:`AbstractFrontEnd.support`).

    Attributes:
        link_score: (cameras, n_links) each link's support in [0, 1] (NaN: not judged).
        unexplained_px: the largest blob of unexplained foreground over the cameras (px).
    """

    link_score: np.ndarray
    unexplained_px: float = 0.0


def finger_of_frame(model: Model) -> np.ndarray:
    """(n_frames,) each frame's finger: its ancestor right under the base frame (as that frame's
    index minus one); -1 for the base frame itself."""
    parents = model.parents
    out = []
    for f in range(len(parents)):
        while f > 0 and parents[f] > 0:
            f = parents[f]
        out.append(f - 1 if f > 0 else -1)
    return np.asarray(out, int)


def finger_of_link(model: Model) -> np.ndarray:
    """(n_links,) each link's finger (:func:`finger_of_frame` of its frame); -1 for a link on the
    base frame itself, which no finger judges."""
    return finger_of_frame(model)[np.asarray(model.link_frame, int)]


def moved_links(model: Model) -> np.ndarray:
    """(n_q, n_links) bool: whether q entry ``j`` moves link ``l`` (the link's frame is the joint's
    frame or below it); a free or planar base's entries move every link."""
    below = model.ancestors.T[:, np.asarray(model.link_frame, int)]   # [f, l]: link l's frame is f or below it
    out = np.zeros((model.n_q, model.n_links), bool)
    out[: model.n_base_q] = True
    for f, j in enumerate(model.q_index):
        if j >= model.n_base_q:
            out[j] = below[f]
    return out


def finger_supports(link_scores, finger: np.ndarray) -> dict[int, float]:
    """Each judged finger's support: the mean of its links' scores (NaN: not judged, left out;
    ``link_scores`` may be (cameras, links), then averaged over the cameras that judge a link first)."""
    s = np.asarray(link_scores, float).reshape(-1, len(finger))
    judged = np.isfinite(s)
    per_link = np.where(judged.any(0), np.where(judged, s, 0.0).sum(0) / np.maximum(judged.sum(0), 1), np.nan)
    return {int(g): float(np.nanmean(per_link[finger == g])) for g in np.unique(finger[finger >= 0])
            if np.isfinite(per_link[finger == g]).any()}


def weakest_finger(link_scores, finger: np.ndarray) -> float:
    """The lowest finger support (:func:`finger_supports`); NaN when no finger has a judged link."""
    supports = finger_supports(link_scores, finger)
    return min(supports.values()) if supports else float("nan")


def tip_link_scores(link_scores, tip_links) -> np.ndarray:
    """The (..., links) link scores with every link that carries no tip (not in ``tip_links``)
    set to NaN (not judged)."""
    s = np.array(link_scores, float)
    keep = np.zeros(s.shape[-1], bool)
    keep[np.asarray(tip_links, int)] = True
    s[..., ~keep] = np.nan
    return s


def judge_weights(link_scores: list, finger: np.ndarray, power: float) -> np.ndarray:
    """(candidates,) each candidate's weakest finger support to ``power`` (1 where no finger is
    judged), from each candidate's (cameras, links) link scores: the hypotheses' image judge."""
    weakest = np.array([weakest_finger(s, finger) for s in link_scores])
    return np.where(np.isfinite(weakest), np.clip(weakest, 0.0, 1.0), 1.0) ** power


def support_confidence(support: float, config: SupportConfig) -> float:
    """The support's confidence: 0 at ``config.lost``, 1 at ``config.good``, linear between and
    clipped; 1 for NaN (no finger judged: no evidence against the frame)."""
    return _ramp(support, config.lost, config.good)


def whole_finger_confidence(fingers: dict[int, float], config: SupportConfig) -> float:
    """The weakest whole finger's confidence (``fingers``: each finger's support over all its
    links, :func:`finger_supports`): 0 at ``config.whole_lost``, 1 at ``config.whole_good``,
    linear between and clipped; 1 when that term is off or no finger is judged."""
    if config.whole_good <= 0.0 or not fingers:
        return 1.0
    return _ramp(min(fingers.values()), config.whole_lost, config.whole_good)


def _ramp(value: float, lost: float, good: float) -> float:
    if not np.isfinite(value):
        return 1.0
    return float(np.clip((value - lost) / (good - lost), 0.0, 1.0))


def largest_unexplained_px(foreground, silhouette, margin_px: int) -> int:
    """The area (px) of the largest 8-connected blob of ``foreground`` outside ``silhouette``
    grown by ``margin_px``, after a 5x5 opening: a band up to 4 px wide along the outline is
    rounding or a model a pixel or two off a finger's side, not a finger the model lacks."""
    grown = cv2.dilate(np.asarray(silhouette, np.uint8),
                       cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * margin_px + 1, 2 * margin_px + 1)))
    outside = (np.asarray(foreground, bool) & (grown == 0)).astype(np.uint8)
    outside = cv2.morphologyEx(outside, cv2.MORPH_OPEN, np.ones((5, 5), np.uint8))
    n, _, stats, _ = cv2.connectedComponentsWithStats(outside, connectivity=8)
    return int(stats[1:, cv2.CC_STAT_AREA].max()) if n > 1 else 0


def unexplained_confidence(area_px: float, config: SupportConfig) -> float:
    """The unexplained foreground's confidence: 1 at none, 0.5 at ``config.unexplained_px``, 0 at
    twice it (linear, clipped); 1 when the term is off."""
    if config.unexplained_px <= 0:
        return 1.0
    return float(np.clip(1.0 - area_px / (2.0 * config.unexplained_px), 0.0, 1.0))
