"""The static sparsity of a batched problem: which Jacobian entries can be nonzero, the products
that make J^T J and J^T r from them, and the independent blocks of J^T J."""

from __future__ import annotations

import numpy as np
from jaxtyping import Array, Float

__all__ = ["SparsePattern"]


class SparsePattern:
    """The static structure of a batched problem's Jacobian and normal equations.

    From the (m, n) pattern of J's possible nonzeros: their positions in the compact layout
    (row-major: ``J_values[t]`` is entry ``(rows[t], cols[t])``); the products that make each
    entry of J^T J and J^T r (index arrays padded with a zero slot); and the independent blocks
    of J^T J (q entries that share no residual row), padded to one size, which are factorised
    side by side. hand21's fingers share no joint: its 21x21 system is five blocks of <= 5.
    """

    def __init__(self, jac: np.ndarray):
        jac = np.asarray(jac, bool)
        self.m, self.n = m, n = jac.shape
        self.rows, self.cols = (tuple(int(x) for x in v) for v in np.nonzero(jac))
        self.nnz = nnz = int(jac.sum())
        pos = np.full(jac.shape, nnz)             # nnz: the zero slot
        pos[jac] = np.arange(nnz)
        g_rows = [np.flatnonzero(jac[:, i]) for i in range(n)]
        width = max(1, max(len(v) for v in g_rows))
        self.g_j = np.full((n, width), nnz)
        self.g_r = np.full((n, width), m)
        for i, rs in enumerate(g_rows):
            self.g_j[i, :len(rs)], self.g_r[i, :len(rs)] = pos[rs, i], rs
        pairs = [(i, j) for i in range(n) for j in range(i + 1) if np.any(jac[:, i] & jac[:, j])]
        width = max(1, max((int(np.sum(jac[:, i] & jac[:, j])) for i, j in pairs), default=1))
        self.a_1 = np.full((len(pairs), width), nnz)
        self.a_2 = np.full((len(pairs), width), nnz)
        for t, (i, j) in enumerate(pairs):
            rs = np.flatnonzero(jac[:, i] & jac[:, j])
            self.a_1[t, :len(rs)], self.a_2[t, :len(rs)] = pos[rs, i], pos[rs, j]
        a_pos = {ij: t for t, ij in enumerate(pairs)}
        self.diag = np.array([a_pos.get((i, i), len(pairs)) for i in range(n)])   # len(pairs): the zero slot
        # independent blocks: connected components of the graph of J^T J
        label = np.arange(n)
        for i, j in pairs:
            a_, b_ = label[i], label[j]
            label[label == max(a_, b_)] = min(a_, b_)
        blocks = [np.flatnonzero(label == c) for c in np.unique(label)]
        size = max(len(b_) for b_ in blocks)
        self.block_q = np.full((len(blocks), size), n)                            # n: the padding slot
        for k, blk in enumerate(blocks):
            self.block_q[k, :len(blk)] = blk
        self.block_a = np.full((len(blocks), size, size), len(pairs))
        for k, blk in enumerate(blocks):
            for u, i in enumerate(blk):
                for v, j in enumerate(blk):
                    self.block_a[k, u, v] = a_pos.get((max(i, j), min(i, j)), len(pairs))
        where = {int(q): k * size + u for k, blk in enumerate(blocks) for u, q in enumerate(blk)}
        self.q_slot = np.array([where[i] for i in range(n)])
        self.n_pairs = len(pairs)
        self._key = (jac.shape, np.packbits(jac).tobytes())

    @classmethod
    def dense(cls, m: int, n: int) -> SparsePattern:
        return cls(np.ones((m, n), bool))

    def compact(self, J: Float[Array, "m n B"]) -> Float[Array, "nnz B"]:
        """The structural nonzeros of a dense lanes-last J, in the compact order."""
        return J.reshape((self.m * self.n,) + J.shape[2:])[np.array(self.rows) * self.n + np.array(self.cols)]

    def __hash__(self):
        return hash(self._key)

    def __eq__(self, other):
        return isinstance(other, SparsePattern) and self._key == other._key
