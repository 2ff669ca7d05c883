"""The smoothest-path start of a sequence fit: the Viterbi choice against brute force, and the
batched landmark fit with the DIP-PIP term."""

import itertools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

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


def _devset_model():
    from pathlib import Path

    from jaxhand.io import load_devset

    seq = load_devset(Path(__file__).resolve().parent.parent / "data" / "mujoco" / "thumb_opposition")
    return seq, seq.model, landmark_map(seq.model, tips="cap_centre")


def test_branch_rest_prior_picks_the_mirror_branch_nearer_rest():
    # Two candidates per frame for every finger: the rest pose and a "mirror" 25 deg flexed and
    # 13 deg abducted at the base joint that fits a little better (rest: 4 points of 0.05 px^2
    # each, halved, 0.1 px^2 per frame more). Without the prior the Viterbi keeps the better
    # fit; 3 px per rad towards rest makes the rest branch win (0.5 * 9 * (0.44^2 + 0.23^2)
    # ~ 1.1 px^2 per frame against 0.1), in every finger.
    from jaxhand.landmarks import SequenceConfig
    from jaxhand.landmarks._paths import _choose

    _, m, lmap = _devset_model()
    T, n = 6, m.n_q
    names = list(m.q_names)
    rest = np.asarray(m.q_default, float)
    mirror = rest.copy()
    for f in ("thumb_cmc", "index_mcp", "middle_mcp", "ring_mcp", "little_mcp"):
        mirror[names.index(f + "_flex")] += np.radians(25.0)
        mirror[names.index(f + "_abd")] -= np.radians(13.0)
    Q = np.broadcast_to(np.stack([rest, mirror]), (T, 2, n)).copy()
    cost = np.zeros((T, 2, 21))
    cost[:, 0] = 0.05
    coupled = np.zeros((T, 2, 4))
    H = np.broadcast_to(np.eye(n) * 1e4, (T, 2, n, n))
    plain = _choose(m, lmap, SequenceConfig(smooth_px_per_rad=30.0), 1.0, Q, cost, coupled, H)
    prior = _choose(m, lmap, SequenceConfig(smooth_px_per_rad=30.0, branch_rest_px_per_rad=3.0), 1.0, Q, cost,
                    coupled, H)
    np.testing.assert_allclose(plain, Q[:, 1])
    np.testing.assert_allclose(prior, Q[:, 0])


def test_block_costs_add_the_branch_rest_prior_per_finger():
    from jaxhand.landmarks import SequenceConfig, block_costs, independent_blocks

    seq, m, lmap = _devset_model()
    T = 3
    Q = np.asarray(seq.truth.q[40:40 + T])
    lm = make_landmarks(np.moveaxis(seq.truth.points_px[:1, 40:40 + T], 0, 1))
    ratios = np.full(4, 0.6)
    plain, with_prior = (block_costs(m, seq.cameras[0], lm, lmap, SequenceConfig(
        smooth_px_per_rad=30.0, dip_pip_px_per_rad=11.5, branch_rest_px_per_rad=r), Q, ratios) for r in (0.0, 3.0))
    joint = np.asarray(m.is_angle) & (np.arange(m.n_q) >= m.n_base_q)
    d = np.where(joint, Q - np.asarray(m.q_default), 0.0)
    expect = [0.5 * 9.0 * np.sum(d[:, b] ** 2) for b in independent_blocks(m, lmap)]
    np.testing.assert_allclose(with_prior - plain, expect, rtol=1e-9, atol=1e-9)
    assert min(expect) > 0


def test_independent_blocks_are_the_fingers_given_a_free_palm():
    # A free palm moves every landmark; given it, each finger (thumb included) is a block of its
    # own, the palm's 7 entries in none: the same blocks as the fixed-palm hand's, 7 entries on.
    from jaxhand.landmarks import independent_blocks

    free, fixed = jh.builtin_model("hand27_right"), jh.builtin_model("hand21_right")
    blocks = independent_blocks(free, landmark_map(free))
    assert free.n_base_q == 7 and fixed.n_base_q == 0
    assert len(blocks) == 5
    names = list(free.q_names)
    for b in blocks:
        assert b.min() >= free.n_base_q
        assert len({names[k].split("_")[0] for k in b}) == 1, [names[k] for k in b]
    expect = [b + free.n_base_q for b in independent_blocks(fixed, landmark_map(fixed))]
    assert sorted(map(tuple, blocks)) == sorted(map(tuple, expect))


@pytest.mark.slow
def test_the_real_videos_curling_fingers_leave_their_mirror_branch_on_a_free_palm():
    # Frames 54-73 of the real video, where the fingers curl towards the camera. Fitted frame by
    # frame ("track"), 4 of the 20 frames have all 21 points within 15 px: over the whole video
    # that fit kept the curling fingers in their mirror branch, bent back at the MCP with the PIP
    # straight at its limit. The paths (the default on a free palm too) choose each finger's
    # branch from the whole slice and put every frame on the fingers.
    from pathlib import Path

    from jaxhand.landmarks import (
        ON_FINGERS_PX,
        camera_from_fov,
        fit_landmark_sequence,
        load_landmarks,
        projected_landmarks,
    )

    seq = load_landmarks(Path(__file__).resolve().parent.parent / "data" / "real" / "human_hand_video.mediapipe.json")
    seq = seq.slice(54, 74)
    camera = camera_from_fov(seq.image_size, 60.0)
    m = jh.builtin_model("hand27_right")
    on = {}
    for init in ("track", "auto"):
        fit = fit_landmark_sequence(m, camera, seq.to_landmarks(), shape="auto", init=init, path_scales=(1.0,))
        d = np.linalg.norm(projected_landmarks(fit.model, camera, fit.q) - seq.px, axis=-1)
        on[init] = int(np.all(d <= ON_FINGERS_PX, axis=-1).sum())
        assert ("paths_s" in fit.timings_s) == (init == "auto")
    assert on == {"track": 4, "auto": 20}, on
