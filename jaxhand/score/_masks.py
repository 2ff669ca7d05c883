"""Foreground masks given from outside (a segmentation network, a matting tool, a rendering's
truth), one per frame, matched to the frames by their content: the tracker reads a frame's
foreground several times, and a review tracks frames again out of order, so no frame counter
would do."""

from __future__ import annotations

import hashlib
from collections.abc import Iterable, Sequence
from pathlib import Path

import cv2
import numpy as np

from .._errors import InputError
from ._foreground import AbstractForeground

__all__ = ["MaskForeground", "frame_digest"]


def frame_digest(image) -> bytes:
    """A short digest of a frame's pixels and shape: the key by which a frame is known again."""
    a = np.ascontiguousarray(image)
    return hashlib.blake2b(a.tobytes() + repr(a.shape).encode(), digest_size=16).digest()


class MaskForeground(AbstractForeground):
    """One given mask per frame (an array, or the path of an image whose nonzero pixels are the
    hand), looked up by the frame's content. A mask of another size than its frame with the same
    aspect ratio is resized to it (the frames tracked at ``--scale``); images are read when first
    asked for, the last one kept."""

    def __init__(self, frames: Iterable[np.ndarray], masks: Sequence[np.ndarray | str | Path]):
        """``frames``: the frames in order, as the tracker will see them; ``masks``: one per frame.

        Raises:
            InputError: fewer or more masks than frames.
        """
        self._index = {}
        count = 0
        for k, frame in enumerate(frames):
            if frame is not None:   # an unreadable frame keeps its place
                self._index.setdefault(frame_digest(frame), k)
            count = k + 1
        self.masks = list(masks)
        if len(self.masks) != count:
            raise InputError(f"masks: {len(self.masks)} mask(s) for {count} frame(s): give one mask per frame")
        self._last: tuple[int, np.ndarray] | None = None

    def mask(self, image) -> np.ndarray:
        k = self._index.get(frame_digest(image))
        if k is None:
            raise InputError(f"masks: this frame ({np.shape(image)}) is none of the {len(self.masks)} frames the "
                             "masks were given for")
        if self._last is None or self._last[0] != k:
            self._last = (k, self._read(k, np.shape(image)[:2]))
        return self._last[1]

    def _read(self, k: int, shape: tuple[int, int]) -> np.ndarray:
        given = self.masks[k]
        name = f"mask {k}" if isinstance(given, np.ndarray) else str(given)
        m = given if isinstance(given, np.ndarray) else cv2.imread(str(given), cv2.IMREAD_GRAYSCALE)
        if m is None or m.ndim != 2:
            raise InputError(f"{name}: cannot read as a one-channel mask image")
        m = m > 0
        if m.shape != shape:
            (h, w), (mh, mw) = shape, m.shape
            if abs(mw / mh - w / h) > 0.01 * w / h:
                raise InputError(f"{name}: a {mw}x{mh} mask for a {w}x{h} frame (width x height): give masks of "
                                 "the frames' size")
            m = cv2.resize(m.astype(np.float32), (w, h), interpolation=cv2.INTER_AREA) >= 0.5
        return m
