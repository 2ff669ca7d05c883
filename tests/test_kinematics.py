import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import CompileCounter

import jaxhand as jh
from jaxhand.kinematics import dh_transform, frame_poses, quat_to_rotation


def test_dh_transform_matches_thesis_eq_2_1():
    alpha, a, d, theta = 0.3, 12.0, -4.0, 1.1
    ca, sa, ct, st = np.cos(alpha), np.sin(alpha), np.cos(theta), np.sin(theta)
    expected = np.array([[ct, -st, 0, a], [st * ca, ct * ca, -sa, -sa * d], [st * sa, ct * sa, ca, ca * d],
                         [0, 0, 0, 1]])
    np.testing.assert_allclose(dh_transform(alpha, a, d, theta), expected, atol=1e-15)


def _pixels(name, q, p0):
    m = jh.builtin_model(name)
    cam = jh.Orthographic(R=np.eye(3), t=np.zeros(3), scale=1.0, center=p0, size=(64, 64))
    v = jh.project_pose(m, cam, jnp.asarray(q, float))
    return np.asarray(v.link_start_px), np.asarray(v.tips_px)


P0 = np.array([3.0, 0.0])
L = 5.0


@pytest.mark.parametrize("t1", [0.0, 0.7, -2.0, 2.0944])
def test_planar_r_closed_form(t1):
    _, tip = _pixels("planar_r", [t1], P0)
    np.testing.assert_allclose(tip[0], [L * np.cos(t1) + P0[0], L * np.sin(t1) + P0[1]], atol=1e-13)


@pytest.mark.parametrize("d1", [0.0, 1.0, -2.5])
def test_planar_p_closed_form(d1):
    _, tip = _pixels("planar_p", [d1], P0)
    np.testing.assert_allclose(tip[0], [d1 + P0[0], L + P0[1]], atol=1e-13)


@pytest.mark.parametrize("d1, t2", [(0.0, 0.0), (1.5, 0.8), (-1.0, -2.3)])
def test_planar_pr_closed_form(d1, t2):
    _, tip = _pixels("planar_pr", [d1, t2], P0)
    np.testing.assert_allclose(tip[0], [d1 + P0[0] - L * np.sin(t2), P0[1] + L * np.cos(t2)], atol=1e-13)


@pytest.mark.parametrize("t1, t2", [(-np.pi / 3, -np.pi / 2 - np.pi / 6), (np.pi / 6, -np.pi / 3), (0.3, 2.9)])
def test_planar_rr_closed_form(t1, t2):
    starts, tip = _pixels("planar_rr", [t1, t2], P0)
    # thesis §3.2.4: terminal-link point at P = L2 and the second joint at P = L1 on link 1
    expected_tip = [-L * np.sin(t1 + t2) - L * np.sin(t1) + P0[0], L * np.cos(t1 + t2) + L * np.cos(t1) + P0[1]]
    np.testing.assert_allclose(tip[0], expected_tip, atol=1e-13)
    np.testing.assert_allclose(starts[1], [-L * np.sin(t1) + P0[0], L * np.cos(t1) + P0[1]], atol=1e-13)


@pytest.mark.parametrize("name", jh.builtin_names())
def test_pill_lengths_are_invariant(name):
    m = jh.builtin_model(name)
    rng = np.random.default_rng(1)
    for q in jh.random_q(m, rng, 5):
        pose = jh.forward(m, jnp.asarray(q))
        np.testing.assert_allclose(np.linalg.norm(pose.link_end - pose.link_start, axis=-1), m.link_length_mm,
                                   atol=1e-10)


def test_moving_the_free_base_moves_every_frame_rigidly():
    m = jh.builtin_model("hand27")
    q = np.asarray(m.q_default).copy()
    T0 = np.asarray(frame_poses(m, jnp.asarray(q)))
    angle = 0.7
    quat_delta = np.array([np.cos(angle / 2), 0, np.sin(angle / 2), 0])  # about y
    w1, v1 = quat_delta[0], quat_delta[1:]
    w2, v2 = q[0], q[1:4]
    q[:4] = [w1 * w2 - v1 @ v2, *(w1 * v2 + w2 * v1 + np.cross(v1, v2))]
    q[4:7] = [10.0, -20.0, 30.0]
    T1 = np.asarray(frame_poses(m, jnp.asarray(q)))
    G = np.eye(4)
    G[:3, :3] = np.asarray(quat_to_rotation(jnp.asarray(quat_delta)))
    G[:3, 3] = q[4:7]
    np.testing.assert_allclose(T1, G @ T0, atol=1e-10)


def test_quaternion_is_normalised_inside_kinematics():
    m = jh.builtin_model("hand27")
    q = np.asarray(m.q_default).copy()
    q2 = q.copy()
    q2[:4] *= 3.0
    np.testing.assert_allclose(jh.forward(m, q2).tips, jh.forward(m, q).tips, atol=1e-12)


def test_default_pose_is_the_rest_pose_of_the_dh_table():
    m = jh.builtin_model("index")
    pose = jh.forward(m, jnp.zeros(3))  # straight finger along the mount's x axis = world -y
    np.testing.assert_allclose(pose.tips[0], [0.0, -(40 + 24 + 20), 0.0], atol=1e-12)


def test_validate_q_errors():
    m = jh.builtin_model("hand21")
    with pytest.raises(jh.InputError, match=r"expected shape \(21,\) for model 'hand21', got \(3,\)"):
        jh.validate_q(m, np.zeros(3))
    q = np.asarray(m.q_default).copy()
    q[m.q_lookup("index_pip")] = np.nan
    with pytest.raises(jh.InputError, match=r"non-finite value for 'index_pip'"):
        jh.validate_q(m, q)
    q = np.asarray(m.q_default).copy()
    q[m.q_lookup("index_dip")] = np.radians(30)
    with pytest.raises(jh.InputError, match=r"'index_dip' = 30 deg lies outside its limits \[-80, 0\] deg"):
        jh.validate_q(m, q, within_limits=True)


def test_one_compilation_per_structure():
    m = jh.builtin_model("hand21")
    other = m.with_lengths(1.25)  # same structure, other lengths
    rng = np.random.default_rng(0)
    qs = [jnp.asarray(q) for q in jh.random_q(m, rng, 20)]
    jh.forward(m, qs[0])  # may compile (once per process)
    with CompileCounter() as counter:
        for q in qs:
            jh.forward(m, q)
            jh.forward(other, q)
    assert counter.count == 0
    with CompileCounter() as fresh:  # a new structure does compile
        jh.forward(jh.builtin_model("index"), jnp.zeros(3) + 0.1)
    assert fresh.count >= 1


def test_with_lengths_scales_geometry():
    m = jh.builtin_model("hand21")
    q = jnp.asarray(m.q_default)
    np.testing.assert_allclose(jh.forward(m.with_lengths(2.0), q).tips, 2 * jh.forward(m, q).tips, atol=1e-10)


@pytest.mark.parametrize("entry", ["forward", "project_pose"])
def test_public_kinematics_check_q_shape_and_finiteness(entry):
    model = jh.builtin_model("two_fingers")
    cam = jh.Orthographic.fit(np.asarray(jh.forward(model, model.q_default).frames[:, :3, 3]))
    call = (lambda q: jh.forward(model, q)) if entry == "forward" else (lambda q: jh.project_pose(model, cam, q))
    for n in (model.n_q - 1, model.n_q + 1):
        with pytest.raises(jh.InputError, match=rf"q: expected shape \({model.n_q},\) for 'two_fingers'.*got \({n},\)"):
            call(np.zeros(n))
    q = np.asarray(model.q_default, float).copy()
    q[1] = np.nan
    with pytest.raises(jh.InputError, match=rf"entry '{model.q_names[1]}' is nan"):
        call(q)
    # Under jit only the shape is checked, and the traced call gives the eager numbers.
    eager = call(model.q_default)
    traced = jax.jit(call)(model.q_default)
    first = (np.asarray(jax.tree_util.tree_leaves(v)[0]) for v in (eager, traced))
    assert np.array_equal(*first)


def test_one_clip_and_normalise_rule_for_kinematics_and_solvers():
    from jaxhand.kinematics import clip_q, clip_to_limits, normalize_q
    from jaxhand.solve import StateSpace

    m = jh.builtin_model("hand27")
    space = StateSpace.of(m)
    rng = np.random.default_rng(0)
    q = jh.random_q(m, rng)
    q[:4] *= 3.0                       # not normalised
    q[7:] += rng.normal(0, 1.0, m.n_q - 7)   # outside the limits
    clipped = np.asarray(clip_to_limits(jnp.asarray(q), m.q_lower, m.q_upper, True))
    np.testing.assert_array_equal(clipped[:4], q[:4])                    # the quaternion is left to its norm
    np.testing.assert_array_equal(clipped[4:], np.clip(q[4:], np.asarray(m.q_lower)[4:], np.asarray(m.q_upper)[4:]))
    np.testing.assert_array_equal(np.asarray(space.clip(jnp.asarray(q))), clipped)
    unit = np.asarray(normalize_q(m, jnp.asarray(q)))
    np.testing.assert_array_equal(np.asarray(space.normalize(jnp.asarray(q))), unit)
    assert np.linalg.norm(unit[:4]) == pytest.approx(1.0, abs=1e-15)
    both = np.asarray(clip_q(m, jnp.asarray(q)))
    np.testing.assert_array_equal(both, np.r_[unit[:4], clipped[4:]])
    # a zero quaternion stays zero (finite), batches work
    z = np.asarray(normalize_q(m, jnp.zeros((2, m.n_q))))
    assert np.all(z == 0.0)
