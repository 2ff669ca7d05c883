"""The smoothest-path start of a sequence fit: the Viterbi choice against brute force, and the
batched landmark fit with the DIP-PIP term."""

import itertools

import jax
import jax.numpy as jnp
import numpy as np

import jaxhand as jh
from jaxhand.landmarks import (
    BatchConfig,
    fit_landmarks_batch,
    landmark_map,
    landmark_positions,
    landmark_residuals,
    make_landmark_args,
    make_landmarks,
)
from jaxhand.landmarks._paths import _viterbi
from jaxhand.priors import dip_pip_coupling


def _pair(d, Ha, Hb, w):
    # the least 0.5 (x-a)^T Ha (x-a) + 0.5 (y-b)^T Hb (y-b) + 0.5 |w (y - x)|^2, by solving for x, y
    m = len(d)
    A = np.block([[Ha + np.diag(w * w), -np.diag(w * w)], [-np.diag(w * w), Hb + np.diag(w * w)]])
    a, b = np.zeros(m), d                          # candidates at 0 and d
    rhs = np.concatenate([Ha @ a, Hb @ b])
    xy = np.linalg.solve(A, rhs)
    x, y = xy[:m], xy[m:]
    return 0.5 * ((x - a) @ Ha @ (x - a) + (y - b) @ Hb @ (y - b) + np.sum((w * (y - x)) ** 2))


def test_viterbi_matches_brute_force_with_the_marginal_pair_cost():
    rng = np.random.default_rng(3)
    T, K, m = 4, 3, 2
    unary = rng.uniform(0, 5, (T, K))
    Q = rng.normal(0, 1, (T, K, m))
    G = rng.normal(0, 1, (T, K, m, m))
    H = G @ np.swapaxes(G, -1, -2) + 0.1 * np.eye(m)
    w = np.array([2.0, 0.5])
    floor = 1e-3 * np.eye(m)         # the Viterbi's floor on every H

    def cost(path):
        total = sum(unary[t, k] for t, k in enumerate(path))
        for t in range(1, T):
            total += _pair(Q[t, path[t]] - Q[t - 1, path[t - 1]], H[t - 1, path[t - 1]] + floor,
                           H[t, path[t]] + floor, w)
        return total

    best = min(itertools.product(range(K), repeat=T), key=cost)
    assert tuple(_viterbi(unary, Q, w, H)) == best


def test_batched_fit_with_the_dip_pip_term_is_stationary():
    # The fit of noisy landmarks with the coupling rows must zero the gradient of the landmark
    # cost plus the coupling cost (a wrong Jacobian entry of the rows would leave it nonzero).
    m = jh.builtin_model("hand21")
    cam = jh.Perspective.look_at([30.0, -60.0, -450.0], [0.0, -80.0, 0.0], fov_deg=60, size=(640, 480))
    rng = np.random.default_rng(8)
    q_true = jh.random_q(m, rng, margin=0.2)
    p = landmark_positions(m, landmark_map(m), jh.kinematics.pose(m, jnp.asarray(q_true)), jnp.asarray(q_true))
    px = np.asarray(cam.project(p)[0]) + rng.normal(0, 2.0, (21, 2))
    coupling = dip_pip_coupling(m, weight=30.0, ratio=0.6)
    lm = make_landmarks(px[None, None])
    # this pose's middle MCP converges slowly with the coupling (40 steps, the default cap, stop
    # short of the tolerance); 200 let it converge
    res = fit_landmarks_batch(m, cam, lm, q_true[None], coupling=coupling, config=BatchConfig(max_steps=200))
    assert bool(np.asarray(res.converged)[0])
    q = np.asarray(res.q[0])
    args = make_landmark_args(m, (cam,), jax.tree_util.tree_map(lambda x: x[0], lm))

    def total(x):
        r = landmark_residuals(x, args)
        return 0.5 * jnp.sum(r * r) + 0.5 * jnp.sum(coupling(x) ** 2)

    g = np.asarray(jax.grad(total)(jnp.asarray(q)))
    inside = (q > np.asarray(m.q_lower) + 1e-9) & (q < np.asarray(m.q_upper) - 1e-9)
    assert np.max(np.abs(g[inside])) < 1e-4 * np.max(np.abs(np.asarray(jax.grad(total)(jnp.asarray(q_true)))))
    # the term pulled each finger's DIP towards 0.6 x PIP compared with the fit without it
    plain = np.asarray(fit_landmarks_batch(m, cam, lm, q_true[None]).q[0])
    gap = np.abs(np.asarray(coupling(q))) / 30.0
    assert np.all(gap <= np.abs(np.asarray(coupling(plain))) / 30.0 + 1e-9) and gap.sum() > 0
