import json

import cv2
import numpy as np
import pytest

import jaxhand as jh
from jaxhand.io import FrameSource, ResultWriter, open_frames, read_angles_csv


def _folder(tmp_path, n=4, corrupt=None):
    d = tmp_path / "frames"
    d.mkdir()
    for i in range(n):
        cv2.imwrite(str(d / f"frame_{i:04d}.png"), np.full((12, 16, 3), 10 * i, np.uint8))
    if corrupt is not None:
        (d / f"frame_{corrupt:04d}.png").write_bytes(b"not a png")
    return d


def test_image_folder_reports_and_keeps_place_of_corrupt_frames(tmp_path):
    src = FrameSource(_folder(tmp_path, 4, corrupt=2), fps=10)
    frames = list(src)
    assert len(src) == 4 and [f.index for f in frames] == [0, 1, 2, 3]
    assert frames[2].image is None and "frame_0002.png: cannot read image" in frames[2].error
    assert frames[3].image.shape == (12, 16) and frames[3].image.dtype == np.uint8 and frames[3].image[0, 0] == 30
    assert frames[1].time_s == pytest.approx(0.1)


def test_video_round_trip(tmp_path):
    path = tmp_path / "v.avi"
    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 20.0, (32, 24))
    for i in range(5):
        w.write(np.full((24, 32, 3), 40 * i, np.uint8))
    w.release()
    src = FrameSource(path)
    frames = list(src)
    assert len(frames) == 5 and src.fps == pytest.approx(20.0)
    assert abs(int(frames[4].image.mean()) - 160) <= 3


def test_bad_inputs(tmp_path):
    with pytest.raises(jh.InputError, match="no such video file or image folder"):
        FrameSource(tmp_path / "nope")
    (tmp_path / "empty").mkdir()
    with pytest.raises(jh.InputError, match="holds no images"):
        FrameSource(tmp_path / "empty")
    (tmp_path / "bad.mp4").write_bytes(b"")
    with pytest.raises(jh.InputError, match="bad.mp4"):
        FrameSource(tmp_path / "bad.mp4")
    a = _folder(tmp_path, 3)
    (tmp_path / "b").mkdir()
    cv2.imwrite(str(tmp_path / "b" / "x.png"), np.zeros((4, 4), np.uint8))
    with pytest.raises(jh.InputError, match=r"different frame counts: \[3, 1\]"):
        open_frames([a, tmp_path / "b"])


def test_result_writer_flushes_each_frame(tmp_path):
    m = jh.builtin_model("index")
    w = ResultWriter(tmp_path, m, checkpoint_every=2)
    q = np.radians([10.0, -20.0, -30.0])
    w.write(0, 0.0, q, 0.9, False, cost=np.array(1.5))
    # Before close: the CSV already holds the frame (an interrupted run keeps it).
    cols = read_angles_csv(tmp_path / "angles.csv")
    np.testing.assert_allclose([cols["index_mcp_deg"][0], cols["index_dip_deg"][0]], [10.0, -30.0])
    w.write(1, 0.04, q, 0.8, True, cost=np.array(2.5))
    assert (tmp_path / "results.npz").exists()  # checkpoint after 2 frames
    w.skip(2, "corrupt")
    s = w.close({"fps": 25.0})
    assert s["frames_written"] == 2
    assert json.loads((tmp_path / "summary.json").read_text())["frames_skipped"] == [{"frame": 2, "reason": "corrupt"}]
    npz = np.load(tmp_path / "results.npz")
    np.testing.assert_allclose(npz["cost"], [1.5, 2.5])
    with ResultWriter(tmp_path / "x", m) as bad, pytest.raises(jh.InputError, match="non-finite"):
        bad.write(0, 0.0, np.array([np.nan, 0, 0]), 1.0, False)


def test_parse_pose_forms(tmp_path):
    from jaxhand.io import parse_pose, pose_to_dict

    m = jh.builtin_model("index")
    np.testing.assert_allclose(parse_pose(m, None), m.q_default)
    q = parse_pose(m, "index_pip=-45")
    np.testing.assert_allclose(np.degrees(q), [-10.0, -45.0, -10.0])
    np.testing.assert_allclose(np.degrees(parse_pose(m, "-5,-6,-7")), [-5, -6, -7])
    (tmp_path / "p.json").write_text(json.dumps({"q": {"index_mcp": 20}}))
    np.testing.assert_allclose(np.degrees(parse_pose(m, str(tmp_path / "p.json"))), [20, -15, -10])
    assert pose_to_dict(m, q)["index_pip"] == pytest.approx(-45.0)
    with pytest.raises(jh.InputError, match="unknown joint 'index_tip'; valid: index_mcp"):
        parse_pose(m, "index_tip=3")
    with pytest.raises(jh.InputError,
                       match=r"--init: expected 3 values for 'index' \(index_mcp, index_pip, index_dip\), got 2"):
        parse_pose(m, "1,2")
    with pytest.raises(jh.InputError, match=r"'index_dip' = 30 deg lies outside its limits"):
        parse_pose(m, "index_dip=30")
    with pytest.raises(jh.InputError, match="neither 'default'"):
        parse_pose(m, "bent")


def test_image_folder_sorts_frame_numbers_naturally(tmp_path):
    d = tmp_path / "frames"
    d.mkdir()
    for i in range(12):   # frame_0 .. frame_11 without zero padding: string order would put 10 after 1
        cv2.imwrite(str(d / f"frame_{i}.png"), np.full((4, 4), 10 * i, np.uint8))
    assert [int(f.image[0, 0]) for f in FrameSource(d)] == [10 * i for i in range(12)]


def test_frame_of_another_size_names_file_and_both_sizes(tmp_path):
    d = _folder(tmp_path, 3)
    cv2.imwrite(str(d / "frame_0001.png"), np.zeros((6, 8), np.uint8))
    frames = list(FrameSource(d, size=(16, 12)))
    assert frames[0].image is not None and frames[2].image is not None
    assert frames[1].image is None and "frame_0001.png: frame 1 is 8x6 px but the camera's image size is 16x12" \
        in frames[1].error
    with pytest.raises(jh.InputError, match=r"frame 0 is 16x12 px but the camera's image size is 320x240.*camera file"):
        list(open_frames([d], sizes=[(320, 240)])[0])


def test_frames_resized_by_a_scale(tmp_path):
    d = tmp_path / "frames"
    d.mkdir()
    image = np.random.default_rng(0).integers(0, 255, (48, 64), np.uint8)
    cv2.imwrite(str(d / "frame_0.png"), image)
    (frame,) = list(open_frames([d], sizes=[(32, 24)], scale=0.5)[0])
    np.testing.assert_array_equal(frame.image, cv2.resize(image, (32, 24), interpolation=cv2.INTER_AREA))
    with pytest.raises(jh.InputError, match=r"scale: expected a factor in \(0, 1\]"):
        FrameSource(d, scale=2.0)


def test_colour_frames_stay_colour_only_when_asked(tmp_path):
    d, g = tmp_path / "colour", tmp_path / "grey"
    d.mkdir()
    g.mkdir()
    bgr = np.random.default_rng(1).integers(0, 255, (12, 16, 3), np.uint8)
    cv2.imwrite(str(d / "frame_0.png"), bgr)
    cv2.imwrite(str(d / "frame_1.png"), np.dstack([bgr, np.full((12, 16), 255, np.uint8)]))   # BGRA
    cv2.imwrite(str(g / "frame_0.png"), bgr[..., 1])
    first, with_alpha = (f.image for f in open_frames([d], colour=True)[0])
    np.testing.assert_array_equal(first, bgr)
    np.testing.assert_array_equal(with_alpha, bgr)
    (grey,) = (f.image for f in open_frames([d])[0] if f.index == 0)
    np.testing.assert_array_equal(grey, cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY))
    (still_grey,) = (f.image for f in open_frames([g], colour=True)[0])
    np.testing.assert_array_equal(still_grey, bgr[..., 1])
