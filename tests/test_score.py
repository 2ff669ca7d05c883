"""The global image score: golden numbers on jaxhand's own renders and on MuJoCo dev-set frames."""

import numpy as np
import pytest
from helpers import fit_camera
from mujoco_hand import camera, capsules, frame, load_truth

from jaxhand.model import builtin_model
from jaxhand.render import RenderConfig, render_frame
from jaxhand.score import (
    Capsules,
    ConfidenceConfig,
    ScoreConfig,
    ThresholdForeground,
    capsules_from_model,
    frame_confidence,
    image_evidence,
    rasterize,
    score_frame,
    score_poses,
    score_silhouette,
)


@pytest.fixture(scope="module")
def scene():
    m = builtin_model("hand21")
    q = np.asarray(m.q_default).copy()
    q[m.q_lookup("index_mcp")] = -0.5
    q[m.q_lookup("index_pip")] = -0.6
    cam = fit_camera(m)
    return m, cam, q, render_frame(m, cam, q, RenderConfig(antialias=3)).image


def test_true_pose_scores_high_and_20_deg_off_clearly_lower(scene):
    m, cam, q, img = scene
    fg = ThresholdForeground()
    true = score_frame(m, cam, q, img, fg)
    # Golden values (OpenCV 4, this commit); tolerance 0.01 for OpenCV's rounding between versions.
    assert true.score == pytest.approx(0.97, abs=0.015)
    assert true.iou > 0.94 and true.coverage > 0.99 and true.chamfer_px < 0.5  # anti-aliased: iou 0.952
    q20 = q.copy()
    q20[m.q_lookup("index_mcp")] += np.radians(20)
    off = score_frame(m, cam, q20, img, fg)
    assert off.score < true.score - 0.15  # measured 0.76 against 0.97
    assert m.link_names[off.worst_link_index].startswith("index")
    assert off.worst_link < 0.3  # measured 0.18: the displaced finger is found
    rng = np.random.default_rng(0)
    all20 = score_frame(m, cam, q + np.radians(20) * rng.choice([-1, 1], size=q.size), img, fg)
    assert all20.score < 0.45  # measured 0.34


def test_score_falls_with_the_error(scene):
    m, cam, q, img = scene
    ev = image_evidence(img, ThresholdForeground())
    scores = []
    for deg in (0, 5, 10, 20, 30):
        qd = q.copy()
        qd[m.q_lookup("index_mcp")] += np.radians(deg)
        scores.append(score_silhouette(rasterize(capsules_from_model(m, qd), cam), ev).score)
    assert np.all(np.diff(scores) < 0)


def test_one_evidence_many_hypotheses_and_a_given_mask(scene):
    m, cam, q, img = scene
    fg = ThresholdForeground()
    a = score_frame(m, cam, q, img, fg)
    b = score_frame(m, cam, q, img, fg.mask(img))  # a ready mask gives the same
    assert a.score == b.score
    whole = score_frame(m, cam, q, img, fg, config=ScoreConfig(roi_margin_px=None))
    assert whole.iou == pytest.approx(a.iou, abs=1e-12)  # nothing outside the region of interest


def test_empty_silhouette_scores_zero(scene):
    m, cam, q, img = scene
    ev = image_evidence(img, ThresholdForeground())
    none = Capsules.from_arrays(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0))
    s = score_silhouette(rasterize(none, cam), ev)
    assert s.score == 0.0 and s.worst_link_index == -1


# ---- MuJoCo dev set: an independent renderer, a hand with palm and forearm ----

@pytest.fixture(scope="module")
def mujoco():
    return load_truth()


@pytest.mark.parametrize("name", ["open_close_000.png", "open_close_024.png", "open_close_044.png",
                                  "open_close_070.png"])
def test_mujoco_true_pose_with_the_palm_as_occluder(mujoco, name):
    caps, _ = capsules(mujoco["bodies"], mujoco["frames"][name]["joint_angles"])
    cam = camera(mujoco)
    img = frame(name)
    ev = image_evidence(img, ThresholdForeground())
    sil = rasterize(caps, cam)
    # The silhouette never leaves MuJoCo's anti-aliased foreground (measured 0 px); it misses only
    # a band of partly covered outline pixels (measured 144-337 px of 13-17k).
    assert np.count_nonzero(sil.mask & ~ev.foreground) <= 10
    assert np.count_nonzero(ev.foreground & ~sil.mask) < 0.025 * ev.foreground.sum()
    s = score_silhouette(sil, ev)
    assert s.score > 0.91 and s.iou > 0.97  # measured 0.924-0.950 and 0.978-0.989
    # Without the palm and forearm (what jaxhand's built-in hands have) the IoU collapses; the
    # coverage and chamfer parts do not depend on the unmodelled palm.
    fingers = Capsules.from_arrays(caps.start[~caps.occluder], caps.end[~caps.occluder],
                                   caps.radius_mm[~caps.occluder])
    f = score_silhouette(rasterize(fingers, cam), ev)
    assert 0.5 < f.iou < 0.62 and f.coverage > 0.99  # measured 0.55-0.59, 1.000


def test_mujoco_20_deg_off_is_clearly_lower(mujoco):
    name = "open_close_000.png"
    angles = mujoco["frames"][name]["joint_angles"]
    cam = camera(mujoco)
    ev = image_evidence(frame(name), ThresholdForeground())
    true = score_silhouette(rasterize(capsules(mujoco["bodies"], angles)[0], cam), ev)
    for joint, drop in (("index_mcp_flex", 0.15), ("thumb_cmc_flex", 0.2)):  # measured 0.220, 0.251
        moved = dict(angles, **{joint: angles[joint] + np.radians(20)})
        caps, names = capsules(mujoco["bodies"], moved)
        s = score_silhouette(rasterize(caps, cam), ev)
        assert s.score < true.score - drop
        assert names[s.worst_link_index].startswith(joint.split("_")[0])


def test_mujoco_clutter_defeats_the_threshold_foreground(mujoco):
    # Textured background (mean grey ~101): the triangle threshold keeps much of the texture, the
    # true pose scores 0.77 only, and 20 deg on the index barely moves it (measured 0.758). A
    # background model is needed there (BackgroundForeground); this documents the limitation.
    name = "open_close_noise_clutter_024.png"
    angles = mujoco["frames"][name]["joint_angles"]
    cam = camera(mujoco)
    ev = image_evidence(frame(name), ThresholdForeground())
    true = score_silhouette(rasterize(capsules(mujoco["bodies"], angles)[0], cam), ev)
    assert 0.7 < true.score < 0.85
    assert true.iou < 0.8


# ---- confidence and the loss flag ----

def test_confidence_ramps_and_loss_rule():
    c, _ = frame_confidence(0.45, 0.5, 1.0, ConfidenceConfig(score_reference=0.5))
    assert float(c) == 1.0  # 0.45 / 0.5 = 0.9: good
    cfg = ConfidenceConfig(score_lost=0.5, score_good=0.8, rms_good_px=1.0, rms_lost_px=5.0, valid_lost=0.2,
                           valid_good=0.6)
    c, lost = frame_confidence(0.9, 0.5, 1.0, cfg)
    assert float(c) == 1.0 and not bool(lost)
    c, lost = frame_confidence(0.65, 0.5, 1.0, cfg)  # halfway up the score ramp
    assert float(c) == pytest.approx(0.5) and not bool(lost)
    c, lost = frame_confidence(0.9, 4.0, 0.4, cfg)  # rms term 0.25, valid term 0.5: the weakest decides
    assert float(c) == pytest.approx(0.25)
    c, lost = frame_confidence(np.array([0.45, 0.9, 0.9, np.nan]), np.array([0.5, 6.0, 0.5, 0.5]),
                               np.array([1.0, 1.0, 0.1, 1.0]), cfg)
    np.testing.assert_array_equal(lost, [True, True, True, True])
    np.testing.assert_array_equal(c, 0.0)
    with pytest.raises(ValueError, match="score levels"):
        ConfidenceConfig(score_lost=0.9, score_good=0.8)


def test_default_confidence_separates_the_mujoco_true_pose_from_20_deg_off(mujoco):
    name = "open_close_000.png"
    angles = mujoco["frames"][name]["joint_angles"]
    cam = camera(mujoco)
    ev = image_evidence(frame(name), ThresholdForeground())
    true = score_silhouette(rasterize(capsules(mujoco["bodies"], angles)[0], cam), ev).score
    moved = dict(angles, index_mcp_flex=angles["index_mcp_flex"] + np.radians(20))
    off = score_silhouette(rasterize(capsules(mujoco["bodies"], moved)[0], cam), ev).score
    c, lost = frame_confidence(np.array([true, off]), 0.5, 1.0)
    assert c[0] == 1.0 and not lost[0]
    assert c[1] < 0.5  # low confidence: measured score 0.73
    # The fingers alone (no palm) score lower; without the IoU (which the missing palm spoils) and
    # relative to the true frame's score the same holds (measured 0.642 against 0.904).
    fingers = lambda a: Capsules.from_arrays(*(x[~a.occluder] for x in (a.start, a.end, a.radius_mm)))  # noqa: E731
    no_iou = ScoreConfig(w_iou=0.0)
    ref = score_silhouette(rasterize(fingers(capsules(mujoco["bodies"], angles)[0]), cam), ev, no_iou).score
    off = score_silhouette(rasterize(fingers(capsules(mujoco["bodies"], moved)[0]), cam), ev, no_iou).score
    c, lost = frame_confidence(np.array([ref, off]), 0.5, 1.0, ConfidenceConfig(score_reference=ref))
    assert c[0] == 1.0 and c[1] < 0.5


def test_score_poses_matches_one_at_a_time(scene):
    m, cam, q, img = scene
    fg = ThresholdForeground()
    ev = image_evidence(img, fg)
    qs = np.stack([q, q + 0.2, q - 0.1])
    batch = score_poses(m, cam, qs, ev)
    for qi, s in zip(qs, batch):
        assert s.score == score_frame(m, cam, qi, img, fg).score
    assert batch[0].score > batch[1].score
    with pytest.raises(ValueError, match="qs"):
        score_poses(m, cam, q, ev)
