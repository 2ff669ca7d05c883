"""Landmark convention, residuals and their Jacobian, single and batched landmark fits."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxhand as jh
from jaxhand.kinematics import pose
from jaxhand.landmarks import (
    POINT_NAMES,
    BatchConfig,
    fit_landmarks,
    fit_landmarks_batch,
    landmark_map,
    landmark_positions,
    landmark_residuals,
    landmark_residuals_and_jacobian,
    make_landmark_args,
    make_landmarks,
    stacked_residuals,
)
from jaxhand.residuals import make_residual_args, residuals


def _camera(size=(640, 480)):
    return jh.Perspective.look_at([30.0, -60.0, -450.0], [0.0, -80.0, 0.0], fov_deg=60, size=size)


def _points(model, q):
    q = jnp.asarray(q)
    return np.asarray(landmark_positions(model, landmark_map(model), pose(model, q), q))


def _observe(model, cam, q, noise_px=0.0, rng=None):
    p = _points(model, q)
    px = np.asarray(cam.project(jnp.asarray(p))[0])
    if noise_px:
        px = px + rng.normal(0, noise_px, px.shape)
    return px, np.asarray(cam.to_camera(jnp.asarray(p)))


def test_point_names_follow_mediapipe_order():
    assert len(POINT_NAMES) == 21
    assert POINT_NAMES[:5] == ("wrist", "thumb_cmc", "thumb_mcp", "thumb_ip", "thumb_tip")
    assert POINT_NAMES[5:9] == ("index_mcp", "index_pip", "index_dip", "index_tip")
    assert POINT_NAMES[-1] == "little_tip"


def test_map_of_the_hands_and_of_partial_models():
    for name in ("hand21", "hand27"):
        assert all(landmark_map(jh.builtin_model(name)).present)
    m = landmark_map(jh.builtin_model("index"))
    present = {n for n, p in zip(POINT_NAMES, m.present) if p}
    assert present == {"index_mcp", "index_pip", "index_dip", "index_tip"}   # no palm: no wrist


def test_fingertip_is_one_radius_beyond_the_tip_centre():
    # Golden: the distal landmark lies on the distal axis at length + radius from the DIP
    # (a detector marks the skin at the end of the finger, the model's tip is the cap's centre).
    m = jh.builtin_model("hand27")
    q = np.asarray(m.q_default)
    P = pose(m, jnp.asarray(q))
    pts = _points(m, q)
    i = POINT_NAMES.index("index_tip")
    li = m.link_lookup("index_dip")
    dip = np.asarray(P.link_start[li])
    assert np.linalg.norm(pts[i] - dip) == pytest.approx(20.0 + 7.5, abs=1e-9)
    tip_centre = np.asarray(P.tips[m.tip_names.index("index_dip")])
    assert np.linalg.norm(pts[i] - tip_centre) == pytest.approx(7.5, abs=1e-9)
    # the wrist is the palm's root, not a finger joint
    assert np.allclose(pts[0], np.asarray(q[4:7]))
    assert np.allclose(pts[POINT_NAMES.index("index_mcp")], np.asarray(P.frames[m.frame_lookup("index_mcp"), :3, 3]))


def test_builtin_hands_are_left_hands():
    # Seen by a camera with identity rotation (the built-in mount: fingers up the image), flexing
    # moves the fingertips towards the camera (-z), so the palm faces the camera; the thumb is on
    # the image's left. A right hand seen palm-on has its thumb on the right: these are left hands.
    m = jh.builtin_model("hand21")
    q = np.asarray(m.q_default)
    pts = _points(m, q)
    flexed = q.copy()
    flexed[m.q_lookup("index_mcp")] = -1.2
    tip = POINT_NAMES.index("index_tip")
    assert _points(m, flexed)[tip, 2] < pts[tip, 2] - 20
    assert pts[POINT_NAMES.index("thumb_tip"), 0] < pts[POINT_NAMES.index("little_tip"), 0]
    assert jh.landmarks.BUILTIN_HANDEDNESS == "left"


def _args_two_cameras(m, q_obs, frame_3d="camera"):
    rig = (_camera(), jh.Orthographic(R=np.eye(3), t=np.zeros(3), scale=2.0, center=[320, 240], size=(640, 480)))
    px = np.stack([np.asarray(c.project(jnp.asarray(_points(m, q_obs)))[0]) for c in rig])
    mm = _points(m, q_obs) if frame_3d == "world" else np.asarray(rig[0].to_camera(jnp.asarray(_points(m, q_obs))))
    px[0, 3] = np.nan                        # a missing point: masked, NaN must not leak
    w = np.linspace(0.2, 1.0, 21)[None].repeat(2, 0)
    lm = make_landmarks(px, px_weight=w, mm=mm, mm_weight=0.5, frame_3d=frame_3d)
    return make_landmark_args(m, rig, lm)


@pytest.mark.parametrize("frame_3d", ["camera", "world"])
@pytest.mark.parametrize("where", ["zero", pytest.param("random", marks=pytest.mark.slow),
                                   pytest.param("rotated_near_pi", marks=pytest.mark.slow)])
@pytest.mark.slow
def test_geometric_jacobian_matches_autodiff_and_central_differences(frame_3d, where):
    m = jh.builtin_model("hand27")
    rng = np.random.default_rng(3)
    q = jh.random_q(m, rng, margin=0.05, translation_mm=30)
    if where == "zero":
        q[7:] = 0.0
    if where == "rotated_near_pi":
        ang = np.pi - 1e-3
        q[:4] = [np.cos(ang / 2), 0.0, np.sin(ang / 2) * 0.6, np.sin(ang / 2) * 0.8]
    args = _args_two_cameras(m, jh.random_q(m, rng, margin=0.1, translation_mm=30), frame_3d)
    r, J = landmark_residuals_and_jacobian(jnp.asarray(q), args)
    J_ad = jax.jacfwd(landmark_residuals)(jnp.asarray(q), args)
    h = 1e-6
    J_cd = np.stack([(np.asarray(landmark_residuals(jnp.asarray(q + h * e), args))
                      - np.asarray(landmark_residuals(jnp.asarray(q - h * e), args))) / (2 * h)
                     for e in np.eye(m.n_q)], -1)
    assert np.all(np.isfinite(np.asarray(J)))
    np.testing.assert_allclose(np.asarray(r), np.asarray(landmark_residuals(jnp.asarray(q), args)), atol=1e-10)
    np.testing.assert_allclose(np.asarray(J), np.asarray(J_ad), atol=1e-8)
    np.testing.assert_allclose(np.asarray(J), J_cd, atol=1e-4 * max(1.0, np.abs(J_cd).max()) * 1e-2)


def test_masked_point_gives_exact_zeros():
    m = jh.builtin_model("hand27")
    args = _args_two_cameras(m, np.asarray(m.q_default))
    q = jnp.asarray(jh.random_q(m, np.random.default_rng(0), translation_mm=10))
    r, J = landmark_residuals_and_jacobian(q, args)
    rows = [2 * 3, 2 * 3 + 1]                # camera 0, point 3 (thumb_ip), x and y
    assert np.all(np.asarray(r)[rows] == 0.0) and np.all(np.asarray(J)[rows] == 0.0)
    assert len(r) == 2 * 42 + 63


def test_landmarks_stack_after_link_and_tip_residuals():
    m = jh.builtin_model("hand21")
    cam = _camera()
    q = jnp.asarray(m.q_default)
    edges = make_residual_args(m, cam, jh.features.features_from_pose(m, cam, q))
    lm = make_landmarks(_observe(m, cam, np.asarray(q))[0])
    args = make_landmark_args(m, cam, lm, edges=edges)
    r = np.asarray(stacked_residuals(q + 0.05, args))
    np.testing.assert_array_equal(r[: len(residuals(q + 0.05, edges))], np.asarray(residuals(q + 0.05, edges)))
    np.testing.assert_array_equal(r[-(42 + 63):], np.asarray(landmark_residuals(q + 0.05, args)))


@pytest.mark.parametrize("solver", ["bounded", "lm", "fast"])
def test_noise_free_landmarks_recover_the_pose(solver):
    # 2-D plus 3-D points determine every joint of hand21; each solver must find the truth from
    # a start 0.15 rad away.
    m = jh.builtin_model("hand21")
    cam = _camera()
    rng = np.random.default_rng(5)
    q_true = jh.random_q(m, rng, margin=0.15)
    px, mm = _observe(m, cam, q_true)
    lm = make_landmarks(px, mm=mm)
    q0 = np.clip(q_true + rng.normal(0, 0.15, m.n_q), np.asarray(m.q_lower), np.asarray(m.q_upper))
    res = fit_landmarks(m, cam, lm, q0, solver=solver)
    assert res.status_name() == "ok"
    assert np.max(np.abs(np.asarray(res.q) - q_true)) < 1e-6


def test_batch_matches_single_fits_and_keeps_limits():
    m = jh.builtin_model("hand21")
    cam = _camera()
    rng = np.random.default_rng(6)
    qs = jh.random_q(m, rng, 5, margin=0.05)
    px = np.stack([_observe(m, cam, q, 1.0, rng)[0] for q in qs])
    lms = make_landmarks(px[:, None])
    batch = fit_landmarks_batch(m, cam, lms, m.q_default, config=BatchConfig(chunk=2))
    assert batch.q.shape == (5, m.n_q)
    for b in range(5):
        one = fit_landmarks(m, cam, make_landmarks(px[b]), m.q_default, solver="fast")
        np.testing.assert_allclose(np.asarray(one.q), np.asarray(batch.q[b]), atol=1e-9)
    q = np.asarray(batch.q)
    assert np.all(q >= np.asarray(m.q_lower) - 1e-12) and np.all(q <= np.asarray(m.q_upper) + 1e-12)
    # 1 px noise: a converged fit leaves image errors of the noise's size
    rms = np.sqrt(2 * np.asarray(batch.cost) / 42)
    assert np.median(rms) < 1.5


def test_boundary_errors():
    m = jh.builtin_model("hand21")
    cam = _camera()
    with pytest.raises(jh.InputError, match="px"):
        make_landmarks(np.zeros((20, 2)))
    with pytest.raises(jh.InputError, match="weights"):
        make_landmarks(np.zeros((21, 2)), px_weight=-1.0)
    lm = make_landmarks(np.zeros((21, 2)))
    with pytest.raises(jh.InputError, match="unknown landmark solver"):
        fit_landmarks(m, cam, lm, m.q_default, solver="gn2")
    with pytest.raises(jh.InputError, match="rig of 2"):
        make_landmark_args(m, (cam, cam), lm)
    with pytest.raises(jh.InputError, match="frame_3d"):
        make_landmarks(np.zeros((21, 2)), frame_3d="palm")
