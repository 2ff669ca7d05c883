"""The backward review after a jump (jaxhand.track.Review, hypotheses.review_*)."""

import json

import cv2
import numpy as np
import pytest
from helpers import blank_frames, oracle, stopping_oracle

import jaxhand as jh
from jaxhand import InputError
from jaxhand.filter import ghk_init
from jaxhand.io import FrameSource, read_angles_csv
from jaxhand.render import make_preset
from jaxhand.track import (
    FrontEndDiagnostics,
    HypothesisConfig,
    Review,
    StepReport,
    TrackConfig,
    TrackState,
    track_sequence,
)

SIZE = (160, 120)


def _report(frame, q, confidence=0.9, hypothesis="prediction", q_pred=None, lost=False) -> StepReport:
    q = np.radians(np.asarray(q, float))
    return StepReport(frame=frame, time_s=frame / 30, q_pred=q if q_pred is None else np.radians(q_pred),
                      q_solved=q, q_filtered=q, cost=0.0, rms_px=0.0, iterations=1, status="ok", valid_share=1.0,
                      confidence=confidence, lost=lost, timings_s={}, diagnostics=FrontEndDiagnostics(),
                      hypothesis=hypothesis)


class _Scripted:
    """A stand-in tracker: its backward steps return the scripted (joint angle deg, confidence, lost)
    of each frame, and record which frames they were asked for."""

    def __init__(self, backward: dict, **review):
        self.config = TrackConfig(hypotheses=HypothesisConfig(review_jump_deg=15.0, **review))
        self.model = jh.get_model("index")
        self.backward, self.asked = backward, []

    def init(self, q0, frontend_state=None):
        return TrackState(ghk=ghk_init(np.asarray(q0)), frontend_state=frontend_state, q_last=np.asarray(q0))

    def step(self, state, images, frame, time_s, learn=True):
        assert learn is False   # the front end learns nothing from a frame tracked again
        self.asked.append(frame)
        angle, confidence, lost = self.backward[frame]
        return state, _report(frame, [angle, 0.0, 0.0], confidence, lost=lost)


def _run(tracker, forward) -> tuple[Review, list[StepReport], list[list[StepReport]]]:
    review = Review(tracker)
    out, returned = [], []
    for rep in forward:
        state = TrackState(ghk=ghk_init(rep.q_filtered), frontend_state="templates", q_last=rep.q_filtered)
        left = review.push(state, ["image"], rep)
        returned.append([r for _, r in left])
        out += [r for _, r in left]
    return review, out + [r for _, r in review.flush()], returned


# frames 0-1 right, 2-4 on the wrong side of a fold (40 deg against ~10), 5 a jump back to 8 deg
FORWARD = [_report(0, [20, 0, 0]), _report(1, [15, 0, 0]), _report(2, [38, 0, 0], 0.85),
           _report(3, [40, 0, 0], 0.85),
           _report(4, [42, 0, 0], 0.85), _report(5, [8, 0, 0], 0.9, "rest", q_pred=[44, 0, 0])]


def test_review_replaces_the_frames_before_a_jump_where_it_meets_the_forward_track():
    tracker = _Scripted({4: (9.0, 0.95, False), 3: (11.0, 0.95, False), 2: (13.0, 0.5, False),
                         1: (17.0, 0.9, False), 0: (20.0, 0.9, False)})
    review, final, _ = _run(tracker, FORWARD)
    assert tracker.asked == [4, 3, 2, 1]          # newest first, stopping where the tracks meet (2 deg apart)
    assert [r.frame for r in final] == [0, 1, 2, 3, 4, 5]
    angles = [round(float(np.degrees(r.q_filtered[0])), 6) for r in final]
    assert angles == [20.0, 15.0, 38.0, 11.0, 9.0, 8.0]   # frame 2's backward confidence is lower: kept
    assert [r.hypothesis for r in final] == ["prediction"] * 3 + ["review"] * 2 + ["rest"]
    assert (review.reviews, review.met, review.revised) == (1, 1, 2)
    assert review.summary()["frames_revised"] == 2 and review.summary()["jump_deg"] == 15.0


def test_review_changes_nothing_when_the_tracks_do_not_meet_or_the_backward_one_is_lost():
    apart = {k: (a, 0.99, False) for k, a in {4: 9.0, 3: 11.0, 2: 13.0, 1: 30.0, 0: 35.0}.items()}
    for backward, asked in ((apart, [4, 3, 2, 1, 0]), ({**apart, 3: (11.0, 0.99, True)}, [4, 3])):
        tracker = _Scripted(backward)
        review, final, _ = _run(tracker, FORWARD)
        assert tracker.asked == asked
        assert [round(float(np.degrees(r.q_filtered[0])), 6) for r in final] == [20.0, 15.0, 38.0, 40.0, 42.0, 8.0]
        assert (review.reviews, review.met, review.revised) == (1, 0, 0)


def test_only_a_trusted_jump_far_from_the_prediction_is_reviewed():
    for jump in (_report(5, [8, 0, 0], 0.7, "rest", q_pred=[44, 0, 0]),        # in doubt (review_trust 0.8)
                 _report(5, [8, 0, 0], 0.9, "prediction", q_pred=[44, 0, 0]),  # the prediction's own solve
                 _report(5, [8, 0, 0], 0.9, "rest", q_pred=[20, 0, 0])):       # 12 deg: motion, not a jump
        tracker = _Scripted({})
        review, final, _ = _run(tracker, FORWARD[:5] + [jump])
        assert tracker.asked == [] and review.reviews == 0 and len(final) == 6


def test_frames_leave_the_review_late_by_its_frames_and_at_once_when_it_is_off():
    _, _, returned = _run(_Scripted({}, review_frames=2), FORWARD[:4])
    assert [[r.frame for r in left] for left in returned] == [[], [], [0], [1]]
    tracker = _Scripted({})
    tracker.config = TrackConfig()
    _, _, returned = _run(tracker, FORWARD[:3])
    assert [[r.frame for r in left] for left in returned] == [[0], [1], [2]]


def test_review_settings_are_checked():
    with pytest.raises(InputError, match=r"hypotheses.review_jump_deg: expected a finite number >= 0, got -1"):
        HypothesisConfig(review_jump_deg=-1.0)
    with pytest.raises(InputError, match=r"hypotheses.review_frames: a review .* set review_frames >= 1"):
        HypothesisConfig(review_jump_deg=15.0, review_frames=0)
    with pytest.raises(InputError, match=r"hypotheses.review_trust: must lie in \[0, 1\], got 1.5"):
        HypothesisConfig(review_trust=1.5)
    assert TrackConfig().preset("robust-temporal").hypotheses.review_jump_deg == 15.0
    assert TrackConfig().preset("robust-limits").hypotheses.review_jump_deg == 0.0


# ---- in track_sequence: the held frames reach the files, also when the run is stopped --------------

@pytest.fixture(scope="module")
def seq():
    return make_preset("two_finger_occlusion", frames=12, size=SIZE)


@pytest.fixture
def frames_dir(tmp_path, seq):
    return blank_frames(tmp_path / "frames", seq.n_frames, SIZE)


def test_track_sequence_writes_the_held_frames_in_order_when_stopped_and_at_the_end(tmp_path, seq, frames_dir):
    config = TrackConfig(hypotheses=HypothesisConfig(rest=True, review_jump_deg=15.0, review_frames=4))
    out = tmp_path / "stopped"
    with pytest.raises(KeyboardInterrupt, match=r"stopped at frame 7; the 7 finished frame\(s\)"):
        track_sequence(seq.model, seq.cameras, [FrameSource(frames_dir)], seq.q[0], out,
                       stopping_oracle(seq, 7), config=config, video=True)
    assert list(read_angles_csv(out / "angles.csv")["frame"]) == list(range(7))
    assert cv2.VideoCapture(str(out / "overlay.mp4")).get(cv2.CAP_PROP_FRAME_COUNT) == 7
    runs = {}
    for name, hyp in (("review", config.hypotheses), ("off", HypothesisConfig(rest=True))):
        runs[name] = track_sequence(seq.model, seq.cameras, [FrameSource(frames_dir)], seq.q[0], tmp_path / name,
                                    oracle(seq.model, seq.cameras, seq.q), config=TrackConfig(hypotheses=hyp),
                                    truth=seq.q, video=False)
    # a start wins once far from the lagging prediction, but the backward track
    # from it never meets the forward one: every frame as without the review, only later
    review = {k: v for k, v in runs["review"]["review"].items() if k != "s"}
    assert review == {"jump_deg": 15.0, "frames": 4, "reviews": 1, "met": 0, "frames_revised": 0}
    assert "review" not in runs["off"]
    written = [np.load(tmp_path / name / "results.npz") for name in runs]
    np.testing.assert_array_equal(written[0]["frame"], np.arange(12))
    np.testing.assert_array_equal(written[0]["q"], written[1]["q"])
    assert json.loads((tmp_path / "review" / "summary.json").read_text())["review"]["reviews"] == 1


def test_the_cli_summary_accounts_for_the_review(tmp_path):
    import io

    from jaxhand.cli_track import print_summary

    summary = {"frames": 90, "model": "hand", "lost_frames": 0,
               "review": {"jump_deg": 15.0, "frames": 30, "reviews": 2, "met": 1, "frames_revised": 6, "s": 12.34}}
    text = io.StringIO()
    print_summary(summary, tmp_path, file=text)
    assert ("review: 2 jump(s) of over 15 deg tracked back (12.3 s), 1 met the forward track, 6 frame(s) revised\n"
            in text.getvalue())
