"""Foreground models: which pixels show the hand (issue 13 item 3).

A :class:`AbstractForeground` turns a frame into a boolean mask (True: foreground). Three final
implementations, one per kind of footage:

- :class:`ThresholdForeground`: a bright hand on a dark background (the DigitEyes and thesis
  setup, the MuJoCo dev set): grey level above a fixed threshold, or a per-frame one (the
  triangle method, or Otsu's).
- :class:`BackgroundForeground`: a static camera: the absolute difference from a background image
  (given, or the per-pixel median of the first frames) above ``k`` times the background's noise
  (its per-pixel spread over those frames, floored), or above a fixed grey-level difference.
- :class:`SkinForeground`: colour video: a Gaussian model of skin chrominance in YCrCb (fitted
  from sample pixels, or a generic default) thresholded at a Mahalanobis distance.

Every implementation validates its frame first (ndim, dtype, size), computes with OpenCV, then
cleans the mask with a morphological opening of ``open_px`` (0 for none).
"""

from __future__ import annotations

import abc
from dataclasses import dataclass, field

import cv2
import numpy as np
from jaxtyping import Bool, Float, UInt8

from .._errors import InputError

__all__ = ["THRESHOLD_METHODS", "AbstractForeground", "ThresholdForeground", "BackgroundForeground", "SkinForeground",
           "fill_holes",
           "as_grey"]


def as_grey(image, where: str = "image") -> UInt8[np.ndarray, "H W"]:
    """A frame as (H, W) uint8 grey (colour frames are BGR, as OpenCV reads them).

    Raises:
        InputError: not a 2-D or (H, W, 3) array, empty, or non-finite.
    """
    a = np.asarray(image)
    if a.size == 0 or a.ndim not in (2, 3) or (a.ndim == 3 and a.shape[2] != 3):
        raise InputError(f"{where}: expected an (H, W) or (H, W, 3) image, got shape {a.shape}")
    if a.dtype != np.uint8:
        if not np.all(np.isfinite(a)):
            raise InputError(f"{where}: contains non-finite values")
        a = np.clip(np.rint(a), 0, 255).astype(np.uint8)
    return cv2.cvtColor(a, cv2.COLOR_BGR2GRAY) if a.ndim == 3 else a


def _disc(radius: int) -> np.ndarray:
    """The elliptic structuring element of ``radius`` px."""
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1, 2 * radius + 1))


def _open(mask: np.ndarray, open_px: int) -> np.ndarray:
    if open_px <= 0:
        return mask
    return cv2.morphologyEx(mask.astype(np.uint8), cv2.MORPH_OPEN, _disc(open_px)).astype(bool)


class AbstractForeground(abc.ABC):
    """Maps a frame (H, W) or (H, W, 3) to a foreground mask (H, W) bool."""

    @abc.abstractmethod
    def mask(self, image) -> Bool[np.ndarray, "H W"]:
        """The foreground of one frame.

        Raises:
            InputError: a malformed frame (shape, dtype, size).
        """

    def doubtful(self, image, mask=None) -> Bool[np.ndarray, "H W"]:
        """The pixels of :meth:`mask` whose call this model cannot make (foreground or not): the
        scores leave them out. ``mask``: the frame's :meth:`mask`, where the caller has it. None here."""
        return np.zeros(as_grey(image).shape, bool)


def fill_holes(mask: Bool[np.ndarray, "H W"], max_px: int) -> Bool[np.ndarray, "H W"]:
    """``mask`` with every 4-connected hole of fewer than ``max_px`` pixels filled (a background
    region touching the image border is never a hole)."""
    if max_px <= 0:
        return mask
    n, labels, stats, _ = cv2.connectedComponentsWithStats((~mask).astype(np.uint8), connectivity=4)
    h, w = mask.shape
    x, y, bw, bh, area = (stats[:, i] for i in range(5))
    inner = (x > 0) & (y > 0) & (x + bw < w) & (y + bh < h)
    small = inner & (area < max_px)
    small[0] = False   # label 0 is the mask itself
    return mask | small[labels]


THRESHOLD_METHODS = ("fixed", "triangle", "otsu")


@dataclass(frozen=True)
class ThresholdForeground(AbstractForeground):
    """Grey level above a threshold: a fixed one, or one chosen per frame from its histogram.

    On a dark background the histogram is one tall peak (the background) and a long, flat tail
    (the shaded hand). The triangle method (Zack et al. 1977: the level farthest below the line
    from the peak to the far end of the histogram) puts the threshold at the foot of the peak;
    Otsu's method instead splits the hand's own shading when its contours are dark (on the
    MuJoCo dev set it picks 87-92 and drops 4-10 % of the hand; the triangle picks 2).

    Attributes:
        method: ``"triangle"``, ``"otsu"`` or ``"fixed"``.
        threshold: the grey level of ``"fixed"`` (0..255); pixels strictly above are foreground.
        min_level: floor on a histogram-chosen level (grey levels), so a noise-free black
            background is not split by its last few grey levels of anti-aliasing.
        open_px: radius of the morphological opening that removes noise specks (px); 0 for none.
    """

    method: str = "triangle"
    threshold: float = 10.0
    min_level: float = 8.0
    open_px: int = 1

    def __post_init__(self):
        if self.method not in THRESHOLD_METHODS:
            raise InputError(f"ThresholdForeground.method: must be one of {', '.join(THRESHOLD_METHODS)}, "
                             f"got {self.method!r}")
        if not 0 <= self.threshold <= 255:
            raise InputError(f"ThresholdForeground.threshold: need a grey level in 0..255, got {self.threshold!r}")

    def level(self, image) -> float:
        """The threshold used for this frame (grey levels)."""
        if self.method == "fixed":
            return float(self.threshold)
        grey = as_grey(image)
        flag = cv2.THRESH_TRIANGLE if self.method == "triangle" else cv2.THRESH_OTSU
        level, _ = cv2.threshold(grey, 0, 255, cv2.THRESH_BINARY | flag)
        return max(float(level), self.min_level)

    def mask(self, image) -> np.ndarray:
        grey = as_grey(image)
        return _open(grey > self.level(grey), self.open_px)


@dataclass(frozen=True)
class BackgroundForeground(AbstractForeground):
    """Difference from a static background.

    Build it with :meth:`from_frames` (median and spread of the first frames, which should show
    no hand or a moving one) or :meth:`from_image` (a given background image). (For a hand that
    never leaves the view, learn the background while tracking:
    :class:`~jaxhand.score.SequenceBackground`.)

    Attributes:
        background: (H, W) float32 background grey levels.
        noise: (H, W) float32 per-pixel noise level (grey levels): a robust spread of the frames
            it was learned from (1.4826 MAD), floored at ``min_noise``.
        k: a pixel is foreground where ``|image - background| > k * noise``.
        open_px: radius of the opening (px).
    """

    background: Float[np.ndarray, "H W"] = field(repr=False)
    noise: Float[np.ndarray, "H W"] = field(repr=False)
    k: float = 4.0
    open_px: int = 1

    @staticmethod
    def from_frames(frames, *, k: float = 4.0, min_noise: float = 3.0, open_px: int = 1) -> BackgroundForeground:
        """The per-pixel median of ``frames`` (N, H, W[, 3]) as background, their MAD as noise."""
        stack = np.stack([as_grey(f, f"frames[{i}]") for i, f in enumerate(frames)]).astype(np.float32)
        if len(stack) == 0:
            raise InputError("frames: need at least one frame")
        med = np.median(stack, axis=0)
        mad = 1.4826 * np.median(np.abs(stack - med), axis=0)
        return BackgroundForeground(background=med, noise=np.maximum(mad, min_noise).astype(np.float32), k=k,
                                    open_px=open_px)

    def _differs(self, image) -> np.ndarray:
        """(H, W) uint8, 1 where ``image`` differs from the background by more than ``k`` noise levels."""
        grey = as_grey(image)
        if grey.shape != self.background.shape:
            raise InputError(f"image: expected shape {self.background.shape} (the background's), got {grey.shape}")
        return (cv2.absdiff(grey.astype(np.float32), self.background) > self.k * self.noise).view(np.uint8)

    @staticmethod
    def from_image(background, *, difference: float = 12.0, open_px: int = 1) -> BackgroundForeground:
        """A given background image; foreground where the grey difference exceeds ``difference``."""
        bg = as_grey(background, "background").astype(np.float32)
        return BackgroundForeground(background=bg, noise=np.full_like(bg, difference), k=1.0, open_px=open_px)

    def mask(self, image) -> np.ndarray:
        return _open(self._differs(image).view(bool), self.open_px)


# Generic skin chrominance in YCrCb (OpenCV's 8-bit scaling): a mean and covariance broad enough for
# the usual published box (Cr 133..173, Cb 77..127, Chai and Ngan 1999) at about 2 sigma.
_SKIN_MEAN = (153.0, 102.0)
_SKIN_COV = ((100.0, -30.0), (-30.0, 156.0))


@dataclass(frozen=True)
class SkinForeground(AbstractForeground):
    """Skin colour: a Gaussian over (Cr, Cb) in YCrCb, thresholded at a Mahalanobis distance.

    Attributes:
        mean: (Cr, Cb) of skin (8-bit YCrCb).
        cov: 2x2 covariance of (Cr, Cb).
        max_distance: pixels within this Mahalanobis distance of the mean are skin.
        min_luma: darker pixels (Y below this) are never skin: chrominance is noise there.
        open_px: radius of the opening (px).
        fill_px: holes of fewer pixels are filled (:func:`fill_holes`; 0: none).
    """

    mean: tuple[float, float] = _SKIN_MEAN
    cov: tuple[tuple[float, float], tuple[float, float]] = _SKIN_COV
    max_distance: float = 2.5
    min_luma: float = 30.0
    open_px: int = 1
    fill_px: int = 0

    def __post_init__(self):
        c = np.asarray(self.cov, float)
        if c.shape != (2, 2) or not np.allclose(c, c.T) or np.any(np.linalg.eigvalsh(c) <= 0):
            raise InputError(f"SkinForeground.cov: need a symmetric positive definite 2x2 matrix, got {self.cov!r}")

    @staticmethod
    def fit(image, mask, *, max_distance: float = 3.0, min_luma: float = 30.0, open_px: int = 1,
            fill_px: int = 0) -> SkinForeground:
        """Fit the Gaussian to the pixels of a BGR ``image`` where ``mask`` (H, W) is True.

        Raises:
            InputError: not a colour image, or fewer than 10 pixels selected.
        """
        a = np.asarray(image)
        if a.ndim != 3 or a.shape[2] != 3 or a.dtype != np.uint8:
            raise InputError(f"image: expected an (H, W, 3) uint8 BGR image, got {a.shape} {a.dtype}")
        m = np.asarray(mask, bool)
        if m.shape != a.shape[:2] or m.sum() < 10:
            raise InputError("mask: need an (H, W) mask with at least 10 pixels of skin")
        crcb = cv2.cvtColor(a, cv2.COLOR_BGR2YCrCb)[..., 1:][m].astype(float)
        cov = np.cov(crcb.T) + np.eye(2)  # + 1 grey level^2: quantisation, keeps it definite
        mean = crcb.mean(0)
        return SkinForeground(mean=(float(mean[0]), float(mean[1])),
                              cov=((float(cov[0, 0]), float(cov[0, 1])), (float(cov[1, 0]), float(cov[1, 1]))),
                              max_distance=max_distance, min_luma=min_luma, open_px=open_px, fill_px=fill_px)

    def mask(self, image) -> np.ndarray:
        a = np.asarray(image)
        if a.ndim != 3 or a.shape[2] != 3 or a.dtype != np.uint8:
            raise InputError(f"image: SkinForeground needs an (H, W, 3) uint8 BGR image, got {a.shape} {a.dtype}")
        ycc = cv2.cvtColor(a, cv2.COLOR_BGR2YCrCb).astype(np.float32)
        d = ycc[..., 1:] - np.asarray(self.mean, np.float32)
        icov = np.linalg.inv(np.asarray(self.cov, float)).astype(np.float32)
        m2 = icov[0, 0] * d[..., 0] ** 2 + 2 * icov[0, 1] * d[..., 0] * d[..., 1] + icov[1, 1] * d[..., 1] ** 2
        return fill_holes(_open((m2 <= self.max_distance**2) & (ycc[..., 0] >= self.min_luma), self.open_px),
                          self.fill_px)
