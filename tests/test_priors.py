import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import CompileCounter

import jaxhand as jh
from jaxhand.features import features_from_pose
from jaxhand.model import builtin_model
from jaxhand.priors import dip_pip_coupling, soft_limits, stack_priors, temporal_prior
from jaxhand.residuals import (
    DEFAULT_LINK_FRACTIONS,
    make_residual_args,
    n_residuals,
    residuals,
    residuals_and_jacobian,
)


@pytest.fixture(scope="module")
def hand21():
    return builtin_model("hand21")


def _central(f, q, h=1e-6):
    q = np.asarray(q, float)
    cols = []
    for i in range(q.size):
        e = np.zeros_like(q)
        e[i] = h
        cols.append((np.asarray(f(jnp.asarray(q + e))) - np.asarray(f(jnp.asarray(q - e)))) / (2 * h))
    return np.stack(cols, -1)


def test_dip_pip_finds_the_four_fingers_by_name(hand21):
    p = dip_pip_coupling(hand21)
    assert p.fingers == ("little", "ring", "middle", "index")
    assert [hand21.q_names[i] for i in p.dip_index] == ["little_dip", "ring_dip", "middle_dip", "index_dip"]


def test_dip_pip_golden_values(hand21):
    p = dip_pip_coupling(hand21, weight=2.0, ratio=0.5, fingers=("index",))
    q = np.zeros(hand21.n_q)
    q[hand21.q_lookup("index_pip")] = -0.6
    q[hand21.q_lookup("index_dip")] = -0.1
    np.testing.assert_allclose(p(jnp.asarray(q)), [2.0 * (-0.1 - 0.5 * -0.6)])  # 0.4
    q[hand21.q_lookup("index_dip")] = -0.3  # exactly half of the PIP: zero cost
    np.testing.assert_allclose(p(jnp.asarray(q)), [0.0], atol=1e-15)


def test_dip_pip_unknown_finger_is_an_error(hand21):
    with pytest.raises(ValueError, match="thumb"):
        dip_pip_coupling(hand21, fingers=("thumb",))


def test_soft_limits_zero_inside_linear_outside(hand21):
    p = soft_limits(hand21, weight=3.0, margin=0.1, names=("index_mcp", "index_pip"))
    lo, hi = np.asarray(hand21.q_lower), np.asarray(hand21.q_upper)
    i, j = hand21.q_lookup("index_mcp"), hand21.q_lookup("index_pip")
    q = np.asarray(hand21.q_default).copy()
    np.testing.assert_array_equal(p(jnp.asarray(q)), [0.0, 0.0])
    q[i] = hi[i] + 0.05  # inside the margin: still zero
    q[j] = lo[j] - 0.35  # 0.25 past the margin below
    np.testing.assert_allclose(p(jnp.asarray(q)), [0.0, -3.0 * 0.25])
    q[i] = hi[i] + 0.3
    np.testing.assert_allclose(p(jnp.asarray(q))[0], 3.0 * 0.2)


def test_soft_limits_with_a_negative_margin_act_inside_the_range(hand21):
    p = soft_limits(hand21, weight=2.0, margin=-0.2, names=("index_mcp",))
    i = hand21.q_lookup("index_mcp")
    lo, hi = float(hand21.q_lower[i]), float(hand21.q_upper[i])
    q = np.asarray(hand21.q_default).copy()
    q[i] = (lo + hi) / 2
    np.testing.assert_array_equal(p(jnp.asarray(q)), [0.0])
    q[i] = hi - 0.05   # 0.15 into the band below the upper limit
    np.testing.assert_allclose(p(jnp.asarray(q)), [2.0 * 0.15])
    q[i] = lo + 0.05
    np.testing.assert_allclose(p(jnp.asarray(q)), [-2.0 * 0.15])
    with pytest.raises(jh.InputError, match="margin finite"):
        soft_limits(hand21, margin=float("nan"))


def test_soft_limits_inside_the_range_stop_at_the_default_pose_and_zero(hand21):
    p = soft_limits(hand21, weight=1.0, margin=-3.0, names=("index_mcp",))   # a band wider than the range
    i = hand21.q_lookup("index_mcp")
    rest = float(hand21.q_default[i])
    assert rest < -0.1   # hand21 rests flexed: between its default and zero nothing costs
    q = np.asarray(hand21.q_default).copy()
    for angle, expected in ((rest, 0.0), (rest / 2, 0.0), (0.0, 0.0), (0.1, 0.1), (rest - 0.1, -0.1)):
        q[i] = angle
        np.testing.assert_allclose(p(jnp.asarray(q)), [expected], atol=1e-15)


def test_soft_limits_default_covers_every_joint_angle():
    m = builtin_model("hand27")
    p = soft_limits(m)
    assert len(p.index) == m.n_q - 7  # no base entries
    assert all(m.q_kinds[i] == "angle" for i in p.index)


@pytest.mark.parametrize("name", ["hand21", "hand27"])
def test_prior_jacobians_match_central_differences(name):
    m = builtin_model(name)
    priors = (dip_pip_coupling(m), soft_limits(m, margin=0.05))
    rng = np.random.default_rng(3)
    lo, hi = np.asarray(m.q_lower), np.asarray(m.q_upper)
    span = np.where(np.isfinite(hi - lo) & (hi - lo < 10), hi - lo, 1.0)
    # Points inside, and well outside, the limits (away from the kinks at limit +- margin).
    for scale in (0.0, 0.4):
        q = rng.uniform(lo + 0.1 * span, hi - 0.1 * span) if scale == 0 else \
            np.where(rng.uniform(size=m.n_q) < 0.5, lo - scale * span, hi + scale * span)
        q = np.where(np.asarray(m.is_angle), q, np.asarray(m.q_default))

        def f(x):
            return stack_priors(priors, x)

        J = jax.jit(jax.jacfwd(f))(jnp.asarray(q))
        np.testing.assert_allclose(J, _central(f, q), atol=1e-7)
        if scale > 0:
            assert np.abs(np.asarray(J)).sum() > 0


def test_priors_are_jit_compatible_and_retrace_free_for_new_weights(hand21):
    f = eqx.filter_jit(lambda p, q: p(q))
    q = jnp.asarray(hand21.q_default) - 0.3
    f(dip_pip_coupling(hand21, weight=1.0), q)
    with CompileCounter() as c:
        b = f(dip_pip_coupling(hand21, weight=5.0), q)  # traced weight: same program
    assert c.count == 0
    np.testing.assert_allclose(b, 5.0 * (-0.3 + 2 / 3 * 0.3) * np.ones(4))


def test_stack_priors_empty():
    assert stack_priors((), jnp.zeros(3)).shape == (0,)


def test_temporal_prior_golden_and_quaternion_free():
    model = builtin_model("hand27")
    q_pred = np.asarray(model.q_default, float)
    prior = temporal_prior(model, q_pred, sigma_deg=5.0, sigma_mm=2.0)
    q = q_pred.copy()
    q[model.q_names.index("index_pip")] += np.radians(10.0)
    q[model.q_names.index("palm_tx")] += 4.0
    r = np.asarray(prior(jnp.asarray(q)))
    assert r[model.q_names.index("index_pip")] == pytest.approx(2.0)   # 10 deg at sigma 5 deg
    assert r[model.q_names.index("palm_tx")] == pytest.approx(2.0)     # 4 mm at sigma 2 mm
    assert np.all(r[:4] == 0.0)                                        # the quaternion has no prior
    with pytest.raises(jh.InputError, match="sigmas must be > 0"):
        temporal_prior(model, q_pred, sigma_deg=0.0)


@pytest.mark.parametrize("jacobian", ["autodiff", "geometric"])
def test_priors_stack_under_the_image_residuals_with_their_jacobian(jacobian):
    model = builtin_model("two_fingers")
    cam = jh.Orthographic.fit(np.asarray(jh.forward(model, model.q_default).link_end))
    q_true = np.asarray(model.q_default, float) + np.radians([-10, -20, -15, -5, -30, -20])
    feats = features_from_pose(model, cam, q_true)
    priors = (dip_pip_coupling(model), temporal_prior(model, model.q_default, sigma_deg=20.0))
    args = make_residual_args(model, cam, feats, priors=priors)
    plain = make_residual_args(model, cam, feats)
    q = jnp.asarray(q_true)
    r, J = residuals_and_jacobian(q, args)
    n = n_residuals(model, 1, len(DEFAULT_LINK_FRACTIONS))
    assert r.shape == (n + 2 + model.n_q,) and np.array_equal(np.asarray(r[:n]), np.asarray(residuals(q, plain)))
    assert np.allclose(np.asarray(r[n:]), np.asarray(stack_priors(priors, q)), rtol=0, atol=1e-12)
    assert np.allclose(np.asarray(J), np.asarray(jax.jacfwd(residuals)(q, args)), rtol=0, atol=1e-9)
    assert np.allclose(np.asarray(residuals(q, args)), np.asarray(r), rtol=0, atol=1e-12)


def test_the_hyperextension_limit_acts_on_the_fingers_extension_side_only():
    from pathlib import Path

    from jaxhand.io import load_devset
    from jaxhand.track import PriorConfig
    from jaxhand.track._flexion import hyperextension_limits

    dev = Path(__file__).resolve().parent.parent / "data" / "mujoco"
    for m in (builtin_model("hand21"), load_devset(dev / "open_close").model):
        prior = hyperextension_limits(m, 30.0, 15.0)
        names = [m.q_names[i] for i in prior.index]
        assert len(names) == 12 and not any(n.startswith("thumb") for n in names)
        mcp = prior.index[names.index(next(n for n in names if n.startswith("index_mcp")))]
        ext = -1.0 if abs(float(m.q_upper[mcp])) >= abs(float(m.q_lower[mcp])) else 1.0   # the narrower side
        for deg, expected in ((10.0, 0.0), (25.0, 30.0 * np.radians(10.0)), (-60.0, 0.0)):   # -60: flexed
            q = np.asarray(m.q_default, float).copy()
            q[mcp] = np.radians(deg) * ext
            r = np.asarray(prior(jnp.asarray(q)))
            assert abs(r[prior.index.index(mcp)]) == pytest.approx(expected, abs=1e-12)
    for name in ("open_close", "fast_spread"):   # the truth never pays (fast_spread bends back 11 deg)
        seq = load_devset(dev / name)
        prior = hyperextension_limits(seq.model, 30.0, 15.0)
        assert float(np.abs(np.asarray(jax.vmap(prior)(jnp.asarray(seq.truth.q)))).max()) == 0.0
    with pytest.raises(jh.InputError, match="prior.hyperextension_weight: expected a finite number >= 0"):
        PriorConfig(hyperextension_weight=-1.0)
