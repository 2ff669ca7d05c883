"""The tracking loop with an oracle front end (exact features of the ground truth, plus noise)."""

import cv2
import numpy as np
import pytest
from helpers import CompileCounter, FunctionFrontEnd, fixed_front_end, oracle

import jaxhand as jh
from jaxhand.features import features_from_pose
from jaxhand.io import FrameSource, read_angles_csv
from jaxhand.render import make_preset
from jaxhand.track import FilterConfig, RobustConfig, TrackConfig, Tracker, accuracy_summary, track_sequence
from jaxhand.track._sequence import _Timings


@pytest.fixture(scope="module")
def seq():
    return make_preset("two_finger_occlusion", frames=30, size=(160, 120))


@pytest.mark.slow
def test_oracle_tracking_is_accurate_and_compiles_once(seq):
    tracker = Tracker(seq.model, seq.cameras, oracle(seq.model, seq.cameras, seq.q),
                      TrackConfig(filter=FilterConfig(theta=0.5)), dt_s=float(seq.times_s[1] - seq.times_s[0]))
    state = tracker.init(seq.q[0])
    images = [np.zeros((120, 160), np.uint8)]
    state, first = tracker.step(state, images, 0, 0.0)
    errors = []
    with CompileCounter() as counter:
        for k in range(1, len(seq.q)):
            state, rep = tracker.step(state, images, k, float(seq.times_s[k]))
            errors.append(np.degrees(np.abs(rep.q_filtered - seq.q[k])).mean())
            assert np.all(np.isfinite(rep.q_filtered)) and not rep.lost
    assert counter.count == 0
    # 0.3 px feature noise on ~100 px fingers: well under a degree on average after filtering
    assert np.mean(errors) < 1.0, np.mean(errors)


def test_missing_features_never_write_nan(tmp_path, seq):
    d = tmp_path / "frames"
    d.mkdir()
    for k in range(8):
        cv2.imwrite(str(d / f"f{k:03d}.png"), np.zeros((120, 160), np.uint8))
    summary = track_sequence(seq.model, seq.cameras, [FrameSource(d, fps=25)], seq.q[0], tmp_path / "out",
                             oracle(seq.model, seq.cameras, seq.q, drop_frame=3), truth=seq.q[:8], video=False)
    cols = read_angles_csv(tmp_path / "out" / "angles.csv")
    values = np.stack([v for k, v in cols.items()])
    assert values.shape[1] == 8 and np.all(np.isfinite(values))
    assert cols["lost"][3] == 1 and cols["confidence"][3] == 0.0
    assert summary["lost_frames"] == 1 and summary["frames_before_first_loss"] == 3
    # the lost frame holds the last good estimate (hold_on_loss) instead of filtering stray fits
    assert cols["middle_mcp_deg"][3] == cols["middle_mcp_deg"][2]


def test_corrupt_frame_is_reported_and_skipped(tmp_path, seq, capsys):
    d = tmp_path / "frames"
    d.mkdir()
    for k in range(6):
        cv2.imwrite(str(d / f"f{k:03d}.png"), np.zeros((120, 160), np.uint8))
    (d / "f002.png").write_bytes(b"broken")
    summary = track_sequence(seq.model, seq.cameras, [FrameSource(d, fps=25)], seq.q[0], tmp_path / "out",
                             oracle(seq.model, seq.cameras, seq.q), video=True)
    assert "skipping frame 2: f002.png: cannot read image" in capsys.readouterr().err
    assert summary["frames_skipped"] == [{"frame": 2, "reason": "f002.png: cannot read image (missing or corrupt)"}]
    assert list(read_angles_csv(tmp_path / "out" / "angles.csv")["frame"]) == [0, 1, 3, 4, 5]
    assert (tmp_path / "out" / "overlay.mp4").stat().st_size > 0 and (tmp_path / "out" / "angles.png").exists()


def test_interrupted_run_keeps_finished_frames(tmp_path, seq):
    d = tmp_path / "frames"
    d.mkdir()
    for k in range(10):
        cv2.imwrite(str(d / f"f{k:03d}.png"), np.zeros((120, 160), np.uint8))
    inner = oracle(seq.model, seq.cameras, seq.q)

    def extract(images, q_pred, state, frame):
        if frame == 6:
            raise KeyboardInterrupt
        return inner.fn(images, q_pred, state, frame)

    with pytest.raises(KeyboardInterrupt):
        track_sequence(seq.model, seq.cameras, [FrameSource(d, fps=25)], seq.q[0], tmp_path / "out",
                       FunctionFrontEnd(extract, reextracts=False), video=False)
    cols = read_angles_csv(tmp_path / "out" / "angles.csv")
    assert list(cols["frame"]) == [0, 1, 2, 3, 4, 5]
    np.testing.assert_allclose(cols["middle_mcp_deg"][0], np.degrees(seq.q[0][0]), atol=2.0)


def test_tracker_input_errors(seq):
    tracker = Tracker(seq.model, seq.cameras, oracle(seq.model, seq.cameras, seq.q))
    with pytest.raises(jh.InputError, match="outside its limits"):
        tracker.init(np.full(seq.model.n_q, 3.0))
    with pytest.raises(jh.InputError, match=r"one image per camera \(1\), got 2"):
        tracker.step(tracker.init(seq.q[0]), [np.zeros((4, 4), np.uint8)] * 2)
    with pytest.raises(jh.InputError, match="theta must lie in"):
        FilterConfig(theta=1.5)
    with pytest.raises(jh.InputError, match="theta_rate_hz must be > 0"):
        FilterConfig(theta_rate_hz=-1.0)
    with pytest.raises(jh.InputError, match="frontend: expected an AbstractFrontEnd"):
        Tracker(seq.model, seq.cameras, lambda images, q, s: None)


def test_theta_holds_at_its_frame_rate_and_scales_to_others(seq):
    extract = oracle(seq.model, seq.cameras, seq.q)
    # 0.85 per frame at 25 frames/s forgets as much per second as 0.85 ** 2.5 = 0.6663 at 10 frames/s
    assert Tracker(seq.model, seq.cameras, extract, dt_s=0.04).theta == pytest.approx(0.85, abs=1e-12)
    assert Tracker(seq.model, seq.cameras, extract, dt_s=0.1).theta == pytest.approx(0.666112, abs=1e-6)
    assert Tracker(seq.model, seq.cameras, extract, TrackConfig(filter=FilterConfig(theta=0.5, theta_rate_hz=10.0)),
                   dt_s=0.05).theta == pytest.approx(0.7071068, abs=1e-7)
    assert Tracker(seq.model, seq.cameras, extract, TrackConfig(filter=FilterConfig(theta_rate_hz=None)),
                   dt_s=0.1).theta == 0.85


def test_gate_keeps_a_misplaced_feature_from_pulling_the_first_solve(seq):
    # the middle finger's distal line taken 15 px off (from the wrong finger, say); the prediction
    # 2 degrees off: gating the first solve by the distance to the predicted model keeps the fit
    # near the truth, where the robust passes alone start from a fit the outlier has bent
    m, q = seq.model, seq.q[15]
    f = features_from_pose(m, seq.cameras, q)[0]
    bad = type(f)(f.lines.at[m.link_lookup("middle_dip"), 2].add(15.0), f.line_valid, f.line_weight, f.tips,
                  f.tip_valid, f.tip_weight)
    worst = {}
    for gate in (0.0, 2.0):
        tracker = Tracker(m, seq.cameras, fixed_front_end(bad),
                          TrackConfig(robust=RobustConfig(gate_scale_px=gate), reextract=0,
                                      filter=FilterConfig(enabled=False)))
        state = tracker.init(np.clip(q + np.radians(2.0), m.q_lower, m.q_upper))
        _, rep = tracker.step(state, [None], 0, 0.0)
        worst[gate] = np.degrees(np.abs(rep.q_solved - q)).max()
    assert worst[0.0] > 8.0 and worst[2.0] < 3.0, worst


def test_reextract_searches_again_around_the_solved_pose(seq):
    m = seq.model
    asked = []

    def extract(images, q_pred, state, frame):
        asked.append(np.asarray(q_pred, float).copy())
        return features_from_pose(m, seq.cameras, seq.q[10])

    tracker = Tracker(m, seq.cameras, FunctionFrontEnd(extract), TrackConfig(reextract=2))
    state = tracker.init(seq.q[9])
    state, rep = tracker.step(state, [None], 0, 0.0)
    assert len(asked) == 3  # the prediction, then twice around the solve
    np.testing.assert_array_equal(asked[0], seq.q[9])
    np.testing.assert_allclose(asked[1], seq.q[10], atol=1e-6)  # exact features: the first solve is exact
    np.testing.assert_allclose(rep.q_solved, seq.q[10], atol=1e-8)
    with pytest.raises(jh.InputError, match="reextract"):
        TrackConfig(reextract=-1)


def test_accuracy_summary_reports_the_palm_pose():
    m = jh.builtin_model("hand27")
    cam = jh.Orthographic(R=np.eye(3), t=np.array([0.0, 0.0, 500.0]), scale=1.0, center=(160, 120), size=(320, 240))
    truth = np.stack([np.asarray(m.q_default)] * 2)
    est = truth.copy()
    half = np.radians(10.0) / 2   # 10 degrees about (0, 0.6, 0.8), composed with the true orientation
    turn = np.array([np.cos(half), 0.0, 0.6 * np.sin(half), 0.8 * np.sin(half)])
    w1, v1 = turn[0], turn[1:]
    w2, v2 = truth[0, 0], truth[0, 1:4]
    est[:, :4] = np.r_[w1 * w2 - v1 @ v2, w1 * v2 + w2 * v1 + np.cross(v1, v2)]
    est[1, :4] *= -1.0   # the same orientation
    est[:, 4:6] += (3.0, -4.0)
    est[:, m.q_lookup("index_pip")] += np.radians(2.0)
    acc = accuracy_summary(m, cam, est, truth)
    assert acc["palm_rotation_deg"]["mean"] == pytest.approx(10.0, abs=1e-9)
    assert acc["palm_rotation_deg"]["max"] == pytest.approx(10.0, abs=1e-9)
    assert acc["palm_error"]["per_entry_mean"] == pytest.approx({"palm_tx": 3.0, "palm_ty": 4.0, "palm_tz": 0.0})
    assert acc["joint_error_deg"]["per_joint_max"]["index_pip"] == pytest.approx(2.0)
    assert acc["joint_error_deg"]["mean"] == pytest.approx(2.0 / 21)   # 21 finger and thumb joints
    assert "palm_rotation_deg" not in accuracy_summary(jh.builtin_model("hand21"), cam, truth[:, 7:], truth[:, 7:])


def test_a_stage_that_first_runs_after_many_frames_is_timed_from_there():
    """A stage absent for a long stretch (the verify step while every frame is lost) counts 0 s
    there; it first appearing after more frames than its column holds once grown must not fail."""
    timings = _Timings()
    for _ in range(600):
        timings.add({"solve": 1.0})
    timings.add({"solve": 1.0, "verify": 2.0})
    steady = timings.steady()
    assert steady["solve"].shape == steady["verify"].shape == (600,)
    assert steady["verify"][-1] == 2.0 and not steady["verify"][:-1].any()
