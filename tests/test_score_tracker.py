"""The global image score in the tracker: ImageFrontEnd.score (ImageConfig.score), the frame's
confidence and loss flag (judge_frame), and the loss flag's quality in summary.json."""

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

import jaxhand as jh
from jaxhand.image import ImageConfig
from jaxhand.io import load_devset, open_frames
from jaxhand.render import RenderConfig, make_preset, render_frame
from jaxhand.score import ScoreSection, SkinForeground, ThresholdForeground, capsules_from_model, foreground_for
from jaxhand.track import (
    AbstractFrontEnd,
    ExactFrontEnd,
    ImageFrontEnd,
    LossConfig,
    TrackConfig,
    Tracker,
    confidence_of,
    judge_frame,
    loss_flag_quality,
    track_sequence,
)

DEVSET = Path(__file__).resolve().parent.parent / "data" / "mujoco"
AUTO = ImageConfig(score=ScoreSection(foreground="auto"))


@pytest.fixture(scope="module")
def opposition():
    return load_devset(DEVSET / "thumb_opposition")


def _image(seq, k):
    return cv2.imread(str(seq.image_paths[0][k]), cv2.IMREAD_GRAYSCALE)


def test_score_ranks_the_truth_above_perturbed_poses(opposition):
    """thumb_opposition frame 20 (thumb on the index tip): the true pose scores 0.936 (the MJCF
    model's palm and forearm drawn as occluders), each single joint moved 15-20 deg scores less."""
    seq, m = opposition, opposition.model
    q = seq.truth.q[20]
    qs = [q]
    for name, deg in (("index_pip", 20), ("thumb_mcp_flex", 20), ("middle_mcp_flex", -15)):
        moved = q.copy()
        moved[m.q_names.index(name)] += np.radians(deg)
        qs.append(moved)
    s = ImageFrontEnd(m, seq.cameras, AUTO).score([_image(seq, 20)], np.array(qs), None)
    np.testing.assert_allclose(s, [0.936, 0.901, 0.860, 0.759], atol=0.01)
    assert np.all(s[0] > s[1:] + 0.03)


def test_the_frame_evidence_is_computed_once_for_several_calls(opposition, monkeypatch):
    import jaxhand.track._frontend as frontend

    calls = []
    real = frontend.image_evidence
    monkeypatch.setattr(frontend, "image_evidence", lambda *a, **k: calls.append(1) or real(*a, **k))
    fe = ImageFrontEnd(opposition.model, opposition.cameras, AUTO)
    img = _image(opposition, 0)
    a = fe.score([img], opposition.truth.q[:2], None)
    b = fe.score([img.copy()], opposition.truth.q[:1], None)   # same content, another array
    assert len(calls) == 1 and a[0] == b[0]
    fe.score([_image(opposition, 20)], opposition.truth.q[:1], None)   # another frame
    assert len(calls) == 2


def test_model_capsules_carry_its_occluders(opposition):
    m = opposition.model
    caps = capsules_from_model(m, opposition.truth.q[0])
    assert caps.n == m.n_links + m.n_occluders == 20
    np.testing.assert_array_equal(caps.occluder, np.arange(20) >= 15)
    np.testing.assert_allclose(caps.radius_mm[15:], m.occluder_radius_mm)


def test_auto_foreground_and_section_errors():
    grey = np.zeros((4, 4), np.uint8)
    colour = np.zeros((4, 4, 3), np.uint8)
    colour[..., 2] = 200
    section = ScoreSection(foreground="auto")
    assert isinstance(foreground_for(section, grey), ThresholdForeground)
    assert isinstance(foreground_for(section, np.stack([grey] * 3, -1)), ThresholdForeground)  # grey as BGR
    assert isinstance(foreground_for(section, colour), SkinForeground)
    with pytest.raises(jh.InputError, match="score.foreground: must be one of auto, threshold"):
        ScoreSection(foreground="otsu")
    with pytest.raises(jh.InputError, match="score.background_image: foreground 'background' needs"):
        ScoreSection(foreground="background")
    with pytest.raises(jh.InputError, match="loss.score_lost: need 0 <= score_lost < score_good <= 1"):
        LossConfig(score_lost=0.9, score_good=0.8)
    c = TrackConfig().merged({"image": {"score": {"foreground": "auto"}}, "loss": {"score_lost": 0.6}})
    assert c.image.score.foreground == "auto" and c.loss.score_lost == 0.6
    assert jh.track.config_from_dict(jh.track.config_to_dict(c)) == c


class _ExactFeaturesImageScore(AbstractFrontEnd):
    """Exact features of the truth (so the residuals are perfect whatever the image shows) and the
    image front end's score of the images."""

    reextracts = False

    def __init__(self, model, cameras, truth):
        self.exact = ExactFrontEnd(model, cameras, truth, noise_px=0.2, seed=1)
        self.image = ImageFrontEnd(model, cameras, AUTO)

    def extract(self, images, q_start, state, frame):
        return self.exact.extract(images, q_start, state, frame)

    def score(self, images, qs, state):
        return self.image.score(images, qs, state)


@pytest.mark.slow
def test_a_blank_frame_loses_the_frame_the_residuals_would_keep(opposition):
    """Frames 0-2 of thumb_opposition, then frame 3 blank: exact features keep the residual
    confidence near 1 on every frame, the image score flags the blank one as lost (score 0) and
    the estimate is held at frame 2's."""
    seq, m = opposition, opposition.model
    tracker = Tracker(m, seq.cameras, _ExactFeaturesImageScore(m, seq.cameras, seq.truth.q[:5]), TrackConfig(),
                      dt_s=1 / 30)
    state = tracker.init(seq.truth.q[0])
    reps = []
    for k in range(4):
        img = _image(seq, k) if k < 3 else np.zeros_like(_image(seq, 0))
        state, rep = tracker.step(state, [img], k)
        reps.append(rep)
    residual = [confidence_of(r.rms_px, r.valid_share, tracker.config)[0] for r in reps]
    assert min(residual) > 0.9
    assert [r.lost for r in reps] == [False, False, False, True]
    assert all(r.confidence > 0.5 for r in reps[:3]) and reps[3].confidence == 0.0
    assert reps[3].image_score == 0.0 and all(r.image_score > 0.9 for r in reps[:3])
    np.testing.assert_array_equal(reps[3].q_filtered, reps[2].q_filtered)


def test_default_behaviour_without_an_image_score(opposition):
    """The image score is off by default (foreground "none" scores nothing), and a front end
    without a score leaves the residual rule's confidence and loss flag as they are."""
    seq, m = opposition, opposition.model
    assert ImageConfig().score == ScoreSection(foreground="none")
    off = ImageConfig(score=ScoreSection(foreground="none"))
    assert ImageFrontEnd(m, seq.cameras, off).score([_image(seq, 0)], seq.truth.q[:1], None) is None
    tracker = Tracker(m, seq.cameras, ExactFrontEnd(m, seq.cameras, seq.truth.q[:3]), TrackConfig(), dt_s=1 / 30)
    state = tracker.init(seq.truth.q[0])
    for k in range(3):
        state, rep = tracker.step(state, [None], k)
        assert np.isnan(rep.image_score) and "score" not in rep.timings_s
        conf, lost = confidence_of(rep.rms_px, rep.valid_share, tracker.config)
        assert rep.confidence == pytest.approx(conf, abs=1e-12) and rep.lost == lost


def test_loss_flag_quality_counts():
    q = loss_flag_quality([1.0, 2.0, 9.0, 10.0, 5.0], [0.9, 0.4, 0.2, 0.9, 0.1], [False, False, False, False, True])
    assert q == {"bad_px": 8.0, "good_px": 3.0, "frames_bad": 2, "flagged_bad": 0.5, "frames_good": 2,
                 "flagged_good": 0.5, "frames_flagged": 3}
    assert loss_flag_quality([1.0], [1.0], [False])["flagged_bad"] is None


def test_summary_reports_the_loss_flag_on_a_devset_run(opposition, tmp_path):
    """track_sequence with a dev-set truth.json's poses, the image score on: summary.json holds
    the loss flag's quality (golden numbers of the first 6 frames) and which joints were seen."""
    seq = opposition
    sources = open_frames(list(seq.frame_folders), fps=seq.fps)
    config = TrackConfig(image=AUTO)
    summary = track_sequence(seq.model, seq.cameras, sources, seq.truth.q[0], tmp_path, config=config,
                             truth=seq.truth.q, video=False, max_frames=6)
    flag = json.loads((tmp_path / "summary.json").read_text())["loss_flag"]
    assert flag == summary["loss_flag"]
    assert flag == {"bad_px": 8.0, "good_px": 3.0, "frames_bad": 0, "flagged_bad": None, "frames_good": 6,
                    "flagged_good": 0.0, "frames_flagged": 0}
    # every joint seen on these open-hand frames: the seen entries' error is the whole mean
    seen = json.loads((tmp_path / "summary.json").read_text())["seen"]
    assert seen["mostly_unseen"] == [] and seen["unseen_entries_share"] == 0.0 and seen["error_deg_unseen"] is None
    assert seen["error_deg_seen"] == pytest.approx(summary["accuracy_filtered"]["joint_error_deg"]["mean"], rel=1e-9)


class _FixedScore(AbstractFrontEnd):
    """Scores every pose with a given number (to test the rule alone)."""

    def __init__(self, value):
        self.value = value

    def extract(self, images, q_start, state, frame):
        raise NotImplementedError("not called by judge_frame")

    def score(self, images, qs, state):
        return np.full(len(qs), self.value)


def test_judge_frame_ramp_reference_and_loss():
    """Levels 0.7 / 0.9 on the score over the first scored frame's (0.8 here): a frame scoring
    0.64 (ratio 0.8) gets image confidence 0.5, one scoring 0.5 (ratio 0.625) is lost; absolute
    levels judge 0.64 lost; a residual-lost frame is not scored."""
    loss = LossConfig(score_lost=0.7, score_good=0.9)
    q = np.zeros(3)
    conf, lost, score, ref = judge_frame(_FixedScore(0.8), [None], q, None, 0.95, False, loss)
    assert (conf, lost, score, ref) == (0.95, False, 0.8, 0.8)
    conf, lost, score, ref = judge_frame(_FixedScore(0.64), [None], q, None, 0.95, False, loss, 0.8)
    assert conf == pytest.approx(0.5) and not lost and ref == 0.8
    assert judge_frame(_FixedScore(0.5), [None], q, None, 0.95, False, loss, 0.8)[:2] == (0.0, True)
    absolute = LossConfig(score_lost=0.7, score_good=0.9, score_relative=False)
    assert judge_frame(_FixedScore(0.64), [None], q, None, 0.95, False, absolute, 0.8)[:2] == (0.0, True)
    conf, lost, score, ref = judge_frame(_FixedScore(0.9), [None], q, None, 0.0, True, loss, 0.8)
    assert (conf, lost, np.isnan(score), ref) == (0.0, True, True, 0.8)


def test_the_score_loses_a_drifting_track_on_jaxhands_own_renders():
    """two_finger_occlusion (jaxhand's renderer, default settings): the tracker drifts from frame 3
    on (tip error 1.6 px, then 3.0, 4.6, 10.8 px); the image score follows it down (0.962 at the
    start, the truth scores 0.961 at frame 6) and loses frame 6, which is then held."""
    seq = make_preset("two_finger_occlusion", frames=80)
    images = [[render_frame(seq.model, c, q, RenderConfig(antialias=3)).image for c in seq.cameras]
              for q in seq.q[:8]]
    fe = ImageFrontEnd(seq.model, seq.cameras, ImageConfig(method="wssd", score=AUTO.score))
    tracker = Tracker(seq.model, seq.cameras, fe, TrackConfig(), dt_s=float(seq.times_s[1] - seq.times_s[0]))
    state, reps = tracker.init(seq.q[0]), []
    for k in range(8):
        state, rep = tracker.step(state, images[k], k, float(seq.times_s[k]))
        reps.append(rep)
    np.testing.assert_allclose([r.image_score for r in reps[:7]], [0.962, 0.962, 0.957, 0.912, 0.845, 0.783, 0.743],
                               atol=0.005)
    assert [r.lost for r in reps] == [False] * 6 + [True] * 2
    assert reps[4].confidence < 0.5 < reps[3].confidence
    np.testing.assert_array_equal(reps[6].q_filtered, reps[5].q_filtered)
    assert fe.score(images[6], seq.q[6:7], None)[0] == pytest.approx(0.961, abs=0.005)
