"""Overlay videos written frame by frame with OpenCV (MPEG-4 Part 2 in .mp4, or MJPEG in .avi)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from .._errors import InputError

__all__ = ["VideoWriter"]


class VideoWriter:
    """Appends BGR uint8 frames to a video; the codec follows the suffix (.mp4: mp4v, .avi: MJPG)."""

    def __init__(self, path: str | Path, fps: float, size: tuple[int, int]):
        self.path = Path(path)
        codec = {".mp4": "mp4v", ".avi": "MJPG"}.get(self.path.suffix)
        if codec is None:
            raise InputError(f"{self.path}: video suffix must be .mp4 or .avi")
        self.size = size
        self._writer = cv2.VideoWriter(str(self.path), cv2.VideoWriter_fourcc(*codec), float(fps), size)
        if not self._writer.isOpened():
            raise InputError(f"{self.path}: OpenCV cannot open a {codec} video writer")

    def write(self, frame: np.ndarray) -> None:
        if frame.shape[1::-1] != self.size:
            frame = cv2.resize(frame, self.size)
        self._writer.write(frame)

    def close(self) -> None:
        self._writer.release()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
