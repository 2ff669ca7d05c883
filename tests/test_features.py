import re

import jax.numpy as jnp
import numpy as np
import pytest
from helpers import fit_camera

import jaxhand as jh
from jaxhand.features import empty_features, features_from_pose, line_through, validate_features


def test_line_through_hand_case():
    np.testing.assert_allclose(line_through(jnp.array([0.0, 2.0]), jnp.array([4.0, 2.0])), [0.0, -1.0, -2.0])
    np.testing.assert_allclose(line_through(jnp.array([1.0, 1.0]), jnp.array([1.0, 1.0])), [1.0, 0.0, 1.0])


def test_exact_features_pass_through_projected_axes():
    m = jh.builtin_model("hand21")
    cam = fit_camera(m)
    q = jh.random_q(m, np.random.default_rng(3))
    (f,) = features_from_pose(m, cam, q)
    v = jh.project_pose(m, cam, jnp.asarray(q))
    for p in (v.link_start_px, v.link_end_px, 0.3 * v.link_start_px + 0.7 * v.link_end_px):
        np.testing.assert_allclose(jnp.sum(f.lines[:, :2] * p, -1) - f.lines[:, 2], 0.0, atol=1e-9)
    np.testing.assert_allclose(f.tips, v.tips_px)
    assert validate_features(m, (cam,), (f,))[0] is f


def test_validate_features_errors():
    m = jh.builtin_model("index")
    cam = fit_camera(m)
    with pytest.raises(jh.InputError, match=r"one Features per camera \(1\), got 2"):
        validate_features(m, cam, (empty_features(m), empty_features(m)))
    bad = empty_features(m)
    bad = type(bad)(bad.lines, bad.line_valid.at[0].set(True), bad.line_weight, bad.tips, bad.tip_valid,
                    bad.tip_weight)
    bad = type(bad)(bad.lines.at[0, 0].set(jnp.nan), *[getattr(bad, n) for n in
                    ("line_valid", "line_weight", "tips", "tip_valid", "tip_weight")])
    with pytest.raises(jh.InputError, match=r"valid line or tip holds NaN"):
        validate_features(m, cam, bad)


def test_feature_value_checks_agree_on_host_and_in_jit():
    import jax

    from jaxhand.features import FEATURE_CHECKS, feature_value_checks

    m = jh.builtin_model("two_fingers")
    cam = jh.Orthographic(R=np.eye(3), t=np.array([0.0, 0.0, 500.0]), scale=1.0, center=(160, 120), size=(320, 240))
    good = features_from_pose(m, cam, m.q_default)[0]
    bad = {
        "finite": eqx_set(good, "lines", good.lines.at[1, 2].set(jnp.nan)),
        "unit_normal": eqx_set(good, "lines", good.lines.at[0, :2].multiply(1.1)),
        "line_weight": eqx_set(good, "line_weight", good.line_weight.at[0].set(-1.0)),
        "tip_weight": eqx_set(good, "tip_weight", good.tip_weight.at[0].set(jnp.inf)),
    }
    masked = eqx_set(eqx_set(good, "lines", good.lines.at[1].set(jnp.nan)), "line_valid",
                     good.line_valid.at[1].set(False))
    jitted = jax.jit(feature_value_checks)
    names = [n for n, _ in FEATURE_CHECKS]
    for label, f in [("good", good), ("masked", masked)] + list(bad.items()):
        want = [n != label for n in names]
        host = [bool(x) for x in feature_value_checks(_as_numpy(f), np)]
        assert host == want == [bool(x) for x in jitted(f)], label
        if label in bad:
            with pytest.raises(jh.InputError, match=re.escape(f"features[0]{dict(FEATURE_CHECKS)[label]}")):
                validate_features(m, cam, f)


def eqx_set(f, name, value):
    import equinox as eqx

    return eqx.tree_at(lambda g: getattr(g, name), f, value)


def _as_numpy(f):
    import types

    return types.SimpleNamespace(**{k: np.asarray(getattr(f, k)) for k in
                                    ("lines", "line_valid", "line_weight", "tips", "tip_valid", "tip_weight")})


def test_features_from_points_is_the_rule_of_both_exact_feature_builders():
    from jaxhand.features import features_from_points
    from jaxhand.solve import features_from_poses

    m = jh.builtin_model("index_thumb")
    cam = jh.Orthographic(R=np.eye(3), t=np.array([0.0, 0.0, 500.0]), scale=1.0, center=(160, 120), size=(320, 240))
    qs = jh.random_q(m, np.random.default_rng(1), 3)
    batch = features_from_poses(m, cam, qs)[0]
    for b, q in enumerate(qs):
        one = features_from_pose(m, cam, q)[0]
        v = jh.project_pose(m, cam, q)
        direct = features_from_points(v.link_start_px, v.link_end_px, v.tips_px)
        for name in ("lines", "line_valid", "tips", "tip_valid", "line_weight"):
            np.testing.assert_array_equal(np.asarray(getattr(one, name)), np.asarray(getattr(direct, name)))
            np.testing.assert_allclose(np.asarray(getattr(batch, name))[b], np.asarray(getattr(one, name)), atol=1e-9)
