"""Landmark fits: throughput of the batch solver against its peers, in one run.

Problems: hand21 (fixed wrist, 21 DOF), 21 noise-free 2-D landmarks of a random pose within the
joint limits (margin 5 % of each range) seen by a 640x480 pinhole camera, fitted from the
model's default pose. Methods:

- ``batch``: :func:`jaxhand.landmarks.fit_landmarks_batch` (the batched bounded
  Levenberg-Marquardt: lanes last, block Cholesky of the normal equations, active set at the
  limits, slow lanes regrouped), over 1,000 and 10,000 problems;
- ``loop_bounded``: a Python loop of :func:`jaxhand.landmarks.fit_landmarks` (bounded);
- ``scipy_trf``: a loop of ``scipy.optimize.least_squares`` (trf with the joint limits as bounds,
  the jitted geometric Jacobian of the landmark residuals);
- peers vmapped over the problems, on the same residuals and Jacobian, 40 iterations at most,
  no joint limits (they have none): optimistix's ``GaussNewton`` and ``LevenbergMarquardt``
  (``optx.least_squares``) and jaxopt's ``GaussNewton`` and ``LevenbergMarquardt``.

Reported per method: fits/s (steady state; compilation apart), the converged share (the
method's own stopping rule fired), the success share (image RMS < 0.5 px: noise-free data, a miss
is a local minimum; one camera cannot tell some flexions from their mirror images), the share
within the joint limits, the median final cost and iterations.

    python benchmarks/landmarks.py [--quick] [--sizes 1000 10000] [--loop 50]
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

from _common import RESULTS, environment, format_table, load_average, write_json  # noqa: E402
from _peers import vmapped_peers  # noqa: E402

import jaxhand as jh  # noqa: E402

jh.enable_x64()
from jaxhand.kinematics import pose  # noqa: E402
from jaxhand.landmarks import (  # noqa: E402
    fit_landmarks,
    fit_landmarks_batch,
    landmark_map,
    landmark_positions,
    landmark_residuals_and_jacobian,
    make_landmark_args,
    make_landmarks,
)

PEER_STEPS = 40


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


def timed(fn):
    """(first call s, steady s, result): a first call, then the median of two more."""
    t = time.perf_counter()
    out = jax.block_until_ready(fn())
    first = time.perf_counter() - t
    runs = []
    for _ in range(2):
        t = time.perf_counter()
        out = jax.block_until_ready(fn())
        runs.append(time.perf_counter() - t)
    s = float(np.median(runs))
    return max(first - s, 0.0), s, out


def peer_programs(model, cam):
    """Vmapped peers on the landmark residuals (r and the geometric J from one jitted function)."""
    lmap = landmark_map(model)

    def rj(q, lm):
        return landmark_residuals_and_jacobian(q, make_landmark_args(model, cam, lm, lmap=lmap))

    return vmapped_peers(lambda q, lm: rj(q, lm)[0], lambda q, lm: rj(q, lm)[1], PEER_STEPS)


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="small sizes (a few minutes)")
    ap.add_argument("--sizes", type=int, nargs="*", default=None)
    ap.add_argument("--loop", type=int, default=None, help="problems in the loops (default 50, quick 20)")
    ap.add_argument("--peers", type=int, default=None, help="problems for the vmapped peers (default 1000)")
    args = ap.parse_args(argv)
    sizes = args.sizes or ([1000] if args.quick else [1000, 10000])
    n_loop = args.loop or (20 if args.quick else 50)
    n_peer = args.peers or (200 if args.quick else 1000)
    env = environment(extra_packages=("scipy", "optimistix", "jaxopt"))
    model = jh.builtin_model("hand21")
    cam = jh.Perspective.look_at([30.0, -60.0, -450.0], [0.0, -80.0, 0.0], fov_deg=60, size=(640, 480))
    q0 = np.asarray(model.q_default)
    lo, hi = np.asarray(model.q_lower), np.asarray(model.q_upper)
    rows, metrics = [], {}
    qs_all, px_all = problems(model, cam, max(sizes + [n_peer, n_loop]))

    def record(name, n, seconds, compile_s, q, cost, iters, converged):
        q = np.asarray(q)
        m = {"problems": n, "fits_per_s": n / seconds, "seconds": seconds, "compile_s": compile_s,
             "converged_rate": float(np.mean(converged)), "success_rate": float(np.mean(rms_px(cost) < 0.5)),
             "within_limits_rate": float(np.mean(np.all((q >= lo - 1e-9) & (q <= hi + 1e-9), axis=-1))),
             "median_cost_px2": float(np.median(cost)), "median_iterations": float(np.median(iters)),
             "load_1min": load_average()}
        metrics[name] = m
        rows.append([name, n, m["fits_per_s"], compile_s, m["converged_rate"], m["success_rate"],
                     m["within_limits_rate"], m["median_cost_px2"], m["median_iterations"], m["load_1min"]])
        print(f"  {name}: {m['fits_per_s']:.1f} fits/s (load {m['load_1min']})", flush=True)

    for n in sizes:
        lms = make_landmarks(px_all[:n, None])
        c, s, out = timed(lambda lms=lms: fit_landmarks_batch(model, cam, lms, q0))
        record(f"batch.{n}", n, s, c, out.q, np.asarray(out.cost), out.iterations, out.converged)

    # loops of single fits
    lm_list = [make_landmarks(px_all[i]) for i in range(n_loop)]
    t = time.perf_counter()
    fit_landmarks(model, cam, lm_list[0], q0, solver="bounded").q.block_until_ready()
    c = time.perf_counter() - t
    t = time.perf_counter()
    res = jax.block_until_ready([fit_landmarks(model, cam, lm, q0, solver="bounded") for lm in lm_list])
    s = time.perf_counter() - t
    record(f"loop_bounded.{n_loop}", n_loop, s, c, np.stack([r.q for r in res]), np.array([float(r.cost) for r in res]),
           np.array([int(r.iterations) for r in res]), np.array([bool(r.converged) for r in res]))

    from scipy.optimize import least_squares

    lmap = landmark_map(model)

    @jax.jit
    def rj(q, lm):
        return landmark_residuals_and_jacobian(q, make_landmark_args(model, cam, lm, lmap=lmap))

    x0 = np.clip(q0, lo + 1e-9, hi - 1e-9)
    jax.block_until_ready(rj(jnp.asarray(x0), lm_list[0]))
    sols = []
    t = time.perf_counter()
    for lm in lm_list:
        cache = {}

        def fun(x, lm=lm, cache=cache):
            r, J = rj(jnp.asarray(x), lm)
            cache["J"] = np.asarray(J)
            return np.asarray(r)

        sols.append(least_squares(fun, x0, jac=lambda x, cache=cache: cache["J"], bounds=(lo, hi), method="trf",
                                  xtol=1e-10, ftol=1e-10, gtol=1e-10))
    s = time.perf_counter() - t
    record(f"scipy_trf.{n_loop}", n_loop, s, 0.0, np.stack([o.x for o in sols]), np.array([o.cost for o in sols]),
           np.array([o.njev for o in sols]), np.array([o.status > 0 for o in sols]))

    lms = make_landmarks(px_all[:n_peer, None])
    for name, run in peer_programs(model, cam).items():
        q0s = jnp.asarray(np.broadcast_to(q0, (n_peer, q0.size)))
        c, s, (q, cost, conv, it) = timed(lambda run=run, q0s=q0s: run(lms, q0s))
        record(f"{name}.{n_peer}", n_peer, s, c, q, np.asarray(cost), np.asarray(it), np.asarray(conv))

    scipy = metrics[f"scipy_trf.{n_loop}"]["fits_per_s"]
    for v in metrics.values():
        v["ratio_to_scipy_loop"] = v["fits_per_s"] / scipy
    env["load_average_1min_end"] = load_average()
    print(format_table(rows, ["method.problems", "problems", "fits/s", "compile s", "converged", "success",
                              "in limits", "median cost px2", "median iters", "load"]))
    for k, v in metrics.items():
        print(f"{k}: {v['ratio_to_scipy_loop']:.1f}x the scipy loop")
    data = {"benchmark": "landmarks", "problem": "hand21, 21 noise-free 2-D landmarks, random pose within limits "
            "(margin 0.05), start at the default pose, 640x480 pinhole camera", "success_rule": "image RMS < 0.5 px",
            "peer_max_steps": PEER_STEPS, "metrics": metrics, "environment": env}
    path = write_json(data, RESULTS / ("landmarks_quick.json" if args.quick else "landmarks.json"))
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
