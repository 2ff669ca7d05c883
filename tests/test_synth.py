"""Synthetic sequences: minimum-jerk trajectories, presets, sequence folders and `jaxhand synth`."""

import json

import cv2
import numpy as np
import pytest

import jaxhand as jh
from jaxhand.cli import main
from jaxhand.render import (
    RenderConfig,
    joint_trajectory,
    load_sequence,
    make_preset,
    min_jerk_profile,
    minimum_jerk,
    preset_names,
    render_frame,
    write_sequence,
)
from jaxhand.render._trajectory import slerp

SMALL = (64, 48)


# ---- trajectories ----

def test_min_jerk_profile_golden_values():
    np.testing.assert_allclose(min_jerk_profile([0.0, 0.5, 1.0]), [0.0, 0.5, 1.0])
    np.testing.assert_allclose(min_jerk_profile(0.25), 10 / 64 - 15 / 256 + 6 / 1024)
    np.testing.assert_allclose(min_jerk_profile([-1.0, 2.0]), [0.0, 1.0])


def test_minimum_jerk_hits_keys_and_rests_there():
    keys = np.array([[0.0, 1.0], [2.0, -1.0], [2.0, 3.0]])
    key_times = np.array([0.0, 1.0, 3.0])
    np.testing.assert_allclose(minimum_jerk(keys, key_times, key_times), keys)
    h = 1e-5
    for t in key_times[1:-1]:
        v = (minimum_jerk(keys, key_times, [t + h]) - minimum_jerk(keys, key_times, [t - h])) / (2 * h)
        np.testing.assert_allclose(v, 0.0, atol=1e-8)  # zero velocity at every key
    t = np.linspace(0, 3, 301)
    x = minimum_jerk(keys, key_times, t)
    seg = t <= 1.0
    assert np.all(np.diff(x[seg, 0]) >= 0) and np.all(np.diff(x[seg, 1]) <= 0)  # monotone within a segment
    np.testing.assert_allclose(minimum_jerk(keys, key_times, [0.5]), [[1.0, 0.0]])  # s(1/2) = 1/2
    with pytest.raises(jh.InputError, match="strictly increasing"):
        minimum_jerk(keys, [0.0, 2.0, 1.0], t)


def test_slerp_stays_unit_and_hits_the_ends():
    q0 = np.array([1.0, 0, 0, 0])
    q1 = np.array([np.cos(0.5), np.sin(0.5), 0, 0])  # 1 rad about x
    s = np.linspace(0, 1, 11)
    q = slerp(np.tile(q0, (11, 1)), np.tile(q1, (11, 1)), s)
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0)
    np.testing.assert_allclose(q[[0, -1]], [q0, q1], atol=1e-12)
    np.testing.assert_allclose(2 * np.arccos(q[5, 0]), 0.5, atol=1e-12)  # halfway: half the angle
    np.testing.assert_allclose(slerp(q0, -q1, 1.0), q1, atol=1e-12)  # the short way round


def test_joint_trajectory_checks_limits_by_name():
    m = jh.builtin_model("index")
    good = np.asarray(m.q_default)
    bad = good.copy()
    bad[m.q_lookup("index_pip")] = np.radians(20.0)  # PIP limit is [-100, 0]
    with pytest.raises(jh.InputError, match="keys\\[1\\].*'index_pip' = 20 deg"):
        joint_trajectory(m, [good, bad], [0.0, 1.0], [0.5])


# ---- presets ----

def _clearance(model, q, samples=21):
    """Smallest gap (mm) between the pills of links in different branches (negative: they overlap)."""
    pose = jh.forward(model, q)
    a, b = np.asarray(pose.link_start), np.asarray(pose.link_end)
    s = np.linspace(0, 1, samples)
    pts = a[:, None] + s[None, :, None] * (b - a)[:, None]
    r = np.asarray(model.link_radius_mm)
    anc, lf = model.ancestors, model.link_frame
    gap = np.inf
    for i in range(model.n_links):
        for j in range(i + 1, model.n_links):
            if anc[lf[i], lf[j]] or anc[lf[j], lf[i]]:
                continue  # same chain: neighbours share their joint spheres
            d = np.linalg.norm(pts[i][:, None] - pts[j][None], axis=-1).min()
            gap = min(gap, d - r[i] - r[j])
    return gap


@pytest.mark.parametrize("name", preset_names())
def test_every_preset_builds_within_limits_and_renders(name):
    seq = make_preset(name, frames=9, size=SMALL)
    m = seq.model
    assert seq.n_frames == 9 and seq.q.shape == (9, m.n_q) and seq.size == SMALL
    assert np.all(np.diff(seq.times_s) > 0)
    for i, q in enumerate(seq.q):
        jh.validate_q(m, q, name=f"{name}[{i}]", within_limits=True)
        # no pills of different fingers pass through each other (grasps close to about 1 mm)
        assert _clearance(m, q) > 0.0
    if m.base_kind == "free":
        np.testing.assert_allclose(np.linalg.norm(seq.q[:, :4], axis=1), 1.0)
    w, h = SMALL
    for cam in seq.cameras:
        for i in (0, 4, 8):
            v = jh.project_pose(m, cam, seq.q[i])
            ends = np.concatenate([np.asarray(v.link_start_px), np.asarray(v.link_end_px)])
            assert np.all((ends >= 0) & (ends <= [w - 1, h - 1]))  # the cameras frame the whole motion
            res = render_frame(m, cam, seq.q[i])
            assert np.all(res.alone_px > 0)
            assert (res.link_id >= 0).mean() > 0.03
    assert len(seq.cameras) == (2 if name == "two_camera_hand" else 1)


def test_preset_motion_is_the_same_for_any_frame_count():
    a = make_preset("mouse3d", frames=11, size=SMALL)
    b = make_preset("mouse3d", frames=21, size=SMALL)
    np.testing.assert_allclose(a.q, b.q[::2], atol=1e-12)
    np.testing.assert_allclose(b.times_s[1], 0.1)  # DigitEyes: 100 ms per frame


def _links(model, finger):
    return [model.link_lookup(f"{finger}_{j}") for j in ("mcp", "pip", "dip")]


def test_two_finger_occlusion_index_covers_part_of_the_middle_finger():
    seq = make_preset("two_finger_occlusion", frames=13, size=(160, 120))
    m, cam = seq.model, seq.cameras[0]
    vis = np.array([render_frame(m, cam, q, RenderConfig(mode="binary")).visible_fraction for q in seq.q])
    middle, index = vis[:, _links(m, "middle")], vis[:, _links(m, "index")]
    assert middle.min() < 0.3  # some part of the middle finger gets well covered
    assert np.all(middle.max(axis=1) > 0.4)  # but never the whole finger
    assert np.ptp(middle, axis=0).min() > 0.2  # and the covered part changes along the sequence
    assert index.min() > middle.min()  # the index is in front
    # a 45-degree tilt about the image's horizontal axis
    np.testing.assert_allclose(np.asarray(cam.R)[1:, 1:], np.sqrt(0.5) * np.array([[1, -1], [1, 1]]), atol=1e-12)


def test_full_hand_spread_flex_follows_the_thesis_description():
    seq = make_preset("full_hand_spread_flex", frames=25, size=SMALL)
    m = seq.model
    deg = np.degrees(seq.q)
    col = {n: deg[:, m.q_lookup(n)] for n in m.q_names}
    for n in m.q_names:
        if n.startswith("thumb"):
            assert np.ptp(col[n]) == 0.0  # the thumb stays still
    for f in ("little", "ring", "middle", "index"):
        np.testing.assert_allclose(col[f"{f}_pip"], col[f"{f}_dip"])  # PIP = DIP (thesis Fig. 6.6)
        assert col[f"{f}_abd"][12] > col[f"{f}_abd"][0]  # the fingers spread first
    assert col["little_mcp"][-1] >= 30 and col["index_mcp"][-1] <= -50  # little hyper-extends, index flexes
    final = [col[f"{f}_mcp"][-1] for f in ("little", "ring", "middle", "index")]
    assert np.all(np.diff(final) < 0)  # ring and middle in between


def test_make_preset_errors():
    with pytest.raises(jh.InputError, match="unknown preset 'nope'; valid presets: two_finger_occlusion, "):
        make_preset("nope")
    with pytest.raises(jh.InputError, match="frames"):
        make_preset("mouse3d", frames=1)
    with pytest.raises(jh.InputError, match="WxH"):
        make_preset("mouse3d", size="320by240")
    with pytest.raises(jh.InputError, match="8..8192"):
        make_preset("mouse3d", size=(0, 240))


# ---- folders ----

def test_write_then_load_round_trip(tmp_path):
    seq = make_preset("two_camera_hand", frames=3, size=SMALL)
    gt_path = write_sequence(seq, tmp_path / "out", RenderConfig(noise_sigma=2.0), maps=True)
    folder = load_sequence(tmp_path / "out")
    assert folder.complete and folder.name == "two_camera_hand" and folder.n_frames == 3
    np.testing.assert_allclose(folder.q, seq.q, atol=1e-12)
    np.testing.assert_allclose(folder.times_s, seq.times_s)
    assert folder.model.structure() == seq.model.structure()
    for c, cam in enumerate(seq.cameras):
        np.testing.assert_allclose(folder.cameras[c].K, cam.K)
        np.testing.assert_allclose(folder.cameras[c].R, cam.R)
        assert folder.image_paths[c][2] == tmp_path / "out" / f"cam{c}" / "frame_0002.png"
        res = render_frame(seq.model, cam, seq.q[2], RenderConfig(noise_sigma=2.0), frame_index=2)
        np.testing.assert_array_equal(folder.image(2, c), res.image)
        np.testing.assert_allclose(folder.visible_fraction[2, c], res.visible_fraction)
        maps = np.load(tmp_path / "out" / f"cam{c}" / "maps_0002.npz")
        np.testing.assert_array_equal(maps["link_id"], res.link_id)
    gt = json.loads(gt_path.read_text())
    rec = gt["frames"][1]
    assert rec["q"]["index_mcp"] == pytest.approx(np.degrees(seq.q[1, seq.model.q_lookup("index_mcp")]))
    v = jh.project_pose(seq.model, seq.cameras[1], seq.q[1])
    tip = seq.model.tip_names.index("index_dip")
    np.testing.assert_allclose(rec["views"][1]["tips"]["index_dip"]["px"], v.tips_px[tip], atol=1e-5)
    k = seq.model.frame_lookup("index_pip")
    np.testing.assert_allclose(rec["views"][1]["joints"]["index_pip"]["px"], v.joints_px[k], atol=1e-5)
    assert gt["q_units"][:5] == ["1", "1", "1", "1", "mm"] and gt["q_units"][-1] == "deg"
    assert jh.load_camera(tmp_path / "out" / "cameras.json")[1].size == SMALL
    assert not (tmp_path / "out" / "ground_truth.partial.jsonl").exists()


def test_an_interrupted_run_keeps_its_frames(tmp_path, monkeypatch):
    import jaxhand.render._io as io

    seq = make_preset("index_thumb_grasp", frames=5, size=SMALL)
    real = io.render_frame

    def failing(model, camera, q, config, *, frame_index):
        if frame_index == 3:
            raise RuntimeError("power cut")
        return real(model, camera, q, config, frame_index=frame_index)

    monkeypatch.setattr(io, "render_frame", failing)
    with pytest.raises(RuntimeError, match="power cut"):
        write_sequence(seq, tmp_path / "out")
    folder = load_sequence(tmp_path / "out")
    assert not folder.complete and folder.n_frames == 3
    np.testing.assert_allclose(folder.q, seq.q[:3], atol=1e-12)
    assert all(p.is_file() for p in folder.image_paths[0])


def test_folder_errors(tmp_path):
    seq = make_preset("mouse3d", frames=2, size=SMALL)
    write_sequence(seq, tmp_path / "out")
    with pytest.raises(jh.InputError, match="not empty: choose another folder or overwrite"):
        write_sequence(seq, tmp_path / "out")
    write_sequence(make_preset("mouse3d", frames=2, size=SMALL), tmp_path / "out", overwrite=True)
    with pytest.raises(jh.InputError, match="not a folder"):
        load_sequence(tmp_path / "missing")
    (tmp_path / "empty").mkdir()
    with pytest.raises(jh.InputError, match="no ground_truth.json"):
        load_sequence(tmp_path / "empty")
    (tmp_path / "out" / "ground_truth.json").write_text('{"format": "other"}')
    with pytest.raises(jh.InputError, match="'format' must be 'jaxhand-synth'"):
        load_sequence(tmp_path / "out")


# ---- command line ----

def test_cli_synth_writes_the_expected_files(tmp_path, capsys):
    out = tmp_path / "two"
    rc = main(["synth", "two_camera_hand", str(out), "--frames", "2", "--size", "64x48", "--binary", "--maps"])
    assert rc == 0
    for c in (0, 1):
        for i in (0, 1):
            img = cv2.imread(str(out / f"cam{c}" / f"frame_{i:04d}.png"), cv2.IMREAD_UNCHANGED)
            assert img.shape == (48, 64) and img.dtype == np.uint8 and set(np.unique(img)) <= {0, 255}
            assert (out / f"cam{c}" / f"maps_{i:04d}.npz").is_file()
        assert jh.load_camera(out / f"cam{c}" / "camera.json")[0].size == (64, 48)
    for name in ("cameras.json", "ground_truth.json", "README.md", "model.json"):
        assert (out / name).is_file()
    assert "ground_truth.json" in (out / "README.md").read_text()
    assert "2 frames x 2 camera(s)" in capsys.readouterr().out
    one = tmp_path / "one"
    assert main(["synth", "mouse3d", str(one), "--frames", "2", "--size", "40x30", "--noise", "3",
                 "--background", "constant:60"]) == 0
    assert (one / "frame_0001.png").is_file() and (one / "camera.json").is_file()
    assert load_sequence(one).ground_truth["render"]["noise_sigma"] == 3.0


@pytest.mark.parametrize("args,message", [
    (["nope"], "unknown preset 'nope'; valid presets: two_finger_occlusion, full_hand_spread_flex"),
    (["mouse3d", "--size", "64by48"], "--size: expected WxH"),
    (["mouse3d", "--background", "no/such/file.png"], "--background: .*existing image file"),
    (["mouse3d", "--frames", "1"], "--frames: expected an integer >= 2"),
    (["mouse3d", "--noise", "-2"], "--noise: expected a value >= 0"),
])
def test_cli_synth_bad_input(tmp_path, capsys, args, message):
    argv = ["synth", args[0], str(tmp_path / "o"), *args[1:]]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("jaxhand synth: error:")
    assert len(err.strip().splitlines()) == 1
    import re

    assert re.search(message, err)
    assert not (tmp_path / "o").exists()  # nothing written on bad input


def test_cli_synth_interrupted_keeps_a_consistent_folder_and_resumes(tmp_path, capsys, monkeypatch):
    import jaxhand.render._io as io_mod

    out, ref = tmp_path / "cut", tmp_path / "ref"
    argv = ["synth", "two_finger_occlusion", "--frames", "6", "--size", "48x36", "--binary"]
    assert main([*argv[:2], str(ref), *argv[2:]]) == 0
    real = io_mod.render_frame
    calls = []

    def render_then_stop(model, cam, q, config, frame_index=0):   # Ctrl-C while frame 3 is written
        calls.append(frame_index)
        res = real(model, cam, q, config, frame_index=frame_index)
        if frame_index == 3:
            io_mod._write_png(out / "frame_0003.png", res.image)   # its image is on disk already
            raise KeyboardInterrupt
        return res

    monkeypatch.setattr(io_mod, "render_frame", render_then_stop)
    assert main([*argv[:2], str(out), *argv[2:]]) == 130
    assert "interrupted; the finished frames in" in capsys.readouterr().err
    assert sorted(p.name for p in out.glob("frame_*.png")) == [f"frame_{i:04d}.png" for i in range(3)]
    assert load_sequence(out).q.shape[0] == 3 and not load_sequence(out).complete
    monkeypatch.setattr(io_mod, "render_frame", real)
    assert main([*argv[:2], str(out), *argv[2:]]) == 2
    assert "holds an interrupted run (3 of 6 frames)" in capsys.readouterr().err
    assert main([*argv[:2], str(out), *argv[2:], "--frames", "7", "--resume"]) == 2
    assert "cannot resume: the interrupted run had other settings (cameras, n_frames)" in capsys.readouterr().err
    assert main([*argv[:2], str(out), *argv[2:], "--resume"]) == 0
    assert (out / "ground_truth.json").read_text() == (ref / "ground_truth.json").read_text()
    for i in range(6):
        assert (out / f"frame_{i:04d}.png").read_bytes() == (ref / f"frame_{i:04d}.png").read_bytes()
    assert main([*argv[:2], str(out), *argv[2:], "--resume"]) == 2
    assert "nothing to resume (it is complete)" in capsys.readouterr().err
