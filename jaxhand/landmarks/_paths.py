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
   block when some landmark moves with both. With the palm fixed each finger is a block, so each
   finger takes its branch from whichever start found it, whatever the others did; a free palm
   moves every landmark, so all joints form one block;
3. per block, the path through the frames' candidates that minimises the landmark cost of the
   block's points and its fingers' DIP-PIP term plus the first-difference smoothness term of
   :class:`~jaxhand.landmarks.SequenceConfig` (the sequence objective without its shape terms),
   found by dynamic programming (Viterbi: O(frames x candidates^2) per block);
4. ``jumps`` rounds: every frame of the chosen path also from its kinematic jumps
   (:func:`jump_starts`: in each block, every subset of its hinges reflected across the folds
   where their links lie across the viewing ray, :func:`~jaxhand.kinematics.fold_turns`) and
   from the path's states at the frames before and after; the refined fits join the candidates
   and step 3 runs again over all of them. A finger's mirror branch that no fixed start reached
   is one jump away from the branch that was, and what one frame finds spreads to its
   neighbours. The rounds stop early when the path no longer changes.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..camera import as_rig
from ..kinematics import fold_hinges, fold_turns
from ..model import Model
from ..kinematics import pose as pose_at
from ._convention import FINGERS, POINT_NAMES, LandmarkMap, landmark_positions
from ._fit import BatchConfig, _as_float_landmarks, fit_landmarks_batch
from ._residuals import LandmarkArgs, Landmarks, _dependence, landmark_residuals, make_landmarks
from ._sequence import SequenceConfig, _unit_weights, sequence_coupling

__all__ = ["joint_starts", "jump_starts", "independent_blocks", "smoothest_paths", "START_FRACTIONS"]

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
    """The q entries in groups no landmark couples (connected components of "moves a common
    point"); q entries that move no landmark are left out. Each group: sorted q indices."""
    dep = _dependence(model, lmap)                     # (21, n_q)
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


def _viterbi(unary: np.ndarray, Q: np.ndarray, w: np.ndarray, H: np.ndarray | None = None) -> np.ndarray:
    """Candidate index per frame minimising sum_t unary[t, k_t] + pair(t-1, t).

    unary (T, K); Q (T, K, m) the block's entries; w (m,) the smoothness weights. Without H,
    pair = 0.5 |w (Q[t, k_t] - Q[t-1, k_{t-1}])|^2. With H (T, K, m, m), each candidate's
    Gauss-Newton matrix, pair = 0.5 d^T (Ha^-1 + Hb^-1 + W^-1)^-1 d, d = Q[t, b] - Q[t-1, a]:
    the least smoothness plus data cost of two states near the candidates, each a quadratic
    about its candidate. A direction the landmarks hardly see (a finger near its fold, seen
    by one camera) then costs little to jitter along, so a branch whose per-frame fits scatter
    along it is not outweighed by a smoother wrong one."""
    T, K = unary.shape
    m = Q.shape[-1]
    if H is not None:
        # Guard: a direction no landmark sees has H ~ 0; the floor keeps the inverse finite
        # (1e3 rad^2 of spread: free).
        S = np.linalg.inv(H + 1e-3 * np.eye(m))                      # (T, K, m, m)
        Winv = np.diag(1.0 / np.maximum(w * w, 1e-12))
    V = unary[0].copy()
    back = np.zeros((T, K), int)
    for t in range(1, T):
        d = Q[t][None, :, :] - Q[t - 1][:, None, :]                  # (K prev, K now, m)
        if H is None:
            pair = 0.5 * np.sum((d * w) ** 2, axis=-1)
        else:
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


@eqx.filter_jit
def _jump(model, camera, Q, hinge, mask):
    """Q (B, n_q) with hinge ``hinge`` (traced) of :func:`~jaxhand.kinematics.fold_hinges`
    reflected across its fold where ``mask`` (B,) is set and the fold exists, clipped into the
    limits."""
    joint = jnp.asarray(fold_hinges(model)[0])[hinge]
    turn, ok = jax.vmap(lambda q: fold_turns(model, camera, q))(Q)
    value = jnp.clip(Q[:, joint] + 2 * turn[:, hinge], model.q_lower[joint], model.q_upper[joint])
    return Q.at[:, joint].set(jnp.where(mask & ok[:, hinge], value, Q[:, joint]))


import os
JUMP_KIND = os.environ.get("JUMP_KIND", "both")
VITERBI_KIND = os.environ.get("VITERBI_KIND", "gauss")
COUPLED_FITS = os.environ.get("COUPLED_FITS", "1") == "1"


def jump_starts(model: Model, camera, q, blocks) -> np.ndarray:
    """(T, P, n_q) kinematic jumps of the states q (T, n_q): start p reflects, in every block of
    ``blocks`` at once, one non-empty subset of the block's hinges across their folds (the
    blocks' subsets cycle through all 2^k - 1 of a block with k hinges; P is the largest count),
    one hinge after the other along q, each fold taken at the state the previous jumps left."""
    hinges = fold_hinges(model)[0]
    T = q.shape[0]
    own = [np.nonzero(np.isin(hinges, b))[0] for b in blocks]
    P = max([2 ** len(h) - 1 for h in own] + [0])
    if P == 0:
        return np.zeros((T, 0, model.n_q))
    mask = np.zeros((P, len(hinges)), bool)
    for h in own:
        for p in range(P):
            bits = p % (2 ** len(h) - 1) + 1
            mask[p, h] = [(bits >> i) & 1 for i in range(len(h))]
    Q = jnp.asarray(np.repeat(np.asarray(q, float)[:, None], P, axis=1).reshape(T * P, model.n_q))
    full = np.tile(mask, (T, 1))
    for k in range(len(hinges)):
        if full[:, k].any():
            Q = _jump(model, camera, Q, jnp.asarray(k), jnp.asarray(full[:, k]))
    return np.asarray(Q).reshape(T, P, model.n_q)


#: Each finger's landmark chain in :data:`POINT_NAMES` order, from its root (the point the palm
#: carries) to its tip.
CHAINS = tuple(tuple(POINT_NAMES.index(f"{f}_{j}") for j in joints)
               for f, joints in (("thumb", ("cmc", "mcp", "ip", "tip")),) + tuple(
                   (f, ("mcp", "pip", "dip", "tip")) for f in FINGERS))


def depth_branches(model: Model, camera, px: np.ndarray, q: np.ndarray, lmap: LandmarkMap) -> np.ndarray:
    """(T, 2^k, 21, 3) world points of every depth branch of the landmarks ``px`` (T, 21, 2) seen
    by ``camera`` (k = 3 segments per chain of :data:`CHAINS`), NaN where undetermined.

    Each chain starts at its root's position in the model at q (T, n_q); each next point lies on
    its pixel's viewing ray at the segment's length (the model's, at q) from the point before: the
    nearer or the farther of the two intersections, as bit j of the branch index says for
    segment j (Taylor 2000). A ray that misses the sphere gives its point nearest to it. Branch b
    applies to every chain at once; each chain's q entries are an independent block."""
    P = np.asarray(jax.vmap(lambda x: landmark_positions(model, lmap, pose_at(model, x), x))(jnp.asarray(q)))
    origin = np.asarray(camera.unproject(jnp.asarray(px), jnp.zeros(px.shape[:-1])))
    ray = np.asarray(camera.unproject(jnp.asarray(px), jnp.ones(px.shape[:-1]))) - origin
    ray /= np.linalg.norm(ray, axis=-1, keepdims=True)
    k = max(len(c) for c in CHAINS) - 1
    out = np.full((px.shape[0], 2 ** k, 21, 3), np.nan)
    for branch in range(2 ** k):
        for chain in CHAINS:
            prev = P[:, chain[0]]
            for j, (a, b) in enumerate(zip(chain[:-1], chain[1:])):
                length = np.linalg.norm(P[:, b] - P[:, a], axis=-1)
                c = np.sum(ray[:, b] * (prev - origin[:, b]), -1)          # along the ray to the closest point
                h2 = c * c - np.sum((prev - origin[:, b]) ** 2, -1) + length ** 2
                s = c + (1 if branch >> j & 1 else -1) * np.sqrt(np.maximum(h2, 0.0))
                prev = origin[:, b] + s[:, None] * ray[:, b]
                out[:, branch, b] = prev
    return out


def _choose(model, lmap, config, Q, cost, coupled, H) -> np.ndarray:
    """Per independent block, the Viterbi path through the candidates Q (T, K, n_q) with the
    point costs ``cost`` (T, K, 21), squared DIP-PIP residuals ``coupled`` (T, K, fingers) and
    Gauss-Newton matrices H (T, K, n_q, n_q)."""
    T = Q.shape[0]
    dep = _dependence(model, lmap)
    w = np.asarray(_unit_weights(model, config, jnp.asarray(0.0).dtype))
    pip = np.asarray(sequence_coupling(model, config).pip_index, int)
    q = Q[:, 0].copy()
    for block in independent_blocks(model, lmap):
        points = dep[:, block].any(axis=1)
        unary = 0.5 * (cost[..., points].sum(-1) + coupled[..., np.isin(pip, block)].sum(-1))
        Hb = H[..., block[:, None], block[None, :]] if VITERBI_KIND == "gauss" else None
        path = _viterbi(unary, Q[..., block], w[block], Hb)
        q[:, block] = Q[np.arange(T), path][:, block]
    return q


def smoothest_paths(model: Model, cameras, landmarks: Landmarks, lmap: LandmarkMap, *, candidates=None,
                    config: SequenceConfig | None = None, batch_config: BatchConfig | None = None,
                    fractions=START_FRACTIONS, draws: int = 16, jumps: int = 2) -> np.ndarray:
    """(T, n_q) start of a sequence fit: per independent block of joints, the smoothest low-cost
    path through every frame's candidate fits (see the module docstring).

    Args:
        landmarks: (T, cams, 21, 2) batched :class:`Landmarks`.
        candidates: optional (C, T, n_q) states also offered per frame (refined like the starts);
            the starts of a moving base take their base entries from the first candidate.
        config: the smoothness weights (:class:`~jaxhand.landmarks.SequenceConfig`).
        fractions, draws: the starts of :func:`joint_starts` (seed 0).
        jumps: rounds of kinematic jumps (step 4 of the module docstring); 0: none.
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
    lm = _as_float_landmarks(landmarks)
    blocks = independent_blocks(model, lmap)
    pool = []

    def refine(S):               # (T, K, n_q) starts -> their fits, point costs and DIP-PIP terms
        K = S.shape[1]
        lmK = jax.tree_util.tree_map(lambda x: jnp.repeat(x, K, axis=0), lm)
        res = fit_landmarks_batch(model, rig, lmK, S.reshape(T * K, model.n_q), config=batch_config, lmap=lmap,
                                  coupling=coupling if COUPLED_FITS else None)
        cost, coupled, H = (np.asarray(x) for x in _point_terms(model, rig, lmap, coupling, lmK, res.q))
        pool.append((np.asarray(res.q).reshape(T, K, model.n_q), cost.reshape(T, K, 21),
                     coupled.reshape(T, K, -1), H.reshape(T, K, model.n_q, model.n_q)))
        return _choose(model, lmap, config, *(np.concatenate(x, axis=1) for x in zip(*pool)))

    q = refine(starts)
    px0 = np.where(np.asarray(lm.px_valid)[:, 0, :, None], np.asarray(lm.px)[:, 0], np.nan)
    for _ in range(jumps):
        # the path's neighbours as starts carry a branch found in one frame to the next
        near = np.stack([np.concatenate([q[:1], q[:-1]]), np.concatenate([q[1:], q[-1:]])], axis=1)
        S = [near]
        if JUMP_KIND in ("folds", "both"):
            S.append(jump_starts(model, rig[0], q, blocks))
        if JUMP_KIND in ("branches", "both"):
            X = depth_branches(model, rig[0], px0, q, lmap)                  # (T, B, 21, 3)
            B = X.shape[1]
            lm3 = jax.tree_util.tree_map(lambda x: jnp.repeat(x, B, axis=0), lm)
            to3 = make_landmarks(np.asarray(lm3.px), px_valid=np.asarray(lm3.px_valid), mm=X.reshape(T * B, 21, 3),
                                 mm_weight=1.0, frame_3d="world")
            r3 = fit_landmarks_batch(model, rig, to3, np.repeat(q, B, axis=0), config=batch_config, lmap=lmap)
            S.append(np.asarray(r3.q).reshape(T, B, model.n_q))
        q_new = refine(np.concatenate(S, axis=1))
        if np.array_equal(q_new, q):
            break
        q = q_new
    return q
