"""Link and tip residuals of many problems at once, lanes last, with the Jacobian's structural
nonzeros only: the residual kernel of ``fit_batch(solver="batch")``.

The reference is :func:`jaxhand.residuals.residuals_and_jacobian` (one problem, dense J); this
kernel computes the same numbers for B problems with every array ending in the batch axis, so
that XLA's CPU backend runs them as fused elementwise loops (see :mod:`._lanes`). Each residual
point (a tip, or a link point at fraction ``f_k``) moves with the joints above its frame only
(:func:`~._lanes.point_dependence`: on hand21 a finger's points depend on that finger's 4-5
joints), so J has 136 structural nonzeros of 840 per camera and J^T J is five blocks of <= 5,
which the batched solver factorises side by side (:class:`~._sparsity.SparsePattern`).

Residual order (as :func:`jaxhand.residuals.residuals`): per camera, the tips (tip-major, then
x, y), then the links (link-major, then point). J's nonzeros come row by row, then by q entry.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from ..features import Features
from ..model import Model
from ..residuals import masked_features
from ._lanes import lane_contract, lane_frames, lane_point_jacobian, point_dependence
from ._sparsity import SparsePattern

__all__ = ["EdgeLanes"]


def _attached(model: Model, n_fractions: int) -> np.ndarray:
    """The frame each residual point is attached to: the tips, then every link's points."""
    link_frame = np.array(model.link_frame, dtype=int)
    return np.concatenate([link_frame[np.array(model.tip_links, dtype=int)], np.repeat(link_frame, n_fractions)])


def _tip_order(dep_tips: np.ndarray) -> np.ndarray:
    """Positions in the flattened (tip pairs, 2) array of the compact row order: tip, then x/y,
    then q entry."""
    start = np.concatenate([[0], np.cumsum(dep_tips.sum(axis=1))])
    return np.array([2 * t + c for i in range(dep_tips.shape[0]) for c in range(2)
                     for t in range(start[i], start[i + 1])], dtype=int)


def _pixels_and_jacobian(camera, points: Float[Array, "P 3 B"]) -> tuple[Float[Array, "P 2 B"],
                                                                        Float[Array, "P 2 3 B"]]:
    """Pixels of world points and d pixel / d p_world, lanes last (forward-mode through the
    camera alone, exact for any camera, its depth clamp included)."""
    P, _, B = points.shape

    def one(p):
        px = camera.project(p)[0]
        return px, px

    rows = jnp.moveaxis(points, -1, 0).reshape(-1, 3)
    J, px = jax.vmap(jax.jacfwd(one, has_aux=True))(rows)
    return jnp.moveaxis(px.reshape(B, P, 2), 0, -1), jnp.moveaxis(J.reshape(B, P, 2, 3), 0, -1)


class EdgeLanes(eqx.Module):
    """``fn(q, feats) -> (r, J_values)`` for :func:`~._batched.solve_batched`: the link and tip
    residuals of a chunk of b problems, lanes last (a pytree callable, so that its compiled
    programs are cached across calls).

    Attributes:
        model: the articulated model (static structure, traced numbers).
        cameras: the rig (traced numbers).
        fractions: (K,) traced fractions along each link of its residual points (K static).
    """

    model: Model
    cameras: tuple
    fractions: Float[Array, " K"]

    def pattern(self) -> SparsePattern:
        """The static nonzero pattern of J: per camera, two rows per tip and one per link point,
        each nonzero in the columns of the joints above that point."""
        K = self.fractions.shape[0]
        dep = point_dependence(self.model, _attached(self.model, K))
        nt = self.model.n_tips
        one = np.concatenate([np.repeat(dep[:nt], 2, axis=0), dep[nt:]])
        return SparsePattern(np.concatenate([one] * len(self.cameras)))

    def __call__(self, q: Float[Array, "nq b"], feats: tuple[Features, ...]
                 ) -> tuple[Float[Array, "r b"], Float[Array, "nnz b"]]:
        """Residuals (r, b) and the nonzeros of J (nnz, b) in :meth:`pattern`'s order at q (n_q, b);
        ``feats`` holds one :class:`~jaxhand.Features` per camera with a leading axis b."""
        model, dtype = self.model, q.dtype
        K, nt, nl = self.fractions.shape[0], model.n_tips, model.n_links
        R, p = lane_frames(model, q)
        link_frame = np.array(model.link_frame, dtype=int)
        start = p[link_frame]                                                                # (L, 3, b)
        end = start + model.link_length_mm.astype(dtype)[:, None, None] * R[link_frame, :, np.array(model.link_axis)]
        f = self.fractions.astype(dtype)[None, :, None, None]
        link_pts = start[:, None] + f * (end - start)[:, None]                               # (L, K, 3, b)
        points = jnp.concatenate([end[np.array(model.tip_links, dtype=int)], link_pts.reshape(nl * K, 3, -1)])
        attached = _attached(model, K)
        dep = point_dependence(model, attached)
        pair_p = np.nonzero(dep)[0]
        tip_pairs = pair_p < nt
        Jp = lane_point_jacobian(model, q, R, p, points, attached)                          # (pairs, 3, b)
        tip_order = _tip_order(dep[:nt])
        rs, Js = [], []
        for cam, fc in zip(self.cameras, feats):
            tip_valid, tip_obs, sqrt_tip_w, lines, sqrt_line_w = (
                jnp.moveaxis(x, 0, -1) for x in jax.vmap(lambda one: masked_features(one, dtype))(fc))
            px, dpx = _pixels_and_jacobian(cam, points)
            # tips: (pixel - observed) * sqrt(w), exact zeros in masked slots
            r_tip = jnp.where(tip_valid, px[:nt] - tip_obs, 0.0) * sqrt_tip_w[:, None]      # (T, 2, b)
            w_t = (jnp.where(tip_valid, 1.0, 0.0)[:, 0] * sqrt_tip_w)[pair_p[tip_pairs]]
            J_tip = lane_contract(dpx[pair_p[tip_pairs]], Jp[tip_pairs][:, None], axis=2) * w_t[:, None]
            # links: signed distance a x + b y - rho of each point, and its normal times d pixel
            px_l = px[nt:].reshape(nl, K, 2, -1)
            d_link = lane_contract(lines[:, None, :2], px_l, axis=2) - lines[:, None, 2]   # (L, K, b)
            normal = lane_contract(lines[:, None, :2, None], dpx[nt:].reshape(nl, K, 2, 3, -1), axis=2)
            link_p = pair_p[~tip_pairs] - nt
            w_l = jnp.repeat(sqrt_line_w, K, axis=0)[link_p]
            J_link = lane_contract(normal.reshape(nl * K, 3, -1)[link_p], Jp[~tip_pairs], axis=1) * w_l
            rs += [r_tip.reshape(2 * nt, -1), (d_link * sqrt_line_w[:, None]).reshape(nl * K, -1)]
            Js += [J_tip.reshape(-1, J_tip.shape[-1])[tip_order], J_link]
        return jnp.concatenate(rs), jnp.concatenate(Js)
