"""Landmark files (MediaPipe JSON, plain CSV and JSON), their error paths, and the commands."""

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

from jaxhand.cli import main
from jaxhand.landmarks import POINT_NAMES, LandmarkFileError, load_landmarks, mirror_x, save_landmarks_csv

REAL = Path(__file__).resolve().parent.parent / "data" / "real" / "human_hand_video.mediapipe.json"


def test_mediapipe_json_of_the_real_video():
    seq = load_landmarks(REAL)
    assert len(seq) == 621 and seq.image_size == (1280, 720) and seq.fps == 30.0
    assert seq.handedness == "right"
    raw = json.loads(REAL.read_text())["frames"][0]["hands"][0]["landmarks_px"][0]
    # MediaPipe's (0, 0) is the image corner; jaxhand's the centre of the top-left pixel
    np.testing.assert_allclose(seq.px[0, 0], np.array(raw[:2]) - 0.5)
    # six frames hold a second detection of the same hand: the one nearest the previous frame is kept
    assert seq.notes["two_hand_frames"] == [555, 557, 559, 561, 563, 565]
    assert np.all(np.isfinite(seq.px)) and np.all(seq.confidence == 1.0)


def _mediapipe(tmp_path, frames):
    p = tmp_path / "mp.json"
    p.write_text(json.dumps({"joint_names": list(POINT_NAMES), "summary": {"size": [64, 48], "fps": 10},
                             "frames": frames}))
    return p


def test_mediapipe_wrong_point_count_is_an_error(tmp_path):
    p = _mediapipe(tmp_path, [{"frame": 0, "hands": [{"landmarks_px": [[1, 2, 0]] * 20}]}])
    with pytest.raises(LandmarkFileError, match="frame 0: hand 0: expected 21 landmarks"):
        load_landmarks(p)


def test_mediapipe_frames_without_a_hand_are_reported(tmp_path):
    hand = {"landmarks_px": [[1.0, 2.0, 0.0]] * 21, "handedness_unmirrored": "Left"}
    p = _mediapipe(tmp_path, [{"frame": 0, "hands": [hand]}, {"frame": 1, "hands": []}, {"frame": 2, "hands": [hand]}])
    seq = load_landmarks(p)
    assert len(seq) == 3 and seq.notes["missing_frames"] == [1]
    assert not seq.valid[1].any() and seq.valid[0].all() and seq.handedness == "left"


def _csv(tmp_path, rows, header="frame,point,x,y,confidence"):
    p = tmp_path / "lm.csv"
    p.write_text(header + "\n" + "\n".join(rows) + "\n")
    return p


def test_plain_csv_round_trip(tmp_path):
    rng = np.random.default_rng(0)
    rows = [f"{f},{n},{rng.uniform(0, 100):.4f},{rng.uniform(0, 100):.4f},0.5" for f in (3, 4) for n in POINT_NAMES]
    seq = load_landmarks(_csv(tmp_path, rows))
    assert list(seq.frames) == [3, 4] and np.all(seq.confidence == 0.5)
    back = load_landmarks(save_landmarks_csv(seq, tmp_path / "again.csv"))
    np.testing.assert_allclose(back.px, seq.px, atol=1e-4)


def test_plain_csv_with_3d_points(tmp_path):
    rows = [f"0,{n},{i},{2 * i},{3 * i}" for i, n in enumerate(POINT_NAMES)]
    seq = load_landmarks(_csv(tmp_path, rows, header="frame,point,x,y,z"))
    assert seq.mm.shape == (1, 21, 3) and seq.mm[0, 2].tolist() == [2.0, 4.0, 6.0]
    assert not seq.valid.any()                 # no pixels given


def test_csv_errors_name_the_row_and_point(tmp_path):
    with pytest.raises(LandmarkFileError, match="unknown point 'index_tp'.*did you mean 'index_tip'"):
        load_landmarks(_csv(tmp_path, ["0,index_tp,1,2,1"]))
    with pytest.raises(LandmarkFileError, match="'wrist' appears twice"):
        load_landmarks(_csv(tmp_path, ["0,wrist,1,2,1", "0,wrist,1,2,1"]))
    with pytest.raises(LandmarkFileError, match="x: not a number"):
        load_landmarks(_csv(tmp_path, ["0,wrist,abc,2,1"]))
    with pytest.raises(LandmarkFileError, match="unknown column"):
        load_landmarks(_csv(tmp_path, ["0,wrist,1,2,1"], header="frame,point,x,y,conf"))


def test_nan_points_and_missing_frames_are_masked_and_reported(tmp_path):
    seq = load_landmarks(_csv(tmp_path, ["0,wrist,nan,2,1", "0,index_tip,5,6,1", "2,wrist,1,1,1"]))
    assert seq.notes == {"missing_frames": [1], "nan_points": 1, "absent_points": 19 + 20}
    assert seq.valid[0, POINT_NAMES.index("index_tip")] and not seq.valid[0, 0]
    assert seq.confidence[0, 0] == 0.0


def test_plain_json(tmp_path):
    p = tmp_path / "lm.json"
    rows = [{"frame": 0, "point": n, "x": 1.0, "y": 2.0} for n in POINT_NAMES]
    p.write_text(json.dumps({"format": "jaxhand-landmarks", "format_version": 1, "image_size": [64, 48],
                             "rows": rows}))
    seq = load_landmarks(p)
    assert seq.image_size == (64, 48) and seq.valid.all()
    p.write_text(json.dumps({"format_version": 1, "rows": rows, "colour": 1}))
    with pytest.raises(LandmarkFileError, match="unknown key"):
        load_landmarks(p)


def test_mirror_x_is_an_involution():
    px = np.array([[0.0, 1.0], [639.0, 5.0]])
    np.testing.assert_array_equal(mirror_x(px, 319.5), [[639.0, 1.0], [0.0, 5.0]])
    np.testing.assert_array_equal(mirror_x(mirror_x(px, 10.0), 10.0), px)


@pytest.mark.skipif(importlib.util.find_spec("mediapipe") is not None, reason="mediapipe is installed here")
def test_landmarks_command_without_mediapipe_says_how_to_get_it(tmp_path, capsys):
    video = REAL.with_suffix("").with_suffix(".mp4")
    assert main(["landmarks", str(video), "-o", str(tmp_path / "x.json")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert "mediapipe==0.10.21" in err and "numpy<2" in err and "--python" in err


def test_fit_landmarks_command_error_is_one_line(tmp_path, capsys):
    p = _csv(tmp_path, ["0,wrist,1,2,1"])
    assert main(["fit-landmarks", str(p), "--out", str(tmp_path / "o")]) == 2   # no image size anywhere
    assert "image size is unknown" in capsys.readouterr().err


@pytest.mark.slow
def test_fit_landmarks_command_on_the_real_video(tmp_path):
    # The first 6 frames only (the whole video is benchmarks/real_video.py's job), frame by
    # frame: the default's paths are tests/test_landmarks_paths.py's (and twice as slow here).
    out = tmp_path / "out"
    assert main(["fit-landmarks", str(REAL), "--out", str(out), "--max-frames", "6", "--steps", "20",
                 "--save-model", str(tmp_path / "hand.toml"), "--init", "track"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    for f in ("angles.csv", "results.npz", "summary.json", "overlay.mp4", "angles.png", "camera.json"):
        assert (out / f).exists()
    assert summary["mirrored"] is True and summary["within_limits"] is True and summary["init"] == "track"
    # threshold: MediaPipe's own landmarks are 7-11 px from hand labels; the fit must stay well inside that
    assert summary["median_px"] < 6.0 and summary["frames"] == 6
    from jaxhand import load_model

    assert load_model(tmp_path / "hand.toml").name == "hand27_calibrated"


@pytest.mark.slow
def test_fit_landmarks_reads_the_model_handedness(tmp_path):
    # the video shows a right hand: hand27_right fits it as it is, hand27 (left) mirrored
    for model, mirrored in (("hand27_right", False), ("hand27", True)):
        out = tmp_path / model
        assert main(["fit-landmarks", str(REAL), "--model", model, "--out", str(out), "--max-frames", "2",
                     "--steps", "10", "--init", "track"]) == 0
        summary = json.loads((out / "summary.json").read_text())
        assert summary["model_hand"] == ("right" if model.endswith("right") else "left")
        assert summary["mirrored"] is mirrored and summary["init"] == "track"


def test_mediapipe_nan_points_are_masked_and_reported(tmp_path):
    pts = [[1.0, 2.0, 0.0]] * 21
    pts[8] = [float("nan"), 3.0, 0.0]
    p = tmp_path / "mp.json"
    # json.dumps writes NaN, which MediaPipe's own writer (Python json) does as well
    p.write_text(json.dumps({"joint_names": list(POINT_NAMES),
                             "frames": [{"frame": 0, "hands": [{"landmarks_px": pts}]}]}))
    seq = load_landmarks(p)
    assert seq.notes["nan_points"] == 1
    assert not seq.valid[0, 8] and seq.valid[0, :8].all() and seq.confidence[0, 8] == 0.0


def test_mediapipe_unknown_point_names_are_an_error(tmp_path):
    names = list(POINT_NAMES)
    names[4] = "thumb_end"
    p = tmp_path / "mp.json"
    p.write_text(json.dumps({"joint_names": names, "frames": []}))
    with pytest.raises(LandmarkFileError, match="joint_names differ from the 21-point convention"):
        load_landmarks(p)


def test_plain_json_unknown_point_name_is_an_error(tmp_path):
    p = tmp_path / "lm.json"
    p.write_text(json.dumps({"format": "jaxhand-landmarks", "format_version": 1,
                             "rows": [{"frame": 0, "point": "index_tp", "x": 1.0, "y": 2.0}]}))
    with pytest.raises(LandmarkFileError, match="unknown point 'index_tp'"):
        load_landmarks(p)


def test_a_second_hand_is_skipped_and_reported(tmp_path):
    # Two different hands in frames 1 and 2 (a left hand far away, listed first): the hand
    # nearest the previous frame's is kept, the other skipped, and the frames are named.
    right = [[100.0 + i, 50.0, 0.0] for i in range(21)]
    left = [[400.0 + i, 300.0, 0.0] for i in range(21)]
    r = {"landmarks_px": right, "score": 0.9, "handedness_unmirrored": "Right"}
    le = {"landmarks_px": left, "score": 0.95, "handedness_unmirrored": "Left"}
    p = _mediapipe(tmp_path, [{"frame": 0, "hands": [r]}, {"frame": 1, "hands": [le, r]},
                              {"frame": 2, "hands": [le, r]}])
    seq = load_landmarks(p)
    assert seq.notes["two_hand_frames"] == [1, 2]
    np.testing.assert_allclose(seq.px[:, 0], np.array([[99.5, 49.5]] * 3))
    assert seq.handedness == "right"


def test_fit_landmarks_command_without_any_landmark_is_one_line(tmp_path, capsys):
    p = _mediapipe(tmp_path, [{"frame": 0, "hands": []}, {"frame": 1, "hands": []}])
    assert main(["fit-landmarks", str(p), "--out", str(tmp_path / "o"), "--no-video"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].endswith("mp.json: no landmarks")
