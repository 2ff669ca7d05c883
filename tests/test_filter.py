import jax
import jax.numpy as jnp
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from jaxhand.filter import (
    KalmanState,
    damp_unseen,
    ghk_gains,
    ghk_init,
    ghk_predict,
    ghk_update,
    kalman_predict,
    kalman_update,
    marginal_information,
    seen_share,
    width_update,
)


def test_ghk_gains_for_theta_0_85():
    g, h, k = ghk_gains(0.85)
    np.testing.assert_allclose([g, h, k], [1 - 0.85**3, 1.5 * (1 - 0.85**2) * 0.15, 0.5 * 0.15**3])
    np.testing.assert_allclose(ghk_gains(0.0), (1.0, 1.5, 0.5))
    np.testing.assert_allclose(ghk_gains(1.0), (0.0, 0.0, 0.0))


def test_one_ghk_step_by_hand():
    s = ghk_init(jnp.array([1.0]), jnp.array([2.0]), jnp.array([4.0]))
    p = ghk_predict(s, 0.5)  # x = 1 + 2*0.5 + 4*0.125 = 2.5, v = 2 + 4*0.5 = 4, a = 4
    np.testing.assert_allclose([p.x[0], p.v[0], p.a[0]], [2.5, 4.0, 4.0])
    theta = 0.5
    g, h, k = 0.875, 1.5 * 0.75 * 0.5, 0.5 * 0.125
    u = ghk_update(p, jnp.array([3.5]), theta, 0.5)  # e = 1
    np.testing.assert_allclose([u.x[0], u.v[0], u.a[0]], [2.5 + g, 4.0 + h / 0.5, 4.0 + 2 * k / 0.25])


def test_ghk_tracks_constant_acceleration_without_lag():
    dt, theta = 0.04, 0.85
    t = np.arange(300) * dt
    truth = 0.3 + 1.5 * t - 2.0 * t**2
    s = ghk_init(jnp.array([0.0]))
    for y in truth:
        s = ghk_update(ghk_predict(s, dt), jnp.array([y]), theta, dt)
    assert abs(float(s.x[0]) - truth[-1]) < 1e-6
    assert abs(float(s.v[0]) - (1.5 - 4.0 * t[-1])) < 1e-4


def test_ghk_invalid_measurement_keeps_prediction():
    s = ghk_predict(ghk_init(jnp.array([1.0, 2.0]), jnp.array([1.0, 1.0])), 1.0)
    u = ghk_update(s, jnp.array([10.0, 10.0]), 0.5, 1.0, valid=jnp.array([True, False]))
    assert float(u.x[1]) == 3.0 and float(u.x[0]) != 2.0


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 10_000))
def test_kalman_keeps_P_symmetric_psd(seed):
    rng = np.random.default_rng(seed)
    n, m = 3, 2
    A = jnp.asarray(np.eye(n) + 0.1 * rng.normal(size=(n, n)))
    H = jnp.asarray(rng.normal(size=(m, n)))
    L = rng.normal(size=(n, n))
    Q = jnp.asarray(L @ L.T * 0.01 + 1e-6 * np.eye(n))
    R = jnp.asarray(np.diag(rng.uniform(0.01, 1.0, m)))
    s = KalmanState(x=jnp.zeros(n), P=jnp.eye(n))
    for _ in range(20):
        s = kalman_update(kalman_predict(s, A, Q), jnp.asarray(rng.normal(size=m)), H, R)
        P = np.asarray(s.P)
        assert np.allclose(P, P.T, atol=0)
        assert np.linalg.eigvalsh(P).min() > -1e-12


def test_kalman_estimates_a_constant():
    rng = np.random.default_rng(0)
    s = KalmanState(x=jnp.zeros(1), P=jnp.eye(1) * 100.0)
    A, Q, H, R = jnp.eye(1), jnp.zeros((1, 1)), jnp.eye(1), jnp.eye(1) * 0.25
    ys = 7.0 + rng.normal(0, 0.5, 400)
    for y in ys:
        s = kalman_update(kalman_predict(s, A, Q), jnp.array([y]), H, R)
    # With Q = 0 the filter is the recursive mean (up to the prior's weight 0.25/100)
    np.testing.assert_allclose(float(s.x[0]), ys.mean(), atol=1e-3)


def test_width_update_appendix_e():
    p = width_update(jnp.array([10.0, 8.0]), jnp.array([[12.0, 14.0, 0.0], [1.0, 2.0, 3.0]]),
                     jnp.array([[True, True, False], [False, False, False]]), 0.5)
    np.testing.assert_allclose(p, [(1 - 0.5) * 10.0 + 0.5 * 13.0, 8.0])


def test_marginal_information_by_hand():
    # Lambda = [[2, 1], [1, 1]]: its inverse is [[1, -1], [-1, 2]], so the marginals are 1 and 1/2
    lam = jnp.array([[2.0, 1.0], [1.0, 1.0]])
    np.testing.assert_allclose(marginal_information(lam, 1e-12), [1.0, 0.5], rtol=1e-9)
    # an entry without features (a zero row and column) has none, up to eps; the other keeps its own
    hidden = jnp.array([[4.0, 0.0], [0.0, 0.0]])
    np.testing.assert_allclose(marginal_information(hidden, 1e-9), [4.0, 1e-9], rtol=1e-6)
    # the share seen: against a reference with nothing hidden; an entry the reference does not see counts as seen
    ref = jnp.diag(jnp.array([4.0, 2.0, 1.0, 0.0]))
    np.testing.assert_allclose(seen_share(jnp.diag(jnp.array([4.0, 1.0, 0.0, 0.0])), ref), [1.0, 0.5, 0.0, 1.0],
                               atol=1e-6)


def test_seen_share_under_vmap_takes_one_eigh_and_matches_the_single_call():
    rng = np.random.default_rng(2)
    A = rng.normal(size=(3, 5, 6))
    seen = np.asarray([1.0, 1.0, 1.0, 0.0, 1.0])   # entry 3 hidden
    infos = jnp.asarray(A @ np.swapaxes(A, 1, 2) * np.outer(seen, seen))
    ref = jnp.asarray(A[0] @ A[0].T)
    batched = jax.jit(jax.vmap(lambda lam: seen_share(lam, ref)))
    # one batched call: two independent ones can starve jaxlib's CPU thread pool
    assert batched.lower(infos).compile().as_text().count("lapack_dsyevd") == 1
    got = np.asarray(batched(infos))
    for k in range(3):
        np.testing.assert_allclose(got[k], np.asarray(seen_share(infos[k], ref)), rtol=1e-9)
    assert got[:, 3].max() < 1e-6 and got.min() >= 0.0   # sanity: the hidden entry is unseen


def test_damp_unseen_by_hand():
    s = ghk_init(jnp.array([1.0, 2.0, 3.0]), jnp.array([4.0, 4.0, 4.0]), jnp.array([8.0, 8.0, 8.0]))
    d = damp_unseen(s, jnp.array([1.0, 0.0, 0.5]), 0.25)   # keeps 1, 0.25 and 0.5 + 0.5 * 0.25
    np.testing.assert_allclose(d.x, [1.0, 2.0, 3.0])
    np.testing.assert_allclose(d.v, [4.0, 1.0, 2.5])
    np.testing.assert_allclose(d.a, [8.0, 2.0, 5.0])


def test_a_hidden_joint_stays_put_when_damped():
    """A joint followed while it accelerates, then hidden (the solve returns the prediction, so
    no innovation): undamped, the filter integrates its last velocity and acceleration on and on;
    damped with tau = 0.2 s it stops within about v tau of where it was last seen."""
    dt, theta, tau = 0.04, 0.85, 0.2
    t = np.arange(40) * dt
    seen_q = 0.5 * t**2   # rad: accelerating at 1 rad/s^2, at 1.56 rad/s when hidden
    ends = {}
    for damped in (False, True):
        s = ghk_init(jnp.array([0.0]))
        for y in seen_q:
            s = ghk_predict(ghk_update(s, jnp.array([y]), theta, dt), dt)
        last = float(s.x[0])
        for _ in range(200):   # 8 s hidden: the measurement is the prediction itself
            u = ghk_update(s, s.x, theta, dt)
            if damped:
                u = damp_unseen(u, jnp.array([0.0]), np.exp(-dt / tau))
            s = ghk_predict(u, dt)
        ends[damped] = float(s.x[0]) - last
    assert ends[True] < 1.6 * 2 * tau   # within twice v tau of the last seen pose
    assert ends[False] > 10.0           # undamped it runs on for radians (past any joint limit)
