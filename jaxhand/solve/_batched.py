"""A batched, bounded Levenberg-Marquardt built for throughput on many small problems.

What it does, and why each step (measured in ``benchmarks/landmarks.py``):

1. every array is laid out lanes last (``(..., B)``): r is (m, B), J (m, n, B), q (n, B), so
   the normal equations, the Cholesky factorisation and the solves are elementwise loops over
   the B problems, which XLA's CPU backend vectorises; batched LAPACK calls of ``jax.vmap``
   loop over tiny matrices instead;
2. the step solves the damped normal equations ``(J^T J + lambda D) dq = -J^T r`` with
   ``D = diag(J^T J)`` by a Cholesky factorisation unrolled over the n columns (n <= 30 here:
   far cheaper than a QR of J per problem);
3. projected steps with an active set: an entry at a limit whose gradient pushes it outwards
   is held there (its row and column of the system replaced by the identity), the others take
   the step, which is then clipped into the limits; the quaternion, if any, is renormalised.
   Without the active set a step that pointed out of the box was clipped to nothing, raised
   lambda and rejected again: the lanes that hit the step cap;
4. a trial that lowers the cost is taken and lambda divided by ``lambda_down``; otherwise
   lambda is multiplied by ``lambda_up``;
5. a lane stops when an accepted step changed the cost by at most ``ftol * H + atol_px2``,
   when a trial moved q by at most ``xtol`` (sum of |dq|), or at H <= ``atol_px2``; a stopped
   lane is frozen (its values selected, not updated) and the loop ends when every lane of its
   chunk has stopped or after ``max_steps`` trials;
6. the batch runs in chunks of ``chunk`` problems (``lax.map`` over chunks), so a slow problem
   holds back its own chunk only.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._errors import InputError
from ._lanes import lane_contract
from ._parts import StateSpace
from ._result import FitResult
from ._sparsity import SparsePattern
from ._status import Status

__all__ = ["BatchConfig", "check_batch_config", "batched_lm", "batch_lm", "solve_batched", "lane_cholesky_solve"]


def _f(x):
    return jnp.asarray(x, dtype=float)


class BatchConfig(eqx.Module):
    """Options of the batched solver (:func:`~jaxhand.landmarks.fit_landmarks_batch`,
    :func:`~jaxhand.fit_batch` with ``solver="batch"``).

    Attributes:
        max_steps: static. Most trial steps per problem.
        chunk: static. Problems per vmapped loop (a slow problem holds back its chunk only).
        rank_test: static. Compute the rank of J at the result (an eigen-decomposition per problem).
        phase_steps: static. Host-driven batches (:func:`solve_batched`) run every chunk this
            many trials, then regroup the lanes still running into full chunks and go on, so a
            slow lane no longer keeps a whole chunk of finished ones busy.
        threads: static. Host threads that run those chunks side by side (the results do not
            depend on it).
        ftol: traced, relative. Stop when an accepted step changes the cost by <= ftol * H + atol_px2.
        atol_px2: traced, px^2. Absolute part of that rule (noise-free data reach H ~ 0).
        xtol: traced, q units. Stop when the step moves q by at most xtol (sum of |dq|).
        lambda0: traced. Initial relative damping (times diag(J^T J)).
        lambda_up, lambda_down: traced. Damping factors after a rejected / accepted trial.
    """

    max_steps: int = eqx.field(static=True, default=40)
    chunk: int = eqx.field(static=True, default=256)
    rank_test: bool = eqx.field(static=True, default=False)
    phase_steps: int = eqx.field(static=True, default=12)
    threads: int = eqx.field(static=True, default=2)
    ftol: Float[Array, ""] = eqx.field(converter=_f, default=1e-8)
    atol_px2: Float[Array, ""] = eqx.field(converter=_f, default=1e-12)
    xtol: Float[Array, ""] = eqx.field(converter=_f, default=1e-9)
    lambda0: Float[Array, ""] = eqx.field(converter=_f, default=1e-3)
    lambda_up: Float[Array, ""] = eqx.field(converter=_f, default=4.0)
    lambda_down: Float[Array, ""] = eqx.field(converter=_f, default=3.0)


def check_batch_config(config: BatchConfig | None) -> BatchConfig:
    """Boundary check of a BatchConfig (None: the defaults).

    Raises:
        InputError: naming the field and its value.
    """
    config = BatchConfig() if config is None else config
    if not isinstance(config, BatchConfig):
        raise InputError(f"config: expected a BatchConfig, got {type(config).__name__}")
    for name in ("max_steps", "chunk", "phase_steps", "threads"):
        if not isinstance(getattr(config, name), (int, np.integer)) or getattr(config, name) < 1:
            raise InputError(f"config.{name}: expected an integer >= 1, got {getattr(config, name)!r}")
    for name in ("ftol", "atol_px2", "xtol", "lambda0"):
        v = float(getattr(config, name))
        if not np.isfinite(v) or v < 0:
            raise InputError(f"config.{name}: must be finite and >= 0, got {v}")
    if not float(config.lambda_up) > 1 or not float(config.lambda_down) > 1:
        raise InputError("config.lambda_up and config.lambda_down must be > 1")
    return config


def _unrolled_sum(terms):
    return functools.reduce(jnp.add, terms)


def lane_cholesky_solve(M: Float[Array, "*k n n B"], b: Float[Array, "*k n B"]) -> Float[Array, "*k n B"]:
    """Solve ``M x = b`` for symmetric positive definite M, lane by lane (and block by block over
    the leading axes): a Cholesky factorisation ``M = L L^T`` column by column, then the two
    triangular solves, every sum unrolled (see :func:`~jaxhand.solve.internal.lane_contract`)."""
    n = M.shape[-2]
    tiny = jnp.finfo(M.dtype).tiny
    rows = np.arange(n)[:, None]
    cols: list[Array] = []                       # column j of L, zeros above row j: (*k, n, B)
    for j in range(n):
        v = M[..., :, j, :]
        if cols:
            v = v - _unrolled_sum([c * c[..., j:j + 1, :] for c in cols])
        # Guard: rounding can leave a pivot <= 0 for a nearly singular M; the floor keeps the
        # factor finite (a wrong step is then rejected by the cost test).
        d = jnp.sqrt(jnp.maximum(v[..., j:j + 1, :], tiny))
        cols.append(jnp.where(rows >= j, v / d, 0.0))
    y, ys = b, []
    for k in range(n):                           # L y = b
        yk = y[..., k:k + 1, :] / cols[k][..., k:k + 1, :]
        ys.append(yk)
        y = y - cols[k] * yk
    xs: list[Array] = [jnp.zeros_like(ys[0])] * n
    for i in reversed(range(n)):                 # L^T x = y
        acc = ys[i]
        if i + 1 < n:
            acc = acc - _unrolled_sum([cols[i][..., k:k + 1, :] * xs[k] for k in range(i + 1, n)])
        xs[i] = acc / cols[i][..., i:i + 1, :]
    return jnp.concatenate(xs, axis=-2)


class _State(eqx.Module):
    q: Array        # (n, B)
    r: Array        # (m, B)
    J: Array        # (nnz, B): the structural nonzeros of J
    H: Array        # (B,)
    lam: Array      # (B,)
    running: Array  # (B,)
    k: Array        # (B,) trials so far


def _lane_space(space: StateSpace, dtype):
    lo, hi = space.lower.astype(dtype)[:, None], space.upper.astype(dtype)[:, None]
    bounded = np.asarray(space.bounded)[:, None]

    def project(q):
        q = jnp.where(bounded, jnp.clip(q, lo, hi), q)
        if space.has_quaternion:
            quat = q[:4]
            nrm = jnp.sqrt(quat[0] ** 2 + quat[1] ** 2 + quat[2] ** 2 + quat[3] ** 2)
            # Guard: a zero quaternion stays zero (the kinematics map it to the identity).
            safe = jnp.where(nrm > 0, nrm, 1.0)
            q = jnp.concatenate([jnp.where(nrm > 0, quat / safe, quat), q[4:]])
        return q

    return lo, hi, bounded, project


def _normal_equations(pattern: SparsePattern, J: Array, r: Array):
    """The structural entries of J^T J (pairs i >= j, (pairs, B)) and J^T r ((n, B))."""
    Jz = jnp.concatenate([J, jnp.zeros_like(J[:1])])
    rz = jnp.concatenate([r, jnp.zeros_like(r[:1])])
    A = lane_contract(Jz[pattern.a_1], Jz[pattern.a_2], axis=1)
    g = lane_contract(Jz[pattern.g_j], rz[pattern.g_r], axis=1)
    return A, g


def _step(fn, args, space: StateSpace, config: BatchConfig, pattern: SparsePattern, s: _State) -> _State:
    """One projected Levenberg-Marquardt trial of every running lane (the others are frozen)."""
    lo, hi, bounded, project = _lane_space(space, s.q.dtype)
    A, g = _normal_equations(pattern, s.J, s.r)
    Az = jnp.concatenate([A, jnp.zeros_like(A[:1])])
    d = Az[pattern.diag]                                                       # diag(J^T J): (n, B)
    # Guard: a column of J that is zero (a DOF nothing sees) would leave M singular; the floor,
    # 1e-12 of the largest diagonal entry, keeps the factor finite.
    d = jnp.maximum(d, 1e-12 * jnp.max(d, axis=0) + jnp.finfo(d.dtype).tiny)
    # Held: an entry at a limit whose gradient pushes it outwards; its row and column become d_i.
    free = ~(bounded & (((s.q <= lo) & (g > 0)) | ((s.q >= hi) & (g < 0))))
    ones = jnp.ones_like(d[:1])
    D = jnp.concatenate([d, ones])[pattern.block_q]                            # (blocks, size, B)
    F = jnp.concatenate([free, ones > 0])[pattern.block_q]
    G = jnp.concatenate([g, 0 * ones])[pattern.block_q]
    eye = np.eye(pattern.block_q.shape[1], dtype=bool)[None, :, :, None]
    M = jnp.where(F[:, :, None] & F[:, None, :], Az[pattern.block_a], 0.0)
    M = jnp.where(eye, M + jnp.where(F, s.lam * D, D)[:, :, None], M)
    x = lane_cholesky_solve(M, jnp.where(F, G, 0.0))
    dq = -x.reshape((-1,) + x.shape[2:])[pattern.q_slot]
    dq = jnp.where(jnp.isfinite(dq), dq, 0.0)
    q_t = project(s.q + dq)
    r_t, J_t = fn(q_t, args)
    H_t = 0.5 * jnp.sum(r_t * r_t, axis=0)
    active = s.running & (s.k < config.max_steps)
    ok = jnp.isfinite(H_t) & jnp.all(jnp.isfinite(J_t), axis=0)
    accept = ok & (H_t < s.H) & active
    moved = jnp.sum(jnp.abs(q_t - s.q), axis=0)
    done = (accept & ((s.H - H_t <= config.ftol * s.H + config.atol_px2) | (moved <= config.xtol))) | (
        ~accept & (moved <= config.xtol)) | (s.H <= config.atol_px2)
    lam = jnp.where(accept, jnp.maximum(s.lam / config.lambda_down, 1e-12),
                    jnp.minimum(s.lam * config.lambda_up, 1e12))
    return _State(q=jnp.where(accept, q_t, s.q), r=jnp.where(accept, r_t, s.r), J=jnp.where(accept, J_t, s.J),
                  H=jnp.where(accept, H_t, s.H), lam=jnp.where(active, lam, s.lam),
                  running=s.running & ~(active & done), k=s.k + active.astype(s.k.dtype))


def _status(finite, converged, singular):
    return Status.where(~finite, Status.nonfinite,
                        Status.where(converged, Status.where(singular, Status.singular, Status.ok), Status.max_steps))


def _dtype_floors(config: BatchConfig, dtype) -> BatchConfig:
    """The config in ``dtype`` with the stopping tolerances floored at the dtype's rounding.

    In float32 an ftol of 1e-8, an atol of 1e-12 px^2 and an xtol of 1e-9 never held and lanes
    ran to max_steps (benchmarks/README.md): ftol >= 100 eps, atol >= (1e4 eps)^2 px^2 and
    xtol >= 1e3 eps (no effect in float64)."""
    config = jax.tree_util.tree_map(lambda x: x.astype(dtype), config)
    eps = jnp.finfo(dtype).eps
    return eqx.tree_at(lambda c: (c.ftol, c.atol_px2, c.xtol), config,
                       (jnp.maximum(config.ftol, 100 * eps), jnp.maximum(config.atol_px2, (1e4 * eps) ** 2),
                        jnp.maximum(config.xtol, 1e3 * eps)))


def _start(fn, args, q0: Float[Array, "b nq"], space: StateSpace, config: BatchConfig) -> _State:
    q = _lane_space(space, q0.dtype)[3](q0.T)
    r, J = fn(q, args)
    H = 0.5 * jnp.sum(r * r, axis=0)
    b = q.shape[-1]
    return _State(q=q, r=r, J=J, H=H, lam=jnp.full((b,), config.lambda0, q.dtype), running=jnp.isfinite(H),
                  k=jnp.zeros((b,), jnp.int32))


def _advance(fn, args, s: _State, budget, space, config, pattern) -> _State:
    """Up to ``budget`` more trials of every lane (each lane stops on its own rules or cap)."""

    def cond(c):
        i, st = c
        return (i < budget) & jnp.any(st.running & (st.k < config.max_steps))

    def body(c):
        i, st = c
        return i + 1, _step(fn, args, space, config, pattern, st)

    return jax.lax.while_loop(cond, body, (jnp.array(0), s))[1]


def _result(s: _State, q0: Float[Array, "nq b"], H0, space: StateSpace, config: BatchConfig,
            pattern: SparsePattern) -> FitResult:
    b = s.q.shape[-1]
    finite = jnp.isfinite(s.H) & jnp.all(jnp.isfinite(s.q), axis=0)
    converged = ~s.running & finite
    if config.rank_test:
        A, _ = _normal_equations(pattern, s.J, s.r)
        Az = jnp.concatenate([A, jnp.zeros_like(A[:1])])
        index = np.full((pattern.n, pattern.n), pattern.n_pairs)
        for k, blk in enumerate(pattern.block_q):
            for u, i in enumerate(blk):
                for v, j in enumerate(blk):
                    if i < pattern.n and j < pattern.n:
                        index[i, j] = pattern.block_a[k, u, v]
        ev = jnp.linalg.eigvalsh(jnp.moveaxis(Az[index], -1, 0))
        rank = jnp.sum(ev > 1e-18 * ev[:, -1:], axis=-1)   # eigenvalues of J^T J: squares of s_i
    else:
        rank = jnp.full((b,), space.dof, jnp.int32)
    status = jax.vmap(_status)(finite, converged, rank < space.dof)
    return FitResult(q=jnp.where(finite, s.q, q0).T, cost=jnp.where(finite, s.H, H0), start_cost=H0, iterations=s.k,
                     converged=converged, status=status, rank=rank.astype(jnp.int32),
                     history_q=jnp.zeros((b, 0, q0.shape[0]), q0.dtype), history_cost=jnp.zeros((b, 0), q0.dtype))


def _pattern(fn, args, q0s, pattern):
    if pattern is not None:
        return pattern
    one = jax.tree_util.tree_map(lambda x: x[:1], args)
    r, _ = jax.eval_shape(fn, q0s[:1].T, one)
    return SparsePattern.dense(r.shape[0], q0s.shape[-1])


def batched_lm(fn: Callable, args, q0s: Float[Array, "B nq"], space: StateSpace, config: BatchConfig,
               pattern: SparsePattern | None = None) -> FitResult:
    """The batched solver on B problems, traceable (computes in q0s's dtype): chunks of
    ``config.chunk`` lanes, each run until all its lanes stop (see :func:`solve_batched` for the
    host-driven form that regroups slow lanes).

    Args:
        fn: ``fn(q, args_chunk) -> (r, J_values)`` lanes last: q (n_q, b), r (m, b) and the
            nonzeros of J (nnz, b) in ``pattern``'s compact order, for a chunk of b problems
            (``args_chunk``: ``args`` with a leading axis b).
        args: a pytree whose arrays have the leading batch axis B.
        q0s: (B, n_q) starts.
        pattern: static. The :class:`SparsePattern` of J (None: dense, J_values = J (m n, b)).

    Returns:
        A :class:`FitResult` with leading axis B (no history).
    """
    config = _dtype_floors(config, q0s.dtype)
    pattern = _pattern(fn, args, q0s, pattern)

    def solve_chunk(inputs):
        a, q0 = inputs
        s0 = _start(fn, a, q0, space, config)
        s = _advance(fn, a, s0, config.max_steps, space, config, pattern)
        return _result(s, s0.q, s0.H, space, config, pattern)

    B = q0s.shape[0]
    size = min(config.chunk, B)
    n_chunks = -(-B // size)
    out = jax.lax.map(solve_chunk, (jax.tree_util.tree_map(lambda x: _chunks(x, size), args), _chunks(q0s, size)))
    return jax.tree_util.tree_map(lambda x: x.reshape((n_chunks * size,) + x.shape[2:])[:B], out)


def _chunks(x, size):
    """x (B, ...) padded (repeating its last row) and split into (chunks, size, ...)."""
    B = x.shape[0]
    n_chunks = -(-B // size)
    pad = n_chunks * size - B
    x = jnp.concatenate([x, jnp.repeat(x[-1:], pad, axis=0)]) if pad else x
    return x.reshape((n_chunks, size) + x.shape[1:])


def batch_lm(fn: Callable, args, q0s: Float[Array, "B nq"], space: StateSpace, config: BatchConfig) -> FitResult:
    """:func:`batched_lm` for a per-problem ``fn(q, args_one) -> (r, J)`` with a dense J
    (vmapped, then laid out lanes last)."""

    def lanes(q, a):
        r, J = jax.vmap(fn)(q.T, a)
        return jnp.moveaxis(r, 0, -1), jnp.moveaxis(J, 0, -1).reshape(-1, q.shape[-1])

    return batched_lm(lanes, args, q0s, space, config)


@eqx.filter_jit
def _start_jit(fn, args, q0, space, config):
    return _start(fn, args, q0, space, _dtype_floors(config, q0.dtype))


@eqx.filter_jit
def _advance_jit(fn, args, s, budget, space, config, pattern):
    return _advance(fn, args, s, budget, space, _dtype_floors(config, s.q.dtype), pattern)


@eqx.filter_jit
def _result_jit(s, q0, H0, space, config, pattern):
    return _result(s, q0, H0, space, config, pattern)


def solve_batched(fn: Callable, args, q0s: Float[Array, "B nq"], space: StateSpace, config: BatchConfig,
                  pattern: SparsePattern | None = None) -> FitResult:
    """:func:`batched_lm` driven from the host, with the same result lane by lane: every chunk
    runs ``config.phase_steps`` trials; the lanes still running are then gathered into full
    chunks (the last padded by repeating a lane) for another ``phase_steps``, until every lane
    has stopped or used ``max_steps``. One compiled program per chunk size serves every phase.

    ``fn`` must be a pytree callable (an ``equinox.Module``) so that the programs are cached
    across calls; the other arguments are those of :func:`batched_lm`. Not traceable.
    """
    pattern = _pattern(fn, args, q0s, pattern)
    B = q0s.shape[0]
    size = min(config.chunk, B)
    lanes = np.minimum(np.arange(-(-B // size) * size), B - 1)   # the padding repeats the last problem
    host_args = jax.tree_util.tree_map(np.asarray, args)   # gathers and scatters in NumPy: eager jnp
    q0s = np.asarray(q0s)                                   # indexing cost more than the solves

    def take(idx):
        return jax.tree_util.tree_map(lambda x: x[idx], host_args)

    def host(tree):
        return jax.tree_util.tree_map(np.asarray, tree)

    def first(c):
        idx = lanes[c:c + size]
        st = _start_jit(fn, take(idx), q0s[idx], space, config)
        return host(st), host(_advance_jit(fn, take(idx), st, config.phase_steps, space, config, pattern))

    pool = ThreadPoolExecutor(config.threads)   # XLA releases the GIL: chunks run side by side
    parts = list(pool.map(first, range(0, lanes.size, size)))
    starts = jax.tree_util.tree_map(lambda *xs: np.concatenate(xs, axis=-1), *[p[0] for p in parts])
    state = jax.tree_util.tree_map(lambda *xs: np.concatenate(xs, axis=-1), *[p[1] for p in parts])
    while True:
        busy = np.flatnonzero((state.running & (state.k < config.max_steps))[:B])
        if busy.size == 0:
            break
        groups = np.concatenate([busy, np.full(-busy.size % size, busy[-1])]).reshape(-1, size)

        def more(idx, state=state):
            sub = jax.tree_util.tree_map(lambda leaf: leaf[..., idx], state)
            return host(_advance_jit(fn, take(lanes[idx]), sub, config.phase_steps, space, config, pattern))

        for idx, sub in zip(groups, pool.map(more, groups), strict=True):
            for x, y in zip(jax.tree_util.tree_leaves(state), jax.tree_util.tree_leaves(sub), strict=True):
                x[..., idx] = y
    pool.shutdown()
    out = _result_jit(state, starts.q, starts.H, space, config, pattern)
    return jax.tree_util.tree_map(lambda x: x[:B], out)
