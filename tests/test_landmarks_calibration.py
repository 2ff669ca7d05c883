"""Hand shape, the whole-sequence solver (block tridiagonal elimination) and calibration."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxhand as jh
from jaxhand.kinematics import pose
from jaxhand.landmarks import (
    SequenceConfig,
    apply_shape,
    calibrate_landmarks,
    fit_landmarks_batch,
    fit_sequence,
    hand_shape,
    landmark_map,
    landmark_positions,
    make_landmarks,
    save_calibrated_model,
)
from jaxhand.landmarks._sequence import _block_tridiag_solve, _pair_blocks, _smooth_gradient


@pytest.mark.parametrize("T", [1, 2, 5, 6])
def test_paired_band_solve_matches_dense(T):
    # Reference vs fast: the smoothness bands grouped in pairs of frames and solved by the block
    # Thomas recursion, against a dense solve of data blocks + e D1^T D1 + a D2^T D2 (explicit
    # difference matrices).
    rng = np.random.default_rng(T)
    n, k = 4, 3
    e, a = rng.uniform(0.5, 2.0, n), rng.uniform(0.5, 2.0, n)
    D = np.stack([(lambda A: A @ A.T + np.eye(n))(rng.normal(size=(n, n))) for _ in range(T)])
    R = rng.normal(size=(T, n, k))
    D1 = (np.eye(T, k=1) - np.eye(T))[:-1]
    D2 = (np.eye(T) - 2 * np.eye(T, k=1) + np.eye(T, k=2))[: max(T - 2, 0)]
    dense = np.zeros((T * n, T * n))
    for t in range(T):
        dense[t * n:(t + 1) * n, t * n:(t + 1) * n] = D[t]
    dense += np.kron(D1.T @ D1, np.diag(e)) + np.kron(D2.T @ D2, np.diag(a))
    Dm, lo = _pair_blocks(jnp.asarray(D), jnp.asarray(e), jnp.asarray(a))
    M = (T + 1) // 2
    Rp = np.concatenate([R, np.zeros((2 * M - T, n, k))]).reshape(M, 2 * n, k)
    x = np.asarray(_block_tridiag_solve(Dm, lo, jnp.asarray(Rp))).reshape(2 * M, n, k)[:T]
    np.testing.assert_allclose(x.reshape(T * n, k), np.linalg.solve(dense, R.reshape(T * n, k)), atol=1e-10)


def test_smoothness_gradient_matches_autodiff():
    rng = np.random.default_rng(1)
    Q = jnp.asarray(rng.normal(size=(7, 3)))
    e, a = jnp.asarray(rng.uniform(0.5, 2, 3)), jnp.asarray(rng.uniform(0.5, 2, 3))

    def cost(Q):
        d1, d2 = Q[1:] - Q[:-1], Q[2:] - 2 * Q[1:-1] + Q[:-2]
        return 0.5 * jnp.sum(e * d1 * d1) + 0.5 * jnp.sum(a * d2 * d2)

    np.testing.assert_allclose(np.asarray(_smooth_gradient(Q, e, a)), np.asarray(jax.grad(cost)(Q)), atol=1e-12)


def test_nominal_shape_is_the_model_and_scales_move_the_right_numbers():
    m = jh.builtin_model("hand27")
    shape = hand_shape(m)
    assert shape.n_scales == m.n_links and len(shape.palm) == 14
    same = apply_shape(m, shape, jnp.asarray(shape.nominal()))
    np.testing.assert_array_equal(np.asarray(same.dh), np.asarray(m.dh))
    theta = shape.nominal()
    li = m.link_lookup("index_mcp")
    theta[li] = 1.1
    scaled = apply_shape(m, shape, jnp.asarray(theta))
    pip = m.frame_lookup("index_pip")
    assert float(scaled.dh[pip, 1]) == pytest.approx(1.1 * 40.0)
    assert float(scaled.link_length_mm[li]) == pytest.approx(1.1 * 40.0)
    assert float(scaled.link_radius_mm[li]) == float(m.link_radius_mm[li])


def test_saved_calibrated_model_loads_back(tmp_path):
    m = jh.builtin_model("hand27")
    shape = hand_shape(m)
    theta = shape.nominal()
    theta[:shape.n_scales] = np.linspace(0.9, 1.1, shape.n_scales)
    mc = apply_shape(m, shape, jnp.asarray(theta))
    back = jh.load_model(save_calibrated_model(mc, tmp_path / "cal.toml"))
    assert back.name == "hand27_calibrated"
    np.testing.assert_allclose(np.asarray(back.dh), np.asarray(mc.dh), atol=1e-9)
    np.testing.assert_allclose(np.asarray(back.link_length_mm), np.asarray(mc.link_length_mm), atol=1e-9)


def _quat_rot(rng, sigma):
    """(w, x, y, z) of 180 deg about z (the built-in palm-to-camera pose) times a small random turn."""
    v = rng.normal(0, sigma, 3)
    a = np.linalg.norm(v)
    dq = np.concatenate([[np.cos(a / 2)], np.sin(a / 2) * v / a])
    w1, x1, y1, z1 = dq
    w2, x2, y2, z2 = 0.0, 0.0, 0.0, 1.0
    return np.array([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])


def _synthetic(seed, T=60, noise_px=2.0, noise_mm=1.0):
    m = jh.builtin_model("hand27")
    cam = jh.Perspective.look_at([0.0, 0.0, -500.0], [0.0, -80.0, 0.0], fov_deg=60, size=(640, 480))
    rng = np.random.default_rng(seed)
    shape = hand_shape(m)
    theta = np.concatenate([rng.uniform(0.85, 1.15, shape.n_scales), rng.uniform(-3, 3, len(shape.palm))])
    mt = apply_shape(m, shape, jnp.asarray(theta))
    Q = jh.random_q(m, rng, T, margin=0.2)
    for i in range(T):
        Q[i, :4] = _quat_rot(rng, 0.5)
        Q[i, 4:7] = rng.uniform([-40, -40, -50], [40, 40, 50])
    lmap = landmark_map(m)
    P = jax.vmap(lambda q: landmark_positions(mt, lmap, pose(mt, q), q))(jnp.asarray(Q))
    px = np.asarray(cam.project(P)[0]) + rng.normal(0, noise_px, (T, 21, 2))
    mm = np.asarray(cam.to_camera(P)) + rng.normal(0, noise_mm, (T, 21, 3))
    # tracker-like starts: the truth disturbed by 0.1 rad per joint and 5 mm
    Q0 = Q.copy()
    Q0[:, 7:] += rng.normal(0, 0.1, (T, m.n_q - 7))
    Q0[:, 4:7] += rng.normal(0, 5.0, (T, 3))
    Q0 = np.clip(Q0, np.asarray(m.q_lower), np.asarray(m.q_upper))
    return m, cam, shape, theta, Q, px, mm, Q0


@pytest.mark.slow
def test_calibration_recovers_phalanx_scales_within_2_percent():
    # Issue 14 item 3: phalanges 0.85-1.15 x the model's, 2 px noise, 60 frames, one camera plus
    # 3-D landmarks (here with 1 mm noise, weighted as inverse variances: 4 px^2/mm^2 against the
    # 2-D points' 1). Seed 1 measured 1.23 % worst, 0.58 % median (with equal weights 1.9 %; with
    # 2 mm noise and equal weights 2.1 %). One camera alone (no 3-D points): 4.4 % worst, 1.2 % median.
    m, cam, shape, theta, Q, px, mm, Q0 = _synthetic(1)
    lms = make_landmarks(px[:, None], mm=mm, mm_weight=4.0)
    start = fit_landmarks_batch(m, cam, lms, Q0)
    mc, res, shape = calibrate_landmarks(m, cam, lms, np.asarray(start.q))
    est = np.asarray(res.theta)[:shape.n_scales]
    err = est / theta[:shape.n_scales] - 1
    assert bool(res.converged)
    assert np.max(np.abs(err)) < 0.02, dict(zip(shape.names, np.round(100 * err, 2)))
    np.testing.assert_allclose(np.asarray(mc.link_length_mm), np.asarray(m.link_length_mm) * est)


@pytest.mark.slow
def test_sequence_fit_with_smoothness_keeps_limits_and_fits():
    m, cam, shape, theta, Q, px, mm, Q0 = _synthetic(2, T=12)
    lms = make_landmarks(px[:, None])
    res = fit_sequence(m, cam, lms, Q0, shape=None, config=SequenceConfig(max_steps=30, smooth_px_per_rad=1.0))
    q = np.asarray(res.q)
    assert np.all(q >= np.asarray(m.q_lower) - 1e-12) and np.all(q <= np.asarray(m.q_upper) + 1e-12)
    assert np.allclose(np.linalg.norm(q[:, :4], axis=-1), 1.0)
    assert float(res.cost) < float(res.start_cost)
