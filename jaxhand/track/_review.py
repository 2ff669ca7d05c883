"""The backward review: after a jump, the frames before it tracked again backward (issue 13 item 7).

One view leaves a finger's depth ambiguous near the angle at which its link lies across the
viewing ray (its fold): both sides show the link at nearly the same place. A solve can follow
the wrong side for several frames while the image fits both alike, until a start on the other
side wins (a jump; :attr:`~jaxhand.track.HypothesisConfig.review_jump_deg`, in a frame of
confidence ``review_trust`` at least). The frames before the jump then hold the wrong side, and
only the motion tells: followed backward from the jump's estimate, it stays on the side the
jump found.

So the review holds the last ``review_frames`` frames. After a jump it tracks them again from
the jump's estimate, newest first, with the tracker's own step (the front end learns nothing
from them). Where the backward track meets the forward one (no joint angle more than
``review_agree_deg`` apart), the frames in between take the backward estimate wherever its
confidence is at least the forward one's less ``review_margin``. A backward track that is lost
or never meets the forward one changes nothing: the jump itself may be the mistake. Frames
leave the review, final, ``review_frames`` frames late (:meth:`Review.push`, :meth:`Review.flush`).
"""

from __future__ import annotations

import dataclasses
import time
from collections import deque
from collections.abc import Callable

import numpy as np

from ._hypotheses import joint_angles
from ._state import StepReport, TrackState

__all__ = ["Review", "is_jump"]

#: The label of a frame whose estimate the review replaced (:attr:`StepReport.hypothesis`).
REVIEWED = "review"


def is_jump(report: StepReport, joints: np.ndarray, jump_rad: float, trust: float = 0.0) -> bool:
    """Whether ``report``'s frame was won by a start other than the prediction and moved one of
    ``joints`` (a mask) more than ``jump_rad`` from the prediction, with a confidence of at least
    ``trust`` and not lost."""
    if report.hypothesis in ("prediction", REVIEWED) or report.lost or jump_rad <= 0 or report.confidence < trust:
        return False
    moved = np.abs(np.asarray(report.q_filtered) - np.asarray(report.q_pred))[joints]
    return bool(moved.size and moved.max() > jump_rad)


class Review:
    """Holds a tracker's last frames and reviews them backward after a jump (module docstring).

    Args:
        tracker: the :class:`~jaxhand.track.Tracker` whose frames are pushed (its
            :class:`~jaxhand.track.HypothesisConfig` gives the review's settings).
        step: ``step(state, images, report) -> (state, report)`` tracks one held frame again
            (default: the tracker's own step at that frame's index and time, learning nothing);
            a caller that adds terms to each frame passes a step that adds them too.

    Attributes:
        reviews: how many backward tracks ran; ``met``: how many of them met the forward one.
        revised: how many frames took a backward estimate.
        seconds: the time the backward tracks took.
    """

    def __init__(self, tracker, step: Callable | None = None):
        hyp = tracker.config.hypotheses
        self.tracker = tracker
        self.jump_rad = float(np.radians(hyp.review_jump_deg))
        self.frames = hyp.review_frames if self.jump_rad > 0 else 0
        self.agree_rad = float(np.radians(hyp.review_agree_deg))
        self.margin, self.trust = hyp.review_margin, hyp.review_trust
        self._joints = joint_angles(tracker.model)
        self._step = step or (lambda state, images, report: tracker.step(state, images, report.frame,
                                                                         report.time_s, learn=False))
        self._held: deque[tuple[list, StepReport]] = deque()
        self.reviews = self.met = self.revised = 0
        self.seconds = 0.0

    def push(self, state: TrackState, images: list, report: StepReport) -> list[tuple[list, StepReport]]:
        """Take the frame just tracked (``state`` after it); return the frames that leave the
        review, final, oldest first, as (images, report): at once when the review is off."""
        if not self.frames:
            return [(images, report)]
        if self._held and is_jump(report, self._joints, self.jump_rad, self.trust):
            self._review(state, report)
        self._held.append((images, report))
        return [self._held.popleft() for _ in range(len(self._held) - self.frames)]

    def flush(self) -> list[tuple[list, StepReport]]:
        """The frames still held, oldest first (at the end of a run, or when it is stopped)."""
        out = list(self._held)
        self._held.clear()
        return out

    def _review(self, state: TrackState, report: StepReport) -> None:
        t0 = time.perf_counter()
        back = dataclasses.replace(self.tracker.init(report.q_filtered, state.frontend_state),
                                   score_reference=state.score_reference)
        found, met = [], False
        for i in range(len(self._held) - 1, -1, -1):
            images, forward = self._held[i]
            back, again = self._step(back, images, forward)
            if again.lost:
                break
            apart = np.abs(np.asarray(again.q_filtered) - np.asarray(forward.q_filtered))[self._joints]
            if apart.max(initial=0.0) <= self.agree_rad:
                met = True
                break
            found.append((i, again))
        self.reviews += 1
        if met:
            self.met += 1
            for i, again in found:
                images, forward = self._held[i]
                if again.confidence >= forward.confidence - self.margin:
                    self._held[i] = (images, dataclasses.replace(again, hypothesis=REVIEWED))
                    self.revised += 1
        self.seconds += time.perf_counter() - t0

    def summary(self) -> dict:
        """What ``summary.json`` reports under ``"review"``."""
        return {"jump_deg": self.tracker.config.hypotheses.review_jump_deg, "frames": self.frames,
                "reviews": self.reviews, "met": self.met, "frames_revised": self.revised, "s": round(self.seconds, 3)}
