"""The weakest finger's starts (``hypotheses.finger_level``): after a frame of low confidence the
next frame also starts from the prediction with the finger the image supports least bent.

- each finger's flexion hinges, on the dev set's MuJoCo hand and the built-in hand21;
- the starts bend towards each hinge's wider side (flexion) and stay within the limits;
- the tracker names the weakest finger after a low-confidence frame only, and the next frame
  solves the prediction plus one start per bend;
- config round trip and errors;
- end to end on wave_two_cameras, where the index takes the ring finger's image (slow).
"""

from pathlib import Path

import cv2
import numpy as np
import pytest
from helpers import FunctionFrontEnd, fit_camera

import jaxhand as jh
from jaxhand.features import features_from_pose
from jaxhand.io import load_devset
from jaxhand.track import (
    HypothesisConfig,
    ImageFrontEnd,
    ImageSupport,
    SupportConfig,
    TrackConfig,
    Tracker,
    config_from_dict,
    config_to_dict,
)
from jaxhand.track._flexion import flexion_hinges
from jaxhand.track._hypotheses import extra_starts, finger_starts
from jaxhand.track._support import finger_of_frame, finger_of_link

DEVSET = Path(__file__).resolve().parent.parent / "data" / "mujoco"


def _names(m):
    return {g: [m.q_names[i] for i in v] for g, v in flexion_hinges(m, finger_of_frame(m)).items()}


def test_flexion_hinges_are_each_planar_fingers_flexion_chain():
    dev = load_devset(DEVSET / "thumb_opposition").model
    assert _names(dev) == {5: ["index_mcp_flex", "index_pip", "index_dip"],
                           9: ["middle_mcp_flex", "middle_pip", "middle_dip"],
                           13: ["ring_mcp_flex", "ring_pip", "ring_dip"],
                           17: ["little_mcp_flex", "little_pip", "little_dip"]}
    hand = _names(jh.builtin_model("hand21"))
    assert hand[14] == ["index_mcp", "index_pip", "index_dip"] and hand[0] == ["little_mcp", "little_pip", "little_dip"]
    assert sorted(hand) == [0, 4, 9, 14]   # the thumb (two abduction hinges) is not a planar finger


def test_finger_starts_bend_towards_flexion_within_the_limits():
    for m, sign in ((load_devset(DEVSET / "thumb_opposition").model, 1.0), (jh.builtin_model("hand21"), -1.0)):
        joints = flexion_hinges(m, finger_of_frame(m))[5 if sign > 0 else 14]   # the index finger
        q = np.clip(np.zeros(m.n_q), m.q_lower, m.q_upper)
        starts = finger_starts(q, joints, (20.0, 200.0, -20.0), np.asarray(m.q_lower), np.asarray(m.q_upper))
        moved = np.degrees(starts - q)
        others = np.setdiff1d(np.arange(m.n_q), joints)
        assert starts.shape == (3, m.n_q) and np.all(moved[:, others] == 0.0)
        np.testing.assert_allclose(moved[0, joints], 20.0 * sign, atol=1e-9)
        far = np.where(sign > 0, np.asarray(m.q_upper), np.asarray(m.q_lower))[joints]
        np.testing.assert_allclose(starts[1, joints], far)          # 200 deg: clipped at the limit
        expected = np.clip(q[joints] - np.radians(20.0) * sign, m.q_lower[joints], m.q_upper[joints])
        np.testing.assert_allclose(starts[2, joints], expected)


def test_extra_starts_add_the_finger_rows_only_when_asked():
    m = jh.builtin_model("hand21")
    joints = flexion_hinges(m, finger_of_frame(m))[14]
    q = np.asarray(m.q_default, float)
    hyp = HypothesisConfig(finger_level=0.3, finger_deg=(10.0, -10.0))
    rows, valid, labels = extra_starts(m, hyp, q, None, None, None, None, 0, joints)
    assert labels == ("finger", "finger") and valid.all()
    np.testing.assert_allclose(rows, finger_starts(q, joints, (10.0, -10.0), np.asarray(m.q_lower),
                                                   np.asarray(m.q_upper)))
    assert extra_starts(m, hyp, q, None, None, None, None, 0, None)[2] == ()


class _WeakIndex(FunctionFrontEnd):
    """Exact features of the truth; the index finger's links scored ``index_score`` on every frame."""

    unexplained_px = 0.0

    def __init__(self, m, rig, truth, index_scores):
        feats = features_from_pose(m, rig, truth)
        super().__init__(lambda images, q, state, frame: feats, reextracts=False)
        self.m, self.index_scores = m, index_scores

    def support(self, images, q, state, margin_px=1):
        finger = finger_of_link(self.m)
        score = np.where(finger == 14, self.index_scores.pop(0), 1.0)
        return ImageSupport(link_score=score[None], unexplained_px=self.unexplained_px)


@pytest.mark.slow
def test_the_tracker_bends_the_weakest_finger_after_a_low_confidence_frame():
    m = jh.builtin_model("hand21")
    truth = jh.random_q(m, np.random.default_rng(3), margin=0.25)
    rig = (fit_camera(m, truth),)
    config = TrackConfig(hypotheses=HypothesisConfig(finger_level=0.5, finger_deg=(20.0, 40.0, -20.0)),
                         support=SupportConfig(enabled=True))
    tracker = Tracker(m, rig, _WeakIndex(m, rig, truth, [0.5, 1.0, 1.0]), config)
    state = tracker.init(truth)
    state, first = tracker.step(state, [None], 0)      # the index scored 0.5: confidence 0
    assert first.confidence == 0.0 and state.weak_finger == 14 and first.starts == 1
    state, second = tracker.step(state, [None], 1)     # the prediction and three bends of the index
    assert second.starts == 4 and second.confidence == 1.0 and state.weak_finger == -1
    state, third = tracker.step(state, [None], 2)
    assert third.starts == 1
    np.testing.assert_allclose(third.q_solved, truth, atol=1e-6)


def test_finger_config_round_trip_and_errors():
    hyp = HypothesisConfig(finger_level=0.25, finger_deg=(15.0, -30.0))
    assert hyp.enabled and not HypothesisConfig().enabled
    assert config_from_dict(config_to_dict(TrackConfig(hypotheses=hyp))).hypotheses == hyp
    with pytest.raises(jh.InputError, match="hypotheses.finger_level: must lie in"):
        HypothesisConfig(finger_level=1.5)
    with pytest.raises(jh.InputError, match="hypotheses.finger_deg: expected a non-empty list of finite numbers"):
        HypothesisConfig(finger_deg=())
    with pytest.raises(jh.InputError, match="hypotheses.finger_deg: expected a list"):
        TrackConfig().merged({"hypotheses": {"finger_deg": 20.0}})


@pytest.mark.slow
def test_bending_the_weakest_finger_brings_the_ring_finger_back_on_wave_two_cameras():
    """wave_two_cameras from frame 50 (the true pose), camera 0: at 56-59 the ring finger flexes and
    the model's index takes its image (benchmarks/README.md); bending the weakest finger after a
    frame of low confidence keeps the ring finger on its own image."""
    seq = load_devset(DEVSET / "wave_two_cameras")
    m, cams = seq.model, seq.truth.cameras
    ring = [m.q_lookup(n) for n in m.q_names if n.startswith(("ring", "index"))]
    errors = {}
    with_ = TrackConfig().preset("robust-limits")     # finger_level 0.2
    for label, config in (("with", with_), ("without", with_.merged({"hypotheses": {"finger_level": 0.0}}))):
        tracker = Tracker(m, cams, ImageFrontEnd(m, cams, config.image), config, dt_s=1 / 30)
        state, err = tracker.init(np.asarray(seq.truth.q[50])), []
        for k in range(51, 66):
            images = [cv2.imread(str(seq.image_paths[c][k]), cv2.IMREAD_GRAYSCALE) for c in range(len(cams))]
            state, rep = tracker.step(state, images, k)
            err.append(np.degrees(np.abs(rep.q_filtered - np.asarray(seq.truth.q[k])))[ring])
        errors[label] = float(np.mean(err))
    print(errors)
    assert errors["with"] < 0.4 * errors["without"], errors


def test_the_rest_start_is_kept_but_not_valid_unless_the_frame_before_was_doubtful():
    m = jh.builtin_model("hand21")
    q = np.asarray(m.q_default, float) + 0.1
    hyp = HypothesisConfig(rest=True, rest_below=0.5)
    for ok in (True, False):
        rows, valid, labels = extra_starts(m, hyp, q, None, None, None, None, 0, rest_ok=ok)
        assert labels == ("rest",) and valid.tolist() == [ok]
        np.testing.assert_allclose(rows[0], np.asarray(m.q_default))   # hand21's base is fixed: no base entries
    with pytest.raises(jh.InputError, match=r"hypotheses\.rest_below: must lie in \[0, 1\]"):
        HypothesisConfig(rest_below=1.5)
    # without the fingers: the thumb rests, the fingers stay at the prediction
    keep = np.array([not n.startswith("thumb") for n in m.q_names])
    rows = extra_starts(m, hyp, q, None, None, None, None, 0, rest_keep=keep)[0]
    np.testing.assert_allclose(rows[0, keep], q[keep])
    np.testing.assert_allclose(rows[0, ~keep], np.asarray(m.q_default)[~keep])


def test_an_unexplained_blob_alone_bends_no_finger():
    """Foreground the pose leaves unexplained takes the confidence to 0 but names no finger: the
    next frame starts from the prediction alone."""
    m = jh.builtin_model("hand21")
    truth = jh.random_q(m, np.random.default_rng(3), margin=0.25)
    rig = (fit_camera(m, truth),)
    config = TrackConfig(hypotheses=HypothesisConfig(finger_level=0.5, finger_deg=(20.0, 40.0, -20.0)),
                         support=SupportConfig(enabled=True))
    frontend = _WeakIndex(m, rig, truth, [0.97, 0.97])
    frontend.unexplained_px = 100.0
    tracker = Tracker(m, rig, frontend, config)
    state, first = tracker.step(tracker.init(truth), [None], 0)
    assert first.confidence == 0.0 and state.weak_finger == -1
    state, second = tracker.step(state, [None], 1)
    assert second.starts == 1
