"""Landmarks in a tracking run (``jaxhand track --landmarks``): the first pose, a restart
whenever the tracker is lost, and (``landmarks.fuse_weight`` > 0) every frame's landmarks as a
solve term beside the edges.

The landmark poses of every frame are fitted before the first frame
(:func:`~jaxhand.landmarks.fit_landmark_poses`, in the first camera), so a frame costs only
what the tracker costs, plus the solve of a restart. Rules:

- the first pose is the landmark pose of the first tracked frame (or of the first later frame
  with landmarks); an initial pose given as well (``--init``) wins, and the landmarks then
  only restart and fuse;
- a frame the tracker reports lost (or, with ``landmarks.restart_px``, whose reported pose's
  landmark points lie a median of more than that from the frame's landmarks) is solved again
  from its landmark pose, with the filter at rest there and the front end's state (templates,
  widths) started afresh; the restart's report is the frame's, even when it is off too; a frame
  without landmarks is tracked on without a restart.
"""

from __future__ import annotations

import dataclasses
import warnings

import cv2
import numpy as np

from .._errors import JaxhandWarning
from ..landmarks import LandmarkPoses, LandmarkSequence, fit_landmark_poses, landmark_agreement, projected_landmarks
from ..model import Model
from ._config import LandmarkConfig
from ._state import StepReport, TrackState
from ._tracker import Tracker

__all__ = ["LandmarkRun"]


class LandmarkRun:
    """The landmark side of one run: its poses, settings and restart count.

    Args:
        poses: the fitted :class:`~jaxhand.landmarks.LandmarkPoses`, or a
            :class:`~jaxhand.landmarks.LandmarkSequence` to fit here in ``camera``.
        n_frames: frames the run covers (a file covering fewer is warned about).
    """

    def __init__(self, model: Model, camera, poses: LandmarkPoses | LandmarkSequence, config: LandmarkConfig,
                 n_frames: int):
        if isinstance(poses, LandmarkSequence):
            poses = fit_landmark_poses(model, camera, poses, fit=config.fit, frames=n_frames)
        self.model, self.camera, self.poses, self.config = model, camera, poses, config
        self.restart_frames: list[int] = []
        self.n_frames = n_frames
        missing = poses.missing(n_frames)
        if missing:
            warnings.warn(f"landmarks {poses.source}: {missing} of the {n_frames} frame(s) have no landmark pose "
                          f"(the file covers frames {int(poses.frames[0])}-{int(poses.frames[-1])}): they are "
                          "tracked without restarts or landmark terms", JaxhandWarning, stacklevel=3)

    def first_pose(self, frame: int = 0) -> np.ndarray:
        """The landmark pose to start from at ``frame`` (see the module docstring)."""
        return self.poses.first_pose(frame)[1]

    def _extra(self, frame: int) -> tuple:
        weight = self.config.fuse_weight
        return (self.poses.term(frame, weight),) if weight else ()

    def _proposals(self, frame: int, proposals) -> np.ndarray | None:
        """The caller's starts of ``frame`` and, with ``propose``, the frame's landmark pose."""
        q = self.poses.pose(frame) if self.config.propose else None
        if q is None:
            return proposals
        q = np.clip(q, np.asarray(self.model.q_lower), np.asarray(self.model.q_upper))[None]
        return q if proposals is None else np.concatenate([np.asarray(proposals, float).reshape(-1, q.shape[1]), q])

    def step(self, tracker: Tracker, state: TrackState, images, frame: int, time_s: float, proposals=None
             ) -> tuple[TrackState, StepReport, bool]:
        """One frame with the landmark term (and the landmark pose among its starts), restarted
        from the landmark pose when lost: (state, report, whether it restarted). A restart's
        timings include the lost try."""
        terms = self._extra(frame)
        state, rep = tracker.step(state, images, frame, time_s, self._proposals(frame, proposals), terms)
        q = self.poses.pose(frame) if self.config.restart else None
        if q is None or not (rep.lost or self._off(frame, rep.q_filtered)):
            return state, rep, False
        q = np.clip(q, np.asarray(self.model.q_lower), np.asarray(self.model.q_upper))
        lost_try = rep.timings_s
        state, rep = tracker.step(tracker.init(q), images, frame, time_s, proposals, terms)
        timings = {k: v + lost_try.get(k, 0.0) for k, v in rep.timings_s.items()}
        self.restart_frames.append(int(frame))
        return state, dataclasses.replace(rep, timings_s=timings), True

    def review_step(self, tracker: Tracker):
        """The step of a :class:`~jaxhand.track.Review`: a held frame tracked again with its
        landmark term and pose among its starts, without restarts, the front end learning nothing."""
        def step(state: TrackState, images, report: StepReport) -> tuple[TrackState, StepReport]:
            return tracker.step(state, images, report.frame, report.time_s, self._proposals(report.frame, None),
                                self._extra(report.frame), learn=False)
        return step

    def _off(self, frame: int, q) -> bool:
        """Whether ``q`` sits more than ``restart_px`` (median) off frame ``frame``'s landmarks."""
        if not self.config.restart_px:
            return False
        d = np.linalg.norm(projected_landmarks(self.model, self.camera, q)[0] - self.poses.landmarks(frame), axis=-1)
        return bool(np.nanmedian(d) > self.config.restart_px)

    def draw(self, tile: np.ndarray, frame: int) -> None:
        """Mark frame ``frame``'s landmarks on the overlay tile of the first camera (yellow dots)."""
        px = self.poses.landmarks(frame)
        for x, y in ([] if px is None else px[np.all(np.isfinite(px), -1)]):
            cv2.circle(tile, (int(round(x)), int(round(y))), 3, (0, 255, 255), -1, cv2.LINE_AA)

    def summary(self, frames: np.ndarray, q: np.ndarray) -> dict:
        """What ``summary.json`` reports under ``"landmarks"``: the file, the fit, the restarts,
        and how the reported poses agree with the landmarks (:func:`~jaxhand.landmarks.landmark_agreement`)."""
        p = self.poses
        return {"file": p.source, "fit": p.fit, "fit_s": p.fit_s, "fit_median_px": p.median_px,
                "fuse_weight": self.config.fuse_weight, "restart": self.config.restart,
                "restart_px": self.config.restart_px,
                "restarts": len(self.restart_frames), "restart_frames": self.restart_frames,
                "frames_without_landmarks": p.missing(self.n_frames), "notes": p.notes,
                "agreement": landmark_agreement(self.model, self.camera, p, frames, q)}
