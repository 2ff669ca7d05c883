"""HypothesisConfig: the several starts per frame (:mod:`jaxhand.track._hypotheses`), a part of
:class:`~jaxhand.TrackConfig`."""

from __future__ import annotations

import dataclasses

from ._config_checks import count, finite_number, flag, need

__all__ = ["HypothesisConfig"]


@dataclasses.dataclass(frozen=True)
class HypothesisConfig:
    """Several starts per frame, solved in one vectorised call, the best kept (thesis ch. 7, "a
    bank of filters"; :mod:`jaxhand.track._hypotheses`). All off by default: one solve from the
    prediction, as the thesis does. The starts: the prediction, then ``flips``, ``folds``,
    ``last_solve``, ``rest``, the carried runners-up, the caller's proposals, after a lost frame
    ``recover`` and after a frame of low confidence the weakest finger bent (``finger_level``).

    Attributes:
        flips: static. Starts from the prediction with one of its most poorly observed joints
            (smallest image-Jacobian column at the prediction) pushed by +/- ``flip_deg``, in
            pairs, worst joint first.
        flip_deg: traced, deg. How far a flip start pushes its joint.
        folds: static. Starts with one hinge reflected across its fold (the one-view depth ambiguity).
        last_solve: static. Also start from the last frame's solve.
        rest: static. Also start from the model's default joint angles (the predicted base).
        rest_fingers: host. False: the rest start rests only the digits that are not planar
            fingers (the thumb) and keeps the fingers at the prediction.
        rest_below: host, in [0, 1]. ...only after a frame whose confidence is below this (1: after
            every frame). A start far from the motion can win by a hair where the image cannot
            tell two branches apart (a finger flexing or hyperextending towards the camera).
        max_step_deg: host, deg. After a frame whose confidence reached ``step_trust``, a candidate
            that moves some joint (not the base) more than this from the last estimate cannot win,
            unless it is the prediction's (0: no limit). A hand's joints move some 25 deg per frame
            at 30 frames/s at most; a start far from the motion that wins by a hair with a 60-deg
            jump (a curling finger sent into hyperextension) is a branch change, not motion.
        step_trust: host, in [0, 1]. The confidence a frame needs for ``max_step_deg`` and
            ``prediction_margin`` to hold on the next.
        prediction_margin: host, >= 0. After a frame whose confidence reached ``step_trust``, a
            candidate other than the prediction's wins only where its merit beats the prediction's
            by more than this share (0: the best merit wins). Where the image cannot tell poses
            apart (a thumb turning in depth), a start that wins by noise moves the estimate along
            what the image does not see.
        carry: static. Runners-up carried to the next frame as extra starts (at most this many).
        carry_margin: host, in [0, 1]. A runner-up is carried when its merit is at least this
            share of the winner's (the score could not decide between them).
        carry_min_deg: host, deg. ...and it differs from the winner by more than this in some joint.
        recover: static. Starts around the last good pose on each frame after a lost one, until
            a frame is not lost (0: none; the prediction then is that pose alone).
        recover_deg: host, deg. Sigma of the recovery starts' joint angles around the last good pose.
        recover_mm: host, mm. The same for length entries (base translation, prismatic joints).
        seed: host. Seed of the recovery starts (frame k's are drawn from ``(seed, k)``).
        coarse_steps: static. Where the merit alone chooses (no image score or support judge), every start
            runs this many iterations of the gated pass and the best one's start alone is solved (0: all are).
        finger_level: host, in [0, 1]. After a frame whose confidence (leaving out the
            unexplained foreground, which names no finger) is below this, the next
            frame also starts from the prediction with the finger the image supports least (the
            support rule's per-finger score) bent by each of ``finger_deg`` (0: off), if it is a
            planar finger (not a thumb: :func:`~jaxhand.track._hypotheses.flexion_hinges`). A
            finger that lost its image is bent back towards it, the others keep their motion.
        finger_deg: host, deg. The bends of those starts, each added to every flexion hinge of
            the finger (axis parallel to its last hinge's) towards the wider side of the hinge's
            range (a hand's flexion); negative: the other way.
        verify_below: host, in [0, 1]. After a frame's estimate whose fingers' image support (the
            support rule's confidence without its unexplained-foreground part, which names no
            finger) is below this, the finger whose links the image supports
            least, where it is a planar finger (not a thumb), is searched again: from the estimate
            with that finger bent by each of ``finger_deg``, with each of its hinges reflected
            across its fold, and with its joints at the last trusted pose, each start with
            features searched around itself and a solve without the temporal prior. The best by
            finger support replaces the estimate where it wins by ``verify_margin``
            (:mod:`jaxhand.track._verify`; 0: off). All other starts share features searched
            around the prediction, so a finger folded the wrong way keeps the features of that fold.
        verify_margin: host, in [0, 1]. How much more support the weakest finger must get (and
            the most any other finger may lose) for a verified start to replace the estimate.
        review_jump_deg: host, deg. After a frame won by a start other than the prediction whose
            estimate moved some joint angle more than this from the prediction (a jump to another
            branch), the frames before it are tracked again backward from it, and those the
            backward track explains as well replace the forward ones (:mod:`jaxhand.track._review`;
            0: off). Results then leave the tracker ``review_frames`` frames late, and that many
            frames' images are held.
        review_trust: host, in [0, 1]. The confidence a jump's frame needs to be reviewed: a jump
            in doubt is more often the mistake than the frames before it.
        review_frames: host. How many frames a review may go back (and the results' delay).
        review_agree_deg: host, deg. The backward track meets the forward one where no joint
            angle differs by more than this; a review that does not meet them changes nothing.
        review_margin: host, in [0, 1]. A backward estimate replaces the forward one where its
            confidence is at least the forward one's less this.
        fold_passage_deg: host, deg. With one camera, a hinge whose estimate came towards its fold
            (the angle at which its link lies across the viewing ray) at ``fold_passage_speed_deg``
            per frame or faster, to within this of it, and turns back there is tried reflected across
            the fold, with features searched around that pose and a solve without the temporal
            prior; the reflected pose is kept unless some finger's image support drops by more than
            ``verify_margin`` (:mod:`jaxhand.track._passage`; 0: off). The view cannot tell the two
            sides of a fold apart; a finger opening from a fist passes through it, a lagging
            estimate turns back.
        fold_passage_speed_deg: host, deg per frame. How fast the hinge must have come towards its
            fold over the three frames before.
    """

    flips: int = 0
    flip_deg: float = 25.0
    folds: int = 0
    last_solve: bool = False
    rest: bool = False
    rest_fingers: bool = True
    rest_below: float = 1.0
    max_step_deg: float = 0.0
    step_trust: float = 0.5
    prediction_margin: float = 0.0
    carry: int = 0
    carry_margin: float = 0.9
    carry_min_deg: float = 5.0
    recover: int = 0
    recover_deg: float = 15.0
    recover_mm: float = 10.0
    seed: int = 0
    coarse_steps: int = 0
    finger_level: float = 0.0
    finger_deg: tuple[float, ...] = (20.0, 40.0, -20.0)
    verify_below: float = 0.0
    verify_margin: float = 0.05
    review_jump_deg: float = 0.0
    review_trust: float = 0.8
    review_frames: int = 30
    review_agree_deg: float = 5.0
    review_margin: float = 0.0
    fold_passage_deg: float = 0.0
    fold_passage_speed_deg: float = 1.5

    def __post_init__(self):
        for name in ("flips", "folds", "carry", "recover", "seed", "coarse_steps", "review_frames"):
            count(getattr(self, name), f"hypotheses.{name}")
        for name in ("last_solve", "rest", "rest_fingers"):
            flag(getattr(self, name), f"hypotheses.{name}")
        for name in ("flip_deg", "carry_min_deg", "recover_deg", "recover_mm", "max_step_deg",
                     "prediction_margin", "review_jump_deg", "review_agree_deg", "fold_passage_deg",
                     "fold_passage_speed_deg"):
            value = getattr(self, name)
            need(finite_number(value) and value >= 0, f"hypotheses.{name}",
                 f"expected a finite number >= 0, got {value!r}")
        for name in ("carry_margin", "finger_level", "rest_below", "step_trust", "verify_below", "verify_margin",
                     "review_margin", "review_trust"):
            value = getattr(self, name)
            need(finite_number(value) and 0.0 <= value <= 1.0,
                 f"hypotheses.{name}", f"must lie in [0, 1], got {value!r}")
        need(not self.review_jump_deg or self.review_frames > 0, "hypotheses.review_frames",
             "a review (review_jump_deg > 0) needs at least one frame to go back: set review_frames >= 1")
        need(isinstance(self.finger_deg, tuple) and len(self.finger_deg) > 0
             and all(finite_number(d) for d in self.finger_deg),
             "hypotheses.finger_deg", f"expected a non-empty list of finite numbers, got {self.finger_deg!r}")

    @property
    def enabled(self) -> bool:
        """Whether any start besides the prediction is configured (static)."""
        return bool(self.flips or self.folds or self.last_solve or self.rest or self.carry or self.recover
                    or self.finger_level)
