"""`jaxhand track` on bad input, faults and interruptions (issue 15): one line, exit 2, nothing lost."""

import errno
import json
import os
import warnings

import cv2
import numpy as np
import pytest
from helpers import blank_frames, fit_camera, oracle, stopping_oracle

import jaxhand as jh
from jaxhand.cli import main
from jaxhand.cli_track import load_truth_arg
from jaxhand.io import FrameSource, ResultWriter, read_angles_csv
from jaxhand.render import make_preset, render_frame
from jaxhand.track import ExactFrontEnd, track_sequence
from jaxhand.track._sequence import _check_background, _check_fit

SIZE = (160, 120)


def _one_line_error(capsys, command: str = "track") -> str:
    err = capsys.readouterr().err
    assert err.startswith(f"jaxhand {command}: error: ") and err.count("\n") == 1, err
    return err


@pytest.fixture(scope="module")
def index_input(tmp_path_factory):
    """Four rendered frames of the index model, its camera file and its model file."""
    root = tmp_path_factory.mktemp("index")
    model = jh.builtin_model("index")
    cam = fit_camera(model, size=SIZE)
    (root / "frames").mkdir()
    for k in range(4):
        cv2.imwrite(str(root / "frames" / f"f{k}.png"), render_frame(model, cam, model.q_default).image)
    jh.save_camera(cam, root / "cam.json")
    jh.save_model(model, root / "index.toml")
    return root


def _track(root, *extra):
    return ["track", str(root / "frames"), "--camera", str(root / "cam.json"), *extra]


def _model_variant(root, tmp_path, edit) -> str:
    lines = (root / "index.toml").read_text().splitlines()
    path = tmp_path / "variant.toml"
    path.write_text("\n".join(edit(lines)) + "\n")
    return str(path)


def test_model_without_pills_or_moving_joints(index_input, tmp_path, capsys):
    no_pills = _model_variant(index_input, tmp_path, lambda ls: [ln for ln in ls if not ln.startswith("link = ")])
    assert main(_track(index_input, "--model", no_pills, "--out", str(tmp_path / "o1"))) == 2
    assert "has no link pills" in _one_line_error(capsys)

    def fix_joints(ls):
        return [("joint = \"fixed\"" if ln.startswith("joint = ") else ln) for ln in ls
                if not ln.startswith(("limits = ", "default = "))]

    assert main(_track(index_input, "--model", _model_variant(index_input, tmp_path, fix_joints),
                       "--out", str(tmp_path / "o2"))) == 2
    assert "has no moving joint" in _one_line_error(capsys)


def test_out_is_a_file_under_a_file_or_not_writable(index_input, tmp_path, capsys):
    (tmp_path / "f").write_text("x")
    assert main(_track(index_input, "--model", "index", "--out", str(tmp_path / "f"))) == 2
    assert f"--out {tmp_path / 'f'}: exists and is a file" in _one_line_error(capsys)
    assert main(_track(index_input, "--model", "index", "--out", str(tmp_path / "f" / "sub"))) == 2
    assert "lies under a file" in _one_line_error(capsys)
    if os.geteuid() != 0:   # root writes anywhere
        (tmp_path / "ro").mkdir(mode=0o500)
        assert main(_track(index_input, "--model", "index", "--out", str(tmp_path / "ro"))) == 2
        assert "not writable" in _one_line_error(capsys)


def test_max_frames_and_truth_arguments(index_input, tmp_path, capsys):
    out = str(tmp_path / "o")
    assert main(_track(index_input, "--model", "index", "--out", out, "--max-frames", "-5")) == 2
    assert "--max-frames: expected a count >= 1, got -5" in _one_line_error(capsys)
    assert main(_track(index_input, "--model", "index", "--out", out, "--truth", str(tmp_path / "nope.json"))) == 2
    assert f"--truth {tmp_path / 'nope.json'}: no such file or folder" in _one_line_error(capsys)
    # a synth folder of another model, and one shorter than the input
    assert main(["synth", "two_finger_occlusion", str(tmp_path / "s"), "--frames", "2", "--size", "80x60"]) == 0
    capsys.readouterr()
    assert main(_track(index_input, "--model", "index", "--out", out, "--truth", str(tmp_path / "s"))) == 2
    err = _one_line_error(capsys)
    assert "the truth of model 'two_fingers'" in err and "the tracked model is 'index'" in err
    assert main(_track(index_input, "--model", "two_fingers", "--out", out, "--truth",
                       str(tmp_path / "s" / "ground_truth.json"))) == 2
    assert "has 2 frame(s) but the input has 4" in _one_line_error(capsys)


def test_truth_in_the_dev_set_format():
    model = jh.io.load_devset("data/mujoco/open_close").model
    q = load_truth_arg("data/mujoco/open_close/truth.json", model)
    assert q.shape == (90, model.n_q)
    np.testing.assert_allclose(load_truth_arg("data/mujoco/open_close", model), q)
    with pytest.raises(jh.InputError, match=r"--truth: .*model 'index' has joints the truth does not: index_mcp"):
        load_truth_arg("data/mujoco/open_close/truth.json", jh.builtin_model("index"))


def test_frame_size_is_checked_against_the_camera(index_input, tmp_path, capsys):
    jh.save_camera(fit_camera(jh.builtin_model("index"), size=(320, 240)), tmp_path / "big.json")
    assert main(["track", str(index_input / "frames"), "--camera", str(tmp_path / "big.json"), "--model", "index",
                 "--out", str(tmp_path / "o")]) == 2
    assert "is 160x120 px but the camera's image size is 320x240" in _one_line_error(capsys)


def test_perspective_camera_behind_or_around_the_hand(index_input, tmp_path, capsys):
    model = jh.builtin_model("index")
    centre = np.asarray(jh.forward(model, model.q_default).link_end).mean(0)
    behind = jh.Perspective.look_at(eye_mm=centre + [0, 0, 400], target_mm=centre + [0, 0, 800], size=SIZE)
    jh.save_camera(behind, tmp_path / "behind.json")
    assert main(["track", str(index_input / "frames"), "--camera", str(tmp_path / "behind.json"), "--model",
                 "index", "--out", str(tmp_path / "o")]) == 2
    err = _one_line_error(capsys)
    assert "camera 0 (perspective): the hand at the initial pose lies behind the camera" in err
    assert "check the camera's R and t" in err
    inside = jh.Perspective.look_at(eye_mm=centre + [0, 0, 2], target_mm=centre, size=SIZE)
    jh.save_camera(inside, tmp_path / "inside.json")
    assert main(["track", str(index_input / "frames"), "--camera", str(tmp_path / "inside.json"), "--model",
                 "index", "--out", str(tmp_path / "o")]) == 2
    assert "lies around the camera" in _one_line_error(capsys)


def test_skin_foreground_reads_colour_frames(index_input, tmp_path, capsys):
    """'skin' on grey frames is one line naming the way out; on the same frames tinted a skin
    colour the CLI opens them in colour and tracks."""
    out = str(tmp_path / "o")
    assert main(_track(index_input, "--model", "index", "--out", out, "--foreground", "skin")) == 2
    assert "'skin' reads colour, but the frames are grey" in _one_line_error(capsys)
    assert not any((tmp_path / "o").glob("*"))   # failed before any output
    tinted = tmp_path / "tinted"
    tinted.mkdir()
    for f in sorted((index_input / "frames").iterdir()):
        grey = cv2.imread(str(f), cv2.IMREAD_GRAYSCALE).astype(float)[..., None] / 255.0
        cv2.imwrite(str(tinted / f.name), np.rint(grey * np.array([120.0, 150.0, 210.0])).astype(np.uint8))
    args = ["track", str(tinted), "--camera", str(index_input / "cam.json"), "--model", "index", "--out", out,
            "--foreground", "skin", "--max-frames", "2", "--no-video"]
    assert main(args) == 0
    assert json.loads((tmp_path / "o" / "summary.json").read_text())["frames"] == 2


def test_masks_replace_the_foreground_model(index_input, tmp_path, capsys):
    """--masks: the robust preset's silhouette term and support read the given masks. On the
    frames' own silhouettes the still finger stays at its pose; on the same masks moved 20 px it
    is pulled off it. A folder with a mask short, or settings that read no foreground, are one
    line each."""
    moved = {}
    for shift in (0, 20):
        folder = tmp_path / f"masks{shift}"
        folder.mkdir()
        for f in sorted((index_input / "frames").iterdir()):
            m = cv2.imread(str(f), cv2.IMREAD_GRAYSCALE) > 0
            cv2.imwrite(str(folder / f.name), np.roll(m, shift, axis=1).astype(np.uint8) * 255)
        out = tmp_path / f"o{shift}"
        assert main(_track(index_input, "--model", "index", "--out", str(out), "--preset", "robust", "--masks",
                           str(folder), "--max-frames", "2", "--no-video")) == 0
        q = np.load(out / "results.npz")["q"]
        moved[shift] = float(np.degrees(np.abs(q - jh.builtin_model("index").q_default).max()))
    assert moved[0] < 2.0 and moved[20] > 10.0, moved   # 0.2 and 33 deg
    (tmp_path / "masks0" / "f3.png").unlink()
    assert main(_track(index_input, "--model", "index", "--out", str(tmp_path / "o"), "--foreground", "auto",
                       "--masks", str(tmp_path / "masks0"))) == 2
    assert "--masks " in (err := _one_line_error(capsys)) and "3 mask(s) for 4 frame(s)" in err
    assert main(_track(index_input, "--model", "index", "--out", str(tmp_path / "o"), "--masks",
                       str(tmp_path / "masks20"))) == 2
    assert "--masks: these settings read no foreground" in _one_line_error(capsys)
    assert main(_track(index_input, "--model", "index", "--out", str(tmp_path / "o"), "--preset", "robust",
                       "--masks", str(tmp_path / "masks20"), "--masks", str(tmp_path / "masks20"))) == 2
    assert "--masks: 2 folder(s) for 1 camera(s): give one per camera" in _one_line_error(capsys)


def test_mask_rim_auto_measures_an_eroded_mask(index_input, tmp_path, capsys):
    """--mask-rim auto: masks eroded by 2 px are measured about 2 px short at the initial pose and
    summary.json says so; a word other than 'auto' is one line."""
    folder = tmp_path / "eroded"
    folder.mkdir()
    for f in sorted((index_input / "frames").iterdir()):
        m = (cv2.imread(str(f), cv2.IMREAD_GRAYSCALE) > 0).astype(np.uint8) * 255
        cv2.imwrite(str(folder / f.name), cv2.erode(m, cv2.getStructuringElement(cv2.MORPH_CROSS, (3, 3)),
                                                    iterations=2))
    out = tmp_path / "o"
    assert main(_track(index_input, "--model", "index", "--out", str(out), "--preset", "robust", "--masks",
                       str(folder), "--mask-rim", "auto", "--max-frames", "2", "--no-video")) == 0
    summary = json.loads((out / "summary.json").read_text())
    (rim,) = summary["silhouette_rim_px_measured"]
    assert 1.5 < rim < 2.5, rim
    assert summary["config"]["image"]["silhouette_term"]["rim_px"] == "auto"
    assert main(_track(index_input, "--model", "index", "--out", str(out), "--preset", "robust", "--masks",
                       str(folder), "--mask-rim", "wide", "--overwrite")) == 2
    assert "--mask-rim: expected a number of px or 'auto', got 'wide'" in _one_line_error(capsys)


def test_flags_are_named_in_config_errors(index_input, tmp_path, capsys):
    out = str(tmp_path / "o")
    for flags, want in ((["--steps", "0"], "--steps: expected an integer >= 1, got 0"),
                        (["--theta-rate", "-1"], "--theta-rate: must be > 0 Hz (or 0: per frame), got -1.0"),
                        (["--theta", "2"], "--theta: must lie in [0, 1], got 2.0"),
                        (["--method", "edgy"], "--method: unknown search 'edgy'; valid: derivative"),
                        (["--width-gain", "-1"], "--width-gain: must lie in [0, 1], got -1.0"),
                        (["--solver", "gn2"], "--solver: unknown solver 'gn2'; valid solvers: gn"),
                        (["--reacquire", "-5"], "--reacquire: angles must lie in (0, 90] degrees"),
                        (["--init", "1,2"], "--init: expected 3 values for 'index'")):
        assert main(_track(index_input, "--model", "index", "--out", out, *flags)) == 2, flags
        err = _one_line_error(capsys)
        assert want in err, (want, err)
        assert "ImageConfig" not in err and "max_steps" not in err and "theta_rate_hz" not in err


def test_help_lists_searches_solvers_and_demo_presets(capsys):
    with pytest.raises(SystemExit):
        main(["track", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert all(name in text for name in jh.image.SEARCH_NAMES) and "--resume" in text and "--overwrite" in text
    assert "gn | gn_eta | lm_fixed | lm | bounded (default: bounded)" in text
    with pytest.raises(SystemExit):
        main(["demo", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "Render a synthetic sequence" in text
    assert all(name in text for name in jh.render.preset_names())


def test_cameras_in_the_wrong_order_are_warned_about(tmp_path):
    model = jh.builtin_model("index")
    a = fit_camera(model, size=SIZE)
    # b: the view turned by 90 deg about its axis, the hand kept in the middle of the image
    pts = np.concatenate([jh.forward(model, model.q_default).link_start, jh.forward(model, model.q_default).link_end])
    b = jh.Orthographic(R=np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]]) @ np.asarray(a.R), t=a.t,
                        scale=a.scale * 0.8, center=a.center, size=SIZE)
    shift = np.asarray(a.project(pts)[0]).mean(0) - np.asarray(b.project(pts)[0]).mean(0)
    b = jh.Orthographic(R=b.R, t=b.t, scale=b.scale, center=np.asarray(a.center) + shift, size=SIZE)
    for name, cam in (("a", a), ("b", b)):
        (tmp_path / name).mkdir()
        cv2.imwrite(str(tmp_path / name / "f0.png"), render_frame(model, cam, model.q_default).image)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        _check_fit(model, (a, b), [FrameSource(tmp_path / "a"), FrameSource(tmp_path / "b")], model.q_default)
    with pytest.warns(jh.JaxhandWarning) as caught:
        _check_fit(model, (a, b), [FrameSource(tmp_path / "b"), FrameSource(tmp_path / "a")], model.q_default)
    text = [str(w.message) for w in caught]
    assert len(text) == 2 and "camera 0: only 20% " in text[0] and "fits input 1's frame better (100%)" in text[0]
    assert "are the inputs in the order of the cameras?" in text[1]
    # a dark hand on a lit background (a real room): the check knows dark backgrounds only
    for name in ("a", "b"):
        image = cv2.imread(str(tmp_path / name / "f0.png"), cv2.IMREAD_GRAYSCALE)
        cv2.imwrite(str(tmp_path / name / "f0.png"), 255 - image)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        _check_fit(model, (a, b), [FrameSource(tmp_path / "b"), FrameSource(tmp_path / "a")], model.q_default)


def test_the_edge_tracker_on_a_bright_background_points_to_the_robust_preset(tmp_path):
    """The defaults read no foreground; on a first frame whose background is not dark they warn
    once and name the preset; a dark scene, or settings that read a foreground, say nothing."""
    model = jh.builtin_model("index")
    cam = fit_camera(model, size=SIZE)
    image = render_frame(model, cam, model.q_default).image
    (tmp_path / "dark").mkdir()
    (tmp_path / "lit").mkdir()
    cv2.imwrite(str(tmp_path / "dark" / "f0.png"), image)
    cv2.imwrite(str(tmp_path / "lit" / "f0.png"), 255 - image)   # a dark hand before a lit wall
    defaults, robust = jh.TrackConfig(), jh.TrackConfig().preset("robust-temporal")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        _check_background(defaults, [FrameSource(tmp_path / "dark")])
        _check_background(robust, [FrameSource(tmp_path / "lit")])
    with pytest.warns(jh.JaxhandWarning) as caught:
        _check_background(defaults, [FrameSource(tmp_path / "lit")])
    assert len(caught) == 1
    text = str(caught[0].message)
    assert text.startswith("input 0: the first frame's background is not dark (its darker half averages grey 95)")
    assert "use --preset robust-temporal" in text


# ---- runs that stop: interrupt, resume, full disk, earlier runs -----------------------------------

@pytest.fixture(scope="module")
def seq():
    return make_preset("two_finger_occlusion", frames=12, size=SIZE)


@pytest.fixture
def frames_dir(tmp_path, seq):
    return blank_frames(tmp_path / "frames", seq.n_frames, SIZE)


def test_interrupted_run_says_so_and_resumes(tmp_path, seq, frames_dir):
    out = tmp_path / "out"
    with pytest.raises(KeyboardInterrupt, match=r"stopped at frame 6; the 6 finished frame\(s\) in .* --resume"):
        track_sequence(seq.model, seq.cameras, [FrameSource(frames_dir)], seq.q[0], out, stopping_oracle(seq, 6),
                       truth=seq.q, video=True)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["interrupted"] is True and summary["interrupted_at_frame"] == 6 and summary["frames"] == 6
    assert list(read_angles_csv(out / "angles.csv")["frame"]) == [0, 1, 2, 3, 4, 5]
    assert len(np.load(out / "results.npz")["frame"]) == 6
    assert cv2.VideoCapture(str(out / "overlay.mp4")).get(cv2.CAP_PROP_FRAME_COUNT) == 6   # closed: readable
    # an earlier run is not mixed with a new one
    with pytest.raises(jh.OutputExistsError, match="holds an earlier tracking run"):
        track_sequence(seq.model, seq.cameras, [FrameSource(frames_dir)], seq.q[0], out,
                       oracle(seq.model, seq.cameras, seq.q), video=False)
    summary = track_sequence(seq.model, seq.cameras, [FrameSource(frames_dir)], None, out,
                             oracle(seq.model, seq.cameras, seq.q), truth=seq.q, video=False, resume=True)
    assert summary["interrupted"] is False and summary["frames"] == 12
    assert summary["resumed"]["after_frame"] == 5 and "zero velocity" in summary["resumed"]["state"]
    assert summary["resumed"]["frames_this_run"] == 6
    cols = read_angles_csv(out / "angles.csv")
    assert list(cols["frame"]) == list(range(12))
    np.testing.assert_array_equal(np.load(out / "results.npz")["frame"], np.arange(12))
    # the restart at zero velocity costs a few degrees while the fingers move
    assert summary["accuracy_filtered"]["joint_error_deg"]["mean"] < 8.0
    # --overwrite replaces the run: its files first
    summary = track_sequence(seq.model, seq.cameras, [FrameSource(frames_dir)], seq.q[0], out,
                             oracle(seq.model, seq.cameras, seq.q), video=False, max_frames=3, overwrite=True)
    assert summary["frames"] == 3 and not (out / "overlay.mp4").exists()
    assert list(read_angles_csv(out / "angles.csv")["frame"]) == [0, 1, 2]


def test_full_disk_stops_with_one_message_and_keeps_the_frames(tmp_path, seq, frames_dir, monkeypatch):
    import jaxhand.io._results as results

    real = results._user_units

    def full(model, q):
        if len(calls) == 7:
            raise OSError(errno.ENOSPC, "No space left on device")
        calls.append(1)
        return real(model, q)

    calls: list = []
    monkeypatch.setattr(results, "_user_units", full)
    out = tmp_path / "out"
    with pytest.raises(jh.InputError, match=r"angles.csv: cannot write \(No space left on device\); the 7 finished "
                                            r"frames are kept; stopped at frame 7: make room and rerun with --resume"):
        track_sequence(seq.model, seq.cameras, [FrameSource(frames_dir)], seq.q[0], out,
                       oracle(seq.model, seq.cameras, seq.q), video=False)
    assert list(read_angles_csv(out / "angles.csv")["frame"]) == list(range(7))
    assert len(np.load(out / "results.npz")["frame"]) == 7
    assert json.loads((out / "summary.json").read_text())["interrupted_at_frame"] == 7
    assert not list(out.glob("*.tmp*"))


def test_cli_interrupt_is_one_line_and_resume_continues(tmp_path, capsys, monkeypatch):
    """SIGINT/SIGTERM (cli.main maps SIGTERM to KeyboardInterrupt) during `jaxhand track`."""
    assert main(["synth", "two_finger_occlusion", str(tmp_path / "s"), "--frames", "6", "--size", "80x60"]) == 0
    seq = jh.render.load_sequence(tmp_path / "s")
    exact = ExactFrontEnd(seq.model, seq.cameras, seq.q, noise_px=0.0)

    def extract(self, images, q, state, frame):
        if frame == 3 and not resumed:
            raise KeyboardInterrupt("terminated")
        return exact.extract(images, q, state, frame)

    resumed = False
    monkeypatch.setattr(jh.ImageFrontEnd, "extract", extract)
    monkeypatch.setattr(jh.ImageFrontEnd, "refresh", lambda self, images, q, state: state)
    args = ["track", str(tmp_path / "s"), "--out", str(tmp_path / "o"), "--no-video"]
    assert main(args) == 130
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "jaxhand track: interrupted; stopped at frame 3" in err and "--resume" in err
    assert main(args) == 2
    assert "holds an earlier tracking run" in _one_line_error(capsys)
    resumed = True
    assert main([*args, "--resume"]) == 0
    assert "resumed after frame 2" in capsys.readouterr().out
    assert list(read_angles_csv(tmp_path / "o" / "angles.csv")["frame"]) == list(range(6))


# ---- the writer alone ------------------------------------------------------------------------------

def test_writer_writes_atomically_and_leaves_no_temporary_file(tmp_path, monkeypatch):
    import jaxhand.io._results as results

    m = jh.builtin_model("index")
    w = ResultWriter(tmp_path, m, checkpoint_every=2)
    for k in range(2):
        w.write(k, k / 25, np.zeros(3), 1.0, False)
    before = (tmp_path / "results.npz").read_bytes()

    def savez(f, **arrays):
        f.write(b"half a file")
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(results.np, "savez", savez)
    w.write(2, 0.08, np.zeros(3), 1.0, False)
    with pytest.raises(jh.InputError, match=r"results.npz: cannot write \(No space left on device\); the 4 finished"):
        w.write(3, 0.12, np.zeros(3), 1.0, False)
    assert (tmp_path / "results.npz").read_bytes() == before and not list(tmp_path.glob("*.tmp*"))
    assert list(read_angles_csv(tmp_path / "angles.csv")["frame"]) == [0, 1, 2, 3]
    w._close_files()


def test_writer_refuses_an_earlier_run_and_resumes_it(tmp_path):
    m = jh.builtin_model("index")
    with ResultWriter(tmp_path, m, checkpoint_every=3) as w:
        for k in range(5):
            w.write(k, k / 25, np.full(3, -0.1 * k), 1.0, False, cost=float(k))
        w._csv_file.flush()
        # a crash here (no close): angles.csv holds 5 frames, results.npz the checkpoint of 3
        os.replace(tmp_path / "results.npz", tmp_path / "keep.npz")
    os.replace(tmp_path / "keep.npz", tmp_path / "results.npz")
    with pytest.raises(jh.OutputExistsError, match="holds an earlier tracking run"):
        ResultWriter(tmp_path, m)
    with pytest.raises(jh.InputError, match="tracked other joints"):
        ResultWriter(tmp_path, jh.builtin_model("two_fingers"), resume=True)
    w = ResultWriter(tmp_path, m, resume=True)
    assert w.last_frame == 2 and len(w) == 3
    np.testing.assert_allclose(w.last_q, np.full(3, -0.2))
    assert list(read_angles_csv(tmp_path / "angles.csv")["frame"]) == [0, 1, 2]   # cut to the checkpoint
    w.write(3, 0.12, np.zeros(3), 1.0, False, cost=3.0)
    w.close({})
    np.testing.assert_allclose(np.load(tmp_path / "results.npz")["cost"], [0, 1, 2, 3])
    assert list(read_angles_csv(tmp_path / "angles.csv")["frame"]) == [0, 1, 2, 3]
    with pytest.raises(jh.InputError, match="nothing to resume"):
        ResultWriter(tmp_path / "empty", m, resume=True)


@pytest.mark.slow
def test_track_a_dev_set_folder(tmp_path, capsys):
    assert main(["track", "data/mujoco/open_close", "--out", str(tmp_path / "o"), "--max-frames", "3",
                 "--no-video"]) == 0
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summary["frames"] == 3 and summary["fps_input"] == 30.0 and "accuracy_filtered" in summary
    assert summary["accuracy_filtered"]["joint_error_deg"]["mean"] < 5.0


@pytest.mark.slow
def test_track_a_dev_set_folder_with_the_robust_preset(tmp_path):
    assert main(["track", "data/mujoco/fast_spread", "--out", str(tmp_path / "o"), "--max-frames", "4",
                 "--no-video", "--preset", "robust", "--steps", "15"]) == 0
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    config = summary["config"]
    assert config["image"]["silhouette_term"]["weight"] == 0.5 and config["hypotheses"]["rest"] is True
    assert config["fit"]["max_steps"] == 15   # a flag still overrides the preset
    assert summary["accuracy_filtered"]["joint_error_deg"]["mean"] < 3.0
