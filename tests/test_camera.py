import json

import cv2
import jax.numpy as jnp
import numpy as np
import pytest

import jaxhand as jh
from jaxhand.camera import look_at_rotation


def _perspective():
    return jh.Perspective.look_at([100.0, -50.0, -400.0], [0.0, 0.0, 0.0], size=(320, 240), fov_deg=50)


def test_point_on_the_optical_axis_projects_to_the_principal_point():
    cam = _perspective()
    centre = -np.asarray(cam.R).T @ np.asarray(cam.t)
    pix, depth = cam.project(jnp.asarray(centre + 250.0 * np.asarray(cam.R)[2]))
    np.testing.assert_allclose(pix, [159.5, 119.5], atol=1e-9)
    np.testing.assert_allclose(depth, 250.0, atol=1e-9)


@pytest.mark.parametrize("cam", [_perspective(), jh.Orthographic(R=look_at_rotation([1, 1, -3], [0, 0, 0]),
                                                                 t=[1.0, 2.0, 300.0], scale=2.5,
                                                                 center=[160.0, 120.0], size=(320, 240))])
def test_project_unproject_agree(cam):
    rng = np.random.default_rng(0)
    p = jnp.asarray(rng.uniform(-50, 50, (20, 3)))
    pix, depth = cam.project(p)
    np.testing.assert_allclose(cam.unproject(pix, depth), p, atol=1e-9)


def test_opencv_round_trip_matches_project_points():
    cam = _perspective()
    K, rvec, tvec = cam.to_opencv()
    cam2 = jh.Perspective.from_opencv(K, rvec, tvec, size=(320, 240))
    p = np.random.default_rng(1).uniform(-40, 40, (10, 3))
    cv_pix, _ = cv2.projectPoints(p, rvec, tvec, K, None)
    np.testing.assert_allclose(cam2.project(jnp.asarray(p))[0], cv_pix.reshape(-1, 2), atol=1e-9)
    P = cam.projection_matrix()
    h = np.hstack([p, np.ones((10, 1))]) @ P.T
    np.testing.assert_allclose(h[:, :2] / h[:, 2:], cv_pix.reshape(-1, 2), atol=1e-9)


def test_orthographic_fit_frames_the_points():
    pts = np.array([[0, 0, 0], [100, 50, 10.0]])
    cam = jh.Orthographic.fit(pts, size=(200, 100), margin=0.1)
    pix, _ = cam.project(jnp.asarray(pts))
    assert np.all(pix >= -1e-9) and np.all(pix[:, 0] <= 199) and np.all(pix[:, 1] <= 99)
    np.testing.assert_allclose(float(cam.scale), 0.8 * min(200 / 100, 100 / 50))


def test_camera_file_round_trip_and_errors(tmp_path):
    rig = (_perspective(), jh.Orthographic(R=np.eye(3), t=np.zeros(3), scale=1.0, center=[0, 0], size=(10, 10)))
    path = jh.save_camera(rig, tmp_path / "rig.json")
    rig2 = jh.load_camera(path)
    assert [type(c) for c in rig2] == [type(c) for c in rig]
    np.testing.assert_allclose(rig2[0].K, rig[0].K)
    (tmp_path / "bad.json").write_text('{"kind": "fisheye"}')
    with pytest.raises(jh.CameraError, match=r"bad.json: field 'kind' must be"):
        jh.load_camera(tmp_path / "bad.json")
    (tmp_path / "bad2.json").write_text('{"kind": "orthographic", "R": [[1,0,0],[0,1,0],[0,0,1]], "t": [0,0,0], '
                                        '"scale": -1, "center": [0,0], "size": [10,10]}')
    with pytest.raises(jh.CameraError, match=r"'scale' must be > 0"):
        jh.load_camera(tmp_path / "bad2.json")


@pytest.mark.parametrize("field, value, match", [
    ("R", "identity", "field 'R' must be finite numbers of shape \\(3, 3\\)"),
    ("R", [[1, 0, 0], [0, 1], [0, 0, 1]], "field 'R' must be finite numbers"),
    ("size", ["320", "x"], "field 'size' must be finite numbers of shape \\(2,\\)"),
    ("size", [320.5, 240], "field 'size' must be two positive integers"),
    ("size", [0, 240], "field 'size' must be two positive integers"),
    ("K", [[0, 0, 0], [0, 0, 0], [0, 0, 0]], "field 'K' must be an intrinsic matrix"),
    ("K", [[400, 0, 160], [0, 400, 120], [0, 0, 2]], "field 'K' must be an intrinsic matrix"),
])
def test_malformed_perspective_camera_files_name_the_field(tmp_path, field, value, match):
    d = {"kind": "perspective", "K": [[400, 0, 159.5], [0, 400, 119.5], [0, 0, 1]], "R": np.eye(3).tolist(),
         "t": [0, 0, 400], "size": [320, 240], field: value}
    path = tmp_path / "cam.json"
    path.write_text(json.dumps(d))
    with pytest.raises(jh.CameraError, match=match):
        jh.load_camera(path)


def test_empty_rig_file_is_an_error(tmp_path):
    (tmp_path / "rig.json").write_text("[]")
    with pytest.raises(jh.CameraError, match="lists no camera"):
        jh.load_camera(tmp_path / "rig.json")


@pytest.mark.parametrize("factor", [0.5, 0.25, 0.3])
def test_a_scaled_camera_sees_the_resized_image(factor):
    from jaxhand.camera import scale_camera

    rng = np.random.default_rng(1)
    p = rng.uniform(-60, 60, (20, 3))
    persp = _perspective()
    ortho = jh.Orthographic.fit(p, size=(320, 240))
    for cam in (persp, ortho) if factor != 0.3 else (persp,):
        small = scale_camera(cam, factor)
        s = np.array(small.size) / np.array(cam.size)
        assert small.size == (round(320 * factor), round(240 * factor))
        np.testing.assert_allclose(np.asarray(small.project(p)[0]), (np.asarray(cam.project(p)[0]) + 0.5) * s - 0.5,
                                   atol=1e-9)
        np.testing.assert_allclose(np.asarray(small.project(p)[1]), np.asarray(cam.project(p)[1]), atol=1e-9)
    with pytest.raises(jh.CameraError, match="scale: expected a finite factor > 0"):
        scale_camera(persp, 0.0)
