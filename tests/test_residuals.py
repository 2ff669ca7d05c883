import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from _params import model_params
from helpers import fit_camera

import jaxhand as jh
from jaxhand.check import central_difference_jacobian
from jaxhand.features import Features, features_from_pose
from jaxhand.residuals import cost, make_residual_args, n_residuals, residual_jacobian, residual_labels, residuals

# The library's residuals are plain functions meant to be traced inside a solver; jit them here
# so the tests do not run the kinematics op by op.
residuals = eqx.filter_jit(residuals)
cost = eqx.filter_jit(cost)


def _oblique(model, q=None):
    """Two orthographic cameras with different oblique view rotations."""
    from scipy.spatial.transform import Rotation

    return tuple(fit_camera(model, q, R=Rotation.from_euler("xyz", e, degrees=True).as_matrix())
                 for e in ((40, 25, 0), (-35, -30, 10)))


# Every built-in model is covered by test_solve's exact-fit test (H < 1e-10 at the truth); here a
# fixed base, a free base and a planar chain.
@pytest.mark.parametrize("name", model_params(["index_thumb", "hand27", "planar_rr"]))
def test_residuals_vanish_at_the_pose_that_made_the_features(name):
    m = jh.builtin_model(name)
    q = jh.random_q(m, np.random.default_rng(3))
    cams = _oblique(m, q)
    args = make_residual_args(m, cams, features_from_pose(m, cams, q))
    r = residuals(jnp.asarray(q), args)
    assert r.shape == (n_residuals(m, 2, 2),)
    assert len(residual_labels(m, 2)) == r.shape[0]
    np.testing.assert_allclose(r, 0.0, atol=1e-9)
    # ... and not elsewhere: moving the first joint moves something in some view
    q2 = q.copy()
    q2[m.n_base_q] += 0.05
    assert float(cost(jnp.asarray(q2), args)) > 1e-6


def test_planar_rr_residuals_match_the_thesis_closed_form():
    # thesis §3.2.4: tip rows, then the base link (line 1) and terminal link (line 2) at P = 3, 2
    m = jh.builtin_model("planar_rr")
    p0 = np.array([3.0, 0.0])
    cam = jh.Orthographic(R=np.eye(3), t=np.zeros(3), scale=1.0, center=p0, size=(32, 32))
    l1, l2, tip = np.array([0.5, -np.sqrt(3) / 2, 1.5]), np.array([1.0, 0.0, 7.3]), np.array([7.0, -2.0])
    feats = Features(lines=jnp.array([l1, l2]), line_valid=jnp.ones(2, bool), line_weight=jnp.ones(2),
                     tips=jnp.array([tip]), tip_valid=jnp.ones(1, bool), tip_weight=jnp.ones(1))
    args = make_residual_args(m, cam, feats, (0.6, 0.4))
    t1, t2 = 0.4, -1.3
    L = 5.0
    s1, c1, s12, c12 = np.sin(t1), np.cos(t1), np.sin(t1 + t2), np.cos(t1 + t2)
    expected = [-L * s12 - L * s1 + p0[0] - tip[0], L * c12 + L * c1 + p0[1] - tip[1]]
    expected += [l1 @ [-P * s1 + p0[0], P * c1 + p0[1], -1] for P in (3.0, 2.0)]
    expected += [l2 @ [-P * s12 - L * s1 + p0[0], P * c12 + L * c1 + p0[1], -1] for P in (3.0, 2.0)]
    np.testing.assert_allclose(residuals(jnp.array([t1, t2]), args), expected, atol=1e-12)


def _hand_problem(name="index_thumb", seed=0):
    m = jh.builtin_model(name)
    q = jh.random_q(m, np.random.default_rng(seed))
    cams = _oblique(m, q)
    return m, cams, q, features_from_pose(m, cams, q, noise_px=1.0, rng=np.random.default_rng(seed))


def test_masked_slots_give_exact_zeros_and_no_nan_even_when_they_hold_nan():
    m, cams, q, feats = _hand_problem()
    f0 = feats[0]
    poisoned = Features(lines=f0.lines.at[1].set(jnp.nan), line_valid=f0.line_valid.at[1].set(False),
                        line_weight=f0.line_weight.at[1].set(jnp.nan),
                        tips=f0.tips.at[0].set(jnp.inf), tip_valid=f0.tip_valid.at[0].set(False),
                        tip_weight=f0.tip_weight)
    args = make_residual_args(m, cams, (poisoned, feats[1]), validate=False)
    r = np.asarray(residuals(jnp.asarray(q), args))
    labels = residual_labels(m, 2)
    masked = [i for i, lab in enumerate(labels) if lab.startswith(f"cam0/link/{m.link_names[1]}@")
              or lab.startswith(f"cam0/tip/{m.tip_names[0]}/")]
    assert len(masked) == 4
    assert np.all(r[masked] == 0.0)
    assert np.all(np.isfinite(r)) and np.any(r != 0)
    J = np.asarray(residual_jacobian(jnp.asarray(q), args))
    assert np.all(np.isfinite(J))
    assert np.all(J[masked] == 0.0)


def test_weights_scale_the_cost_per_slot():
    m, cams, q, feats = _hand_problem()
    qj = jnp.asarray(q) + 0.01
    base = make_residual_args(m, cams, feats)
    f0 = feats[0]
    w = 4.0
    heavy = Features(lines=f0.lines, line_valid=f0.line_valid, line_weight=f0.line_weight.at[2].set(w),
                     tips=f0.tips, tip_valid=f0.tip_valid, tip_weight=f0.tip_weight.at[1].set(w))
    args = make_residual_args(m, cams, (heavy, feats[1]))
    r0, r1 = np.asarray(residuals(qj, base)), np.asarray(residuals(qj, args))
    labels = residual_labels(m, 2)
    scaled = np.array([lab.startswith(f"cam0/link/{m.link_names[2]}@") or lab.startswith(f"cam0/tip/{m.tip_names[1]}/")
                       for lab in labels])
    np.testing.assert_allclose(r1[scaled], np.sqrt(w) * r0[scaled], rtol=1e-12)
    np.testing.assert_array_equal(r1[~scaled], r0[~scaled])
    # H = 1/2 sum weight * raw^2
    np.testing.assert_allclose(float(cost(qj, args)),
                               0.5 * (np.sum(r0[~scaled] ** 2) + w * np.sum(r0[scaled] ** 2)), rtol=1e-12)


@pytest.mark.parametrize("name", model_params(["index_thumb", "hand27", "planar_pr"]))
def test_residual_jacobian_matches_central_differences(name):
    m = jh.builtin_model(name)
    rng = np.random.default_rng(5)
    q = jh.random_q(m, rng)
    cams = _oblique(m, q)
    if name == "hand27":   # a verging perspective camera as the second view
        pose = jh.forward(m, jnp.asarray(q))
        centre = np.asarray(pose.link_end).mean(0)
        cams = (cams[0], jh.Perspective.look_at(centre + np.array([250.0, -100.0, -400.0]), centre))
    feats = features_from_pose(m, cams, q, noise_px=0.5, rng=rng)
    args = make_residual_args(m, cams, feats)
    q_eval = jnp.asarray(q + rng.normal(0, 0.02, q.shape))
    J = np.asarray(residual_jacobian(q_eval, args))
    batch = jax.jit(jax.vmap(residuals, in_axes=(0, None)))
    fd = central_difference_jacobian(lambda qs: batch(jnp.asarray(qs), args), np.asarray(q_eval), eps=1e-6)
    scale = max(1.0, np.abs(J).max())
    assert np.abs(J - fd).max() / scale < 1e-7


def test_residual_args_reject_bad_fractions_and_features():
    m = jh.builtin_model("index")
    cam = fit_camera(m)
    feats = features_from_pose(m, cam, np.asarray(m.q_default))
    with pytest.raises(jh.InputError, match="link_fractions"):
        make_residual_args(m, cam, feats, (0.5, 1.5))
    with pytest.raises(jh.InputError, match="one Features per camera"):
        make_residual_args(m, (cam, cam), feats)


def test_feature_distances_are_the_unweighted_residuals():
    # One rule for the residuals and the tracker's distances: with unit weights the tip distance
    # is the norm of the tip's residual pair and the link distance the largest |residual| of its
    # points; masked slots give 0 in both.
    import equinox as eqx

    from jaxhand.features import features_from_pose
    from jaxhand.residuals import feature_distances

    m = jh.builtin_model("index_thumb")
    cam = jh.Orthographic(R=np.eye(3), t=np.array([0.0, 0.0, 500.0]), scale=1.0, center=(160, 120), size=(320, 240))
    rng = np.random.default_rng(3)
    f = features_from_pose(m, cam, jh.random_q(m, rng), noise_px=2.0, rng=rng)[0]
    f = eqx.tree_at(lambda g: (g.line_valid, g.lines), f, (f.line_valid.at[0].set(False), f.lines.at[0].set(jnp.nan)))
    q = jnp.asarray(jh.random_q(m, rng))
    fractions = jnp.asarray((0.1, 0.5, 0.9))
    (e_link, e_tip), = feature_distances(m, (cam,), (f,), q, fractions)
    r = np.asarray(residuals(q, make_residual_args(m, cam, f, fractions)))
    nt = 2 * m.n_tips
    np.testing.assert_allclose(np.asarray(e_tip), np.linalg.norm(r[:nt].reshape(-1, 2), axis=-1), rtol=1e-12)
    np.testing.assert_allclose(np.asarray(e_link), np.abs(r[nt:].reshape(m.n_links, 3)).max(-1), rtol=1e-12)
    assert float(e_link[0]) == 0.0 and float(e_link[1:].min()) > 0
