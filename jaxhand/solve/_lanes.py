"""Kinematics in a lanes-last layout for batched solvers: every array ends in the batch axis B.

Why a second layout of :mod:`jaxhand.kinematics`: ``jax.vmap`` of the frame composition turns
each 4x4 product into a batched ``dot_general`` over (B, frames) tiny matrices and each level's
``.at[].set`` into a scatter, which XLA's CPU backend runs as loops of small calls. With the
batch axis last, every product is a broadcast multiply and sum over a small static axis, i.e.
elementwise loops over B that XLA fuses and vectorises (``benchmarks/landmarks.py``). The
reference stays :func:`jaxhand.kinematics.pose` and :func:`jaxhand.residuals.point_jacobian`;
tests check that these kernels agree with them.

Layout: ``R`` (frames, 3, 3, B) and ``p`` (frames, 3, B) hold T_world_frame; q is (n_q, B).
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from ..kinematics import base_pose
from ..model import Model

__all__ = ["lane_frames", "lane_point_jacobian", "lane_matmul", "lane_root", "lane_contract",
           "point_dependence"]


def lane_contract(a: Array, b: Array, axis: int) -> Array:
    """``sum_k a[.., k, ..] * b[.., k, ..]`` over a small static axis, written as k products added
    up: XLA's CPU backend runs a broadcast product reduced over an axis as a slow generic
    reduction (20-200x slower on the shapes here, ``benchmarks/README.md``), and the unrolled
    sum as one fused elementwise loop."""
    a, b = jnp.broadcast_arrays(a, b)
    axis = axis % a.ndim
    n = a.shape[axis]
    out = jax.lax.index_in_dim(a, 0, axis, keepdims=False) * jax.lax.index_in_dim(b, 0, axis, keepdims=False)
    for k in range(1, n):
        out = out + jax.lax.index_in_dim(a, k, axis, keepdims=False) * jax.lax.index_in_dim(b, k, axis, keepdims=False)
    return out


def lane_matmul(A: Array, C: Array) -> Array:
    """Products of small matrices lane by lane: A (..., i, k, B) times C (..., k, j, B), the
    leading axes broadcast."""
    return lane_contract(A[..., :, :, None, :], C[..., None, :, :, :], axis=-3)


def lane_root(model: Model, q: Float[Array, "nq B"]):
    """T_world_root of every lane: (3, 3, B) and (3, B)."""
    if model.base_kind == "fixed":
        T = model.T_world_mount.astype(q.dtype)
        B = q.shape[-1]
        return jnp.broadcast_to(T[:3, :3, None], (3, 3, B)), jnp.broadcast_to(T[:3, 3, None], (3, B))
    T = jnp.moveaxis(jax.vmap(lambda one: base_pose(model, one))(q.T), 0, -1)
    return T[:3, :3], T[:3, 3]


def _dh(model: Model, q: Float[Array, "nq B"]):
    """T_parent_frame of every frame (modified DH, then the pre-transforms), lanes last."""
    idx = np.array(model.q_index)
    qf = jnp.where((idx >= 0)[:, None], q[np.maximum(idx, 0)], 0.0)                  # (F, B)
    revolute = np.array([k == "revolute" for k in model.joint_kinds])[:, None]
    prismatic = np.array([k == "prismatic" for k in model.joint_kinds])[:, None]
    dh = model.dh.astype(q.dtype)
    theta = dh[:, 3:4] + jnp.where(revolute, qf, 0.0)
    d = dh[:, 2:3] + jnp.where(prismatic, qf, 0.0)
    ca, sa = jnp.cos(dh[:, 0:1]), jnp.sin(dh[:, 0:1])
    ct, st = jnp.cos(theta), jnp.sin(theta)
    ca, sa = jnp.broadcast_to(ca, ct.shape), jnp.broadcast_to(sa, ct.shape)
    zero = jnp.zeros_like(ct)
    R = jnp.stack([jnp.stack([ct, -st, zero], 1), jnp.stack([st * ca, ct * ca, -sa], 1),
                   jnp.stack([st * sa, ct * sa, ca], 1)], 1)                               # (F, 3, 3, B)
    p = jnp.stack([jnp.broadcast_to(dh[:, 1:2], ct.shape), -sa * d, ca * d], 1)          # (F, 3, B)
    if model.pre_transform_frames:   # static: T_pre @ DH for imported bodies
        pre = np.array(model.pre_transform_frames)
        Tp = model.T_pre_transform.astype(q.dtype)
        Rp, pp = Tp[:, :3, :3, None], Tp[:, :3, 3, None]
        R = R.at[pre].set(lane_matmul(Rp, R[pre]))
        p = p.at[pre].set(lane_contract(Rp, p[pre][:, None], axis=2) + pp)
    return R, p


def lane_frames(model: Model, q: Float[Array, "nq B"]) -> tuple[Float[Array, "F 3 3 B"], Float[Array, "F 3 B"]]:
    """T_world_frame of every frame for every lane, composed one depth level at a time (the
    lanes-last form of :func:`jaxhand.kinematics.frame_poses`)."""
    R_pf, p_pf = _dh(model, q)
    R_root, p_root = lane_root(model, q)
    Rs, ps, order = [], [], []
    for level in model.levels:   # static; a frame's parent sits in the level before its own
        idx = np.array(level)
        parent = np.array([model.parents[i] for i in level])
        if order:
            pos = {f: i for i, f in enumerate(order[-1])}
            at = np.array([pos.get(int(f), 0) for f in parent])
            R_par = jnp.where((parent < 0)[:, None, None, None], R_root, Rs[-1][at])
            p_par = jnp.where((parent < 0)[:, None, None], p_root, ps[-1][at])
        else:
            R_par, p_par = R_root[None], p_root[None]
        Rs.append(lane_matmul(R_par, R_pf[idx]))
        ps.append(lane_contract(R_par, p_pf[idx][:, None], axis=2) + p_par)
        order.append([int(f) for f in level])
    perm = np.argsort(np.concatenate([np.array(o) for o in order]))
    return jnp.concatenate(Rs)[perm], jnp.concatenate(ps)[perm]


def point_dependence(model: Model, attached: np.ndarray) -> np.ndarray:
    """(P, n_q) static bool: True where q entry k can move a point attached to frame
    ``attached[p]`` (a joint above it, or the moving base): the pattern of
    :func:`lane_point_jacobian`'s nonzeros."""
    attached = np.asarray(attached, dtype=int)
    dep = np.zeros((attached.size, model.n_q), bool)
    for f in range(model.n_frames):
        if model.q_index[f] >= 0:
            dep[:, model.q_index[f]] |= model.ancestors[attached, f]
    if model.base_kind != "fixed":
        base = np.ones(model.n_q, bool)
        base[[model.q_index[f] for f in range(model.n_frames) if model.q_index[f] >= 0]] = False
        dep[:, base] = True
    return dep


def lane_point_jacobian(model: Model, q: Float[Array, "nq B"], R: Float[Array, "F 3 3 B"], p: Float[Array, "F 3 B"],
                        points: Float[Array, "P 3 B"], attached: np.ndarray) -> Float[Array, "pairs 3 B"]:
    """d p_world / d q of points rigidly attached to frames, at the structural nonzeros only: one
    (3, B) column per True entry of :func:`point_dependence` (row-major: point, then q entry).

    The lanes-last, sparse form of :func:`jaxhand.residuals.point_jacobian`: a revolute joint
    above a point gives ``z_j x (p - o_j)``, a prismatic one ``z_j``; a moving base its own
    columns (forward-mode through :func:`jaxhand.kinematics.base_pose`, a few flops a point)."""
    attached = np.asarray(attached, dtype=int)
    pair_p, pair_k = np.nonzero(point_dependence(model, attached))
    terms = [(t, f) for t, (pt, k) in enumerate(zip(pair_p, pair_k, strict=True)) for f in range(model.n_frames)
             if model.q_index[f] == k and model.ancestors[attached[pt], f]]
    sources = [[] for _ in pair_p]                        # per pair: rows of the stacked sources
    parts = []
    if terms:
        tt, tf = (np.array(v, dtype=int) for v in zip(*terms, strict=True))
        z, o = R[tf, :, 2], p[tf]                                                            # (T, 3, B)
        revolute = np.array([model.joint_kinds[f] == "revolute" for f in tf])[:, None, None]
        parts.append(jnp.where(revolute, jnp.cross(z, points[pair_p[tt]] - o, axis=1), z))
        for row, t in enumerate(tt):
            sources[t].append(row)
    if model.base_kind != "fixed":
        R_root, p_root = lane_root(model, q)
        local = lane_contract(R_root[None], (points - p_root[None])[:, :, None], axis=1)      # R^T (p - t)

        def moved(one_q, one_local):
            T = base_pose(model, one_q)
            return one_local @ T[:3, :3].T + T[:3, 3]

        Jb = jax.vmap(jax.jacfwd(moved))(q.T, jnp.moveaxis(local, -1, 0))                   # (B, P, 3, nq)
        joint_q = {model.q_index[f] for f in range(model.n_frames) if model.q_index[f] >= 0}
        base_pairs = np.array([t for t, k in enumerate(pair_k) if k not in joint_q], dtype=int)
        parts.append(Jb[:, pair_p[base_pairs], :, pair_k[base_pairs]].transpose(0, 2, 1))    # (nb, 3, B)
        offset = sum(x.shape[0] for x in parts[:-1])
        for row, t in enumerate(base_pairs):
            sources[t].append(offset + row)
    stacked = jnp.concatenate(parts)
    if all(len(v) == 1 for v in sources):
        return stacked[np.array([v[0] for v in sources], dtype=int)]
    return jnp.stack([functools.reduce(jnp.add, [stacked[i] for i in v]) for v in sources])
