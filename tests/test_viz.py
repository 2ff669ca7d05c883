import cv2
import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import fit_camera

import jaxhand as jh
from jaxhand.viz import VideoWriter, draw_view, joint_groups, plot_joint_angles


def test_joint_groups_by_digit():
    g = joint_groups(jh.builtin_model("hand27"))
    assert list(g) == ["palm", "little", "ring", "middle", "index", "thumb"]
    assert len(g["palm"]) == 7 and len(g["thumb"]) == 5


def test_plot_joint_angles_writes_a_figure(tmp_path):
    m = jh.builtin_model("two_fingers")
    t = np.linspace(0, 1, 20)
    q = np.outer(np.sin(t), np.ones(m.n_q)) * -0.5
    path = plot_joint_angles(m, t, q, tmp_path / "angles.png", q_truth=q + 0.01, q_raw=q - 0.01)
    img = cv2.imread(str(path))
    assert img.shape[0] > 300 and img.shape[1] > 600 and img.std() > 10


def test_draw_view_marks_link_pixels():
    m = jh.builtin_model("index")
    cam = fit_camera(m, size=(80, 60))
    v = jh.project_pose(m, cam, m.q_default)
    img = draw_view(np.zeros((60, 80, 3), np.uint8), v, (0, 0, 255))
    mid = np.round(0.5 * (np.asarray(v.link_start_px[1]) + np.asarray(v.link_end_px[1]))).astype(int)
    assert img[mid[1], mid[0], 2] > 100


def test_video_writer_round_trip(tmp_path):
    with VideoWriter(tmp_path / "o.mp4", 10, (32, 24)) as w:
        for i in range(4):
            w.write(np.full((24, 32, 3), 60 * i, np.uint8))
    cap = cv2.VideoCapture(str(tmp_path / "o.mp4"))
    assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == 4
    cap.release()
    with pytest.raises(jh.InputError, match="suffix must be .mp4 or .avi"):
        VideoWriter(tmp_path / "o.gif", 10, (32, 24))


def test_draw_view_skips_points_it_cannot_draw():
    # a link end at a perspective camera's plane projects to huge or non-finite pixels
    m = jh.builtin_model("two_fingers")
    cam = fit_camera(m)
    view = jh.project_pose(m, cam, np.zeros(m.n_q))
    far = view.link_end_px.at[0].set(jnp.array([3e9, jnp.nan]))
    w, h = cam.size
    image = draw_view(np.zeros((h, w, 3), np.uint8), eqx.tree_at(lambda v: v.link_end_px, view, far))
    clean = draw_view(np.zeros((h, w, 3), np.uint8), view)
    assert image.any() and image.sum() < clean.sum()   # the other links drawn, the bad one left out
