"""Write notebooks/03_image_analysis.ipynb (without outputs).

Run ``.venv/bin/python notebooks/_make_03.py`` after editing the cells below; the notebook is
stored without outputs and ``tests/test_notebooks.py`` executes it.
"""

from pathlib import Path

from _nbgen import Notebook

HERE = Path(__file__).resolve().parent
OUT = HERE / "03_image_analysis.ipynb"

nb = Notebook()
md, code = nb.md, nb.code

md(r"""
# 03 · Image analysis

**What this shows.** The image front end of thesis chapter 4 and appendix D at work on two synthetic frames, in
the manner of thesis Figs. 4.2-4.23:

1. the frame, the predicted model, the link samplers and tip samplers placed across it (§4.1), and the
   visibility analysis: each link's outline, the part of it nearer fingers leave visible and its window
   polygon (§4.3.3);
2. every feature search of `jaxhand.image.SEARCH_NAMES` (derivative, Gaussian derivative, width-restricted,
   width-compensated, PLLS, MWPLLS, IMWPLLS and the windowed-SSD template search) on the same frame, one panel
   each, with the detected boundary points, the fitted boundary lines and the axial lines that become the link
   features, over the true link axes;
3. a few sampled profiles with the boundaries each search found and the true ones;
4. the angle and offset error of every method's link lines against the ground truth on both frames.

The frames: frame 20 of the two-finger occlusion experiment (`two_fingers`, thesis §6.1: the index finger
crosses in front of the middle finger) and frame 20 of the spreading and flexing hand (`hand21`, thesis §6.2.2),
both 320 × 240, shaded with 3 × 3 antialiasing. The trackers are placed at the pose a tracker would predict,
$2 q_{19} - q_{18}$ (constant velocity from the two previous true poses).

**What it uses.** The public API: `jaxhand.render` (`make_preset`, `render_frame`, `RenderConfig`),
`jaxhand.image` (`extract_features` with `ImageConfig(method=...)` and its `Diagnostics`, `capture_templates`,
`SEARCH_NAMES`), `jaxhand.features.features_from_pose` (the ground-truth lines) and `jaxhand.project_pose`; plus
NumPy, shapely (the window polygons) and matplotlib. The frames are rendered deterministically. It runs in about
ten seconds on two CPU cores.
""")

code(r"""
import matplotlib.pyplot as plt
import numpy as np
import shapely

import jaxhand as jh
from jaxhand.features import features_from_pose
from jaxhand.image import SEARCH_NAMES, ImageConfig, capture_templates, extract_features
from jaxhand.render import RenderConfig, make_preset, render_frame

jh.enable_x64()   # jaxhand computes in float64 (it asks rather than switching it on at import)

%matplotlib inline

RENDER = RenderConfig(antialias=3)
K = 20  # the analysed frame
frames = {}
for preset in ("two_finger_occlusion", "full_hand_spread_flex"):
    seq = make_preset(preset, frames=40)
    model, camera = seq.model, seq.cameras[0]

    def image(k, seq=seq):
        return render_frame(seq.model, seq.cameras[0], seq.q[k], RENDER, frame_index=k).image

    # WSSD's templates: taken at the first frame (the fingers apart), then refreshed at the previous frame's
    # pose, as the tracker does after each solve; only the samples that show a link overwrite its template.
    state = capture_templates(image(0), model, camera, seq.q[0])
    state = capture_templates(image(K - 1), model, camera, seq.q[K - 1], state=state)
    frames[preset] = dict(model=model, camera=camera, image=image(K), q_true=seq.q[K],
                          q_pred=2 * seq.q[K - 1] - seq.q[K - 2], state=state)
    print(f"{preset}: model {model.name} ({model.dof} DOF, {model.n_links} links), image {camera.size}")
""")

md(r"""
## 1. Samplers and visibility

Every method shares the first steps. The prediction places `per_link = 8` samplers across each projected link,
between 20 % and 80 % of its length, each 48 samples spanning ±1.75 predicted radii about the predicted axis
(thesis Fig. 4.2); the tip sampler runs along the terminal link's axis through the predicted tip (Fig. 4.3).
The visibility analysis outlines every link's pill, sorts the pills by depth and cuts each by the nearer pills of
other fingers (Figs. 4.13-4.17); the window polygon (the outline grown by a strip of background, less the grown
nearer pills) decides which samples of a profile may be used (Fig. 4.18). Shown for the two-finger frame, where
the index finger's pills cover part of the middle finger's.
""")

code(r"""
def analyse(name, method):
    fr = frames[name]
    features, diag = extract_features(fr["image"], fr["model"], fr["camera"], fr["q_pred"],
                                      ImageConfig(method=method), fr["state"])
    return features[0], diag.cameras[0]


def zoom(ax, name, pad=25):
    fr = frames[name]
    h, w = fr["image"].shape[:2]
    ys, xs = np.nonzero(fr["image"] > 20)
    ax.set_xlim(max(xs.min() - pad, -0.5), min(xs.max() + pad, w - 0.5))
    ax.set_ylim(min(ys.max() + pad, h - 0.5), max(ys.min() - pad, -0.5))
    ax.set_xticks([])
    ax.set_yticks([])


def draw_polygon(ax, poly, **kw):
    for part in getattr(poly, "geoms", [poly]):
        if not part.is_empty and part.geom_type == "Polygon":
            ax.plot(*np.asarray(part.exterior.coords).T, **kw)


def true_axes(name):
    fr = frames[name]
    view = jh.project_pose(fr["model"], fr["camera"], fr["q_true"])
    return np.asarray(view.link_start_px), np.asarray(view.link_end_px), np.asarray(view.link_radius_px)


name = "two_finger_occlusion"
fr = frames[name]
_, cam = analyse(name, "wssd")
pred = jh.project_pose(fr["model"], fr["camera"], fr["q_pred"])
start, end, _ = true_axes(name)
fig, axes = plt.subplots(1, 3, figsize=(17, 4.8), layout="constrained")
for ax in axes:
    ax.imshow(fr["image"], cmap="gray", vmin=0, vmax=255)
    zoom(ax, name)
ax = axes[0]
for s, e in zip(start, end):
    ax.plot(*np.stack([s, e]).T, color="cyan", lw=1.5)
for s, e in zip(np.asarray(pred.link_start_px), np.asarray(pred.link_end_px)):
    ax.plot(*np.stack([s, e]).T, color="orange", lw=1.5, ls="--")
ax.set_title("true link axes (cyan), predicted axes (orange, dashed)", fontsize=10)
ax = axes[1]
for link_ends in cam.samplers.ends:            # (samplers, 2, 2)
    for a, b in link_ends:
        ax.plot([a[0], b[0]], [a[1], b[1]], color="yellow", lw=0.8)
for pts in cam.tip_samplers.points:            # (points, 2)
    ax.plot(*pts[[0, -1]].T, color="red", lw=2)
ax.plot(*cam.samplers.centres.reshape(-1, 2).T, ".", color="orange", ms=3)
ax.set_title("link samplers (yellow), their centres (orange), tip samplers (red)", fontsize=10)
ax = axes[2]
vis = cam.visibility
for link, colour in zip(range(len(vis.outlines)), plt.cm.tab10.colors):
    draw_polygon(ax, vis.outlines[link], color=colour, lw=0.8, ls=":")
    draw_polygon(ax, vis.windows[link], color=colour, lw=1.5)
    for part in getattr(vis.visible[link], "geoms", [vis.visible[link]]):
        if not part.is_empty and part.geom_type == "Polygon":
            ax.fill(*np.asarray(part.exterior.coords).T, color=colour, alpha=0.25)
    c = shapely.centroid(vis.outlines[link])
    ax.annotate(f"{fr['model'].link_names[link]}\n{vis.visible_share[link]:.0%} visible", (c.x, c.y),
                fontsize=7, color="white", ha="center")
ax.set_title("outlines (dotted), visible parts (filled), windows (solid)", fontsize=10)
fig.suptitle(f"two_finger_occlusion, frame {K}: trackers and visibility at the predicted pose")
plt.show()
""")

md(r"""
## 2. Every search on the same frame

Each panel runs `extract_features` with one `ImageConfig(method=...)` from the same prediction. Red and blue dots:
the boundary points found on each profile (boundary 0 and 1, on either side of the axis); yellow: the boundary
lines fitted to them (RANSAC, then PCA); green: the axial line between them, the link's feature; dashed cyan: the
true axis; red stars: the tip boundaries found. The WSSD panel also shows the window polygons (magenta), the only
search that uses them. The title gives the links with a valid line and the median angle error against the truth.
""")

code(r"""
def line_segment(line, p0, p1, extend=0.15):
    # The part of the line (a, b, rho) beside the segment p0-p1 (lengthened by `extend` at each end).
    a, b, rho = line
    n = np.array([a, b])
    d = p1 - p0
    ends = np.stack([p0 - extend * d, p1 + extend * d])
    return ends - (ends @ n - rho)[:, None] * n


def angle_errors(name, feats):
    truth = np.asarray(features_from_pose(frames[name]["model"], frames[name]["camera"], frames[name]["q_true"])[0]
                       .lines)
    lines, valid = np.asarray(feats.lines), np.asarray(feats.line_valid)
    cos = np.abs(np.sum(lines[:, :2] * truth[:, :2], -1))
    angle = np.degrees(np.arccos(np.clip(cos, 0.0, 1.0)))
    start, end, _ = true_axes(name)
    mid = 0.5 * (start + end)
    offset = np.abs(np.sum(lines[:, :2] * mid, -1) - lines[:, 2])   # true midpoint to the found line, px
    return np.where(valid, angle, np.nan), np.where(valid, offset, np.nan)


results = {name: {method: analyse(name, method) for method in SEARCH_NAMES} for name in frames}


def method_panels(name):
    fr = frames[name]
    start, end, _ = true_axes(name)
    fig, axes = plt.subplots(2, 4, figsize=(18, 8.6), layout="constrained")
    for ax, method in zip(axes.ravel(), SEARCH_NAMES):
        feats, cam = results[name][method]
        ax.imshow(fr["image"], cmap="gray", vmin=0, vmax=255)
        zoom(ax, name)
        for link_ends in cam.samplers.ends:
            for a, b in link_ends:
                ax.plot([a[0], b[0]], [a[1], b[1]], color="0.55", lw=0.4)
        if method == "wssd":
            for poly in cam.visibility.windows:
                draw_polygon(ax, poly, color="magenta", lw=0.8)
        centres = cam.samplers.centres
        for link in range(len(centres)):
            if not cam.samplers.ok[link]:
                continue
            p0, p1 = centres[link, 0], centres[link, -1]
            for side in range(2):
                if cam.boundary_valid[link, side]:
                    ax.plot(*line_segment(cam.boundary_lines[link, side], p0, p1).T, color="yellow", lw=1)
            if bool(feats.line_valid[link]):
                ax.plot(*line_segment(np.asarray(feats.lines[link]), p0, p1).T, color="lime", lw=1.6)
            ax.plot(*np.stack([start[link], end[link]]).T, color="cyan", lw=1, ls="--")
        ax.plot(*cam.edge_px[:, :, 0].reshape(-1, 2).T, "o", color="red", ms=2.5)
        ax.plot(*cam.edge_px[:, :, 1].reshape(-1, 2).T, "o", color="dodgerblue", ms=2.5)
        ax.plot(*cam.tip_edge_px.T, "*", color="red", ms=9)
        angle, _ = angle_errors(name, feats)
        n_valid = int(np.asarray(feats.line_valid).sum())
        ax.set_title(f"{method}: {n_valid}/{len(angle)} lines, median {np.nanmedian(angle):.2f} deg off",
                     fontsize=10)
    fig.suptitle(f"{name}, frame {K} ({fr['model'].name}): every feature search from the same prediction")
    plt.show()


method_panels("two_finger_occlusion")
""")

md(r"""
On the two-finger frame the searches that look only at intensity changes (derivative, Gaussian, width,
width-compensated) can take the near finger's edge for the covered finger's boundary where the fingers overlap,
which tilts that link's line (the worst link in section 4); the correlation-surface searches (PLLS family) reject
outlying edges along the whole link or drop the line; WSSD matches each profile against the link's stored template
inside its window only. On the unoccluded hand frame (below) the searches agree to a fraction of a degree; there
WSSD is the one that drops links (in this frame both boundaries of two index-finger phalanges fail its match
against templates taken at frames 0 and 19), so it keeps fewer lines than the derivative searches.
""")

code(r"""
method_panels("full_hand_spread_flex")
""")

md(r"""
## 3. Profiles

Four profiles of the two-finger frame: the middle sampler of the index finger's middle phalanx (in front) and of
the three middle-finger phalanges (partly behind it), plus one of the hand frame. Grey: the sampled intensity
against the position along the sampler (px from the predicted axis); shaded: samples outside the link's window;
dashed black: the true boundaries (true axis ± true radius, measured along the sampler); below the profile, one
row per search: ticks where it put the two boundaries (none where it found none).
""")

code(r"""
def true_boundaries(name, cam, link, sampler):
    # Where the sampler crosses the true axis, and the true radius measured along the sampler, in px.
    start, end, radius = true_axes(name)
    c, n = cam.samplers.centres[link, sampler], cam.samplers.normal[link]
    d = (end[link] - start[link]) / np.linalg.norm(end[link] - start[link])
    normal = np.array([d[1], -d[0]])
    cross = normal @ n
    t = (normal @ start[link] - normal @ c) / cross
    half = radius[link] / abs(cross)
    return t - half, t + half


names = {name: fr["model"].link_names for name, fr in frames.items()}
picks = [("two_finger_occlusion", names["two_finger_occlusion"].index(link))
         for link in ("index_pip", "middle_mcp", "middle_pip", "middle_dip")]
picks.append(("full_hand_spread_flex", names["full_hand_spread_flex"].index("index_pip")))
fig, axes = plt.subplots(1, len(picks), figsize=(4 * len(picks), 4.2), layout="constrained", sharey=True)
for ax, (name, link) in zip(axes, picks):
    _, cam0 = results[name]["wssd"]
    sampler = cam0.samplers.centres.shape[1] // 2
    prof = cam0.profiles
    j = np.arange(prof.values.shape[-1])
    x = (j - prof.centre) * prof.spacing_px[link]
    ax.plot(x, prof.values[link, sampler], color="0.3", lw=2)
    outside = ~prof.window[link, sampler]
    ax.fill_between(x, 0, 255, where=outside, color="0.85", step="mid", zorder=0)
    for b in true_boundaries(name, cam0, link, sampler):
        ax.axvline(b, color="k", ls="--", lw=1)
    for m, method in enumerate(SEARCH_NAMES):
        _, cam = results[name][method]
        e = cam.edges
        for side in range(2):
            if e.valid[link, sampler, side]:
                pos = (e.pos[link, sampler, side] - prof.centre) * prof.spacing_px[link]
                ax.plot(pos, -12 - 11 * m, "|", color=f"C{m}", ms=9, mew=2.5)
    ax.axhline(0, color="0.5", lw=0.5)
    ax.set_ylim(-12 - 11 * len(SEARCH_NAMES), 260)
    ax.set_xlabel("px along the sampler from the predicted axis")
    ax.set_title(f"{frames[name]['model'].link_names[link]}, sampler {sampler + 1}\n({name}, "
                 f"{cam0.visibility.visible_share[link]:.0%} visible)", fontsize=9)
axes[0].set_ylabel("grey level")
axes[0].set_yticks([0, 100, 200] + [-12 - 11 * m for m in range(len(SEARCH_NAMES))],
                   ["0", "100", "200"] + list(SEARCH_NAMES), fontsize=8)
for tick, m in zip(axes[0].get_yticklabels()[3:], range(len(SEARCH_NAMES))):
    tick.set_color(f"C{m}")
plt.show()
""")

md(r"""
## 4. Line error against the ground truth

For each method and frame, the angle between each valid link line and the true projected axis
(`features_from_pose` at the true pose) and the distance of the true link midpoint from the found line. Bars: the
median over the links with a valid line; whiskers up to the worst link; the number of valid links above each bar.
""")

code(r"""
rows = []
for name in frames:
    for method in SEARCH_NAMES:
        feats, _ = results[name][method]
        angle, offset = angle_errors(name, feats)
        rows.append((name, method, int(np.sum(np.isfinite(angle))), len(angle), np.nanmedian(angle),
                     np.nanmax(angle), np.nanmedian(offset), np.nanmax(offset)))
print(f"{'frame':22s} {'method':18s} {'lines':>6s} {'median deg':>10s} {'max deg':>8s} {'median px':>9s} "
      f"{'max px':>7s}")
for r in rows:
    print(f"{r[0]:22s} {r[1]:18s} {r[2]:>3d}/{r[3]:<2d} {r[4]:10.2f} {r[5]:8.2f} {r[6]:9.2f} {r[7]:7.2f}")

fig, axes = plt.subplots(1, 2, figsize=(16, 5), layout="constrained")
width = 0.38
x = np.arange(len(SEARCH_NAMES))
for ax, (med_i, max_i) in zip(axes, ((4, 5), (6, 7))):
    for f, name in enumerate(frames):
        sel = [r for r in rows if r[0] == name]
        med = np.array([r[med_i] for r in sel])
        worst = np.array([r[max_i] for r in sel])
        bars = ax.bar(x + (f - 0.5) * width, med, width, color=f"C{f}", label=name,
                      yerr=np.stack([np.zeros_like(med), worst - med]), capsize=3, error_kw=dict(lw=0.8))
        for bar, r in zip(bars, sel):
            ax.annotate(f"{r[2]}/{r[3]}", (bar.get_x() + bar.get_width() / 2, bar.get_height()),
                        xytext=(0, 2), textcoords="offset points", ha="center", fontsize=7)
    ax.set_yscale("log")
    ax.set_xticks(x, SEARCH_NAMES, rotation=20)
    ax.legend()
axes[0].set(ylabel="angle to the true axis (deg)", title=f"line angle error, frame {K} (bar: median, whisker: worst)")
axes[1].set(ylabel="true midpoint to the found line (px)", title=f"line offset error, frame {K}")
plt.show()
""")

nb.write(OUT)
