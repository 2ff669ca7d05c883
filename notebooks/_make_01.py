"""Write notebooks/01_kinematic_models.ipynb (without outputs).

Run ``.venv/bin/python notebooks/_make_01.py`` after editing the cells below; the notebook is
stored without outputs and ``tests/test_notebooks.py`` executes it.
"""

from pathlib import Path

from _nbgen import Notebook

HERE = Path(__file__).resolve().parent
OUT = HERE / "01_kinematic_models.ipynb"

nb = Notebook()
md, code = nb.md, nb.code

md(r"""
# 01 · Kinematic models

**What this shows.** The kinematic models of the thesis (chapter 2 and chapter 6) as jaxhand's built-in models,
and a check of their derivatives:

1. the modified Denavit-Hartenberg tables of thesis Tables 2.2 (`index`), 2.3 (`index_thumb`), 6.1 (`two_fingers`)
   and 6.2 (`hand21`), printed from the models themselves;
2. each model drawn in 3D (link axes, joints, joint axes, tips) at its default pose and at one random pose within
   its joint limits, and the same poses projected by an orthographic camera (`jaxhand.viz.sketch_model`);
3. the joint ranges of `hand21` (thesis Table 2.1 under the sign convention of §6.2.2: opening the hand is positive);
4. the Jacobian of the projected link ends, from `jax.jacfwd`, checked against central differences and against the
   geometric Jacobian of DigitEyes eqs. 8-10 for every built-in model, with a picture of `hand21`'s Jacobian.

**What it uses.** The public API only: `jaxhand` (built-in models, `forward`, `random_q`, cameras), `jaxhand.camera`,
`jaxhand.check` and `jaxhand.viz`, plus NumPy and matplotlib. Random poses come from a seeded generator. It runs in
about half a minute on two CPU cores.
""")

code(r"""
import matplotlib.pyplot as plt
import numpy as np

import jaxhand as jh
from jaxhand.camera import look_at_rotation
from jaxhand.check import autodiff_jacobian, jacobian_errors, projected_geometric_jacobian
from jaxhand.viz import sketch_model

jh.enable_x64()   # jaxhand computes in float64 (it asks rather than switching it on at import)

# Show figures inline (importing jaxhand.viz selects matplotlib's non-interactive Agg backend).
%matplotlib inline

rng = np.random.default_rng(2005)
THESIS = {"index": "Table 2.2", "index_thumb": "Table 2.3", "two_fingers": "Table 6.1", "hand21": "Table 6.2"}
models = {name: jh.builtin_model(name) for name in THESIS}
for name, m in models.items():
    print(f"{name:12s} thesis {THESIS[name]}: {m.dof:2d} DOF, {m.n_frames:2d} frames, {m.n_links:2d} links, "
          f"{m.n_tips} tips")
""")

md(r"""
## 1. DH tables

Frame *i* sits on its parent by Craig's modified DH transform (thesis eq. 2.1),
$\,{}^{i-1}_{\;i}T = \mathrm{Rot}_x(\alpha_{i-1})\,\mathrm{Trans}_x(a_{i-1})\,
\mathrm{Rot}_z(\theta_i)\,\mathrm{Trans}_z(d_i)$;
a revolute joint adds its state entry to $\theta_i$. Frames are numbered from 1 as in the thesis, with the base as
frame 0; frames without a joint are the thesis's auxiliary frames. The thesis leaves the lengths symbolic
($a_1$, $|d_5|$, ...): jaxhand fills in an adult hand's lengths in mm, and writes out the rows that Table 6.2
leaves out (ring like little, index like middle). `link` is the pill (cylinder with hemispherical ends) along
the frame's x axis; `tip` marks the links whose far end is a fingertip feature.
""")

code(r"""
def dh_table(m):
    dh = np.asarray(m.dh)
    lo, hi = np.degrees(np.asarray(m.q_lower)), np.degrees(np.asarray(m.q_upper))
    link_of = {f: k for k, f in enumerate(m.link_frame)}
    head = (f"{'i':>2}  {'frame':14s} {'parent':19s} {'alpha_i-1':>9s} {'a_i-1':>7s} {'d_i':>7s} "
            f"{'theta_i':>24s} {'limits':>14s}  link")
    lines = [head, f"{'':>2}  {'':14s} {'':19s} {'deg':>9s} {'mm':>7s} {'mm':>7s} {'deg':>24s} {'deg':>14s}",
             "-" * (len(head) + 14)]
    for i, name in enumerate(m.frame_names):
        alpha, a, d, theta = dh[i]
        parent = "base (0)" if m.parents[i] < 0 else f"{m.frame_names[m.parents[i]]} ({m.parents[i] + 1})"
        j = m.q_index[i]
        offset = f"{np.degrees(theta):+.0f} + " if abs(theta) > 0 else ""
        theta_s = f"{offset}{m.q_names[j]}" if j >= 0 else f"{np.degrees(theta):.0f}"
        limits = f"[{lo[j]:.0f}, {hi[j]:.0f}]" if j >= 0 else ""
        link = ""
        if i in link_of:
            k = link_of[i]
            link = f"{float(m.link_length_mm[k]):.0f} mm, r {float(m.link_radius_mm[k]):.1f}"
            link += ", tip" if k in m.tip_links else ""
        lines.append(f"{i + 1:>2}  {name:14s} {parent:19s} {np.degrees(alpha):9.0f} {a:7.1f} {d:7.1f} "
                     f"{theta_s:>24s} {limits:>14s}  {link}")
    return "\n".join(lines)


for name, m in models.items():
    print(f"{name} (thesis {THESIS[name]}), q = ({', '.join(m.q_names)})\n{dh_table(m)}\n")
""")

md(r"""
## 2. The models in 3D and in the image

Blue: link axes (the pills' cylinder axes); red dots: joints, with their rotation axes (frame $z$) as short red
lines; grey dashes: the tree from the base through auxiliary frames; black triangles: tips. Each model is shown at
its default pose and at one random pose within its joint limits, in world coordinates (mm) turned so that the
image's up points up and depth recedes.
""")

code(r"""
poses = {name: [np.asarray(m.q_default), jh.random_q(m, rng, margin=0.1)] for name, m in models.items()}


def draw_3d(ax, m, q):
    # Plotted as (x, z, -y): the image's x to the right, depth away from the camera, the image's up (-y) upwards.
    def xyz(p):
        p = np.asarray(p)
        return p[..., 0], p[..., 2], -p[..., 1]

    pose = jh.forward(m, q)
    T = np.asarray(pose.frames)
    origin = T[:, :3, 3]
    base = np.asarray(m.T_world_mount)[:3, 3]
    for f, p in enumerate(m.parents):
        ax.plot(*xyz(np.stack([base if p < 0 else origin[p], origin[f]])), color="0.6", lw=0.8, ls="--")
    for s, e in zip(np.asarray(pose.link_start), np.asarray(pose.link_end)):
        ax.plot(*xyz(np.stack([s, e])), color="C0", lw=2.5)
    joints = [f for f in range(m.n_frames) if m.q_index[f] >= 0]
    ax.scatter(*xyz(origin[joints]), color="C3", s=14, depthshade=False)
    for f in joints:
        ax.plot(*xyz(np.stack([origin[f] - 8 * T[f, :3, 2], origin[f] + 8 * T[f, :3, 2]])), color="C3", lw=1)
    ax.scatter(*xyz(pose.tips), color="k", marker="^", s=18, depthshade=False)
    pts = np.stack(xyz(np.concatenate([origin, np.asarray(pose.link_end), base[None]])), -1)
    mid, half = (pts.max(0) + pts.min(0)) / 2, (pts.max(0) - pts.min(0)).max() / 2 + 5
    ax.set(xlim=(mid[0] - half, mid[0] + half), ylim=(mid[1] - half, mid[1] + half),
           zlim=(mid[2] - half, mid[2] + half), xlabel="x", ylabel="z (depth)", zlabel="-y (up)")
    ax.set_box_aspect((1, 1, 1))
    ax.tick_params(labelsize=6)
    ax.view_init(elev=15, azim=-70)


fig = plt.figure(figsize=(16, 8.5), layout="constrained")
for col, (name, m) in enumerate(models.items()):
    for row, q in enumerate(poses[name]):
        ax = fig.add_subplot(2, 4, 1 + col + 4 * row, projection="3d")
        draw_3d(ax, m, q)
        ax.set_title(f"{name} ({THESIS[name]}), {'default pose' if row == 0 else 'random pose'}", fontsize=9)
fig.suptitle("Built-in models in 3D (world frame, mm; the camera looks along +z, image y points down)")
plt.show()
""")

md(r"""
The same poses seen by an orthographic camera (thesis §2.4.1), framed to fit both poses. As in the experiments of
thesis chapter 6, the camera looks at `two_fingers` and `hand21` tilted by 45° about the horizontal image axis;
`index` and `index_thumb` are seen from the side, as in thesis Figures 2.6 and 2.9.
""")

code(r"""
def tilt_x(deg):
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


TILT = {"index": 0.0, "index_thumb": 0.0, "two_fingers": 45.0, "hand21": 45.0}
fig, axes = plt.subplots(2, 4, figsize=(16, 6.5), layout="constrained")
for col, (name, m) in enumerate(models.items()):
    ends = [np.concatenate([jh.forward(m, q).link_start, jh.forward(m, q).link_end]) for q in poses[name]]
    camera = jh.Orthographic.fit(np.concatenate(ends), size=(320, 240), R=tilt_x(TILT[name]))
    for row, q in enumerate(poses[name]):
        image = sketch_model(m, camera, q)           # BGR, uint8
        axes[row, col].imshow(image[..., ::-1])
        axes[row, col].set_title(f"{name}, {'default' if row == 0 else 'random'} pose, tilt {TILT[name]:.0f}°",
                                 fontsize=9)
        axes[row, col].set_xticks([])
        axes[row, col].set_yticks([])
fig.suptitle("Projected by an orthographic camera (jaxhand.viz.sketch_model, 320 x 240 px)")
plt.show()
""")

md(r"""
## 3. Joint limits of the 21-DOF hand

Thesis Table 2.1 gives the typical ranges of motion; jaxhand's `hand21` uses them with the sign convention of
thesis §6.2.2 (opening or spreading the hand is positive, so flexion is negative). The dot is the default pose.
""")

code(r"""
m = models["hand21"]
lo, hi, q0 = (np.degrees(np.asarray(a)) for a in (m.q_lower, m.q_upper, m.q_default))
fingers = [n.split("_")[0] for n in m.q_names]
colors = {f: f"C{k}" for k, f in enumerate(dict.fromkeys(fingers))}
fig, ax = plt.subplots(figsize=(8, 7))
y = np.arange(m.n_q)[::-1]
ax.barh(y, hi - lo, left=lo, color=[colors[f] for f in fingers], alpha=0.7)
ax.plot(q0, y, "ko", ms=4, label="default pose")
ax.axvline(0, color="0.3", lw=0.8)
ax.set_yticks(y, m.q_names, fontsize=8)
ax.set_xlabel("joint range (deg)")
ax.set_title("hand21 joint limits (thesis Table 2.1, opening positive)")
ax.legend(loc="lower left")
fig.tight_layout()
plt.show()
""")

md(r"""
## 4. Jacobian checks

The tracker's Gauss-Newton steps need $\partial\,\text{pixels}/\partial q$ of the projected model. jaxhand gets it
from `jax.jacfwd`; `jaxhand.check.jacobian_errors` compares it with central differences (step $10^{-6}$, float64)
and with the geometric Jacobian of DigitEyes eqs. 8-10 ($z_j \times (p - o_j)$ for a revolute joint, the palm's
translation and quaternion columns for a free base), both mapped to pixels through the camera. The errors are
max-abs differences divided by $\max(1, \max|J|)$, worst over ten poses of every built-in model (the default pose,
every joint at its upper limit, eight random poses) seen by a tilted orthographic camera, and for the free-palm
`hand27` also by a perspective camera. Central differences agree to their truncation
and rounding error (~1e-8); the geometric Jacobian agrees to rounding error.
""")

code(r"""
names = jh.builtin_names()
errors = {}
for name in names:
    m = jh.builtin_model(name)
    pose = jh.forward(m, m.q_default)
    cameras = [jh.Orthographic.fit(np.concatenate([pose.link_start, pose.link_end]), size=(320, 240),
                                   R=look_at_rotation([1.0, -0.5, -2.0], [0.0, 0.0, 0.0]))]
    if m.base_kind == "free":  # the DigitEyes hand: also through a perspective camera
        cameras.append(jh.Perspective.look_at([80.0, -60.0, -500.0], [0.0, 0.0, 0.0]))
    at_limits = np.where(np.array(m.q_kinds) == "quat", m.q_default, m.q_upper)  # every joint at its upper limit
    qs = [np.asarray(m.q_default), at_limits] + list(jh.random_q(m, rng, 8))
    worst = {"finite_difference": 0.0, "geometric": 0.0}
    for camera in cameras:
        for q in qs:
            e = jacobian_errors(m, camera, q)
            worst = {k: max(worst[k], e[k]) for k in worst}
    errors[name] = worst

print(f"{'model':12s} {'DOF':>4s}   {'vs central differences':>22s}   {'vs geometric (eqs. 8-10)':>24s}")
for name in names:
    print(f"{name:12s} {jh.builtin_model(name).dof:4d}   {errors[name]['finite_difference']:22.1e}   "
          f"{errors[name]['geometric']:24.1e}")

fig, ax = plt.subplots(figsize=(10, 3.8))
x = np.arange(len(names))
for k, (key, label) in enumerate([("finite_difference", "vs central differences"),
                                  ("geometric", "vs geometric Jacobian (DigitEyes eqs. 8-10)")]):
    vals = np.maximum([errors[n][key] for n in names], 1e-17)  # an exact zero would vanish on a log axis
    ax.bar(x + (k - 0.5) * 0.38, vals, width=0.38, label=label)
ax.set_yscale("log")
ax.set_xticks(x, names, rotation=20)
ax.set_ylabel("max |J_jacfwd - J| / max(1, max |J|)")
ax.set_title("jax.jacfwd Jacobian of the projected link ends, worst over 10 poses")
ax.legend(fontsize=8)
fig.tight_layout()
plt.show()
""")

md(r"""
What the Jacobian looks like: `hand21` at its random pose, seen by the 45°-tilted orthographic camera. Rows are the
$x$ and $y$ pixel of each link's start and end point, columns the joints. The tree shows as a block structure:
a joint moves only the link ends below it, so each finger's rows are zero outside its own columns. Right: the
absolute difference to the geometric Jacobian.
""")

code(r"""
m = models["hand21"]
q = poses["hand21"][1]
ends = [np.concatenate([jh.forward(m, p).link_start, jh.forward(m, p).link_end]) for p in poses["hand21"]]
camera = jh.Orthographic.fit(np.concatenate(ends), size=(320, 240), R=tilt_x(45.0))
J = np.asarray(autodiff_jacobian(m, camera, q))                       # (2 links, 2, n_q): px per rad
diff = np.abs(J - np.asarray(projected_geometric_jacobian(m, camera, q)))
rows = [f"{m.link_names[k % m.n_links]} {'start' if k < m.n_links else 'end'} {c}"
        for k in range(2 * m.n_links) for c in "xy"]
J, diff = J.reshape(len(rows), m.n_q), diff.reshape(len(rows), m.n_q)

fig, (a1, a2) = plt.subplots(1, 2, figsize=(15, 9), sharey=True)
lim = np.abs(J).max()
im1 = a1.imshow(J, cmap="RdBu_r", vmin=-lim, vmax=lim, aspect="auto")
a1.set_title("d pixel / d q by jax.jacfwd (px/rad)")
fig.colorbar(im1, ax=a1, shrink=0.6)
im2 = a2.imshow(np.log10(np.maximum(diff, 1e-18)), cmap="magma", vmin=-18, vmax=-10, aspect="auto")
a2.set_title(f"log10 |jacfwd - geometric| (max {diff.max():.1e} px/rad)")
fig.colorbar(im2, ax=a2, shrink=0.6)
for ax in (a1, a2):
    ax.set_xticks(range(m.n_q), m.q_names, rotation=90, fontsize=7)
a1.set_yticks(range(len(rows)), rows, fontsize=5.5)
fig.suptitle("hand21: Jacobian of the projected link ends at a random pose")
fig.tight_layout()
plt.show()
""")

nb.write(OUT)
