"""Landmark poses per frame, fitted up front: what ``jaxhand track --landmarks`` starts and
restarts from (and fuses into each frame's solve).

:func:`fit_landmark_poses` fits every frame of a :class:`~jaxhand.landmarks.LandmarkSequence`
in the tracker's model and first camera with :func:`~jaxhand.landmarks.fit_landmark_sequence`
(the model's own shape: no calibration), either with the whole-sequence solve (``"sequence"``)
or frame by frame only (``"frames"``: each frame from the previous, cheaper). The result, a
:class:`LandmarkPoses`, answers per video frame: its pose, or None where the file has no usable
landmarks there (fewer than :data:`MIN_POINTS` points, or a frame outside the file).
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from .._errors import InputError
from ..model import Model
from ._convention import POINT_NAMES
from ._io import LandmarkSequence
from ._pipeline import fit_landmark_sequence, projected_landmarks
from ._prior import LandmarkTerm, landmark_term

__all__ = ["LandmarkPoses", "fit_landmark_poses", "landmark_agreement", "LANDMARK_FITS", "MIN_POINTS",
           "ON_FINGERS_PX"]

#: Ways :func:`fit_landmark_poses` fits the frames.
LANDMARK_FITS = ("sequence", "frames")
#: A frame with fewer landmark points than this has no landmark pose (too few to fix 27 DOF).
MIN_POINTS = 11
#: Distance (px) within which a projected point counts as on its landmark (issue 13's rule).
ON_FINGERS_PX = 15.0


@dataclasses.dataclass(frozen=True)
class LandmarkPoses:
    """Landmarks and their fitted poses for the frames ``frames[0] ..`` (host-side NumPy).

    Attributes:
        frames: (T,) video frame numbers, consecutive.
        q: (T, n_q) fitted states (meaningful where ``usable``).
        usable: (T,) True where the frame has at least :data:`MIN_POINTS` landmarks.
        px: (T, 21, 2) observed pixels, NaN where missing; confidence: (T, 21).
        median_px: median distance (px) of the fitted model's landmark points to the observed.
        source: the landmark file's name; notes: what its loader skipped or chose.
        fit: how the poses were fitted (:data:`LANDMARK_FITS`); fit_s: seconds it took.
    """

    frames: np.ndarray
    q: np.ndarray
    usable: np.ndarray
    px: np.ndarray
    confidence: np.ndarray
    median_px: float
    source: str = ""
    notes: dict = dataclasses.field(default_factory=dict)
    fit: str = "sequence"
    fit_s: float = 0.0

    def _row(self, frame: int) -> int | None:
        t = int(frame) - int(self.frames[0]) if len(self.frames) else -1
        return t if 0 <= t < len(self.frames) and self.usable[t] else None

    def pose(self, frame: int) -> np.ndarray | None:
        """Frame ``frame``'s landmark pose (n_q,), or None where it has none."""
        t = self._row(frame)
        return None if t is None else self.q[t].copy()

    def first_pose(self, frame: int) -> tuple[int, np.ndarray]:
        """The pose of ``frame``, or of the first later frame that has one: (that frame, pose)."""
        later = np.flatnonzero(self.usable & (self.frames >= frame))
        if not len(later):
            raise InputError(f"landmarks {self.source}: no frame from {frame} on has {MIN_POINTS} or more landmarks "
                             "to start from: give --init")
        t = int(later[0])
        return int(self.frames[t]), self.q[t].copy()

    def landmarks(self, frame: int) -> np.ndarray | None:
        """Frame ``frame``'s observed (21, 2) pixels (NaN where missing), or None where it has no pose."""
        t = self._row(frame)
        return None if t is None else self.px[t]

    def term(self, frame: int, weight: float) -> LandmarkTerm:
        """Frame ``frame``'s landmarks as a solve term with weights ``weight * confidence``
        (all 0 on a frame without landmarks, so the term's shape never changes)."""
        t = self._row(frame)
        if t is None:
            return landmark_term(np.zeros((len(POINT_NAMES), 2)), 0.0)
        return landmark_term(self.px[t], weight * self.confidence[t])

    def missing(self, n: int) -> int:
        """How many of the video frames 0 .. n-1 have no landmark pose."""
        return sum(self._row(k) is None for k in range(n))


def fit_landmark_poses(model: Model, camera, seq: LandmarkSequence, *, fit: str = "sequence",
                       frames: int | None = None) -> LandmarkPoses:
    """Fit the landmark pose of every frame of ``seq`` (up to video frame ``frames`` - 1).

    Raises:
        InputError: an unknown ``fit``, landmarks of another image size or of the other hand
            than the model's, or no frame with enough landmarks.
    """
    if fit not in LANDMARK_FITS:
        raise InputError(f"landmarks.fit: expected one of {', '.join(LANDMARK_FITS)}, got {fit!r}")
    where = f"landmarks {seq.source}"
    if seq.image_size is not None and tuple(seq.image_size) != tuple(camera.size):
        raise InputError(f"{where}: landmarks of a {seq.image_size[0]}x{seq.image_size[1]} image, but camera 0 is "
                         f"{camera.size[0]}x{camera.size[1]}: give the landmarks of this video (or its camera)")
    hand = getattr(model, "handedness", "none")
    if seq.handedness in ("left", "right") and hand in ("left", "right") and seq.handedness != hand:
        raise InputError(f"{where}: the landmarks are of a {seq.handedness} hand but model {model.name!r} is a "
                         f"{hand} hand: track with its mirror image (e.g. hand27_{seq.handedness}, or "
                         "jaxhand models --mirror)")
    if frames is not None:
        seq = seq.slice(0, max(0, int(frames) - int(seq.frames[0])))
    usable = seq.valid.sum(-1) >= MIN_POINTS
    if not len(seq) or not usable.any():
        raise InputError(f"{where}: no frame has {MIN_POINTS} or more landmarks (of 21)")
    t0 = time.perf_counter()
    result = fit_landmark_sequence(model, camera, seq.to_landmarks(), shape=None, sequence=fit == "sequence")
    fit_s = time.perf_counter() - t0
    err = np.linalg.norm(projected_landmarks(model, camera, result.q) - seq.px, axis=-1)[usable]
    return LandmarkPoses(frames=np.asarray(seq.frames), q=np.asarray(result.q), usable=usable, px=seq.px,
                         confidence=seq.confidence, median_px=float(np.nanmedian(err)), source=seq.source,
                         notes=dict(seq.notes), fit=fit, fit_s=fit_s)


def landmark_agreement(model: Model, camera, poses: LandmarkPoses, frames, q, *,
                       radius_px: float = ON_FINGERS_PX) -> dict:
    """How states ``q`` (n, n_q) of video frames ``frames`` (n,) sit on the landmarks in ``camera``.

    Over the frames whose 21 landmarks are all given: the model's 21 landmark points
    (:func:`~jaxhand.landmarks.projected_landmarks`) against them. A frame is *on the fingers*
    when every one of its 21 points is within ``radius_px``; also the median distance and the
    share of points within ``radius_px``.
    """
    frames = np.asarray(frames, int)
    rows = frames - int(poses.frames[0])
    ok = (rows >= 0) & (rows < len(poses.frames))
    ok[ok] = np.all(np.isfinite(poses.px[rows[ok]]), axis=(-2, -1))
    out = {"radius_px": float(radius_px), "frames_compared": int(ok.sum())}
    if not ok.any():
        return out
    d = np.linalg.norm(projected_landmarks(model, camera, np.asarray(q)[ok]) - poses.px[rows[ok]], axis=-1)
    on = np.all(d <= radius_px, axis=-1)
    off = frames[ok][~on]
    out.update({"frames_on_fingers": int(on.sum()), "share_on_fingers": float(on.mean()),
                "median_px": float(np.median(d)), "share_points_within": float(np.mean(d <= radius_px)),
                "first_frame_off": int(off[0]) if len(off) else None})
    return out
