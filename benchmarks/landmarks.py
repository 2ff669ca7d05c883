"""Landmark fits: throughput of the batch solver against its peers, in one run.

Problems: hand21 (fixed wrist, 21 DOF), 21 noise-free 2-D landmarks of a random pose within the
joint limits (margin 5 % of each range) seen by a 640x480 pinhole camera, fitted from the
model's default pose. Methods:

- ``batch``: :func:`jaxhand.landmarks.fit_landmarks_batch` (projected Levenberg-Marquardt,
  geometric Jacobian, batched Cholesky, chunks), float64 and float32;
- ``vmap_bounded``: ``jax.vmap`` of the general solver (the bounded trust region of
  :func:`jaxhand.fit`, i.e. what ``fit_batch`` does) on the same problems;
- ``loop_bounded``: a Python loop of :func:`jaxhand.landmarks.fit_landmarks` (bounded);
- ``scipy``: a loop of ``scipy.optimize.least_squares`` (trf with the joint limits as bounds,
  the jitted geometric Jacobian of the landmark residuals).

Accuracy: a fit succeeds when its image RMS error is below 0.5 px (noise-free data; a miss is
a local minimum of the 2-D problem: one camera cannot tell some flexions from their mirror
images). Times are steady state (compilation reported apart), medians of repeats.

    python benchmarks/landmarks.py [--quick] [--sizes 1000 10000]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import RESULTS, environment, first_call_seconds, format_table, median_seconds, write_json  # noqa: E402

import jaxhand as jh  # noqa: E402

jh.enable_x64()
from jaxhand.kinematics import pose  # noqa: E402
from jaxhand.landmarks import (  # noqa: E402
    BatchConfig,
    fit_landmarks,
    fit_landmarks_batch,
    landmark_map,
    landmark_positions,
    landmark_residuals_and_jacobian,
    make_landmark_args,
    make_landmarks,
)
from jaxhand.landmarks._fit import _single_jit  # noqa: E402


def problems(model, cam, n, seed=0):
    rng = np.random.default_rng(seed)
    qs = jh.random_q(model, rng, n, margin=0.05)
    lmap = landmark_map(model)

    @jax.jit
    def project(q):
        p = landmark_positions(model, lmap, pose(model, q), q)
        return cam.project(p)[0]

    px = np.asarray(jax.vmap(project)(jnp.asarray(qs)))
    return qs, px


def rms_px(cost, n_points=21):
    return np.sqrt(2 * np.asarray(cost) / (2 * n_points))


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="small sizes (a minute)")
    ap.add_argument("--sizes", type=int, nargs="*", default=None)
    ap.add_argument("--loop", type=int, default=None, help="problems in the loops (default 50, quick 20)")
    args = ap.parse_args(argv)
    sizes = args.sizes or ([1000] if args.quick else [1000, 10000])
    n_loop = args.loop or (20 if args.quick else 50)
    model = jh.builtin_model("hand21")
    cam = jh.Perspective.look_at([30.0, -60.0, -450.0], [0.0, -80.0, 0.0], fov_deg=60, size=(640, 480))
    q0 = np.asarray(model.q_default)
    rows, metrics = [], {}

    def record(name, n, seconds, compile_s, cost, iters):
        ok = float(np.mean(rms_px(cost) < 0.5))
        fps = n / seconds
        metrics[name] = {"problems": n, "fits_per_s": fps, "seconds": seconds, "compile_s": compile_s,
                         "success_rate": ok, "median_iterations": float(np.median(iters)),
                         "median_rms_px": float(np.median(rms_px(cost)))}
        rows.append([name, n, fps, compile_s, ok, float(np.median(iters))])

    for n in sizes:
        qs, px = problems(model, cam, n)
        lms = make_landmarks(px[:, None])
        for dtype in ("float64", "float32"):
            lm_d = jax.tree_util.tree_map(lambda x, dtype=dtype: x.astype(dtype) if x.dtype != bool else x, lms)
            cfg = BatchConfig()
            if dtype == "float32":
                m32 = jax.tree_util.tree_map(lambda x: x.astype(jnp.float32) if isinstance(x, jax.Array) else x,
                                             model)
                c32 = jax.tree_util.tree_map(lambda x: x.astype(jnp.float32) if isinstance(x, jax.Array) else x, cam)
                run = _batch32(m32, c32, lm_d, q0.astype(np.float32), cfg)
            else:
                def run(lm_d=lm_d, cfg=cfg):
                    return fit_landmarks_batch(model, cam, lm_d, q0, config=cfg)
            c = first_call_seconds(run)
            s = median_seconds(run, repeats=3, max_total_s=20.0)
            out = run()
            record(f"batch.{dtype}.{n}", n, s, c, out.cost, out.iterations)

    # the general solver vmapped (what fit_batch does), on fewer problems
    n_vmap = min(sizes[0], 200)
    qs, px = problems(model, cam, n_vmap, seed=1)
    lms = make_landmarks(px[:, None])
    config = jh.FitConfig(jacobian="geometric")

    @jax.jit
    def vmapped(lm):
        return jax.vmap(lambda one: _single_jit(make_landmark_args(model, cam, one), jnp.asarray(q0), "bounded",
                                                config))(lm)

    c = first_call_seconds(lambda: vmapped(lms))
    s = median_seconds(lambda: vmapped(lms), repeats=3, max_total_s=20.0)
    out = vmapped(lms)
    record(f"vmap_bounded.{n_vmap}", n_vmap, s, c, out.cost, out.iterations)

    # loops of single fits on the first n_loop problems
    lm_list = [make_landmarks(px[i]) for i in range(n_loop)]
    t = time.perf_counter()
    fit_landmarks(model, cam, lm_list[0], q0, solver="bounded").q.block_until_ready()
    c = time.perf_counter() - t
    t = time.perf_counter()
    res = [fit_landmarks(model, cam, lm, q0, solver="bounded") for lm in lm_list]
    jax.block_until_ready(res)
    s = time.perf_counter() - t
    record(f"loop_bounded.{n_loop}", n_loop, s, c, np.array([float(r.cost) for r in res]),
           np.array([int(r.iterations) for r in res]))

    try:
        from scipy.optimize import least_squares
    except ImportError:  # pragma: no cover
        least_squares = None
    if least_squares is not None:
        lmap = landmark_map(model)

        @jax.jit
        def rj(q, lm):
            return landmark_residuals_and_jacobian(q, make_landmark_args(model, cam, lm, lmap=lmap))

        lo, hi = np.asarray(model.q_lower), np.asarray(model.q_upper)
        x0 = np.clip(q0, lo + 1e-9, hi - 1e-9)
        costs, iters = [], []
        jax.block_until_ready(rj(jnp.asarray(x0), lm_list[0]))
        t = time.perf_counter()
        for lm in lm_list:
            cache = {}

            def fun(x, lm=lm, cache=cache):
                r, J = rj(jnp.asarray(x), lm)
                cache["J"] = np.asarray(J)
                return np.asarray(r)

            sol = least_squares(fun, x0, jac=lambda x, cache=cache: cache["J"], bounds=(lo, hi), method="trf",
                                xtol=1e-10, ftol=1e-10, gtol=1e-10)
            costs.append(sol.cost)
            iters.append(sol.nfev)
        s = time.perf_counter() - t
        record(f"scipy_trf.{n_loop}", n_loop, s, 0.0, np.array(costs), np.array(iters))

    print(format_table(rows, ["method.problems", "problems", "fits/s", "compile s", "success", "median iters"]))
    best_peer = max(v["fits_per_s"] for k, v in metrics.items() if not k.startswith("batch."))
    for k, v in metrics.items():
        if k.startswith("batch."):
            v["ratio_to_best_peer"] = v["fits_per_s"] / best_peer
            print(f"{k}: {v['ratio_to_best_peer']:.1f}x the best peer")
    data = {"benchmark": "landmarks", "problem": "hand21, 21 noise-free 2-D landmarks, random pose within limits "
            "(margin 0.05), start at the default pose, 640x480 pinhole camera", "success_rule": "image RMS < 0.5 px",
            "metrics": metrics, "environment": environment(extra_packages=("scipy",))}
    path = write_json(data, RESULTS / ("landmarks_quick.json" if args.quick else "landmarks.json"))
    print(f"wrote {path}")


def _batch32(m32, c32, lm, q0, cfg):
    """The batch solver in float32 (model, camera, landmarks and start cast)."""
    from jaxhand.landmarks._fit import _batch_jit

    lmap = landmark_map(m32)
    q = jnp.broadcast_to(jnp.asarray(q0, jnp.float32), (lm.px.shape[0], q0.shape[0]))
    return lambda: _batch_jit(m32, (c32,), lmap, lm, q, cfg)


if __name__ == "__main__":
    main()
