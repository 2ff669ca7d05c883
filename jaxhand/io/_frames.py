"""Frame sources: a video file or a folder of images, read one frame at a time.

A frame that cannot be decoded (a corrupt or vanished image file) is yielded with
``image=None`` and an ``error`` message, so the caller can report and skip it without losing
its place in the sequence.
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np

from .._errors import InputError
from ..camera import scaled_size

__all__ = ["Frame", "FrameSource", "open_frames", "natural_key", "IMAGE_SUFFIXES"]

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm", ".ppm")


@dataclasses.dataclass(frozen=True)
class Frame:
    """One frame: its index, time (s), the uint8 image (grey, or BGR from a source opened with
    ``colour``; None if unreadable) and why not."""

    index: int
    time_s: float
    image: np.ndarray | None
    error: str | None = None


def natural_key(name: str) -> tuple:
    """Sort key that orders digit runs by value, so ``frame_2`` comes before ``frame_10``."""
    return tuple((0, int(part), part) if part.isdigit() else (1, 0, part.lower())
                 for part in re.split(r"(\d+)", name) if part)


def _uint8(image: np.ndarray, colour: bool) -> np.ndarray:
    """A decoded frame as uint8: grey, or BGR where ``colour`` and the frame has colour channels."""
    if image.ndim == 3:
        if colour and image.shape[2] in (3, 4):
            image = image[..., :3] if image.shape[2] == 4 else image
        else:
            code = cv2.COLOR_BGRA2GRAY if image.shape[2] == 4 else cv2.COLOR_BGR2GRAY
            image = cv2.cvtColor(image, code)
    if image.dtype != np.uint8:
        image = cv2.normalize(image, None, 0, 255, cv2.NORM_MINMAX).astype(np.uint8)
    return np.ascontiguousarray(image)


class FrameSource:
    """Frames of a video file or an image folder (in natural order of the file names, so
    ``frame_2`` comes before ``frame_10``), as grey uint8 images, or BGR ones with ``colour``.

    Args:
        path: a video file (anything OpenCV's FFmpeg backend reads) or a folder of images.
        fps: frames per second for image folders, and for videos whose file lacks a frame rate.
        size: the (width, height) in pixels every frame must have (the camera's), or None. The
            first frame of another size is an error (the camera does not fit the input); a later
            one is yielded as unreadable, with a message naming the file and both sizes.
        scale: every frame is resized by this factor (area averaging) before that check, for
            tracking at a lower resolution (with :func:`jaxhand.camera.scale_camera` of the camera).
        colour: keep colour frames in colour (BGR, as OpenCV decodes them), for a foreground
            model that reads colour (skin); grey frames stay grey.

    Raises:
        InputError: the path does not exist, the folder holds no images, the video has no
            frames or cannot be opened, or the first frame's size is not ``size``.
    """

    def __init__(self, path: str | Path, fps: float = 25.0, size: tuple[int, int] | None = None,
                 scale: float = 1.0, colour: bool = False):
        self.path = Path(path)
        self.colour = bool(colour)
        if not fps > 0:
            raise InputError(f"fps must be > 0, got {fps}")
        if not (np.isfinite(scale) and 0 < scale <= 1):
            raise InputError(f"scale: expected a factor in (0, 1] (e.g. 0.5 for half size), got {scale!r}")
        self.scale = float(scale)
        self.fps = float(fps)
        self.size = None if size is None else (int(size[0]), int(size[1]))
        if not self.path.exists():
            raise InputError(f"{self.path}: no such video file or image folder")
        if self.path.is_dir():
            self.files = sorted((p for p in self.path.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES),
                                key=lambda p: natural_key(p.name))
            if not self.files:
                raise InputError(f"{self.path}: the folder holds no images ({', '.join(IMAGE_SUFFIXES)})")
            self._count = len(self.files)
        else:
            self.files = None
            cap = cv2.VideoCapture(str(self.path))
            if not cap.isOpened():
                raise InputError(f"{self.path}: cannot open as a video")
            count = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
            rate = cap.get(cv2.CAP_PROP_FPS)
            ok, _ = cap.read()
            cap.release()
            if not ok:
                raise InputError(f"{self.path}: the video has no frames")
            self._count = max(count, 1)
            if rate and rate > 0:
                self.fps = float(rate)

    def __len__(self) -> int:
        return self._count

    def spread(self, count: int, limit: int | None = None) -> np.ndarray:
        """(k, H, W) up to ``count`` readable frames spread evenly over the first ``limit`` (all:
        None), frame 0 first: what a background learned from the whole sequence reads."""
        n = len(self) if limit is None else min(limit, len(self))
        wanted = set(np.linspace(0, n - 1, min(count, n)).round().astype(int).tolist())
        picked = []
        for frame in self:
            if frame.index >= n:
                break
            if frame.index in wanted and frame.image is not None:
                picked.append(frame.image)
        if not picked:
            raise InputError(f"{self.path}: no readable frame to learn a background from")
        return np.stack(picked)

    def _frame(self, i: int, name: str, image: np.ndarray) -> Frame:
        """The frame (resized by :attr:`scale`), or an unreadable one when its size is not
        :attr:`size` (an error on frame 0)."""
        if self.scale != 1.0:
            h, w = image.shape[:2]
            image = cv2.resize(image, scaled_size((w, h), self.scale), interpolation=cv2.INTER_AREA)
        h, w = image.shape[:2]
        if self.size is None or (w, h) == self.size:
            return Frame(i, i / self.fps, _uint8(image, self.colour))
        msg = (f"{name}: frame {i} is {w}x{h} px but the camera's image size is {self.size[0]}x{self.size[1]} "
               f"(width x height)")
        if i == 0:
            raise InputError(f"{msg}: give the camera file that belongs to this input")
        return Frame(i, i / self.fps, None, msg)

    def __iter__(self) -> Iterator[Frame]:
        if self.files is not None:
            for i, f in enumerate(self.files):
                image = cv2.imread(str(f), cv2.IMREAD_UNCHANGED)
                if image is None or image.size == 0:
                    yield Frame(i, i / self.fps, None, f"{f.name}: cannot read image (missing or corrupt)")
                else:
                    yield self._frame(i, str(f), image)
            return
        cap = cv2.VideoCapture(str(self.path))
        try:
            i = 0
            while True:
                ok, image = cap.read()
                if not ok:
                    break
                yield self._frame(i, f"{self.path} frame {i}", image)
                i += 1
        finally:
            cap.release()


def open_frames(paths, fps: float = 25.0, sizes=None, scale: float = 1.0, colour: bool = False) -> list[FrameSource]:
    """One :class:`FrameSource` per camera; all must have the same number of frames.

    ``sizes``: one (width, height) per path that its frames must have (the cameras', after
    ``scale``), or None. ``scale``: resize every frame by this factor; ``colour``: keep colour
    frames in colour (see :class:`FrameSource`).
    """
    paths = [paths] if isinstance(paths, (str, Path)) else list(paths)
    sizes = [None] * len(paths) if sizes is None else list(sizes)
    if len(sizes) != len(paths):
        raise InputError(f"{len(paths)} input(s) but {len(sizes)} image size(s): give one per camera")
    sources = [FrameSource(p, fps, size, scale, colour) for p, size in zip(paths, sizes)]
    if not sources:
        raise InputError("no input given: pass a video file or an image folder per camera")
    counts = {len(s) for s in sources}
    if len(counts) > 1:
        raise InputError(f"the inputs have different frame counts: {[len(s) for s in sources]}")
    return sources
