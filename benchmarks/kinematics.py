"""Kinematics benchmark: forward kinematics and FK + Jacobian of the projected link ends.

For hand21 (fixed palm, 21 q entries) and hand27 (free palm, 28 q entries) seen by an
orthographic camera, two tasks are timed:

- ``fk``: q -> pixels of every link's start and end point, shape (2 links, 2);
- ``fk_jac``: the same pixels and their Jacobian d pixels / d q, shape (2 links, 2, n_q).

Methods, all run in the same process on the same poses. jaxhand's:

- ``jax``: jaxhand's kernel (``jaxhand.check.keypoint_pixels``, Jacobian by ``jax.jacfwd``) under
  ``jax.jit`` with the model and camera as arguments, batched with ``jax.vmap``;
- ``jax_geo``: jaxhand's own geometric Jacobian (``jaxhand.check.geometric_jacobian``) in the same way;
- ``jax_api``: the public entry point ``jaxhand.check.autodiff_jacobian`` (``eqx.filter_jit``;
  one pose, Jacobian only), to show the dispatch cost users pay per call;

and the peers:

- ``numpy``: a hand-written NumPy forward kinematics and analytic (geometric) Jacobian from
  DigitEyes eqs. 8-10: a per-pose function called in a loop for single calls, a version
  vectorised over the batch for batches;
- ``fd``: central differences (step 1e-6) of jaxhand's jitted FK, with all 2 n_q + 1 states of
  a pose evaluated in one jitted, vmapped call.

Batches of more than CHUNK poses are processed CHUNK poses at a time by every method (see CHUNK).
Before timing, every method's pixels and Jacobian are compared with ``jax``'s and the run stops
if NumPy or ``jax_geo`` differ by more than rounding error or finite differences by more than
their truncation error; the differences are recorded next to the times. Times are medians of
repeated samples after a warm-up call, taken in rounds that interleave all methods of a mode (so
load from other processes hits them alike); the compile time of each jitted function (trace,
lower and compile ahead of its first call) is reported separately.

Run ``python benchmarks/kinematics.py`` (writes ``benchmarks/results/kinematics.json``) or
``python benchmarks/kinematics.py --quick`` for a smoke run (small batch, few repeats, no JSON
unless ``--out`` is given).
"""

from __future__ import annotations

import argparse
import gc
import json
import statistics
import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import REPO, RESULTS, block, environment, load_average  # noqa: E402

import jaxhand as jh  # noqa: E402

jh.enable_x64()
from jaxhand.check import autodiff_jacobian, geometric_jacobian, keypoint_pixels, keypoints  # noqa: E402

DEFAULT_OUT = RESULTS / "kinematics.json"
MODELS = ("hand21", "hand27")
FD_EPS = 1e-6
# Batches above CHUNK poses are processed CHUNK poses at a time by every method (lax.map over vmapped
# chunks, a loop over vectorised NumPy chunks), so a batch of 1,024 is a single vmap. One vmap of
# jax.jacfwd over all 65,536 hand27 poses peaked near 20 GB of memory and took ~27 s per call.
CHUNK = 1024
# NumPy must reproduce jaxhand to rounding error (float64); finite differences to O(eps^2) plus
# O(rounding / eps) ~ 1e-9 relative.
TOL_NUMPY_PX = 1e-9
TOL_FD_RELATIVE = 1e-6


# ---------------------------------------------------------------------------------------------
# The NumPy peer: forward kinematics and the geometric Jacobian written out by hand.
# ---------------------------------------------------------------------------------------------

def _dh_matrices(alpha, a, d, theta):
    """Craig's modified DH transform RotX(alpha) TransX(a) RotZ(theta) TransZ(d), batched on the leading axes."""
    ca, sa, ct, st = np.cos(alpha), np.sin(alpha), np.cos(theta), np.sin(theta)
    ca, sa, a, d = (np.broadcast_to(v, ct.shape) for v in (ca, sa, a, d))
    T = np.zeros(ct.shape + (4, 4))
    T[..., 0, 0], T[..., 0, 1], T[..., 0, 3] = ct, -st, a
    T[..., 1, 0], T[..., 1, 1], T[..., 1, 2], T[..., 1, 3] = st * ca, ct * ca, -sa, -sa * d
    T[..., 2, 0], T[..., 2, 1], T[..., 2, 2], T[..., 2, 3] = st * sa, ct * sa, ca, ca * d
    T[..., 3, 3] = 1.0
    return T


def _quat_matrices(quat):
    """Rotation matrix R(q/|q|) and the map E with omega = E qdot (omega = 2 qdot q*), batched.

    For q = (w, x, y, z), d(q/|q|)/dq = (I - q^ q^T)/|q| and E(q^) q^ = 0, so the angular velocity
    of R(q/|q|) in the fixed frame is ``2 E(q^) qdot / |q|`` (the quaternion rate map of DigitEyes
    eq. 10).
    """
    n = np.linalg.norm(quat, axis=-1, keepdims=True)
    w, x, y, z = np.moveaxis(quat / n, -1, 0)
    R = np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], -2)
    E = np.stack([
        np.stack([-x, w, -z, y], -1),
        np.stack([-y, z, w, -x], -1),
        np.stack([-z, -y, x, w], -1),
    ], -2) * (2.0 / n[..., None])
    return R, E


class NumpyKinematics:
    """Projected link ends of one model and their analytic Jacobian, in plain NumPy.

    Supports fixed and free (quaternion + translation) bases and an orthographic camera. Link
    ends are ordered like ``jaxhand.check.keypoints``: all link starts, then all link ends.
    """

    def __init__(self, model: jh.Model, camera: jh.Orthographic):
        if model.base_kind not in ("fixed", "free"):
            raise ValueError(f"NumpyKinematics: base kind {model.base_kind!r} is not supported (fixed, free)")
        self.n_q = model.n_q
        self.n_frames = model.n_frames
        self.free = model.base_kind == "free"
        self.mount = np.asarray(model.T_world_mount, float)
        dh = np.asarray(model.dh, float)
        self.alpha, self.a, self.d0, self.theta0 = dh.T
        self.parents = tuple(model.parents)
        self.q_index = np.array(model.q_index)
        self.revolute = np.array([k == "revolute" for k in model.joint_kinds])
        self.moving = self.q_index >= 0
        self.q_safe = np.maximum(self.q_index, 0)
        depth = []
        for f in range(self.n_frames):  # depth of each frame, following parents to the base
            k, p = 0, self.parents[f]
            while p >= 0:
                k, p = k + 1, self.parents[p]
            depth.append(k)
        self.order = sorted(range(self.n_frames), key=depth.__getitem__)
        self.levels = [np.array([f for f in range(self.n_frames) if depth[f] == k]) for k in range(max(depth) + 1)]
        self.link_frame = np.array(model.link_frame)
        self.link_axis = np.array(model.link_axis)
        self.link_length = np.asarray(model.link_length_mm, float)
        attached = np.concatenate([self.link_frame, self.link_frame])
        self.n_points = attached.size
        below = np.zeros((attached.size, self.n_frames), bool)  # below[p, f]: frame f moves point p
        for p, f in enumerate(attached):
            while f >= 0:
                below[p, f] = True
                f = self.parents[f]
        # (frame, q entry, revolute?, points it moves) for every moving frame (DigitEyes eq. 8)
        self.joints = [(f, int(self.q_index[f]), bool(self.revolute[f]), np.nonzero(below[:, f])[0])
                       for f in range(self.n_frames) if self.moving[f]]
        scale = float(camera.scale)
        self.A = scale * np.asarray(camera.R, float)[:2]                         # d pixel / d p_world
        self.b = scale * np.asarray(camera.t, float)[:2] + np.asarray(camera.center, float)

    # ---- one pose at a time (loop over frames) ----

    def _root(self, q):
        if not self.free:
            return self.mount
        R, _ = _quat_matrices(q[:4])
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = R, q[4:7]
        return self.mount @ T

    def _frames(self, q):
        T_root = self._root(q)
        T = np.empty((self.n_frames, 4, 4))
        for f in self.order:
            theta, d = self.theta0[f], self.d0[f]
            if self.moving[f]:
                if self.revolute[f]:
                    theta = theta + q[self.q_index[f]]
                else:
                    d = d + q[self.q_index[f]]
            L = _dh_matrices(self.alpha[f], self.a[f], d, np.asarray(theta))
            p = self.parents[f]
            T[f] = (T_root if p < 0 else T[p]) @ L
        return T_root, T

    def _points(self, T):
        Tl = T[..., self.link_frame, :3, :]                                            # (..., links, 3, 4)
        start = Tl[..., 3]
        pick = np.broadcast_to(self.link_axis[:, None, None], Tl.shape[:-1] + (1,))
        axis = np.take_along_axis(Tl, pick, axis=-1)[..., 0]                          # each link's own axis
        return np.concatenate([start, start + self.link_length[:, None] * axis], axis=-2)

    def fk(self, q):
        """Pixels (2 links, 2) of the link ends at one pose."""
        _, T = self._frames(q)
        return self._points(T) @ self.A.T + self.b

    def fk_jac(self, q):
        """Pixels (2 links, 2) and d pixels / d q (2 links, 2, n_q) at one pose (DigitEyes eqs. 8-10)."""
        T_root, T = self._frames(q)
        p = self._points(T)
        J = np.zeros((p.shape[0], 3, self.n_q))
        for f, j, revolute, pts in self.joints:
            z = T[f, :3, 2]
            J[pts, :, j] = np.cross(z, p[pts] - T[f, :3, 3]) if revolute else z         # eq. 8 / prismatic
        if self.free:
            M = self.mount[:3, :3]
            _, E = _quat_matrices(q[:4])
            omega = M @ E                                                               # (3, 4)
            J[:, :, :4] = np.cross(omega.T[None], (p - T_root[:3, 3])[:, None]).transpose(0, 2, 1)  # eq. 10
            J[:, :, 4:7] = M                                                            # eq. 9
        return p @ self.A.T + self.b, np.einsum("ij,pjq->piq", self.A, J)

    # ---- a batch of poses (vectorised over the batch, loop over tree levels and joints) ----

    def _frames_batch(self, Q):
        B = Q.shape[0]
        qf = np.where(self.moving, Q[:, self.q_safe], 0.0)                             # (B, frames)
        theta = self.theta0 + np.where(self.revolute, qf, 0.0)
        d = self.d0 + np.where(self.revolute, 0.0, qf)
        L = _dh_matrices(self.alpha, self.a, d, theta)                                 # (B, frames, 4, 4)
        if self.free:
            R, _ = _quat_matrices(Q[:, :4])
            base = np.zeros((B, 4, 4))
            base[:, :3, :3], base[:, :3, 3], base[:, 3, 3] = R, Q[:, 4:7], 1.0
            T_root = self.mount @ base
        else:
            T_root = np.broadcast_to(self.mount, (B, 4, 4))
        T = np.empty((B, self.n_frames, 4, 4))
        for level in self.levels:
            parents = np.array([self.parents[f] for f in level])
            top = parents < 0
            T_parent = np.where(top[None, :, None, None], T_root[:, None], T[:, np.maximum(parents, 0)])
            T[:, level] = T_parent @ L[:, level]
        return T_root, T

    def _fk_chunk(self, Q):
        _, T = self._frames_batch(Q)
        return self._points(T) @ self.A.T + self.b

    def _fk_jac_chunk(self, Q):
        T_root, T = self._frames_batch(Q)
        p = self._points(T)                                                            # (B, P, 3)
        Jq = np.zeros((self.n_q,) + p.shape)                                           # (n_q, B, P, 3)
        for f, j, revolute, pts in self.joints:
            z = T[:, f, :3, 2][:, None]
            Jq[j][:, pts] = np.cross(z, p[:, pts] - T[:, f, None, :3, 3]) if revolute else z
        if self.free:
            M = self.mount[:3, :3]
            _, E = _quat_matrices(Q[:, :4])
            omega = M @ E                                                              # (B, 3, 4)
            r = p - T_root[:, None, :3, 3]
            for k in range(4):
                Jq[k] = np.cross(omega[:, None, :, k], r)
            Jq[4:7] = M.T[:, None, None, :]
        pixels = p @ self.A.T + self.b
        return pixels, np.moveaxis(Jq @ self.A.T, 0, -1)

    def fk_batch(self, Q):
        """Pixels (B, 2 links, 2) of a batch of poses, CHUNK poses at a time."""
        out = np.empty((Q.shape[0], self.n_points, 2))
        for i in range(0, Q.shape[0], CHUNK):
            out[i:i + CHUNK] = self._fk_chunk(Q[i:i + CHUNK])
        return out

    def fk_jac_batch(self, Q):
        """Pixels (B, 2 links, 2) and the Jacobian (B, 2 links, 2, n_q), CHUNK poses at a time."""
        pixels = np.empty((Q.shape[0], self.n_points, 2))
        J = np.empty((Q.shape[0], self.n_points, 2, self.n_q))
        for i in range(0, Q.shape[0], CHUNK):
            pixels[i:i + CHUNK], J[i:i + CHUNK] = self._fk_jac_chunk(Q[i:i + CHUNK])
        return pixels, J


# ---------------------------------------------------------------------------------------------
# The jaxhand kernels and the finite-difference peer
# ---------------------------------------------------------------------------------------------

def _fk(model, camera, q):
    return keypoint_pixels(model, camera, q)


def _fk_jac(model, camera, q):
    def f(q):
        pixels = keypoint_pixels(model, camera, q)
        return pixels, pixels

    J, pixels = jax.jacfwd(f, has_aux=True)(q)
    return pixels, J


def _fk_geo(model, camera, q):
    """Pixels and jaxhand's own geometric Jacobian (DigitEyes eqs. 8-10 in JAX)."""
    p, _ = keypoints(model, q)
    return camera.project(p)[0], camera.pixel_jacobian(p) @ geometric_jacobian(model, q)


def _fk_fd(model, camera, Q):
    """Pixels at each state of Q (B, n_q) and central differences, all 2 n_q + 1 states per pose in one vmap."""
    B, n = Q.shape
    steps = FD_EPS * jnp.eye(n, dtype=Q.dtype)
    states = jnp.concatenate([Q[:, None], Q[:, None] + steps, Q[:, None] - steps], axis=1)   # (B, 2n + 1, n)
    out = jax.vmap(lambda s: keypoint_pixels(model, camera, s))(states.reshape(-1, n))
    out = out.reshape((B, 2 * n + 1) + out.shape[1:])
    return out[:, 0], jnp.moveaxis((out[:, 1:n + 1] - out[:, n + 1:]) / (2 * FD_EPS), 1, -1)


def _fk_fd_single(model, camera, q):
    pixels, J = _fk_fd(model, camera, q[None])
    return pixels[0], J[0]


def _fk_fd_batch(model, camera, Q):
    """Finite differences over a batch, CHUNK poses at a time (a ``lax.map`` over chunks).

    The perturbed states are flattened into one ``vmap`` rather than nesting ``vmap`` over poses and
    over perturbations: with jaxlib 0.10.2 on CPU, ``jit(vmap(vmap(frame_poses)))`` fails XLA's HLO
    verifier ("Expected instruction to have shape equal to f64[5,8,3,4,4], actual shape is
    f64[3,5,8,4,4]").
    """
    B, n = Q.shape
    c = min(B, CHUNK)
    pixels, J = jax.lax.map(lambda Qc: _fk_fd(model, camera, Qc), Q.reshape(B // c, c, n))
    return pixels.reshape((B,) + pixels.shape[2:]), J.reshape((B,) + J.shape[2:])


def _batched(f):
    """vmap over the poses, CHUNK poses at a time (one chunk for batches up to CHUNK)."""
    return jax.jit(lambda model, camera, Q: jax.lax.map(lambda q: f(model, camera, q), Q, batch_size=CHUNK))


#: (task, method) -> jitted kernel (model, camera, q) for one pose / (model, camera, Q) for a batch.
JAX_KERNELS = {
    ("fk", "jax"): jax.jit(_fk),
    ("fk_jac", "jax"): jax.jit(_fk_jac),
    ("fk_jac", "jax_geo"): jax.jit(_fk_geo),
    ("fk_jac", "fd"): jax.jit(_fk_fd_single),
}
JAX_BATCH_KERNELS = {
    ("fk", "jax"): _batched(_fk),
    ("fk_jac", "jax"): _batched(_fk_jac),
    ("fk_jac", "jax_geo"): _batched(_fk_geo),
    ("fk_jac", "fd"): jax.jit(_fk_fd_batch),
}
JAXHAND_METHODS = ("jax", "jax_geo", "jax_api")  # everything else is a peer
METHOD_ORDER = {"jax": 0, "jax_geo": 1, "jax_api": 2, "numpy": 3, "fd": 4}


# ---------------------------------------------------------------------------------------------
# Timing
# ---------------------------------------------------------------------------------------------

def interleaved_medians(fns: dict, *, min_sample_s: float, repeats: int, max_total_s: float) -> dict:
    """Median seconds per call of each blocking function in ``fns``, sampled in interleaved rounds.

    Like ``_common.median_seconds`` (warm-up, samples of at least ``min_sample_s``, the garbage
    collector paused), but each round takes one sample of every function in turn, so a burst of
    load from other processes on a shared machine falls on all methods of a comparison alike
    rather than on whichever happened to be running. ``repeats`` rounds, fewer (at least 3) where
    they would take longer than ``max_total_s``.
    """
    n = {}
    round_s = 0.0
    for key, fn in fns.items():
        fn()  # warm-up
        t0 = time.perf_counter()
        fn()
        t = time.perf_counter() - t0
        n[key] = max(1, int(np.ceil(min_sample_s / max(t, 1e-9))))
        round_s += n[key] * t
    k = max(3, min(repeats, int(max_total_s / max(round_s, 1e-9))))
    samples: dict = {key: [] for key in fns}
    gc.collect()
    gc.disable()
    try:
        for _ in range(k):
            for key, fn in fns.items():
                t0 = time.perf_counter()
                for _ in range(n[key]):
                    fn()
                samples[key].append((time.perf_counter() - t0) / n[key])
    finally:
        gc.enable()
    return {key: statistics.median(v) for key, v in samples.items()}


def compile_seconds(jitted, *args) -> float:
    """Time to trace, lower and compile a jitted function for these arguments (the later call reuses it)."""
    t0 = time.perf_counter()
    jitted.lower(*args).compile()
    return time.perf_counter() - t0


# ---------------------------------------------------------------------------------------------
# Environment
# ---------------------------------------------------------------------------------------------

def bench_environment() -> dict:
    """``_common.environment`` with jaxhand's version, watching jaxhand and this script for changes."""
    env = environment(watched=("jaxhand", "benchmarks/kinematics.py"))
    env["jaxhand"] = jh.__version__
    return env


# ---------------------------------------------------------------------------------------------
# The benchmark
# ---------------------------------------------------------------------------------------------

def _max_abs(a, b) -> float:
    return float(np.max(np.abs(np.asarray(a) - np.asarray(b))))


def _outputs(out) -> list:
    """The arrays a method returns: pixels, or (pixels, J), or J alone."""
    return [np.asarray(x) for x in (out if isinstance(out, tuple) else (out,))]


def check_agreement(model, single: dict, batch: dict, qs: np.ndarray) -> dict[tuple, float]:
    """Max abs difference of every method's outputs from jax's, over 16 single poses and the batch ``qs``.

    Raises RuntimeError when NumPy or jaxhand's geometric Jacobian differ from jax.jacfwd by more than
    rounding error, or finite differences by more than their truncation error.
    """
    errs = {key: 0.0 for key in single}
    scale = 1.0  # largest Jacobian entry: the tolerances on Jacobians are relative to it
    for q in qs[:16]:
        for (task, method), f in single.items():
            ref, got = _outputs(single[task, "jax"](q)), _outputs(f(q))
            scale = max(scale, float(np.abs(ref[-1]).max()))
            # zip from the end: a method returning J alone is compared on J
            errs[task, method] = max([errs[task, method]] + [_max_abs(r, g) for r, g in zip(ref[::-1], got[::-1])])
    for (task, method), f in batch.items():
        ref, got = _outputs(batch[task, "jax"](qs)), _outputs(f(qs))
        errs[task, method] = max([errs[task, method]] + [_max_abs(r, g) for r, g in zip(ref, got)])
    for (task, method), e in errs.items():
        tol = TOL_FD_RELATIVE * scale if method == "fd" else TOL_NUMPY_PX * (scale if task == "fk_jac" else 1.0)
        if e > tol:
            raise RuntimeError(f"{model.name}: {task} by {method} differs from jax by {e:.3g} (tolerance {tol:.3g})")
    return errs


def bench_model(name: str, batches: tuple[int, ...], timing: dict, rng: np.random.Generator) -> list[dict]:
    model = jh.builtin_model(name)
    pose = jh.forward(model, model.q_default)
    camera = jh.Orthographic.fit(np.concatenate([pose.link_start, pose.link_end]), size=(320, 240))
    np_kin = NumpyKinematics(model, camera)
    q = jh.random_q(model, rng, margin=0.05)
    Qs = {b: jh.random_q(model, rng, b, margin=0.05) for b in batches}
    Qj = {b: jnp.asarray(Q) for b, Q in Qs.items()}

    # Every method as a blocking call on NumPy input (jax methods convert it; timing uses device arrays).
    single = {key: (lambda q, k=k: block(k(model, camera, jnp.asarray(q)))) for key, k in JAX_KERNELS.items()}
    single["fk_jac", "jax_api"] = lambda q: block(autodiff_jacobian(model, camera, jnp.asarray(q)))
    single["fk", "numpy"], single["fk_jac", "numpy"] = np_kin.fk, np_kin.fk_jac
    batch = {key: (lambda Q, k=k: block(k(model, camera, jnp.asarray(Q)))) for key, k in JAX_BATCH_KERNELS.items()}
    batch["fk", "numpy"], batch["fk_jac", "numpy"] = np_kin.fk_batch, np_kin.fk_jac_batch

    # Compile every jitted kernel ahead of time, before anything has called it: trace + lower + compile.
    qj = jnp.asarray(q)
    compile_s = {}
    for (task, method), k in JAX_KERNELS.items():
        compile_s[task, method, "single"] = compile_seconds(k, model, camera, qj)
    compile_s["fk_jac", "jax_api", "single"] = compile_seconds(autodiff_jacobian, model, camera, qj)
    for b in batches:
        for (task, method), k in JAX_BATCH_KERNELS.items():
            compile_s[task, method, f"batch{b}"] = compile_seconds(k, model, camera, Qj[b])

    errs = check_agreement(model, single, batch, Qs[min(batches)])

    kw = dict(min_sample_s=timing["min_sample_s"], repeats=timing["repeats"], max_total_s=timing["max_total_s"])
    rows = []
    for mode, calls, arg in [("single", single, {"jax": qj, "numpy": q})] + [
            (f"batch{b}", batch, {"jax": Qj[b], "numpy": Qs[b]}) for b in batches]:
        # every method of this mode (both tasks) in one set of interleaved rounds
        seconds = interleaved_medians({key: (lambda f=f, x=arg["numpy" if key[1] == "numpy" else "jax"]: f(x))
                                       for key, f in calls.items()}, **kw)
        for (task, method), t in seconds.items():
            rows.append({"task": task, "model": name, "method": method, "mode": mode, "seconds": t,
                         "n_poses": 1 if mode == "single" else int(mode.removeprefix("batch")),
                         "compile_s": compile_s.get((task, method, mode)), "max_abs_diff": errs[task, method]})
    return rows


def add_ratios(rows: list[dict]) -> None:
    """ratio_to_best_peer = time / the fastest peer's (numpy, fd) time of the same task, model and mode."""
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        groups.setdefault((r["task"], r["model"], r["mode"]), []).append(r)
    for group in groups.values():
        best = min(r["seconds"] for r in group if r["method"] not in JAXHAND_METHODS)
        for r in group:
            r["ratio_to_best_peer"] = r["seconds"] / best


def metrics(rows: list[dict]) -> dict[str, float]:
    out = {}
    for r in rows:
        key = f"{r['task']}.{r['model']}.{r['method']}.{r['mode']}"
        if r["mode"] == "single":
            out[f"{key}.median_us"] = r["seconds"] * 1e6
        else:
            out[f"{key}.median_ms"] = r["seconds"] * 1e3
            out[f"{key}.per_pose_us"] = r["seconds"] * 1e6 / r["n_poses"]
        out[f"{key}.ratio_to_best_peer"] = r["ratio_to_best_peer"]
        if r["compile_s"] is not None:
            out[f"{key}.compile_s"] = r["compile_s"]
        out[f"{key}.max_abs_diff_to_jax"] = r["max_abs_diff"]
    return out


def table(rows: list[dict]) -> str:
    head = (f"{'task':6s} {'model':6s} {'mode':10s} {'method':7s} {'per call':>11s} {'per pose':>11s} "
            f"{'/best peer':>10s} {'|diff| jax':>10s} {'compile s':>9s}")
    lines = [head, "-" * len(head)]
    for r in sorted(rows, key=lambda r: (r["task"], r["model"], r["n_poses"], METHOD_ORDER[r["method"]])):
        t = r["seconds"]
        per_call = f"{t * 1e6:8.1f} us" if r["mode"] == "single" else f"{t * 1e3:8.2f} ms"
        per_pose = f"{t * 1e6 / r['n_poses']:8.2f} us"
        comp = "" if r["compile_s"] is None else f"{r['compile_s']:9.2f}"
        lines.append(f"{r['task']:6s} {r['model']:6s} {r['mode']:10s} {r['method']:7s} {per_call:>11s} "
                     f"{per_pose:>11s} {r['ratio_to_best_peer']:9.3f}x {r['max_abs_diff']:10.1e} {comp:>9s}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="smoke run: batch of 256 only, few repeats, no JSON")
    parser.add_argument("--out", type=Path, help=f"JSON output (default {DEFAULT_OUT.relative_to(REPO)}, "
                                                 "none for --quick)")
    args = parser.parse_args(argv)
    if args.quick:
        batches, timing = (256,), {"min_sample_s": 0.002, "repeats": 3, "max_total_s": 0.5}
    else:
        batches, timing = (1024, 65536), {"min_sample_s": 0.02, "repeats": 9, "max_total_s": 20.0}
    out = args.out if args.out is not None else (None if args.quick else DEFAULT_OUT)

    env = bench_environment()
    print(f"kinematics benchmark: {env['cpu']} ({env['cpu_count']} cores, load {env['load_average_1min_start']}), "
          f"jax {env['jax']} on {env['device']}, float64={env['x64']}, "
          f"commit {env['commit']}{' (dirty)' if env['dirty'] else ''}")
    print("fk: q -> pixels of all link ends; fk_jac: pixels and d pixels/d q (orthographic camera)")
    print("jaxhand: jax = jax.jit kernel (+ jax.jacfwd; lax.map of vmap over chunks of "
          f"{CHUNK} for batches), jax_geo = jaxhand.check.geometric_jacobian jitted,\n"
          "         jax_api = jaxhand.check.autodiff_jacobian (public eqx.filter_jit entry point, Jacobian only)")
    print("peers:   numpy = hand-written FK + analytic Jacobian (DigitEyes eqs. 8-10), per-pose loop / vectorised "
          f"batches; fd = central differences (eps {FD_EPS:g}) of jaxhand's jitted FK\n")
    rng = np.random.default_rng(0)
    rows = []
    for name in MODELS:
        rows += bench_model(name, batches, timing, rng)
    add_ratios(rows)
    env["load_average_1min_end"] = load_average()
    print(table(rows))
    print("\n/best peer: time / the fastest peer's (numpy, fd) time for the same task, model and mode (< 1: faster)."
          "\n|diff| jax: max abs difference from the jax row's pixels and Jacobian (px, px/rad, px/mm)."
          "\ncompile s: trace + lower + compile, timed ahead of the first call.")
    if out is not None:
        result = {"benchmark": "kinematics", "schema": 1, "quick": args.quick, "environment": env,
                  "settings": {"models": list(MODELS), "batches": list(batches), "fd_eps": FD_EPS,
                               "camera": "orthographic", "timing": timing, "seed": 0},
                  "metrics": metrics(rows)}
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(result, indent=2, sort_keys=True) + "\n")
        print(f"\nwrote {out.relative_to(REPO) if out.resolve().is_relative_to(REPO) else out.name}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
