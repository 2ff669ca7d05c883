"""Starting a whole-sequence fit without falling into one camera's mirror branches.

Seen by one camera, a finger flexed towards the camera and one flexed as far away from it
project almost alike, and a fit started from the previous frame keeps whichever branch it began
in, even where the joint limits later make that branch fit badly. This module gives the
sequence solve a start that chooses the branch from the whole sequence:

1. every frame is fitted from several starts at once (:func:`joint_starts`: the model's default,
   the joints at fixed fractions of their ranges and at seeded uniform draws within them, plus
   any caller candidates, such as the frame-by-frame track), one batched solve of frames x starts
   problems;
2. the joints split into independent blocks (:func:`independent_blocks`): two joints are in one
   block when some landmark moves with both. Each finger is a block, so each finger takes its
   branch from whichever start found it, whatever the others did. A free palm moves every
   landmark; its entries belong to no block and ride on the first candidate (the frame-by-frame
   track), and each candidate's finger is judged by its own fit, palm included;
3. per block, the path through the frames' candidates that minimises the landmark cost of the
   block's points and its fingers' DIP-PIP term plus the first-difference smoothness term of
   :class:`~jaxhand.landmarks.SequenceConfig` (the sequence objective without its shape terms),
   found by dynamic programming (Viterbi: O(frames x candidates^2) per block, over each frame's
   distinct candidates: most starts reach the same few fits). With ``branch_rest_px_per_rad``
   the cost also holds a prior towards the rest pose, so that of two mirror branches that fit
   alike the one nearer rest wins (the sequence solve itself has no such term). The cost of a
   step between two candidates is the least smoothness plus data cost of two states near them,
   each candidate's data cost a quadratic about it (its Gauss-Newton matrix): along a direction
   the landmarks hardly see (a finger near its fold, seen by one camera) the fits scatter, and
   that scatter must not make the right branch look rougher than a wrong one. The per-frame
   fits carry the DIP-PIP term when the configuration has one, as the sequence solve does;
4. ``rounds``: every frame also from the chosen path's states at the frames before and after,
   the refined fits joining the candidates, and step 3 again (a branch one frame found spreads
   to its neighbours); the rounds stop early when the path no longer changes;
5. one path per smoothness scale: the weight that separates branches best differs from one
   finger to the next, so the caller may solve the sequence from each and keep, per block, the
   solve of least cost (:func:`block_costs`; :func:`~jaxhand.landmarks.fit_landmark_sequence`
   does).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..camera import as_rig
from ..model import Model
from ._convention import LandmarkMap
from ._fit import BatchConfig, _as_float_landmarks, fit_landmarks_batch
from ._residuals import LandmarkArgs, Landmarks, _dependence, landmark_residuals
from ._sequence import SequenceConfig, _accel_weights, _unit_weights, rest_weights, sequence_coupling

__all__ = ["joint_starts", "independent_blocks", "smoothest_paths", "block_costs", "START_FRACTIONS"]

#: Fractions of each joint's range at which :func:`joint_starts` places the joints.
START_FRACTIONS = (0.1, 0.3, 0.5, 0.7, 0.9)


def joint_starts(model: Model, fractions=START_FRACTIONS, *, draws: int = 16, seed: int = 0) -> np.ndarray:
    """(1 + len(fractions) + draws, n_q) starts: the default state, every joint (not the base) at
    ``lower + f * (upper - lower)`` for each fraction f, then ``draws`` states with each joint
    uniform in its range (``numpy.random.default_rng(seed)``). Joints with an infinite limit
    keep their default. The draws mix the joints of one chain (a thumb's abduction against its
    flexion), which the common fractions do not."""
    q0 = np.asarray(model.q_default, float)
    lo, hi = np.asarray(model.q_lower, float), np.asarray(model.q_upper, float)
    joint = np.zeros(model.n_q, bool)
    joint[model.n_base_q:] = True
    joint &= np.isfinite(lo) & np.isfinite(hi)
    out = [q0]
    for f in fractions:
        out.append(np.where(joint, lo + f * (hi - lo), q0))
    u = np.random.default_rng(seed).uniform(size=(draws, model.n_q))
    out.extend(np.where(joint, lo + u * (np.where(joint, hi, 0.0) - np.where(joint, lo, 0.0)), q0))
    return np.stack(out)


def independent_blocks(model: Model, lmap: LandmarkMap) -> list[np.ndarray]:
    """The joint entries in groups no landmark couples (connected components of "moves a common
    point"), given the palm: a free palm's entries, which move every landmark, and q entries
    that move no landmark are left out. Each group: sorted q indices."""
    dep = np.array(_dependence(model, lmap))           # (21, n_q)
    dep[:, :model.n_base_q] = False                    # given the palm, each finger is a group
    parent = list(range(model.n_q))

    def root(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for row in dep:
        ks = np.nonzero(row)[0]
        for k in ks[1:]:
            parent[root(k)] = root(ks[0])
    seen = dep.any(axis=0)
    groups: dict[int, list[int]] = {}
    for k in np.nonzero(seen)[0]:
        groups.setdefault(root(int(k)), []).append(int(k))
    return [np.array(sorted(g)) for g in groups.values()]


@eqx.filter_jit
def _point_terms(model, rig, lmap, coupling, landmarks, Q):
    """(B, 21) squared landmark residuals per point (all cameras and the 3-D entries), (B,
    fingers) squared DIP-PIP residuals and (B, n_q, n_q) the Gauss-Newton matrix J^T J of both."""
    n = len(rig)

    def one(q, lm):
        r = landmark_residuals(q, LandmarkArgs(model=model, cameras=rig, lmap=lmap, landmarks=lm))
        J = jnp.concatenate([jax.jacfwd(landmark_residuals)(q, LandmarkArgs(model=model, cameras=rig, lmap=lmap,
                                                                            landmarks=lm)),
                             jax.jacfwd(coupling)(q)])
        r2 = jnp.sum(r[: 2 * 21 * n].reshape(n, 21, 2) ** 2, axis=(0, 2))
        return r2 + jnp.sum(r[2 * 21 * n:].reshape(21, 3) ** 2, axis=-1), coupling(q) ** 2, J.T @ J

    return jax.vmap(one)(Q, landmarks)


def _viterbi(unary: np.ndarray, Q: np.ndarray, w: np.ndarray, H: np.ndarray) -> np.ndarray:
    """Candidate index per frame minimising sum_t unary[t, k_t] + pair(t-1, t).

    unary (T, K); Q (T, K, m) the block's entries; w (m,) the smoothness weights; H (T, K, m, m)
    each candidate's Gauss-Newton matrix. pair = 0.5 d^T (Ha^-1 + Hb^-1 + W^-1)^-1 d with
    d = Q[t, b] - Q[t-1, a] and W = diag(w^2): the least of 0.5 (x - a)^T Ha (x - a) +
    0.5 (y - b)^T Hb (y - b) + 0.5 |w (y - x)|^2 over the two states x, y."""
    T, K = unary.shape
    m = Q.shape[-1]
    # Guard: a direction no landmark sees has H ~ 0; the floor keeps the inverse finite
    # (1e3 rad^2 of spread: free).
    S = np.linalg.inv(H + 1e-3 * np.eye(m))                          # (T, K, m, m)
    Winv = np.diag(1.0 / np.maximum(w * w, 1e-12))
    V = unary[0].copy()
    back = np.zeros((T, K), int)
    for t in range(1, T):
        d = Q[t][None, :, :] - Q[t - 1][:, None, :]                  # (K prev, K now, m)
        M = S[t - 1][:, None] + S[t][None, :] + Winv
        pair = 0.5 * np.sum(d * np.linalg.solve(M, d[..., None])[..., 0], axis=-1)
        total = V[:, None] + pair
        back[t] = np.argmin(total, axis=0)
        V = unary[t] + total[back[t], np.arange(K)]
    path = np.zeros(T, int)
    path[-1] = int(np.argmin(V))
    for t in range(T - 1, 0, -1):
        path[t - 1] = back[t, path[t]]
    return path


def _choose(model, lmap, config, scale, Q, cost, coupled, H) -> np.ndarray:
    """Per independent block, the Viterbi path through the candidates Q (T, K, n_q) with the
    point costs ``cost`` (T, K, 21), squared DIP-PIP residuals ``coupled`` (T, K, fingers),
    Gauss-Newton matrices H (T, K, n_q, n_q) and the smoothness weights times ``scale``."""
    T = Q.shape[0]
    dep = _dependence(model, lmap)
    w = scale * np.asarray(_unit_weights(model, config, jnp.asarray(0.0).dtype))
    pip = np.asarray(sequence_coupling(model, config).pip_index, int)
    q = Q[:, 0].copy()
    wr = rest_weights(model, config)
    rest = (wr * (Q - np.asarray(model.q_default))) ** 2                       # (T, K, n_q)
    H = H + np.diag(wr * wr)
    for block in independent_blocks(model, lmap):
        points = dep[:, block].any(axis=1)
        unary = 0.5 * (cost[..., points].sum(-1) + coupled[..., np.isin(pip, block)].sum(-1)
                       + rest[..., block].sum(-1))
        keep = _distinct_index(Q[..., block])                      # (T, Kb): many starts share a fit
        Hb = H[..., block[:, None], block[None, :]]
        path = _viterbi(np.take_along_axis(unary, keep, 1), np.take_along_axis(Q[..., block], keep[..., None], 1),
                        w[block], np.take_along_axis(Hb, keep[..., None, None], 1))
        q[:, block] = Q[np.arange(T), keep[np.arange(T), path]][:, block]
    return q


def _distinct_index(X: np.ndarray, tol: float = 1e-3) -> np.ndarray:
    """(T, Kb) indices of each frame's distinct rows of X (T, K, m) (equal after rounding to
    ``tol``), padded with the frame's first; Kb the most any frame has."""
    rows = []
    for x in X:
        _, first = np.unique(np.round(x / tol), axis=0, return_index=True)
        rows.append(np.sort(first))
    Kb = max(len(r) for r in rows)
    return np.stack([np.concatenate([r, np.full(Kb - len(r), r[0])]) for r in rows])


def smoothest_paths(model: Model, cameras, landmarks: Landmarks, lmap: LandmarkMap, *, candidates=None,
                    config: SequenceConfig | None = None, batch_config: BatchConfig | None = None,
                    fractions=START_FRACTIONS, draws: int = 16, rounds: int = 2,
                    scales=(1.0,)) -> np.ndarray:
    """(S, T, n_q) starts of a sequence fit, one per smoothness scale: per independent block of
    joints, the smoothest low-cost path through every frame's candidate fits (see the module
    docstring).

    Args:
        landmarks: (T, cams, 21, 2) batched :class:`Landmarks`.
        candidates: optional (C, T, n_q) states also offered per frame (refined like the starts);
            the starts of a moving base take their base entries from the first candidate.
        config: the smoothness weights and the DIP-PIP term (:class:`~jaxhand.landmarks.SequenceConfig`).
        fractions, draws: the starts of :func:`joint_starts` (seed 0).
        rounds: rounds of neighbour starts (step 4); 0: none.
        scales: (S,) factors on the smoothness weights of the paths' choice; each gives one path
            (the rounds follow the first).
    """
    rig = as_rig(cameras)
    config = SequenceConfig() if config is None else config
    T = landmarks.px.shape[0]
    fixed = joint_starts(model, fractions, draws=draws)
    starts = np.array(np.broadcast_to(fixed, (T,) + fixed.shape))
    if candidates is not None:
        cand = np.asarray(candidates, float).transpose(1, 0, 2)              # (T, C, n_q)
        starts[..., :model.n_base_q] = cand[:, :1, :model.n_base_q]          # the joint starts ride on the palm
        starts = np.concatenate([cand, starts], axis=1)
    coupling = sequence_coupling(model, config)
    fit_coupling = coupling if float(config.dip_pip_px_per_rad) > 0 else None
    lm = _as_float_landmarks(landmarks)
    pool = []

    def refine(S):               # (T, K, n_q) starts -> their fits, point costs, DIP-PIP terms, J^T J
        K = S.shape[1]
        lmK = jax.tree_util.tree_map(lambda x: jnp.repeat(x, K, axis=0), lm)
        res = fit_landmarks_batch(model, rig, lmK, S.reshape(T * K, model.n_q), config=batch_config, lmap=lmap,
                                  coupling=fit_coupling)
        cost, coupled, H = (np.asarray(x) for x in _point_terms(model, rig, lmap, coupling, lmK, res.q))
        pool.append((np.asarray(res.q).reshape(T, K, model.n_q), cost.reshape(T, K, 21),
                     coupled.reshape(T, K, -1), H.reshape(T, K, model.n_q, model.n_q)))

    def choose(scale):
        return _choose(model, lmap, config, scale, *(np.concatenate(x, axis=1) for x in zip(*pool)))

    refine(starts)
    q = choose(scales[0])
    for _ in range(rounds):
        # the path's states at the frames before and after as starts: a branch one frame found
        # spreads to its neighbours
        refine(np.stack([np.concatenate([q[:1], q[:-1]]), np.concatenate([q[1:], q[-1:]])], axis=1))
        q_new = choose(scales[0])
        if np.array_equal(q_new, q):
            break
        q = q_new
    return np.stack([q] + [choose(s) for s in scales[1:]])


def block_costs(model: Model, cameras, landmarks: Landmarks, lmap: LandmarkMap, config: SequenceConfig, Q,
                ratios) -> np.ndarray:
    """(blocks,) the sequence objective of :func:`~jaxhand.landmarks.fit_sequence` (no shape)
    split over :func:`independent_blocks`: each block's points, its fingers' DIP-PIP terms at the
    ratios (fingers,) and their priors, and the smoothness of its entries, for states Q (T, n_q);
    plus the branch choice's rest prior (``branch_rest_px_per_rad``), the cost that picks a branch."""
    rig = as_rig(cameras)
    coupling = eqx.tree_at(lambda c: c.ratio, sequence_coupling(model, config), jnp.asarray(ratios, float))
    cost, coupled, _ = (np.asarray(x) for x in _point_terms(model, rig, lmap, coupling, _as_float_landmarks(landmarks),
                                                           jnp.asarray(Q)))
    dtype = jnp.asarray(0.0).dtype
    w = np.asarray(_unit_weights(model, config, dtype))
    a = np.asarray(_accel_weights(model, config, dtype))
    prior = (float(config.dip_pip_ratio_prior_px) * (np.asarray(ratios) - float(config.dip_pip_ratio))) ** 2
    pip = np.asarray(coupling.pip_index, int)
    dep = _dependence(model, lmap)
    d1, d2 = np.diff(Q, axis=0) * w, np.diff(Q, 2, axis=0) * a
    rest = (rest_weights(model, config) * (np.asarray(Q) - np.asarray(model.q_default))) ** 2
    out = []
    for block in independent_blocks(model, lmap):
        fingers = np.isin(pip, block)
        out.append(0.5 * (cost[:, dep[:, block].any(axis=1)].sum() + coupled[:, fingers].sum() + prior[fingers].sum()
                          + np.sum(d1[:, block] ** 2) + np.sum(d2[:, block] ** 2) + np.sum(rest[:, block])))
    return np.array(out)
