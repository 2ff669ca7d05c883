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
