"""Write notebooks/02_pose_estimation.ipynb (without outputs).

Run ``.venv/bin/python notebooks/_make_02.py`` after editing the cells below; the notebook is
stored without outputs and ``tests/test_notebooks.py`` executes it.
"""

from pathlib import Path

from _nbgen import Notebook

HERE = Path(__file__).resolve().parent
OUT = HERE / "02_pose_estimation.ipynb"

nb = Notebook()
md, code = nb.md, nb.code

md(r"""
# 02 · Pose estimation

**What this shows.** How jaxhand fits a model's state to image features by nonlinear least squares (thesis
chapter 3), and how its solvers compare:

1. the worked examples of thesis §3.2: one revolute joint (R, Table 3.1), one prismatic joint (P, Table 3.2), a
   prismatic and a revolute joint (PR, Table 3.3), two revolute joints (RR, Table 3.4), the RR start from which
   Gauss-Newton's first step raises the cost (Table 3.5) and the step factor $\eta = 0.1$ that avoids it
   (Table 3.6), each as $q_k$ and $H(q_k)$ against the iteration $k$ next to the thesis's numbers;
2. the iterates of the two RR runs from the far start drawn in the image, and the RR cost surface
   $H(\theta_1, \theta_2)$ with both descent paths (thesis Fig. 3.31);
3. batch fitting with `jax.vmap` (`jaxhand.fit_batch`): every start on a grid over $(\theta_1, \theta_2)$ fitted
   in one call, which maps where each Gauss-Newton variant ends;
4. the five solvers of `jaxhand.solve.SOLVERS` on the 21-DOF hand: success rate against the size of the start's
   error, and time per solve next to `scipy.optimize.least_squares`.

**What it uses.** The public API: `jaxhand.fit`, `jaxhand.fit_batch`, `jaxhand.FitConfig`, `jaxhand.SOLVERS`,
`jaxhand.random_q`, `jaxhand.project_pose`, `jaxhand.builtin_model`, `jaxhand.Orthographic`, the chapter-3
problems of `jaxhand.examples.chapter3`, `jaxhand.residuals` (the cost, and the residuals handed to SciPy) and
`jaxhand.solve.features_from_poses`; plus NumPy, SciPy and matplotlib. Random poses and perturbations come from
seeded generators. It runs in under a minute on two CPU cores, most of it compiling the solvers.
""")

code(r"""
import time

import jax
import jax.numpy as jnp
import matplotlib.pyplot as plt
import numpy as np
from scipy.optimize import least_squares

import jaxhand as jh
from jaxhand.examples import chapter3 as ch3
from jaxhand.viz import plot_line
from jaxhand.residuals import cost, make_residual_args, residuals
from jaxhand.solve import features_from_poses

jh.enable_x64()   # jaxhand computes in float64 (it asks rather than switching it on at import)

%matplotlib inline
""")

md(r"""
## 1. The worked examples of thesis chapter 3

`jaxhand.examples.chapter3` holds the thesis's planar chains (built-in models `planar_r`, `planar_p`, `planar_pr`,
`planar_rr`, links of length 5), its image frame (an orthographic camera with the base origin at $p_0 = (3, 0)$),
its features (the lines through the ideal links and the ideal tip; the RR lines are the thesis's printed numbers),
its starts and its stopping rules. `run_example` fits one with `jaxhand.fit` and
`FitConfig(history=True, ...)`, so the result carries every iterate $q_k$ and its cost $H_k$. Two residual points
per link at $P = 3$ and $P = 2$ (`link_fractions=(0.6, 0.4)`), as in the thesis. The tables below put jaxhand's
iterates above the thesis's.
""")

code(r"""
KEYS = ("R", "P", "PR", "RR", "RR divergence", "RR eta=0.1", "RR adaptive eta")
examples = {ex.key: ex for ex in ch3.EXAMPLES}
results = {key: ch3.run_example(examples[key]) for key in KEYS}
for key in KEYS:
    print(ch3.format_table(examples[key], results[key]), end="\n\n")
""")

md(r"""
Lines: jaxhand's $q_k$ (top) and $H(q_k)$ (bottom, log scale; an exact zero is drawn at $10^{-32}$). Open
markers: the thesis's tables at the iterations they print (triangles: printed as 0.0000). The R and P
examples converge in a few steps, PR and RR quadratically once close.
""")

code(r"""
def history(key):
    r = results[key]
    k_end = int(r.iterations)
    return np.arange(k_end + 1), np.asarray(r.history_q)[: k_end + 1], np.asarray(r.history_cost)[: k_end + 1]


def convergence_figure(keys, title, log_cost=True):
    fig, axes = plt.subplots(2, len(keys), figsize=(4.2 * len(keys), 6), squeeze=False, layout="constrained")
    for col, key in enumerate(keys):
        ex = examples[key]
        model = jh.builtin_model(ex.model)
        k, q, H = history(key)
        table = ch3.THESIS_TABLES.get(ex.table) if ex.table else None
        ax_q, ax_h = axes[0, col], axes[1, col]
        for i, name in enumerate(model.q_names):
            unit = "mm" if model.q_kinds[i] == "length" else "rad"
            ax_q.plot(k, q[:, i], "-", color=f"C{i}", lw=1.5, label=f"q{i + 1} ({name}, {unit})")
            ax_q.axhline(ex.q_ideal[i], color=f"C{i}", lw=0.8, ls=":")
            if table:
                ax_q.plot(table.k, [row[i] for row in table.q], "o", mfc="none", color=f"C{i}", ms=7)
        if log_cost:
            ax_h.semilogy(k, np.maximum(H, 1e-32), "k-", lw=1.5, label="jaxhand")
        else:
            ax_h.plot(k, H, "k-", lw=1.5, label="jaxhand")
        if table:
            tH = np.asarray(table.H)
            printed = tH > 0 if log_cost else np.ones(len(tH), bool)
            ax_h.plot(np.asarray(table.k)[printed], tH[printed], "o", mfc="none", color="C3", ms=7,
                      label=f"thesis Table {table.number}")
            if log_cost and (~printed).any():   # printed as 0.0000: below 5e-5
                ax_h.plot(np.asarray(table.k)[~printed], np.full((~printed).sum(), 5e-5), "v", mfc="none",
                          color="C3", ms=7, label="thesis 0.0000 (< 5e-5)")
        eta = f", eta = {ex.eta:g}" if ex.eta != 1 else ""
        ax_q.set_title(f"{key} ({ex.solver}{eta})", fontsize=10)
        ax_q.legend(fontsize=7, loc="best")
        ax_h.legend(fontsize=7, loc="best")
        ax_q.set_xlabel("k")
        ax_h.set_xlabel("k")
        if log_cost:
            ax_h.set_ylim(1e-33, None)
    axes[0, 0].set_ylabel("q_k")
    axes[1, 0].set_ylabel(f"H(q_k) (px$^2${', log scale' if log_cost else ''})")
    fig.suptitle(title)
    plt.show()


convergence_figure(("R", "P", "PR", "RR"), "Thesis Tables 3.1-3.4: q_k (dotted: ideal) and H(q_k) against k")
""")

md(r"""
### The RR divergence case and its bypass

From the far start $(\pi/6, -\pi/3)$ the first Gauss-Newton update overshoots: $H$ rises from 109.35 to 131.26,
exactly as in thesis Table 3.5. Damping the update to $\eta = 0.1$ of the Gauss-Newton step (solver `gn_eta`,
`FitConfig(eta=0.1, max_step_rad=inf)`, Table 3.6) descends monotonically but converges only linearly, the error
shrinking by 0.9 per step, so it needs about a hundred iterations. jaxhand's default adaptive $\eta$ (steps
capped at 0.3 rad, full Gauss-Newton steps near the solution) gets there in about ten.

Where this differs from the thesis: Table 3.5 ends at $(3.3974, -4.5082)$ with $H = 7.93$, but the gradient of
this cost is far from zero there, so those later iterates are not Gauss-Newton steps on this cost; jaxhand's plain
Gauss-Newton takes the same first update (to the printed digits), then a different second one, and from there
reaches the ideal state (the red path below). The thesis's end point lies near a true local minimum of this cost
(the elbow bent the other way, found by the batch fits of section 2).
""")

code(r"""
convergence_figure(("RR divergence", "RR eta=0.1", "RR adaptive eta"),
                   "Thesis Tables 3.5 and 3.6, and jaxhand's adaptive eta, from the far RR start (H on a linear scale)",
                   log_cost=False)
""")

md(r"""
The iterates in the image (thesis Figs. 3.27 and 3.30): each iterate's two links (red: base link, magenta:
terminal link; later iterates darker) and tip (stars), over the observed link lines (blue, black) and the
observed tip (square). Link ends come from `jaxhand.project_pose`, vmapped over the iterates.
""")

code(r"""
rr_model, rr_camera = jh.builtin_model("planar_rr"), ch3.thesis_camera()
rr_features = ch3.thesis_features(examples["RR divergence"])
project_all = jax.jit(jax.vmap(lambda q: jh.project_pose(rr_model, rr_camera, q)))


fig, axes = plt.subplots(1, 2, figsize=(12, 6), layout="constrained")
for ax, key in zip(axes, ("RR divergence", "RR eta=0.1")):
    k, q, H = history(key)
    view = project_all(jnp.asarray(q))
    start, end, tips = (np.asarray(a) for a in (view.link_start_px, view.link_end_px, view.tips_px))
    shade = 0.2 + 0.8 * k / k[-1]
    for i in range(len(k)):
        for link, color in enumerate(("red", "magenta")):
            ax.plot(*np.stack([start[i, link], end[i, link]]).T, color=color, alpha=shade[i], lw=1.2)
        ax.plot(*tips[i, 0], "*", color="magenta", alpha=shade[i], ms=8)
    xlim, ylim = (-6, 14), (-10, 10)
    for line, color in zip(np.asarray(rr_features.lines), ("blue", "black")):
        plot_line(ax, line, color, xlim, ylim)
    ax.plot(*np.asarray(rr_features.tips)[0], "s", mfc="none", color="black", ms=12, mew=2)
    for i in sorted({0, 1, 2, len(k) - 1}):
        ax.annotate(f"k={i}", tips[i, 0], xytext=(6, 4), textcoords="offset points", fontsize=8)
    ax.set(xlim=xlim, ylim=ylim[::-1], aspect="equal", xlabel="x (image units)", ylabel="y (image units, down)",
           title=f"{key}: {len(k) - 1} iterations, H {H[0]:.2f} -> {H[-1]:.1e}")
plt.show()
""")

md(r"""
The cost surface $H(\theta_1, \theta_2)$ of the RR example (thesis Fig. 3.31), evaluated with
`jaxhand.residuals.cost` on a grid, with the plain Gauss-Newton path (red) and the $\eta = 0.1$ path (blue) from
the same far start. The plain path's first step jumps across a ridge; the damped one walks down the valley.
""")

code(r"""
rr_args = make_residual_args(rr_model, rr_camera, rr_features, link_fractions=ch3.FRACTIONS)
cost_many = jax.jit(jax.vmap(cost, in_axes=(0, None)))
paths = {"RR divergence": "red", "RR eta=0.1": "blue"}
allq = np.concatenate([history(key)[1] for key in paths])
lo, hi = np.minimum(allq.min(0) - 0.5, -np.pi), np.maximum(allq.max(0) + 0.5, np.pi)
T1, T2 = np.meshgrid(np.linspace(lo[0], hi[0], 161), np.linspace(lo[1], hi[1], 161))
H_grid = np.asarray(cost_many(jnp.asarray(np.stack([T1.ravel(), T2.ravel()], -1)), rr_args)).reshape(T1.shape)

fig = plt.figure(figsize=(14, 6), layout="constrained")
ax3 = fig.add_subplot(1, 2, 1, projection="3d")
ax3.plot_surface(T1, T2, H_grid, cmap="viridis", linewidth=0, alpha=0.7, rstride=3, cstride=3)
ax2 = fig.add_subplot(1, 2, 2)
levels = ax2.contour(T1, T2, H_grid, levels=30, cmap="viridis", linewidths=0.8)
fig.colorbar(levels, ax=ax2, label="H (px$^2$)")
for key, color in paths.items():
    k, q, H = history(key)
    label = f"{key}: {len(k) - 1} iterations"
    ax3.plot(q[:, 0], q[:, 1], H, color=color, lw=2, marker=".", label=label)
    ax2.plot(q[:, 0], q[:, 1], color=color, lw=1.5, marker=".", ms=4, label=label)
ax2.plot(*examples["RR"].q_ideal, "k*", ms=14, label="ideal")
ax2.plot(*examples["RR divergence"].q0, "ko", mfc="none", ms=10, label="start")
thesis_end = np.angle(np.exp(1j * np.asarray(ch3.THESIS_TABLES["3.5"].q[-1])))   # mod 2 pi, into the window
ax2.plot(*thesis_end, "rx", ms=10, mew=2, label="thesis Table 3.5 end (mod 2 pi)")
ax3.set(xlabel="theta1 (rad)", ylabel="theta2 (rad)", zlabel="H", title="H(theta1, theta2), isometric view")
ax2.set(xlabel="theta1 (rad)", ylabel="theta2 (rad)", aspect="equal", title="level lines and descent paths")
ax2.legend(loc="upper left", fontsize=8)
plt.show()
""")

md(r"""
## 2. Batch fitting with `jax.vmap`

`jaxhand.fit_batch` is `jax.vmap` of the same solve: one compiled call fits a whole batch of problems (here the
same features from every start on a $61 \times 61$ grid over $(\theta_1, \theta_2)$). For a problem this small
most of a single `jaxhand.fit` call is overhead (input checks, dispatch), which the batch pays once: the
printout compares the time per start with a loop of `jaxhand.fit` over 200 of the starts. A vmapped solve runs
until its slowest member stops (finished members idle), so for larger problems on a CPU the gain shrinks; on
an accelerator the batch is the form to use. The three
Gauss-Newton variants share one compiled program (only traced numbers differ), so each batch after the first
costs no compilation. The maps show where each run ends: at the ideal state (mod $2\pi$), elsewhere, or still
moving after 160 iterations. Every run that does not reach the ideal state stops at one other point, a local
minimum of $H$ with the elbow bent the other way (the plus), close to where thesis Table 3.5 ends (yellow x, the
thesis's numbers mod $2\pi$): the thesis's diverging run most likely fell into this minimum. Much of the
boundary between the two basins runs along $\theta_2 = 0$, the stretched elbow, which separates the two bends.
""")

code(r"""
grid = np.linspace(-np.pi, np.pi, 61)
G1, G2 = np.meshgrid(grid, grid)
starts = np.stack([G1.ravel(), G2.ravel()], -1)
B = len(starts)
batch_features = jax.tree_util.tree_map(lambda x: jnp.broadcast_to(x, (B,) + x.shape), rr_features)
variants = {
    "gn (eta = 1)": ("gn", {}),
    "gn_eta, eta = 0.1": ("gn_eta", dict(eta=0.1, max_step_rad=np.inf)),
    "gn_eta, adaptive (0.3 rad cap)": ("gn_eta", dict(max_step_rad=0.3)),
}
# The chapter-3 settings: 160 steps, history on (static fields, so jaxhand.fit's program is shared too),
# the thesis's step rule sum |dq| <= 1e-5 and no cost rule.
base = dict(max_steps=ch3.MAX_STEPS, history=True, link_fractions=ch3.FRACTIONS, xtol=1e-5, ftol=0.0,
            max_step_mm=np.inf)
ideal = np.asarray(examples["RR"].q_ideal)
ends, batch_s = {}, {}
for label, (solver, extra) in variants.items():
    config = jh.FitConfig(**base, **extra)
    t0 = time.perf_counter()
    r = jh.fit_batch(rr_model, rr_camera, batch_features, starts, solver=solver, config=config)
    jax.block_until_ready(r.q)
    batch_s[label] = time.perf_counter() - t0
    q_end = np.angle(np.exp(1j * np.asarray(r.q)))   # mod 2 pi
    at_ideal = np.abs(np.angle(np.exp(1j * (q_end - ideal)))).max(-1) < 1e-3
    elsewhere = ~at_ideal & np.asarray(r.converged)
    ends[label] = np.where(at_ideal, 0, np.where(elsewhere, 1, 2)).reshape(G1.shape)
    others = np.unique(np.round(q_end[elsewhere], 3), axis=0)
    print(f"{label:32s} {batch_s[label]:5.2f} s for {B} starts (the first call compiles); "
          f"ideal {at_ideal.mean():5.1%}, median {np.median(np.asarray(r.iterations)):.0f} iterations; "
          f"other ends {others.tolist()}, H = {np.unique(np.round(np.asarray(r.cost)[elsewhere], 3)).tolist()}")
local_min = np.median(q_end[elsewhere], axis=0)

# The same solve, one start at a time with jaxhand.fit (already compiled by run_example above).
loop_starts = starts[:: B // 200][:200]
config = jh.FitConfig(**base, **variants["gn_eta, adaptive (0.3 rad cap)"][1])
t0 = time.perf_counter()
loop_q = np.stack([np.asarray(jh.fit(rr_model, rr_camera, rr_features, q0, solver="gn_eta", config=config).q)
                   for q0 in loop_starts])
loop_per_problem = (time.perf_counter() - t0) / len(loop_starts)
print(f"jaxhand.fit loop: {1e3 * loop_per_problem:.2f} ms per start; fit_batch: "
      f"{1e3 * batch_s['gn_eta, adaptive (0.3 rad cap)'] / B:.3f} ms per start")
""")

code(r"""
from matplotlib.colors import ListedColormap

cmap = ListedColormap(["#4daf4a", "#e41a1c", "#bbbbbb"])
fig, axes = plt.subplots(1, 3, figsize=(16, 5.6), layout="constrained")
for ax, (label, end) in zip(axes, ends.items()):
    ax.imshow(end, origin="lower", extent=(grid[0], grid[-1], grid[0], grid[-1]), cmap=cmap, vmin=0, vmax=2,
              interpolation="nearest")
    ax.contour(G1, G2, np.asarray(cost_many(jnp.asarray(starts), rr_args)).reshape(G1.shape), levels=15,
               colors="k", linewidths=0.4, alpha=0.5)
    ax.plot(*np.angle(np.exp(1j * ideal)), "k*", ms=14)
    ax.plot(*examples["RR divergence"].q0, "ko", mfc="none", ms=10)
    ax.plot(*examples["RR"].q0, "ks", mfc="none", ms=8)
    ax.plot(*local_min, "P", mfc="white", mec="k", ms=12)
    ax.plot(*thesis_end, "X", mfc="yellow", mec="k", ms=10)
    share = [(end == v).mean() for v in range(3)]
    ax.set(xlabel="theta1 at the start (rad)", ylabel="theta2 at the start (rad)",
           title=f"{label}\nideal {share[0]:.0%}, local minimum {share[1]:.0%}, not stopped {share[2]:.0%}")
    ax.title.set_fontsize(10)
handles = [plt.Rectangle((0, 0), 1, 1, color=cmap(v)) for v in range(3)]
fig.legend(handles, ["ends at the ideal state",
                     f"ends at the local minimum ({local_min[0]:.2f}, {local_min[1]:.2f}) (plus)",
                     "still moving after 160 iterations"], loc="outside lower center", ncol=3)
fig.suptitle(f"RR: where each start ends ({B} starts per map, one fit_batch call each; star: ideal, circle: far "
             "start, square: Table 3.4 start, yellow x: thesis Table 3.5 end mod 2 pi)")
plt.show()
""")

md(r"""
## 3. The solvers on the 21-DOF hand

`hand21` seen by one orthographic camera at an oblique view (tilted 45° about the image's x axis and 20° about
its y axis, like the 45° plane of thesis chapter 6; a frontal view leaves flexion unobservable). For each
perturbation size $\sigma$, 40 poses drawn uniformly within the joint limits (`jaxhand.random_q`), their exact
features (`jaxhand.solve.features_from_poses`), and starts at the true pose plus $N(0, \sigma^2)$ per joint,
clipped to the limits. Every solver fits the same problems with `FitConfig()` defaults (50 steps), one
`jaxhand.fit` call each; a fit succeeds when every joint ends within 1° of the truth. Dashed: the share that fits
the features exactly ($H < 10^{-10}$), which also counts the poses that one view cannot tell from the truth.
""")

code(r"""
def tilt(rx_deg, ry_deg):
    ax, ay = np.radians([rx_deg, ry_deg])
    Rx = np.array([[1, 0, 0], [0, np.cos(ax), -np.sin(ax)], [0, np.sin(ax), np.cos(ax)]])
    Ry = np.array([[np.cos(ay), 0, np.sin(ay)], [0, 1, 0], [-np.sin(ay), 0, np.cos(ay)]])
    return Rx @ Ry


hand = jh.builtin_model("hand21")
pose = jh.forward(hand, hand.q_default)
camera = jh.Orthographic.fit(np.concatenate([pose.link_start, pose.link_end]), size=(320, 240), R=tilt(45, 20))
lower, upper = np.asarray(hand.q_lower), np.asarray(hand.q_upper)
SIGMAS_DEG = (5, 15, 30, 45)
N = 40
rng = np.random.default_rng(3)
problems = {}
for sigma in SIGMAS_DEG:
    Q = jh.random_q(hand, rng, N)
    F = features_from_poses(hand, camera, Q)[0]
    Q0 = np.clip(Q + rng.normal(0.0, np.radians(sigma), Q.shape), lower, upper)
    problems[sigma] = (Q, [jax.tree_util.tree_map(lambda x, i=i: x[i], F) for i in range(N)], Q0)

success, exact, seconds, errors, compile_s = {}, {}, {}, {}, {}
for solver in jh.SOLVERS:
    Q, Fs, Q0 = problems[SIGMAS_DEG[0]]
    t0 = time.perf_counter()
    jax.block_until_ready(jh.fit(hand, camera, Fs[0], Q0[0], solver=solver).q)   # compile (or reuse)
    compile_s[solver] = time.perf_counter() - t0
    for sigma, (Q, Fs, Q0) in problems.items():
        qs, costs, times = [], [], []
        for f, q0 in zip(Fs, Q0):
            t0 = time.perf_counter()
            r = jh.fit(hand, camera, f, q0, solver=solver)
            jax.block_until_ready(r.q)
            times.append(time.perf_counter() - t0)
            qs.append(np.asarray(r.q))
            costs.append(float(r.cost))
        error_deg = np.degrees(np.abs(np.array(qs) - Q).max(-1))
        errors[solver, sigma] = error_deg
        success[solver, sigma] = np.mean(error_deg < 1.0)
        exact[solver, sigma] = np.mean(np.array(costs) < 1e-10)
        seconds[solver, sigma] = np.array(times)
    print(f"{solver:9s} first call {compile_s[solver]:5.2f} s; success at sigma {SIGMAS_DEG}: "
          + ", ".join(f"{success[solver, s]:.0%}" for s in SIGMAS_DEG))
""")

md(r"""
SciPy's `least_squares` on the first 10 problems at $\sigma = 15°$, with the same residuals
(`jaxhand.residuals.residuals`) and their `jax.jacfwd` Jacobian, both jitted once, the features passed per call:
`method="lm"` (MINPACK, unbounded) and `method="trf"` (the joint limits as bounds),
`xtol=1e-10, ftol=1e-12, gtol=1e-10`. Times are wall time per solve after compilation, Python overheads
included on both sides.
""")

code(r"""
def hand_residuals(q, f):
    return residuals(q, make_residual_args(hand, camera, (f,), validate=False))


res_jit, jac_jit = jax.jit(hand_residuals), jax.jit(jax.jacfwd(hand_residuals))
Q, Fs, Q0 = problems[15]
M = 10
jax.block_until_ready(jac_jit(jnp.asarray(Q0[0]), Fs[0]))
jax.block_until_ready(res_jit(jnp.asarray(Q0[0]), Fs[0]))
scipy_seconds, scipy_success = {}, {}
for method in ("lm", "trf"):
    bounds = (-np.inf, np.inf) if method == "lm" else (lower, upper)
    times, errs = [], []
    for f, q0, q_true in zip(Fs[:M], Q0[:M], Q[:M]):
        t0 = time.perf_counter()
        sol = least_squares(lambda q, f=f: np.asarray(res_jit(q, f)), q0,
                            jac=lambda q, f=f: np.asarray(jac_jit(q, f)), method=method, bounds=bounds,
                            xtol=1e-10, ftol=1e-12, gtol=1e-10)
        times.append(time.perf_counter() - t0)
        errs.append(np.degrees(np.abs(sol.x - q_true).max()))
    scipy_seconds[f"scipy {method}"] = np.array(times)
    scipy_success[f"scipy {method}"] = hits = int(np.sum(np.array(errs) < 1.0))
    print(f"scipy {method}: median {1e3 * np.median(times):.1f} ms per solve, {hits}/{M} within 1 deg")
""")

code(r"""
fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(15, 5), layout="constrained")
for i, solver in enumerate(jh.SOLVERS):
    ax1.plot(SIGMAS_DEG, [success[solver, s] for s in SIGMAS_DEG], "o-", color=f"C{i}", label=solver)
    ax1.plot(SIGMAS_DEG, [exact[solver, s] for s in SIGMAS_DEG], "--", color=f"C{i}", alpha=0.6)
ax1.set(xlabel="start perturbation sigma per joint (deg)", ylabel="share of problems", ylim=(-0.03, 1.03),
        title=f"hand21, {N} problems per sigma: success (solid, every joint within 1 deg) "
              "and exact fit (dashed, H < 1e-10)")
ax1.title.set_fontsize(10)
ax1.legend()

names = list(jh.SOLVERS) + list(scipy_seconds)
data = [1e3 * seconds[s, 15][:M] for s in jh.SOLVERS] + [1e3 * scipy_seconds[k] for k in scipy_seconds]
ax2.boxplot(data, showfliers=True)
hits = [int(np.sum(errors[s, 15][:M] < 1.0)) for s in jh.SOLVERS] + list(scipy_success.values())
ax2.set_xticks(range(1, len(names) + 1), [f"{n}\n{h}/{M} ok" for n, h in zip(names, hits)], fontsize=9)
ax2.set_yscale("log")
ax2.set(ylabel="wall time per solve (ms)",
        title=f"time per solve, the same {M} problems at sigma = 15 deg (after compilation; ok: within 1 deg)")
ax2.title.set_fontsize(10)
for x, d in enumerate(data, start=1):
    ax2.annotate(f"{np.median(d):.1f} ms", (x, np.median(d)), xytext=(14, 0), textcoords="offset points",
                 fontsize=8, va="center")
plt.show()
""")

nb.write(OUT)
