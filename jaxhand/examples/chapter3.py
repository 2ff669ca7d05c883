"""Thesis chapter 3 worked examples: the planar R, P, PR and RR chains of §3.2.

Run ``python -m jaxhand.examples.chapter3 [--out DIR]``. It fits each chain from the thesis's
starting state to features observed at the thesis's ideal state, with the thesis's
Gauss-Newton update (eq. 3.4) and stopping rules, prints convergence tables in the layout of
Tables 3.1-3.6 (k, q_k, H(q_k)) next to the thesis's numbers, and saves:

- ``fig3_17_pr_overlay.png``, ``fig3_23_rr_overlay.png``, ``fig3_27_rr_divergence_overlay.png``,
  ``fig3_30_rr_eta_overlay.png``: every iterate's link configuration overlaid on the features;
- ``fig3_31_rr_cost_surface.png``: H(theta1, theta2) of the RR example with the descent paths
  of the plain Gauss-Newton run (red) and the eta = 0.1 run (blue) from the same start;
- ``tables.txt``: the printed tables.

The setup, read from the thesis (figures 3.6-3.24): image frame = base frame, units the same
(an orthographic camera with R = I, t = 0, scale 1 and the base origin p0 = (3, 0) as
its centre; the built-in ``planar_*`` models hold the rotation of the thesis's ^C_0T), link
lengths L = 5, two link residual points at P = 3 and P = 2 (fractions 0.6 and 0.4 of the
link), the tip feature at the ideal tip and each link feature the line through the ideal
link. The RR lines are the thesis's own numbers, (0.5, -sqrt(3)/2, 1.5) for the base link and
(1, 0, 3 + 5 sqrt(3)/2) for the terminal link (printed as -0.866 and 7.3301). The R, P and
PR figures' parameters are missing from the text; the lines through the ideal links at
P = 3, 2 reproduce every number of Tables 3.1-3.3 (see README, "Chapter 3 examples").
Stopping: ``|q_{k+1} - q_k| <= 1e-30`` for R and P, ``sum |q_{k+1} - q_k| <= 1e-5`` for PR and RR
(the thesis's rules; the cost rule is off).
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass, field
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..camera import Orthographic
from ..features import Features, features_from_pose
from ..kinematics import link_points
from ..kinematics import pose as pose_at
from ..model import Model, builtin_model
from ..residuals import ResidualArgs, cost
from ..solve import FitConfig, FitResult, fit
from ..viz import plot_line

__all__ = ["ThesisTable", "Example", "THESIS_TABLES", "EXAMPLES", "thesis_camera", "thesis_features",
           "run_example", "format_table", "main"]

P0 = (3.0, 0.0)
#: Link residual points P = 3 and P = 2 on links of length L = 5.
FRACTIONS = (0.6, 0.4)
#: One static iteration cap (and history length) for every example, so each model and solver
#: compiles once: the longest run (eta = 0.1) needs about 100 iterations.
MAX_STEPS = 160
_SQ3_2 = math.sqrt(3.0) / 2.0


@dataclass(frozen=True)
class ThesisTable:
    """A convergence table as printed in the thesis: selected iterations k, q_k and H(q_k)."""

    number: str
    caption: str
    k: tuple[int, ...]
    q: tuple[tuple[float, ...], ...]   # one tuple per column
    H: tuple[float, ...]
    ideal: tuple[float, ...]


THESIS_TABLES: dict[str, ThesisTable] = {
    "3.1": ThesisTable("3.1", "one revolute joint (R)", (0, 1, 2, 3, 4),
                       ((2.0944,), (1.5727,), (1.5708,), (1.5708,), (1.5708,)),
                       (4.9744, 0.0001, 0.0, 0.0, 0.0), (1.5708,)),
    "3.2": ThesisTable("3.2", "one prismatic joint (P)", (0, 1, 2), ((1.0,), (0.0,), (0.0,)),
                       (1.5, 0.0, 0.0), (0.0,)),
    "3.3": ThesisTable("3.3", "prismatic and revolute joints (PR)", (0, 1, 2, 5, 6, 7),
                       ((2.0, 1.0472), (6.8490, 0.4321), (5.1707, 0.0480), (2.9998, -0.5237), (3.0, -0.5236),
                        (3.0, -0.5236)),
                       (43.9103, 2.1344, 0.7339, 0.0005, 0.0, 0.0), (3.0, -0.5236)),
    "3.4": ThesisTable("3.4", "two revolute joints (RR)", (0, 1, 2, 4, 5, 6),
                       ((-0.7330, -1.7802), (-0.8616, -2.2315), (-1.0617, -2.0927), (-1.0472, -2.0943),
                        (-1.0472, -2.0944), (-1.0472, -2.0944)),
                       (5.2081, 0.7270, 0.0038, 0.0, 0.0, 0.0), (-1.0472, -2.0944)),
    "3.5": ThesisTable("3.5", "RR, initial divergence", (0, 1, 2, 14, 15, 16),
                       ((0.5236, -1.0472), (1.2304, -4.4211), (1.1705, -1.9139), (3.3975, -4.5082),
                        (3.3974, -4.5082), (3.3974, -4.5082)),
                       (109.3510, 131.2587, 105.1625, 7.9345, 7.9345, 7.9345), (-1.0472, -2.0944)),
    "3.6": ThesisTable("3.6", "RR, step eta = 0.1", (0, 1, 2, 96, 97),
                       ((0.5236, -1.0472), (0.5943, -1.3846), (0.6476, -1.6683), (-1.0471, -2.0944),
                        (-1.0471, -2.0944)),
                       (109.3510, 93.2694, 79.9565, 0.0, 0.0), (-1.0472, -2.0944)),
}


@dataclass(frozen=True)
class Example:
    """One worked example: chain, ideal and starting states, solver and stopping rule."""

    key: str
    model: str
    q_ideal: tuple[float, ...]
    q0: tuple[float, ...]
    solver: str = "gn"
    xtol: float = 1e-5
    eta: float = 1.0
    max_step_rad: float = math.inf
    table: str | None = None
    figure: str | None = None
    note: str = field(default="", compare=False)


_RR_IDEAL = (-math.pi / 3, -math.pi / 2 - math.pi / 6)
_RR_FAR = (math.pi / 6, -math.pi / 3)
EXAMPLES: tuple[Example, ...] = (
    Example("R", "planar_r", (math.pi / 2,), (2 * math.pi / 3,), xtol=1e-30, table="3.1"),
    Example("P", "planar_p", (0.0,), (1.0,), xtol=1e-30, table="3.2"),
    Example("PR", "planar_pr", (3.0, -math.pi / 6), (2.0, math.pi / 3), table="3.3", figure="fig3_17_pr_overlay"),
    Example("RR", "planar_rr", _RR_IDEAL, (math.radians(-42.0), math.radians(-102.0)), table="3.4",
            figure="fig3_23_rr_overlay", note="start (-42, -102) deg: H = 5.2081 as in the table"),
    Example("RR divergence", "planar_rr", _RR_IDEAL, _RR_FAR, table="3.5", figure="fig3_27_rr_divergence_overlay"),
    Example("RR eta=0.1", "planar_rr", _RR_IDEAL, _RR_FAR, solver="gn_eta", eta=0.1, table="3.6",
            figure="fig3_30_rr_eta_overlay"),
    Example("RR adaptive eta", "planar_rr", _RR_IDEAL, _RR_FAR, solver="gn_eta", max_step_rad=0.3,
            note="jaxhand's adaptive eta: steps capped at 0.3 rad, plain Gauss-Newton near the solution"),
)


def thesis_camera() -> Orthographic:
    """The thesis's image frame: base frame axes, same units, base origin at p0 = (3, 0)."""
    return Orthographic(R=np.eye(3), t=np.zeros(3), scale=1.0, center=np.array(P0), size=(32, 32))


def thesis_features(example: Example) -> Features:
    """The example's observed features: the thesis's RR lines, else exact lines at the ideal."""
    model = builtin_model(example.model)
    if example.model == "planar_rr":
        tip = (P0[0] + 5 * _SQ3_2, P0[1] - 2.5)   # -L s(t1+t2) - L s(t1) + p0x, L c(t1+t2) + L c(t1)
        return Features(lines=jnp.array([[0.5, -_SQ3_2, 1.5], [1.0, 0.0, P0[0] + 5 * _SQ3_2]]),
                        line_valid=jnp.ones(2, bool), line_weight=jnp.ones(2), tips=jnp.array([tip]),
                        tip_valid=jnp.ones(1, bool), tip_weight=jnp.ones(1))
    return features_from_pose(model, thesis_camera(), np.array(example.q_ideal))[0]


def example_config(example: Example) -> FitConfig:
    return FitConfig(max_steps=MAX_STEPS, history=True, link_fractions=FRACTIONS, xtol=example.xtol, ftol=0.0,
                     eta=example.eta, max_step_rad=example.max_step_rad, max_step_mm=math.inf)


def run_example(example: Example) -> FitResult:
    """Fit the example's chain from its start; the result carries the history (q_k, H_k)."""
    model = builtin_model(example.model)
    return fit(model, thesis_camera(), thesis_features(example), np.array(example.q0), solver=example.solver,
               config=example_config(example))


def _q_names(model: Model) -> list[str]:
    return [f"q{i + 1} = {'d' if kind == 'length' else 'theta'}{i + 1}" for i, kind in enumerate(model.q_kinds)]


def _columns(n_iter: int) -> list[int | None]:
    """Thesis layout: every k when few, else the first three, '...' and the last three."""
    if n_iter + 1 <= 7:
        return list(range(n_iter + 1))
    return [0, 1, 2, None, n_iter - 2, n_iter - 1, n_iter]


def format_table(example: Example, result: FitResult) -> str:
    """The example's convergence table (jaxhand) and, below it, the thesis's table."""
    model = builtin_model(example.model)
    k_end = int(result.iterations)
    hq, hH = np.asarray(result.history_q), np.asarray(result.history_cost)
    names = _q_names(model)
    cols = _columns(k_end)
    width = 10

    def cell(x):
        return f"{x:>{width}.4f}" if x is not None else f"{'...':>{width}}"

    def block(ks, qs, Hs, ideal):
        lines = ["k".ljust(14) + "".join(f"{k:>{width}}" if k is not None else f"{'':>{width}}" for k in ks)
                 + f"{'ideal':>{width}}"]
        for i, name in enumerate(names):
            lines.append(name.ljust(14) + "".join(cell(None if q is None else q[i]) for q in qs) + cell(ideal[i]))
        lines.append("H(q)".ljust(14) + "".join(cell(h) for h in Hs) + cell(0.0))
        return lines

    title = f"{example.key}: {example.solver}, status {result.status_name()}, {k_end} iterations"
    out = [title, "-" * len(title), "jaxhand"]
    out += block(cols, [None if k is None else hq[k] for k in cols], [None if k is None else hH[k] for k in cols],
                 example.q_ideal)
    if example.table:
        t = THESIS_TABLES[example.table]
        out.append(f"thesis Table {t.number} ({t.caption})")
        ks: list[int | None] = []
        qs: list = []
        Hs: list = []
        for i, k in enumerate(t.k):
            if i and k != t.k[i - 1] + 1:
                ks.append(None)
                qs.append(None)
                Hs.append(None)
            ks.append(k)
            qs.append(t.q[i])
            Hs.append(t.H[i])
        out += block(ks, qs, Hs, t.ideal)
    if example.note:
        out.append(f"note: {example.note}")
    return "\n".join(out)


# ---- figures (matplotlib, Agg) ----

def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_overlay(example: Example, result: FitResult, path: Path) -> Path:
    """Every iterate's links (red, magenta), link points (+) and tip (*) over the link features
    (blue, black lines) and the tip feature (black square); numbers are the iterations."""
    plt = _pyplot()
    model = builtin_model(example.model)
    cam = thesis_camera()
    feats = thesis_features(example)
    k_end = int(result.iterations)
    hq = np.asarray(result.history_q)[: k_end + 1]
    starts, ends, tips, link_pts = (np.asarray(a) for a in _iterate_geometry(model, cam, jnp.asarray(hq)))
    pts = np.concatenate([starts.reshape(-1, 2), ends.reshape(-1, 2), np.asarray(feats.tips)])
    lo, hi = pts.min(0) - 1.5, pts.max(0) + 1.5
    from matplotlib.collections import LineCollection
    from matplotlib.colors import to_rgba

    fig, ax = plt.subplots(figsize=(6.5, 6.5))
    link_colors = ("red", "magenta")
    feature_colors = ("blue", "black")
    alpha = 0.25 + 0.75 * np.arange(k_end + 1) / max(k_end, 1)      # later iterates darker
    for li in range(model.n_links):   # one collection per link: every iterate in one artist
        rgba = np.array([to_rgba(link_colors[li % 2], a) for a in alpha])
        ax.add_collection(LineCollection(np.stack([starts[:, li], ends[:, li]], axis=1), colors=rgba, lw=1.5))
        ax.scatter(link_pts[:, li, :, 0].ravel(), link_pts[:, li, :, 1].ravel(), marker="+", s=50,
                   c=np.repeat(rgba, len(FRACTIONS), axis=0))
        ax.scatter(starts[:, li, 0], starts[:, li, 1], marker="o", s=30, facecolors="none",
                   edgecolors=[to_rgba(feature_colors[li % 2], a) for a in alpha])
    tip_rgba = [to_rgba(link_colors[(model.n_links - 1) % 2], a) for a in alpha]
    ax.scatter(tips[:, 0, 0], tips[:, 0, 1], marker="*", s=90, c=tip_rgba)
    label_every = max(1, (k_end + 1) // 12)
    for k in range(0, k_end + 1):
        if k % label_every == 0 or k == k_end:
            ax.annotate(str(k), tips[k, 0], xytext=(6, 6), textcoords="offset points", fontsize=8,
                        bbox=dict(boxstyle="square,pad=0.15", fc="white", ec="0.5", alpha=0.8))
    for li in range(model.n_links):
        if bool(feats.line_valid[li]):
            plot_line(ax, feats.lines[li], feature_colors[li % 2], (lo[0], hi[0]), (lo[1], hi[1]))
    ax.plot(*np.asarray(feats.tips)[0], "s", mfc="none", color="black", ms=12, mew=2)
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(hi[1], lo[1])   # image convention: y down
    ax.set_aspect("equal")
    ax.set_xlabel("x (image units)")
    ax.set_ylabel("y (image units)")
    ax.set_title(f"{example.key}: iterations 0-{k_end} ({example.solver})")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


@eqx.filter_jit
def _iterate_geometry(model: Model, cam: Orthographic, qs):
    """Pixels of link starts, ends, tips and link residual points for a stack of states."""
    def one(q):
        pose = pose_at(model, q)
        return (cam.project(pose.link_start)[0], cam.project(pose.link_end)[0], cam.project(pose.tips)[0],
                cam.project(link_points(pose, jnp.asarray(FRACTIONS)))[0])

    return jax.vmap(one)(qs)


@eqx.filter_jit
def _cost_grid(args: ResidualArgs, T1, T2):
    qs = jnp.stack([T1.ravel(), T2.ravel()], axis=-1)
    return jax.vmap(lambda q: cost(q, args))(qs).reshape(T1.shape)


# Where thesis Table 3.5 stops, (3.3974, -4.5082), shifted by -2 pi in theta1 into the plotted window.
_THESIS_35_END = (3.3974 - 2 * math.pi, -4.5082)


def plot_cost_surface(paths: dict[str, tuple[np.ndarray, str]], path: Path) -> Path:
    """H(theta1, theta2) of the RR example (isometric view, top view, level lines) with the
    descent paths ``{label: (q_k array, colour)}`` from a common start (thesis Fig. 3.31)."""
    plt = _pyplot()
    model = builtin_model("planar_rr")
    example = next(e for e in EXAMPLES if e.key == "RR divergence")
    args = ResidualArgs(model=model, cameras=(thesis_camera(),), features=(thesis_features(example),),
                        fractions=jnp.asarray(FRACTIONS))
    allq = np.concatenate([p for p, _ in paths.values()] + [np.array([_THESIS_35_END])])
    lo = np.minimum(allq.min(0) - 0.5, -math.pi)
    hi = np.maximum(allq.max(0) + 0.5, math.pi)
    t1, t2 = np.linspace(lo[0], hi[0], 161), np.linspace(lo[1], hi[1], 161)
    T1, T2 = np.meshgrid(t1, t2)
    Hs = np.asarray(_cost_grid(args, jnp.asarray(T1), jnp.asarray(T2)))
    costs = {label: np.asarray(_cost_grid(args, jnp.asarray(p[:, :1]), jnp.asarray(p[:, 1:2])))[:, 0]
             for label, (p, _) in paths.items()}
    fig = plt.figure(figsize=(15, 5))
    ax3 = fig.add_subplot(1, 3, 1, projection="3d")
    ax3.plot_surface(T1, T2, Hs, cmap="viridis", linewidth=0, alpha=0.7, rstride=3, cstride=3)
    for label, (p, color) in paths.items():
        ax3.plot(p[:, 0], p[:, 1], costs[label], color=color, lw=2, marker=".")
    ax3.set_xlabel("theta1 (rad)")
    ax3.set_ylabel("theta2 (rad)")
    ax3.set_zlabel("H")
    ax3.set_title("H(q), isometric view")
    ax_top = fig.add_subplot(1, 3, 2)
    im = ax_top.pcolormesh(T1, T2, Hs, cmap="viridis", shading="auto")
    fig.colorbar(im, ax=ax_top, label="H")
    ax_lv = fig.add_subplot(1, 3, 3)
    ax_lv.contour(T1, T2, Hs, levels=30, cmap="viridis", linewidths=0.8)
    for ax in (ax_top, ax_lv):
        for label, (p, color) in paths.items():
            ax.plot(p[:, 0], p[:, 1], color=color, lw=1.5, marker=".", ms=4, label=label)
        ax.plot(*_RR_IDEAL, "k*", ms=12, label="ideal")
        ax.plot(*_THESIS_35_END, "rx", ms=10, mew=2, label="thesis Table 3.5 end (mod 2 pi)")
        ax.set_xlabel("theta1 (rad)")
        ax.set_ylabel("theta2 (rad)")
        ax.set_aspect("equal")
    ax_top.set_title("top view")
    ax_lv.set_title("level lines")
    ax_lv.legend(loc="upper left", fontsize=7, framealpha=0.9)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def main(argv: list[str] | None = None) -> int:
    """Run every example, print the tables, write the figures and tables.txt into ``--out``."""
    parser = argparse.ArgumentParser(prog="python -m jaxhand.examples.chapter3", description=__doc__.split("\n")[0])
    parser.add_argument("--out", default="chapter3_out", help="output folder (created if missing)")
    ns = parser.parse_args(argv)
    out = Path(ns.out)
    out.mkdir(parents=True, exist_ok=True)
    results = {}
    texts = []
    for ex in EXAMPLES:
        res = run_example(ex)
        results[ex.key] = res
        text = format_table(ex, res)
        texts.append(text)
        print(text, end="\n\n")
        if ex.figure:
            plot_overlay(ex, res, out / f"{ex.figure}.png")
    paths = {}
    for key, color in (("RR divergence", "red"), ("RR eta=0.1", "blue")):
        r = results[key]
        paths[f"{key} ({int(r.iterations)} it.)"] = (np.asarray(r.history_q)[: int(r.iterations) + 1], color)
    plot_cost_surface(paths, out / "fig3_31_rr_cost_surface.png")
    (out / "tables.txt").write_text("\n\n".join(texts) + "\n")
    print(f"figures and tables.txt written to {out}")
    return 0


if __name__ == "__main__":
    from .._precision import enable_x64

    enable_x64()
    raise SystemExit(main())
