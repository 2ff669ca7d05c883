"""Solver benchmark: jaxhand's solvers against scipy.optimize.least_squares on the 21-DOF hand.

Problems: ``hand21`` seen by one orthographic camera with an oblique view (rotated 45 deg about
the image x axis and 20 deg about y, like the 45-degree plane of thesis §6; the front view
leaves the hand's flexion unobservable, see the ambiguity section). Ground-truth poses are
uniform within the joint limits; features are projected from them exactly or with 0.5 px
Gaussian noise on the link end points and tips (``jaxhand.solve.features_from_poses``); starts
are the truth plus N(0, sigma) per joint, clipped to the limits, for sigma = 5, 15, 30 deg. Every
(sigma, noise) setting has N problems (200 by default), the same for every solver.

Solvers, all on the same residuals (``jaxhand.residuals``, two points per link at 0.25/0.75):

- jaxhand: ``gn``, ``gn_eta`` (adaptive eta, caps 0.3 rad), ``lm_fixed`` (mu = 1e-3), ``lm``,
  ``bounded`` (joint limits), through the public ``jaxhand.fit`` (one jitted call per problem,
  input validation included) with ``FitConfig()`` defaults (xtol 1e-10, ftol 1e-12, 50 steps);
- scipy: ``least_squares`` with ``method`` 'lm' (unbounded), 'trf' and 'dogbox' (joint limits as
  bounds), each with ``jac='2-point'`` and with the JAX Jacobian (``jax.jacfwd``), residuals and
  Jacobian jitted once (model and camera baked in, features passed per call);
  ``xtol=1e-10, ftol=1e-12, gtol=1e-10``.

Reported per solver and setting: success rate (max joint error < 1 deg); best-minimum rate
(final cost within 1e-6 relative of the lowest cost any solver of the same kind, bounded or
unbounded, reached on that problem: the solver's own success when noise makes 1 deg
unreachable); exact-fit rate (H < 1e-10, noise-free only); the median seconds per solve after
compilation (each solve timed alone and blocked on; compile time = first call less the
median, listed apart); median iterations (jaxhand: trial steps; scipy: Jacobian evaluations,
or function evaluations for 'lm' with '2-point', where scipy counts no Jacobians).
Batch throughput: N_BATCH problems (sigma 15 deg, 0.5 px) with ``jaxhand.fit_batch`` (``lm`` and
``bounded``: one vmapped call that runs until its slowest problem stops; ``batch``: the batched
bounded Levenberg-Marquardt with the lanes-last sparse edge kernel), vmapped optimistix/jaxopt
peers, a Python loop over ``jaxhand.fit`` (``lm``) and loops over scipy; each row with its ratio
to the loop of ``fit`` and to the best scipy loop, its converged share and its median final cost
(the 1-degree success reads 0 for every method at 0.5 px in one view, so the JSON keeps it but
the table shows the cost).
Ambiguity of one view: how often a fit is exact (H < 1e-10) yet more than 1 deg from the truth,
in the oblique and the front view, and which joints the view observes least (the predicted
standard deviation of each joint under 0.5 px noise, ``sigma_px sqrt(diag (J^T J)^-1)`` at the
truth; null-space share of each joint in the front view).

Run ``python benchmarks/solvers.py`` (several minutes; writes ``benchmarks/results/solvers.json``
and ``solvers.png``) or ``--quick`` for a smoke run (20 problems, batch 100, no files unless
``--out``).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from scipy.optimize import least_squares

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import (  # noqa: E402
    RESULTS,
    environment,
    first_call_seconds,
    format_table,
    load_average,
    time_call,
    write_json,
)
from _peers import vmapped_peers  # noqa: E402

import jaxhand as jh  # noqa: E402

jh.enable_x64()
from jaxhand.residuals import DEFAULT_LINK_FRACTIONS, ResidualArgs, residuals, residuals_and_jacobian  # noqa: E402
from jaxhand.solve import SOLVERS, StateSpace, features_from_poses  # noqa: E402
from jaxhand.solve.internal import BatchConfig, solve_batched  # noqa: E402

MODEL = "hand21"
SIGMAS_DEG = (5.0, 15.0, 30.0)
NOISES_PX = (0.0, 0.5)
SUCCESS_DEG = 1.0
EXACT_H = 1e-10
SCIPY = (("lm", "2-point"), ("lm", "jax"), ("trf", "2-point"), ("trf", "jax"), ("dogbox", "2-point"),
         ("dogbox", "jax"))
SCIPY_TOL = dict(xtol=1e-10, ftol=1e-12, gtol=1e-10)
BATCH_SETTING = (15.0, 0.5)
BATCH_SCIPY = (("lm", "jax"), ("trf", "jax"))


def _rotation(rx_deg: float, ry_deg: float) -> np.ndarray:
    ax, ay = np.radians(rx_deg), np.radians(ry_deg)
    Rx = np.array([[1, 0, 0], [0, np.cos(ax), -np.sin(ax)], [0, np.sin(ax), np.cos(ax)]])
    Ry = np.array([[np.cos(ay), 0, np.sin(ay)], [0, 1, 0], [-np.sin(ay), 0, np.cos(ay)]])
    return Rx @ Ry


def camera(model: jh.Model, R: np.ndarray) -> jh.Orthographic:
    """An orthographic 320x240 camera with view rotation R framing the model's default pose."""
    pose = jh.forward(model, model.q_default)
    return jh.Orthographic.fit(np.concatenate([pose.link_start, pose.link_end]), size=(320, 240), R=R)


def make_problems(model, cam, n, sigma_deg, noise_px, seed):
    rng = np.random.default_rng(seed)
    Q = jh.random_q(model, rng, n)
    F = features_from_poses(model, (cam,), Q, noise_px=noise_px, rng=rng)[0]
    Q0 = np.clip(Q + rng.normal(0, np.radians(sigma_deg), Q.shape), np.asarray(model.q_lower),
                 np.asarray(model.q_upper))
    return Q, F, Q0


class DenseEdgeResiduals(eqx.Module):
    """The link and tip residuals with their dense geometric Jacobian, vmapped over problems and
    laid out lanes last: the edge kernel of ``fit_batch(solver="batch")`` before its sparse one."""

    model: jh.Model
    cameras: tuple
    fractions: jax.Array

    def __call__(self, q, feats):
        def one(q1, f1):
            return residuals_and_jacobian(q1, ResidualArgs(model=self.model, cameras=self.cameras, features=f1,
                                                           fractions=self.fractions))

        r, J = jax.vmap(one)(q.T, feats)
        return jnp.moveaxis(r, 0, -1), jnp.moveaxis(J, 0, -1).reshape(-1, q.shape[-1])


def _one(F, i):
    return jax.tree_util.tree_map(lambda x: x[i], F)


def joint_error_deg(q, q_true):
    return np.degrees(np.abs(np.asarray(q) - np.asarray(q_true)).max(axis=-1))


# ---- jaxhand ----

def run_jaxhand(model, cam, solver, Q, F, Q0):
    """Each problem solved alone through jaxhand.fit; returns per-problem arrays and compile time."""
    n = len(Q)
    first = first_call_seconds(lambda: jh.fit(model, cam, _one(F, 0), Q0[0], solver=solver).q)
    times, qs, costs, its, status = [], [], [], [], []
    for i in range(n):
        f = _one(F, i)
        t, r = time_call(lambda f=f, i=i: jh.fit(model, cam, f, Q0[i], solver=solver))
        times.append(t)
        qs.append(np.asarray(r.q))
        costs.append(float(r.cost))
        its.append(int(r.iterations))
        status.append(r.status_name())
    med = statistics.median(times)
    return dict(q=np.array(qs), cost=np.array(costs), iterations=np.array(its), seconds=np.array(times),
                compile_s=max(first - med, 0.0), status=status)


# ---- scipy ----

class ScipyProblem:
    """Residuals and Jacobian jitted once for the model and camera; features are arguments."""

    def __init__(self, model, cam):
        fractions = jnp.asarray(DEFAULT_LINK_FRACTIONS)

        def r(q, f):
            return residuals(q, ResidualArgs(model=model, cameras=(cam,), features=(f,), fractions=fractions))

        self.res = jax.jit(r)
        self.jac = jax.jit(jax.jacfwd(r))
        self.lower, self.upper = np.asarray(model.q_lower), np.asarray(model.q_upper)

    def compile(self, q, f) -> float:
        return first_call_seconds(lambda: self.res(jnp.asarray(q), f)) + first_call_seconds(
            lambda: self.jac(jnp.asarray(q), f))

    def solve(self, method, jac, q0, f):
        fun = lambda q: np.asarray(self.res(q, f))  # noqa: E731
        jacobian = "2-point" if jac == "2-point" else (lambda q: np.asarray(self.jac(q, f)))
        bounds = (-np.inf, np.inf) if method == "lm" else (self.lower, self.upper)
        return least_squares(fun, q0, jac=jacobian, method=method, bounds=bounds, **SCIPY_TOL)


def run_scipy(sp: ScipyProblem, method, jac, Q, F, Q0):
    times, qs, costs, its, ok = [], [], [], [], []
    for i in range(len(Q)):
        f = _one(F, i)
        t0 = time.perf_counter()
        sol = sp.solve(method, jac, Q0[i], f)
        times.append(time.perf_counter() - t0)
        qs.append(sol.x)
        costs.append(float(sol.cost))
        its.append(int(sol.njev) if sol.njev is not None else int(sol.nfev))
        ok.append(bool(sol.success))
    return dict(q=np.array(qs), cost=np.array(costs), iterations=np.array(its), seconds=np.array(times),
                compile_s=0.0, status=["ok" if s else "failed" for s in ok])


# ---- summaries ----

def summarise(name, kind, sigma, noise, out, Q, best_cost=None):
    err = joint_error_deg(out["q"], Q)
    exact = out["cost"] < EXACT_H
    best = out["cost"] if best_cost is None else best_cost
    return {
        "solver": name, "kind": kind, "sigma_deg": sigma, "noise_px": noise, "n": len(Q),
        "success_rate": float(np.mean(err < SUCCESS_DEG)),
        "best_minimum_rate": float(np.mean(out["cost"] <= best * (1 + 1e-6) + 1e-9)),
        "exact_fit_rate": float(np.mean(exact)) if noise == 0 else None,
        "ambiguous_rate": float(np.mean(exact & (err >= SUCCESS_DEG))) if noise == 0 else None,
        "median_ms": 1e3 * float(np.median(out["seconds"])),
        "p90_ms": 1e3 * float(np.percentile(out["seconds"], 90)),
        "median_iterations": float(np.median(out["iterations"])),
        "compile_s": float(out["compile_s"]),
        "median_error_deg": float(np.median(err)),
    }


def weak_joints(model, cam, Q, noise_px=0.5, top=6):
    """Median over poses of each joint's predicted std (deg) under ``noise_px`` pixel noise."""
    sp = ScipyProblem(model, cam)
    F = features_from_poses(model, (cam,), Q)[0]
    stds, ranks = [], []
    for i in range(len(Q)):
        J = np.asarray(sp.jac(jnp.asarray(Q[i]), _one(F, i)))
        s = np.linalg.svd(J, compute_uv=False)
        ranks.append(int(np.sum(s > 1e-9 * s[0])))
        cov = np.linalg.pinv(J.T @ J, rcond=1e-12)
        stds.append(np.degrees(noise_px * np.sqrt(np.maximum(np.diag(cov), 0))))
    med = np.median(np.array(stds), axis=0)
    order = np.argsort(med)[::-1]
    return {"median_rank": float(np.median(ranks)), "dof": model.dof,
            "weakest": [{"joint": model.q_names[j], "std_deg": float(med[j])} for j in order[:top]],
            "strongest": [{"joint": model.q_names[j], "std_deg": float(med[j])} for j in order[-3:]]}


def null_space_joints(model, cam, Q, top=8):
    """Front view: each joint's mean share of the Jacobian's null space (rank-deficient views)."""
    sp = ScipyProblem(model, cam)
    F = features_from_poses(model, (cam,), Q)[0]
    share, ranks = np.zeros(model.n_q), []
    for i in range(len(Q)):
        J = np.asarray(sp.jac(jnp.asarray(Q[i]), _one(F, i)))
        _, s, Vt = np.linalg.svd(J)
        null = Vt[np.concatenate([s, np.zeros(len(Vt) - len(s))]) <= 1e-9 * s[0]]
        ranks.append(model.n_q - len(null))
        share += np.sum(null ** 2, axis=0) / len(Q)
    order = np.argsort(share)[::-1]
    return {"median_rank": float(np.median(ranks)), "dof": model.dof,
            "null_space_share": [{"joint": model.q_names[j], "share": float(share[j])} for j in order[:top]]}


def plot(rows, path):
    """Success rate (top) and best-minimum rate (bottom) against sigma, one panel per noise level."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    metrics = (("success_rate", f"success (%): max joint error < {SUCCESS_DEG} deg"),
               ("best_minimum_rate", "reached the best minimum (%)"))
    fig, axes = plt.subplots(len(metrics), len(NOISES_PX), figsize=(6 * len(NOISES_PX), 4.2 * len(metrics)),
                             sharex=True, sharey=True, squeeze=False)
    for row, (key, label) in enumerate(metrics):
        for col, noise in enumerate(NOISES_PX):
            ax = axes[row, col]
            for name in dict.fromkeys(r["solver"] for r in rows):
                rs = sorted((r for r in rows if r["solver"] == name and r["noise_px"] == noise),
                            key=lambda r: r["sigma_deg"])
                if rs:
                    ax.plot([r["sigma_deg"] for r in rs], [100 * r[key] for r in rs],
                            "-o" if rs[0]["kind"] == "jaxhand" else "--s", label=name, ms=4)
            ax.set_title(f"{MODEL}, one oblique orthographic view, noise {noise:g} px", fontsize=10)
            ax.grid(alpha=0.3)
            if col == 0:
                ax.set_ylabel(label)
            if row == len(metrics) - 1:
                ax.set_xlabel("start perturbation sigma (deg per joint)")
    axes[0, 0].legend(fontsize=8, loc="lower left")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="smoke run: 20 problems, batch 100, no files")
    parser.add_argument("--n", type=int, default=None, help="problems per setting (default 200)")
    parser.add_argument("--out", default=None, help="JSON path (default benchmarks/results/solvers.json)")
    parser.add_argument("--batch-only", action="store_true", help="only the batch throughput section")
    ns = parser.parse_args(argv)
    n = ns.n or (20 if ns.quick else 200)
    n_batch = 100 if ns.quick else 1000
    sigmas = (5.0, 30.0) if ns.quick else SIGMAS_DEG
    out_path = Path(ns.out) if ns.out else (None if ns.quick else RESULTS / "solvers.json")

    env = environment(extra_packages=("scipy", "optimistix", "lineax", "equinox"))
    print(f"solver benchmark: {env['cpu']} ({env['cpu_count']} cores, load {env['load_average_1min_start']}), "
          f"jax {env['jax']}, commit {env['commit']}; {MODEL}, {n} problems per setting")
    model = jh.builtin_model(MODEL)
    cam = camera(model, _rotation(45.0, 20.0))
    sp = ScipyProblem(model, cam)
    rows = []
    for si, sigma in enumerate(() if ns.batch_only else sigmas):
        for ni, noise in enumerate(NOISES_PX):
            Q, F, Q0 = make_problems(model, cam, n, sigma, noise, seed=100 * si + ni)
            scipy_compile = sp.compile(Q0[0], _one(F, 0))
            outs = {}
            for solver in SOLVERS:
                outs[solver] = ("jaxhand", run_jaxhand(model, cam, solver, Q, F, Q0))
            for method, jac in SCIPY:
                res = run_scipy(sp, method, jac, Q, F, Q0)
                res["compile_s"] = scipy_compile if jac == "jax" else 0.0
                outs[f"scipy_{method}_{jac}"] = ("scipy", res)
            # the lowest cost any solver of the same kind (bounded or not) found on each problem
            bounded = {name: name == "bounded" or name.startswith(("scipy_trf", "scipy_dogbox")) for name in outs}
            best = {b: np.min([o["cost"] for name, (_, o) in outs.items() if bounded[name] == b], axis=0)
                    for b in (False, True)}
            load = load_average()
            for name, (kind, o) in outs.items():
                rows.append(summarise(name, kind, sigma, noise, o, Q, best[bounded[name]]) | {"load_1min": load})
            print(f"  sigma {sigma:g} deg, noise {noise:g} px: done (load {load_average()})", flush=True)

    # best scipy per setting, and each solver's time ratio to it
    for r in rows:
        peers = [p for p in rows if p["kind"] == "scipy" and p["sigma_deg"] == r["sigma_deg"]
                 and p["noise_px"] == r["noise_px"]]
        best = min(peers, key=lambda p: p["median_ms"])
        r["ratio_to_best_scipy"] = r["median_ms"] / best["median_ms"]
        r["best_scipy"] = best["solver"]

    # batch throughput
    sigma, noise = BATCH_SETTING
    Q, F, Q0 = make_problems(model, cam, n_batch, sigma, noise, seed=999)
    batch = []
    for solver in (("lm", "bounded") if ns.batch_only else SOLVERS):
        first = first_call_seconds(lambda s=solver: jh.fit_batch(model, cam, F, Q0, solver=s).q)
        runs = [time_call(lambda s=solver: jh.fit_batch(model, cam, F, Q0, solver=s)) for _ in range(3)]
        t = statistics.median(t for t, _ in runs)
        r = runs[0][1]
        batch.append({"solver": solver, "kind": "jaxhand fit_batch", "n": n_batch, "seconds": t,
                      "problems_per_s": n_batch / t, "compile_s": max(first - t, 0.0),
                      "converged_rate": float(np.mean(np.asarray(r.converged))),
                      "median_cost_px2": float(np.median(np.asarray(r.cost))),
                      "success_rate": float(np.mean(joint_error_deg(r.q, Q) < SUCCESS_DEG))})
    # the batched bounded Levenberg-Marquardt (fit_batch(solver="batch")), and peers vmapped alike
    first = first_call_seconds(lambda: jh.fit_batch(model, cam, F, Q0, solver="batch").q)
    runs = [time_call(lambda: jh.fit_batch(model, cam, F, Q0, solver="batch")) for _ in range(3)]
    t = statistics.median(t for t, _ in runs)
    batch.append({"solver": "batch", "kind": "jaxhand fit_batch", "n": n_batch, "seconds": t,
                  "problems_per_s": n_batch / t, "compile_s": max(first - t, 0.0),
                  "converged_rate": float(np.mean(np.asarray(runs[0][1].converged))),
                  "median_cost_px2": float(np.median(np.asarray(runs[0][1].cost))),
                  "iterations_p50_p90_max": [float(x) for x in np.percentile(np.asarray(runs[0][1].iterations),
                                                                             [50, 90, 100])],
                  "success_rate": float(np.mean(joint_error_deg(runs[0][1].q, Q) < SUCCESS_DEG))})
    # the same solver on the dense kernel it had before the lanes-last sparse one (a per-problem
    # Jacobian, vmapped): the kernel's share of the speed-up, in this run
    dense = DenseEdgeResiduals(model=model, cameras=(cam,), fractions=jnp.asarray(DEFAULT_LINK_FRACTIONS))
    feats = (jax.tree_util.tree_map(jnp.asarray, F),)

    def run_dense():
        return solve_batched(dense, feats, jnp.asarray(Q0), StateSpace.of(model), BatchConfig())

    first = first_call_seconds(lambda: run_dense().q)
    runs = [time_call(run_dense) for _ in range(3)]
    t = statistics.median(t for t, _ in runs)
    batch.append({"solver": "batch_dense_kernel", "kind": "jaxhand solve_batched", "n": n_batch, "seconds": t,
                  "problems_per_s": n_batch / t, "compile_s": max(first - t, 0.0),
                  "converged_rate": float(np.mean(np.asarray(runs[0][1].converged))),
                  "median_cost_px2": float(np.median(np.asarray(runs[0][1].cost))),
                  "success_rate": float(np.mean(joint_error_deg(runs[0][1].q, Q) < SUCCESS_DEG))})
    peers = vmapped_peers(lambda q, f: sp.res(q, f), lambda q, f: sp.jac(q, f), 50)
    n_peer = min(n_batch, 200)   # the vmapped peers run every lane to the slowest: fewer problems
    F_peer = jax.tree_util.tree_map(lambda x: x[:n_peer], F)
    for name, run in peers.items():
        first = first_call_seconds(lambda run=run: run(F_peer, jnp.asarray(Q0[:n_peer]))[0])
        t, out = time_call(lambda run=run: run(F_peer, jnp.asarray(Q0[:n_peer])))
        batch.append({"solver": name, "kind": "peer, vmapped", "n": n_peer, "seconds": t,
                      "problems_per_s": n_peer / t, "compile_s": max(first - t, 0.0),
                      "converged_rate": float(np.mean(np.asarray(out[2]))),
                      "median_cost_px2": float(np.median(np.asarray(out[1]))),
                      "success_rate": float(np.mean(joint_error_deg(np.asarray(out[0]), Q[:n_peer]) < SUCCESS_DEG))})
    # warm: the loop's one compilation is not part of its time (the batch rows list theirs apart)
    fit_compile_s = first_call_seconds(lambda: jh.fit(model, cam, _one(F, 0), Q0[0], solver="lm").q)
    t0 = time.perf_counter()
    fits = [jh.fit(model, cam, _one(F, i), Q0[i], solver="lm") for i in range(n_batch)]
    jax.block_until_ready(fits)
    t = time.perf_counter() - t0
    batch.append({"solver": "lm", "kind": "jaxhand fit loop", "n": n_batch, "seconds": t,
                  "problems_per_s": n_batch / t, "compile_s": fit_compile_s,
                  "converged_rate": float(np.mean([bool(f.converged) for f in fits])),
                  "median_cost_px2": float(np.median([float(f.cost) for f in fits])),
                  "success_rate": float(np.mean(joint_error_deg(np.array([f.q for f in fits]), Q) < SUCCESS_DEG))})
    for method, jac in BATCH_SCIPY:
        t0 = time.perf_counter()
        sols = [sp.solve(method, jac, Q0[i], _one(F, i)) for i in range(n_batch)]
        t = time.perf_counter() - t0
        batch.append({"solver": f"scipy_{method}_{jac}", "kind": "scipy loop", "n": n_batch, "seconds": t,
                      "problems_per_s": n_batch / t, "compile_s": 0.0,
                      "converged_rate": float(np.mean([x.status > 0 for x in sols])),
                      "median_cost_px2": float(np.median([x.cost for x in sols])),
                      "success_rate": float(np.mean(joint_error_deg(np.array([x.x for x in sols]), Q) < SUCCESS_DEG))})
    best_loop = max((b for b in batch if b["kind"] == "scipy loop"), key=lambda b: b["problems_per_s"])
    fit_loop = next(b for b in batch if b["kind"] == "jaxhand fit loop")
    for b in batch:
        b["speedup_vs_best_scipy_loop"] = b["problems_per_s"] / best_loop["problems_per_s"]
        b["speedup_vs_fit_loop"] = b["problems_per_s"] / fit_loop["problems_per_s"]
    batch_table = format_table(
        [[b["solver"], b["kind"], b["n"], b["seconds"], b["problems_per_s"], b["speedup_vs_fit_loop"],
          b["speedup_vs_best_scipy_loop"], 100 * b["converged_rate"], b["median_cost_px2"], b["compile_s"]]
         for b in batch],
        ["solver", "how", "n", "seconds", "problems/s", "x fit loop", "x best scipy loop", "converged%",
         "median cost px2", "compile s"])

    if ns.batch_only:
        env["load_average_1min_end"] = load_average()
        print(batch_table)
        if out_path is not None:
            write_json({"benchmark": "solvers.batch", "environment": env, "batch": batch}, out_path)
        return 0

    # one view: ambiguity and weakly observed joints
    Qa = jh.random_q(model, np.random.default_rng(7), min(n, 200))
    observability = {"oblique": weak_joints(model, cam, Qa)}
    front = camera(model, np.eye(3))
    Qf, Ff, Q0f = make_problems(model, front, n, 5.0, 0.0, seed=4242)
    front_runs = {}
    for solver in ("lm", "bounded"):
        res = run_jaxhand(model, front, solver, Qf, Ff, Q0f)
        front_runs[solver] = summarise(solver, "jaxhand", 5.0, 0.0, res, Qf)
        front_runs[solver]["singular_rate"] = float(np.mean(np.array(res["status"]) == "singular"))
    observability["front"] = null_space_joints(model, front, Qa[:50])
    observability["front"]["fits"] = front_runs

    env["load_average_1min_end"] = load_average()
    headers = ["solver", "sigma", "noise", "success%", "best-min%", "exact%", "ambig%", "median ms",
               "x best scipy", "iters", "compile s"]
    table = format_table([[r["solver"], r["sigma_deg"], r["noise_px"], 100 * r["success_rate"],
                           100 * r["best_minimum_rate"],
                           "-" if r["exact_fit_rate"] is None else 100 * r["exact_fit_rate"],
                           "-" if r["ambiguous_rate"] is None else 100 * r["ambiguous_rate"],
                           r["median_ms"], r["ratio_to_best_scipy"], r["median_iterations"], r["compile_s"]]
                          for r in rows], headers)
    print("\nsingle solves (median per solve after compilation)\n" + table)
    print(f"\nbatch throughput, {n_batch} problems, sigma {sigma:g} deg, noise {noise:g} px\n" + batch_table)
    ob = observability["oblique"]
    print(f"\noblique view: median rank {ob['median_rank']:g} of {ob['dof']}; weakest joints (predicted std at "
          f"0.5 px): " + ", ".join(f"{w['joint']} {w['std_deg']:.2f} deg" for w in ob["weakest"]))
    fr = observability["front"]
    print(f"front view: median rank {fr['median_rank']:g} of {fr['dof']}; null space mostly "
          + ", ".join(f"{w['joint']} ({w['share']:.2f})" for w in fr["null_space_share"]))
    for s, r in front_runs.items():
        print(f"  front view, {s}: exact fits {100 * r['exact_fit_rate']:.1f}%, of which >= 1 deg off: "
              f"{100 * r['ambiguous_rate']:.1f}% of all; status singular {100 * r['singular_rate']:.1f}%")

    if out_path is not None:
        metrics = {}
        for r in rows:
            key = f"fit.{MODEL}.{r['solver']}.sigma{r['sigma_deg']:g}.noise{r['noise_px']:g}"
            metrics[f"{key}.median_ms"] = r["median_ms"]
            metrics[f"{key}.success_rate"] = r["success_rate"]
        for b in batch:
            metrics[f"fit_batch.{MODEL}.{b['solver']}.problems_per_s"] = b["problems_per_s"]
        data = {"benchmark": "solvers", "environment": env,
                "setup": {"model": MODEL, "camera": "orthographic 320x240, R = Rx(45 deg) Ry(20 deg)",
                          "problems_per_setting": n, "sigmas_deg": list(sigmas), "noises_px": list(NOISES_PX),
                          "success": f"max joint error < {SUCCESS_DEG} deg", "exact": f"H < {EXACT_H}",
                          "scipy_tolerances": SCIPY_TOL, "jaxhand_config": "FitConfig() defaults",
                          "batch": {"n": n_batch, "sigma_deg": sigma, "noise_px": noise}},
                "single": rows, "batch": batch, "observability": observability, "metrics": metrics}
        write_json(data, out_path)
        png = out_path.with_suffix(".png")
        plot(rows, png)
        print(f"\nwrote {out_path} and {png}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
