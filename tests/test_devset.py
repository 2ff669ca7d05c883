"""The dev-set loader: model, cameras, frame paths, truth in the model's q order."""

import json
from pathlib import Path

import jax
import numpy as np
import pytest

import jaxhand as jh
from jaxhand.io import load_devset, load_truth, open_frames
from jaxhand.kinematics import pose

DEVSET = Path(__file__).resolve().parents[1] / "data" / "mujoco"
HELDOUT = DEVSET.with_name("mujoco_heldout")   # its twin, rendered after the settings were chosen
FRAMES = {"open_close": 90, "index_over_middle": 90, "thumb_opposition": 120, "wave_two_cameras": 90,
          "open_close_noise_clutter": 90, "fast_spread": 45}


@pytest.mark.parametrize("root", [DEVSET, HELDOUT], ids=["devset", "heldout"])
@pytest.mark.parametrize("name", list(FRAMES))
def test_load_devset_every_sequence(root, name):
    seq = load_devset(root / name)
    t = seq.truth
    n, cams = FRAMES[name], 2 if name == "wave_two_cameras" else 1
    assert seq.name == name and seq.fps == 30.0 and seq.n_frames == n and len(seq.cameras) == cams
    assert seq.model.name == "hand" and seq.model.handedness == "right" and t.q_names == seq.model.q_names
    assert t.q.shape == (n, 21) and t.points_px.shape == (cams, n, 21, 2) and t.points_world.shape == (n, 21, 3)
    assert t.point_visible.shape == (cams, n, 21) and t.point_visible.dtype == bool
    assert t.edge_visible.shape == (cams, n, 15, 2) and t.visible_fraction_excl_adjacent.shape == (cams, n, 15)
    np.testing.assert_allclose(t.time_s, np.arange(n) / 30.0, atol=1e-6)  # written with 6 decimals
    raw = json.loads((root / name / "truth.json").read_text())
    for i in (0, n // 2, n - 1):
        for j, q_name in enumerate(seq.model.q_names):
            assert t.q[i, j] == raw["frames"][i]["joint_angles"][q_name]
    assert all(p.is_file() for paths in seq.image_paths for p in paths) and len(seq.image_paths[0]) == n
    assert [p.name for p in seq.image_paths[-1][:2]] == ["000.png", "001.png"]
    # The cameras are in jaxhand's pixel convention: they map the truth's camera-frame points
    # (rounded to 1e-4 mm) onto its pixels (rounded to 1e-3 px).
    for c, cam in enumerate(seq.cameras):
        p_world = (t.points_cam[c] - np.asarray(cam.t)) @ np.asarray(cam.R)
        np.testing.assert_allclose(np.asarray(cam.project(p_world)[0]), t.points_px[c], atol=1e-3)
        assert cam.size == (320, 240)


@pytest.mark.parametrize("name", list(FRAMES))
def test_heldout_twin_has_its_own_view_and_motion(name):
    dev, held = load_devset(DEVSET / name), load_devset(HELDOUT / name)
    assert held.model.q_names == dev.model.q_names and held.n_frames == dev.n_frames
    for a, b in zip(dev.cameras, held.cameras):   # another view: rotations at least 5 deg apart
        angle = np.degrees(np.arccos(np.clip((np.trace(np.asarray(a.R).T @ np.asarray(b.R)) - 1) / 2, -1, 1)))
        assert angle > 5.0
    assert np.max(np.abs(held.truth.q - dev.truth.q)) > np.radians(10.0)   # another motion


def test_devset_model_tips_land_on_the_truth_tips():
    seq = load_devset(DEVSET / "wave_two_cameras")
    t, m = seq.truth, seq.model
    tips = jax.vmap(lambda q: pose(m, q))(t.q).tips
    idx = t.tip_points(m)
    assert [t.point_names[i] for i in idx] == ["thumb_tip", "index_tip", "middle_tip", "ring_tip", "little_tip"]
    for c, cam in enumerate(seq.cameras):
        np.testing.assert_allclose(np.asarray(cam.project(tips)[0]), t.points_px[c][:, idx], atol=1e-3)


def test_devset_frames_open_with_open_frames():
    seq = load_devset(DEVSET / "fast_spread")
    (source,) = open_frames(seq.frame_folders[0], fps=seq.fps)
    assert len(source) == seq.n_frames
    first = next(iter(source))
    assert first.image.shape == (240, 320) and first.image.dtype == np.uint8


def test_load_truth_without_model_and_with_another_model():
    t = load_truth(DEVSET / "open_close" / "truth.json")
    assert t.q_names == t.joint_names and t.q.shape == (90, 21) and t.sequence == "open_close"
    assert load_truth(DEVSET / "open_close").n_frames == 90  # the folder works too
    with pytest.raises(jh.InputError, match=r"truth.json: model 'hand21' has joints the truth does not: little_abd"):
        load_truth(DEVSET / "open_close" / "truth.json", jh.builtin_model("hand21"))
    seq = load_devset(DEVSET / "open_close", model=DEVSET / "models" / "hand.xml")
    assert seq.model.handedness == "none" and seq.truth.q.shape == (90, 21)


def test_load_truth_errors_name_the_file(tmp_path):
    with pytest.raises(jh.InputError, match=r"missing.json: cannot read truth file"):
        load_truth(tmp_path / "missing.json")
    bad = tmp_path / "truth.json"
    bad.write_text("{")
    with pytest.raises(jh.InputError, match=r"truth.json: cannot parse"):
        load_truth(bad)
    raw = json.loads((DEVSET / "fast_spread" / "truth.json").read_text())
    del raw["fps"]
    bad.write_text(json.dumps(raw))
    with pytest.raises(jh.InputError, match=r"truth.json: missing field 'fps'"):
        load_truth(bad)
    raw["fps"] = 30
    raw["cameras"][0]["convention"] = "(0, 0) at the top-left corner"
    bad.write_text(json.dumps(raw))
    with pytest.raises(jh.InputError, match=r"unsupported pixel convention"):
        load_truth(bad)
    del raw["model"]
    (tmp_path / "seq").mkdir()
    (tmp_path / "seq" / "truth.json").write_text(json.dumps(raw))
    with pytest.raises(jh.InputError, match=r"field 'model'"):
        load_devset(tmp_path / "seq")
