"""Feature benchmark: time per frame and line accuracy of every feature search, in one process.

Frames come from :mod:`jaxhand.render` (5x5 antialiasing) for two thesis experiments at 320x240:

- ``full_hand_spread_flex`` (hand21, thesis §6.2.2, 60 frames): the fingers spread, then flex;
- ``two_finger_occlusion`` (two_fingers, thesis §6.1, 40 frames): the index crosses in front of the
  middle finger, covering part of it.

Conditions (light along the viewing direction unless named, so each phalanx is shaded symmetrically):

- ``clean`` (hand21), ``noisy`` (hand21, Gaussian pixel noise of 4 grey levels),
  ``oblique`` (hand21, the renderer's default light from above-left: one limb of each finger is
  dark and soft), ``occluded`` (two_fingers);
- ``clean@truth``: hand21 with the prediction at the true pose (the others predict each frame's
  pose from the two previous true poses at constant velocity, ``2 q[k-1] - q[k-2]``, what a
  tracker's filter does once it has converged).

Every frame runs through :func:`jaxhand.image.extract_features` with each search in
:data:`jaxhand.image.SEARCH_NAMES`. The WSSD search captures its templates from the first frame at
the true pose and, as a tracker would after each solve, refreshes them with
:func:`jaxhand.image.capture_templates` at each frame's true pose (the solve taken as exact), so
it matches every frame against the latest look of each phalanx. A link's error is measured
against its true projected axis: the angle between the lines (degrees) and the distance of the
true link midpoint from the extracted line (px). "occl. links" restricts the ``occluded``
condition to links whose visible share at the true pose lies in [0.3, 0.95].

Time per frame is the median over the clean hand21 frames and repeats (one core; OpenCV and BLAS
threads set to 1), with the first call (which compiles the jitted kinematics) reported separately
and the median stage split from :attr:`Diagnostics.timings_s`. The peer: sampling every profile
with one ``cv2.remap`` per profile (a Python loop) instead of one call for the frame.

Front end vs reference: the same clean hand21 frames through :func:`extract_features` and through
the frozen copy of the front end before its split and speed-up (``tests/reference_image``), each
running all the frames in turn (blocks alternating, as a tracker runs one front end; calls
interleaved one by one made each run on caches the other had just filled), for the wssd, gaussian
and imwplls searches: median wall and CPU ms per frame, the
ratio reference / new, the median CPU ms of each stage (both front ends' stage clocks read
``time.process_time`` during the comparison), and whether every feature came out the same (masks
bit for bit, lines and tips to 0.01 px, weights to 1e-12 relative). Then the whole frame
(``Tracker.step``, hand21, imwplls) with each front end, each tracker running the whole sequence
in turn, twice: CPU and wall ms per steady frame. ``--cli-runtime`` runs JAX as the CLI does.

Run ``python benchmarks/features.py`` (writes ``benchmarks/results/features.json``),
``python benchmarks/features.py --quick`` for a smoke run (no JSON unless ``--out`` is given), or
``python benchmarks/features.py --vs-reference`` for the front-end comparison alone (writes
``benchmarks/results/features_vs_reference.json``).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):  # one core, before numpy loads
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from functools import partial  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
import shapely  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))  # the reference front end
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # this checkout's jaxhand

from _common import (  # noqa: E402
    REPO,
    RESULTS,
    add_runtime_option,
    apply_runtime,
    environment,
    first_call_seconds,
    median_seconds,
    time_call,
    write_json,
)

import jaxhand as jh  # noqa: E402

jh.enable_x64()
from jaxhand.image import SEARCH_NAMES, ImageConfig, capture_templates, extract_features  # noqa: E402
from jaxhand.image.internal import INTERPOLATION_FLAGS, as_grey, sample_profiles  # noqa: E402
from jaxhand.render import RenderConfig, make_preset, render_frame  # noqa: E402
from jaxhand.track import AbstractFrontEnd, FrontEndResult, ImageFrontEnd, TrackConfig, Tracker  # noqa: E402

DEFAULT_OUT = RESULTS / "features.json"
VS_REFERENCE_OUT = RESULTS / "features_vs_reference.json"
REFERENCE_METHODS = ("wssd", "gaussian", "imwplls")
FRONT_LIGHT = (0.0, 0.0, -1.0)
OBLIQUE_LIGHT = RenderConfig().light_dir
NOISE_SIGMA = 4.0
# (condition, preset, light, noise, predict at constant velocity from the previous frames' truth)
CONDITIONS = (
    ("clean", "full_hand_spread_flex", FRONT_LIGHT, 0.0, True),
    ("clean@truth", "full_hand_spread_flex", FRONT_LIGHT, 0.0, False),
    ("noisy", "full_hand_spread_flex", FRONT_LIGHT, NOISE_SIGMA, True),
    ("oblique", "full_hand_spread_flex", OBLIQUE_LIGHT, 0.0, True),
    ("occluded", "two_finger_occlusion", FRONT_LIGHT, 0.0, True),
)
OCCLUDED_SHARE = (0.3, 0.95)


def bench_environment() -> dict:
    """``_common.environment`` with this benchmark's extras: one thread, OpenCV, Shapely, jaxhand."""
    env = environment(watched=("jaxhand/image", "benchmarks/features.py"))
    env.update(threads=1, opencv=cv2.__version__, shapely=shapely.__version__, jaxhand=jh.__version__)
    return env


def line_errors(model, camera, q, lines) -> tuple[np.ndarray, np.ndarray]:
    """Angle (deg) and midpoint offset (px) of each extracted line from the true projected link axis."""
    v = jh.project_pose(model, camera, jnp.asarray(q))
    s, e = np.asarray(v.link_start_px), np.asarray(v.link_end_px)
    u = (e - s) / np.maximum(np.linalg.norm(e - s, axis=-1, keepdims=True), 1e-12)
    ang = np.degrees(np.arcsin(np.clip(np.abs(np.sum(lines[:, :2] * u, -1)), 0, 1)))
    off = np.abs(np.sum(lines[:, :2] * (s + e) / 2, -1) - lines[:, 2])
    return ang, off


def _frames(preset: str, light, noise: float, quick: bool):
    seq = make_preset(preset, size=(320, 240))
    idx = np.arange(seq.n_frames)
    if quick:
        idx = idx[:: max(1, seq.n_frames // 6)]
    cam = seq.cameras[0]
    cfg = RenderConfig(antialias=5, light_dir=light, noise_sigma=noise, seed=7)
    images = [render_frame(seq.model, cam, seq.q[k], cfg, frame_index=int(k)).image for k in idx]
    return seq, cam, idx, images


def _visible_share(model, cam, q, image) -> np.ndarray:
    _, diag = extract_features(image, model, cam, q, ImageConfig(method="gaussian"))
    return diag.cameras[0].visibility.visible_share


def evaluate(quick: bool) -> list[dict]:
    rows = []
    for cond, preset, light, noise, previous in CONDITIONS:
        seq, cam, idx, images = _frames(preset, light, noise, quick)
        m = seq.model
        truth_share = [_visible_share(m, cam, seq.q[k], im) for k, im in zip(idx, images)]
        for method in SEARCH_NAMES:
            config = ImageConfig(method=method)
            state = capture_templates(images[0], m, cam, seq.q[idx[0]], config)
            ang, off, valid, occl, tip_err, tip_valid = [], [], [], [], [], []
            for j, k in enumerate(idx):
                q_pred = 2 * seq.q[max(k - 1, 0)] - seq.q[max(k - 2, 0)] if previous else seq.q[k]
                feats, diag = extract_features(images[j], m, cam, q_pred, config, state)
                # a tracker refreshes the templates at its solved pose; here the solve is taken as exact
                state = capture_templates(images[j], m, cam, seq.q[k], config, diag.state)
                f = feats[0]
                a, o = line_errors(m, cam, seq.q[k], np.asarray(f.lines))
                ang.append(a)
                off.append(o)
                valid.append(np.asarray(f.line_valid))
                sh = truth_share[j]
                occl.append((sh >= OCCLUDED_SHARE[0]) & (sh <= OCCLUDED_SHARE[1]))
                t_true = np.asarray(jh.project_pose(m, cam, jnp.asarray(seq.q[k])).tips_px)
                tip_err.append(np.linalg.norm(np.asarray(f.tips) - t_true, axis=-1))
                tip_valid.append(np.asarray(f.tip_valid))
            ang, off, valid, occl = (np.concatenate(x) for x in (ang, off, valid, occl))
            tip_err, tip_valid = np.concatenate(tip_err), np.concatenate(tip_valid)
            subsets = [(cond, np.ones_like(valid))]
            if cond == "occluded":
                subsets.append(("occl. links", occl))
            for name, sel in subsets:
                rows.append(_summary(method, name, preset, ang, off, valid, sel, tip_err, tip_valid))
                print(_format_row(rows[-1]), flush=True)
    return rows


def _summary(method, condition, preset, ang, off, valid, sel, tip_err, tip_valid) -> dict:
    use = valid & sel
    a, o = ang[use], off[use]
    good = (a < 1.0) & (o < 1.0)

    def stat(x, fn):
        return float(fn(x)) if len(x) else None

    return {"method": method, "condition": condition, "preset": preset, "links": int(sel.sum()),
            "valid_share": float(use.sum() / max(sel.sum(), 1)),
            "angle_median_deg": stat(a, np.median), "angle_p95_deg": stat(a, lambda x: np.percentile(x, 95)),
            "offset_median_px": stat(o, np.median), "offset_p95_px": stat(o, lambda x: np.percentile(x, 95)),
            "within_1deg_1px_share": float(good.sum() / max(sel.sum(), 1)),
            "tip_valid_share": float(tip_valid.mean()) if len(tip_valid) else None,
            "tip_median_px": stat(tip_err[tip_valid], np.median)}


def _loop_sampling(grey, points, interpolation):
    """Peer: one ``cv2.remap`` per profile (the Python loop the front end avoids)."""
    flat = points.reshape(-1, points.shape[-2], 2).astype(np.float32)
    return [cv2.remap(grey, p[None, :, 0], p[None, :, 1], INTERPOLATION_FLAGS[interpolation],
                      borderMode=cv2.BORDER_REPLICATE) for p in flat]


def _median_ms(fn, repeats: int) -> float:
    """Median milliseconds of ``repeats`` single calls of ``fn`` (after a warm-up call)."""
    return 1e3 * median_seconds(fn, repeats=repeats, min_sample_s=0.0)


def timing(quick: bool) -> tuple[list[dict], dict]:
    seq = make_preset("full_hand_spread_flex", size=(320, 240))
    m, cam = seq.model, seq.cameras[0]
    idx = np.linspace(0, seq.n_frames - 1, 4 if quick else 12).round().astype(int)
    cfg = RenderConfig(antialias=5, light_dir=FRONT_LIGHT)
    images = [render_frame(m, cam, seq.q[k], cfg).image for k in idx]
    repeats = 2 if quick else 5
    configs, states, firsts = {}, {}, {}
    for method in SEARCH_NAMES:
        configs[method] = ImageConfig(method=method)
        states[method] = capture_templates(images[0], m, cam, seq.q[idx[0]], configs[method])
        firsts[method] = 1e3 * first_call_seconds(
            partial(extract_features, images[0], m, cam, seq.q[idx[0]], configs[method], states[method]))
    samples = {method: [] for method in SEARCH_NAMES}
    stages = {method: {} for method in SEARCH_NAMES}
    for _ in range(repeats):  # methods interleaved, so a change in machine load hits them alike
        for method in SEARCH_NAMES:
            for j, k in enumerate(idx):
                t, (_, diag) = time_call(
                    partial(extract_features, images[j], m, cam, seq.q[k], configs[method], states[method]))
                samples[method].append(t)
                for name, sec in diag.timings_s.items():
                    stages[method].setdefault(name, []).append(sec)
    rows = [{"method": method, "median_ms": 1e3 * statistics.median(samples[method]), "first_call_ms": firsts[method],
             "stages_median_ms": {k: 1e3 * statistics.median(v) for k, v in stages[method].items()}}
            for method in SEARCH_NAMES]
    best = min(r["median_ms"] for r in rows)
    for r in rows:
        r["over_fastest"] = r["median_ms"] / best
    # peer: profile sampling, one remap per frame vs one per profile
    _, diag = extract_features(images[0], m, cam, seq.q[idx[0]], ImageConfig(method="gaussian"))
    pts = diag.cameras[0].samplers.points
    grey = as_grey(images[0])
    interp = ImageConfig().samplers.interpolation
    ours = _median_ms(lambda: sample_profiles(grey, pts, interp), 20 if quick else 200)
    loop = _median_ms(lambda: _loop_sampling(grey, np.nan_to_num(pts, nan=-10.0), interp), 5 if quick else 50)
    peer = {"profiles": int(np.prod(pts.shape[:2])), "points": int(pts.shape[2]), "one_remap_ms": ours,
            "remap_per_profile_ms": loop, "per_profile_over_one": loop / ours}
    return rows, peer


def _same_features(a, b) -> bool:
    """Masks bit for bit, lines and tips to 0.01 px, weights to 1e-12 relative (tests/test_image_reference.py)."""
    names = ("line_valid", "tip_valid", "tip_weight")
    return all(all(np.array_equal(np.asarray(getattr(x, n)), np.asarray(getattr(y, n))) for n in names)
               and np.allclose(np.asarray(x.lines), np.asarray(y.lines), rtol=0, atol=0.01)
               and np.allclose(np.asarray(x.tips), np.asarray(y.tips), rtol=0, atol=0.01)
               and np.allclose(np.asarray(x.line_weight), np.asarray(y.line_weight), rtol=1e-12, atol=0)
               for x, y in zip(a, b, strict=True))


class _CpuClockTime:
    """Stands in for the ``time`` module of both front ends' stage clocks during the comparison, so
    their per-stage figures are CPU time (``process_time``) like the totals, not wall time."""

    perf_counter = staticmethod(time.process_time)


def versus_reference(quick: bool) -> list[dict]:
    """hand21 ms per frame of the front end and of its frozen reference copy, each running the frames
    in turn (blocks alternating): wall and CPU totals, and CPU per stage (each front end's
    ``timings_s``)."""
    import reference_image
    import reference_image._extract as reference_extract

    import jaxhand.image._diagnostics as diagnostics

    seq = make_preset("full_hand_spread_flex", size=(320, 240))
    m, cam = seq.model, seq.cameras[0]
    idx = np.linspace(0, seq.n_frames - 1, 4 if quick else 12).round().astype(int)
    cfg = RenderConfig(antialias=5, light_dir=FRONT_LIGHT)
    images = [render_frame(m, cam, seq.q[k], cfg).image for k in idx]
    repeats = 2 if quick else 5
    fronts = {"new": (extract_features, capture_templates, ImageConfig),
              "reference": (reference_image.extract_features, reference_image.capture_templates,
                            reference_image.ImageConfig)}
    clocks = (diagnostics, reference_extract)
    saved = [mod.time for mod in clocks]
    for mod in clocks:
        mod.time = _CpuClockTime
    try:
        rows = [_versus_reference_method(method, fronts, m, cam, seq.q[idx], images, repeats)
                for method in REFERENCE_METHODS]
    finally:
        for mod, t in zip(clocks, saved):
            mod.time = t
    return rows


def _versus_reference_method(method, fronts, m, cam, qs, images, repeats) -> dict:
    calls, same = {}, True
    for name, (extract, capture, make_config) in fronts.items():
        config = make_config(method=method)
        state = capture(images[0], m, cam, qs[0], config)
        calls[name] = [partial(extract, images[j], m, cam, qs[j], config, state) for j in range(len(qs))]
        calls[name][0]()  # compile the kinematics and warm the caches
    wall = {name: [] for name in fronts}
    cpu = {name: [] for name in fronts}
    stages = {name: {} for name in fronts}
    for _ in range(repeats):
        outs = {}
        for name in fronts:  # each front end runs every frame in turn (its own caches, as when tracking); the
            for j in range(len(qs)):   # blocks alternate, so load changes hit both alike
                c0, (t, out) = time.process_time(), time_call(calls[name][j])
                cpu[name].append(time.process_time() - c0)
                wall[name].append(t)
                outs.setdefault(name, []).append(out[0])
                for stage, sec in out[1].timings_s.items():
                    stages[name].setdefault(stage, []).append(sec)
        same &= all(_same_features(a, b) for a, b in zip(outs["new"], outs["reference"], strict=True))
    row = {"method": method, "frames": len(qs), "repeats": repeats, "identical_features": bool(same),
           "load_average_1min": os.getloadavg()[0]}
    for name in fronts:
        row[f"{name}_median_ms"] = 1e3 * statistics.median(wall[name])
        row[f"{name}_cpu_median_ms"] = 1e3 * statistics.median(cpu[name])
        row[f"{name}_cpu_stages_median_ms"] = {k: 1e3 * statistics.median(v) for k, v in stages[name].items()}
    row["reference_over_new"] = row["reference_median_ms"] / row["new_median_ms"]
    row["reference_over_new_cpu"] = row["reference_cpu_median_ms"] / row["new_cpu_median_ms"]
    return row


class _ReferenceFrontEnd(AbstractFrontEnd):
    """The frozen reference front end behind the tracker's interface (no templates or widths: the
    whole-frame comparison runs imwplls, as benchmarks/tracking.py does for hand21)."""

    def __init__(self, model, cameras, config):
        import reference_image

        self.model, self.cameras, self.extract_features = model, cameras, reference_image.extract_features
        self.config = reference_image.ImageConfig(method=config.method)

    def extract(self, images, q_start, state, frame: int) -> FrontEndResult:
        features, diag = self.extract_features(images, self.model, self.cameras, np.asarray(q_start), self.config)
        return FrontEndResult(tuple(features), None)


class _CpuTimed(AbstractFrontEnd):
    """A front end with the CPU time of its last :meth:`extract` recorded (the tracker's own stage
    timers read wall time)."""

    def __init__(self, inner: AbstractFrontEnd):
        self.inner, self.cpu_s = inner, 0.0

    def extract(self, images, q_start, state, frame: int) -> FrontEndResult:
        c0 = time.process_time()
        out = self.inner.extract(images, q_start, state, frame)
        self.cpu_s = time.process_time() - c0
        return out

    def refresh(self, images, q, state):
        return self.inner.refresh(images, q, state)


FRAME_METHOD, FRAME_FRAMES = "imwplls", 100   # benchmarks/tracking.py's hand21 experiment (bounded, 20 steps)
BLOCKS = 2   # runs of the whole sequence per front end, in turn


def whole_frame(quick: bool) -> dict:
    """Ms per ``Tracker.step`` on hand21 (front end + compiled solve + host): the front end and its
    reference copy each in its own tracker, run over the whole sequence in turn (new, reference,
    new, reference: a steady tracker's caches, and load changes hit both alike), CPU and wall
    medians over the steady frames, and how far apart the tracked poses come out (the line
    weights differ by rounding, so the solves may too)."""
    seq = make_preset("full_hand_spread_flex", frames=20 if quick else FRAME_FRAMES, size=(320, 240))
    images = [[render_frame(seq.model, c, q, RenderConfig(antialias=3)).image for c in seq.cameras] for q in seq.q]
    config = TrackConfig().merged({"solver": "bounded", "fit": {"max_steps": 20}, "filter": {"theta": 0.85},
                                   "reextract": 0, "image": {"method": FRAME_METHOD}})
    dt = float(seq.times_s[1] - seq.times_s[0])
    makers = {"new": lambda: ImageFrontEnd(seq.model, seq.cameras, config.image),
              "reference": lambda: _ReferenceFrontEnd(seq.model, seq.cameras, config.image)}
    cpu = {k: [] for k in makers}
    wall = {k: [] for k in makers}
    split = {k: {"features": [], "solve": []} for k in makers}   # "solve": the rest of the step (CPU)
    tracked, iterations = {}, []
    for _ in range(BLOCKS):
        for name, make in makers.items():
            front = _CpuTimed(make())
            tracker = Tracker(seq.model, seq.cameras, front, config, dt_s=dt)
            state, qs = tracker.init(seq.q[0]), []
            for k, imgs in enumerate(images):
                c0, w0 = time.process_time(), time.perf_counter()
                state, rep = tracker.step(state, imgs, k, float(seq.times_s[k]))
                w1, c1 = time.perf_counter(), time.process_time()
                if k:  # a block's first frame compiles (the first block) or warms up
                    cpu[name].append(c1 - c0)
                    wall[name].append(w1 - w0)
                    split[name]["features"].append(front.cpu_s)
                    split[name]["solve"].append(c1 - c0 - front.cpu_s)
                    iterations.append(rep.iterations)
                qs.append(rep.q_filtered)
            tracked[name] = np.stack(qs)
    diff = float(np.max(np.abs(tracked["new"] - tracked["reference"])))
    out = {"method": FRAME_METHOD, "frames": len(images), "blocks": BLOCKS, "tracked_q_max_difference": diff,
           "solver_iterations_median": float(np.median(iterations)), "solver_iterations_max": int(max(iterations)),
           "max_steps": 20, "load_average_1min": os.getloadavg()[0]}
    for name in makers:
        out[f"{name}_cpu_median_ms"] = 1e3 * statistics.median(cpu[name])
        out[f"{name}_wall_median_ms"] = 1e3 * statistics.median(wall[name])
        out[f"{name}_frames_per_s_cpu"] = 1.0 / statistics.median(cpu[name])
        out[f"{name}_frames_per_s_wall"] = 1.0 / statistics.median(wall[name])
        for stage, v in split[name].items():
            out[f"{name}_{stage}_median_ms"] = 1e3 * statistics.median(v)
        err = np.abs(tracked[name] - np.asarray(seq.q))[:, np.asarray(seq.model.is_angle)]
        out[f"{name}_joint_error_mean_deg"] = float(np.degrees(err.mean()))
    return out


def print_whole_frame(r: dict) -> None:
    print(f"\nwhole hand21 frame (Tracker.step, {r['method']}, bounded 20 steps; median ms over {r['frames'] - 1} "
          f"frames x {r['blocks']} blocks each; load {r['load_average_1min']:.1f}); solver iterations median "
          f"{r['solver_iterations_median']:.0f}, max {r['solver_iterations_max']}")
    for name in ("new", "reference"):
        print(f"  {name:10s} frame CPU {r[f'{name}_cpu_median_ms']:6.2f} ms ({r[f'{name}_frames_per_s_cpu']:5.0f} "
              f"frames/s), wall {r[f'{name}_wall_median_ms']:6.2f} ms ({r[f'{name}_frames_per_s_wall']:5.0f} "
              f"frames/s): features {r[f'{name}_features_median_ms']:.2f}, solve and host "
              f"{r[f'{name}_solve_median_ms']:.2f} (CPU); mean joint error {r[f'{name}_joint_error_mean_deg']:.3f} deg")
    print(f"  largest difference of the tracked poses (any entry of q, rad or mm): {r['tracked_q_max_difference']:.2e}")


def print_versus_reference(rows: list[dict]) -> None:
    print("\nfront end vs its reference copy, hand21 320x240, one camera (median ms per frame; wall and CPU)")
    print(f"{'method':10s} {'new':>8s} {'ref':>8s} {'ref/new':>8s} {'new cpu':>8s} {'ref cpu':>8s} {'ref/new':>8s} "
          f"{'same':>5s} {'load':>5s}")
    for r in rows:
        print(f"{r['method']:10s} {r['new_median_ms']:8.2f} {r['reference_median_ms']:8.2f} "
              f"{r['reference_over_new']:8.2f} {r['new_cpu_median_ms']:8.2f} {r['reference_cpu_median_ms']:8.2f} "
              f"{r['reference_over_new_cpu']:8.2f} {'yes' if r['identical_features'] else 'NO':>5s} "
              f"{r['load_average_1min']:5.1f}")
    print("\nCPU ms per frame by stage (median; new / reference / reference over new)")
    stages = list(rows[0]["new_cpu_stages_median_ms"])
    print(f"{'method':10s} " + " ".join(f"{s:>22s}" for s in stages))
    for r in rows:
        new, ref = r["new_cpu_stages_median_ms"], r["reference_cpu_stages_median_ms"]
        print(f"{r['method']:10s} " + " ".join(
            f"{new.get(s, 0.0):6.2f} /{ref.get(s, 0.0):6.2f} /{ref.get(s, 0.0) / max(new.get(s, 0.0), 1e-9):5.2f}"
            for s in stages))


def _reference_metrics(rows: list[dict]) -> dict:
    out = {}
    for r in rows:
        key = f"features.hand21.320x240.{r['method']}"
        out[f"{key}.front_end_median_ms"] = r["new_median_ms"]
        out[f"{key}.reference_median_ms"] = r["reference_median_ms"]
        out[f"{key}.reference_over_new"] = r["reference_over_new"]
        out[f"{key}.front_end_cpu_median_ms"] = r["new_cpu_median_ms"]
        out[f"{key}.reference_over_new_cpu"] = r["reference_over_new_cpu"]
        out[f"{key}.identical_to_reference"] = r["identical_features"]
    return out


HEADER = (f"{'method':18s} {'condition':12s} {'links':>5s} {'valid':>6s} {'ang med':>8s} {'ang p95':>8s} "
          f"{'off med':>8s} {'off p95':>8s} {'<=1/1':>6s} {'tips':>5s} {'tip med':>8s}")


def _f(x, fmt):
    return format(x, fmt) if x is not None else format("-", ">" + fmt.split(".")[0].lstrip(">") or "8")


def _format_row(r: dict) -> str:
    return (f"{r['method']:18s} {r['condition']:12s} {r['links']:5d} {100 * r['valid_share']:5.1f}% "
            f"{_f(r['angle_median_deg'], '8.3f')} {_f(r['angle_p95_deg'], '8.3f')} "
            f"{_f(r['offset_median_px'], '8.3f')} {_f(r['offset_p95_px'], '8.3f')} "
            f"{100 * r['within_1deg_1px_share']:5.1f}% {100 * (r['tip_valid_share'] or 0):4.0f}% "
            f"{_f(r['tip_median_px'], '8.2f')}")


def print_tables(accuracy: list[dict], times: list[dict], peer: dict) -> None:
    print("\nper method (angle deg, offset px; '<=1/1': share of link slots valid and within 1 deg and 1 px)")
    for method in SEARCH_NAMES:
        t = next(r for r in times if r["method"] == method)
        print(f"\n{method}: {t['median_ms']:.2f} ms/frame (hand21 320x240; x{t['over_fastest']:.2f} of the fastest, "
              f"first call {t['first_call_ms']:.0f} ms)")
        print("  " + HEADER)
        for r in accuracy:
            if r["method"] == method:
                print("  " + _format_row(r))
    stages = sorted({k for r in times for k in r["stages_median_ms"]})
    print("\ntime per frame, hand21 320x240 (median ms; stages from Diagnostics.timings_s)")
    print(f"{'method':18s} {'total':>7s} {'x best':>6s} " + " ".join(f"{s:>10s}" for s in stages))
    for r in times:
        print(f"{r['method']:18s} {r['median_ms']:7.2f} {r['over_fastest']:6.2f} "
              + " ".join(f"{r['stages_median_ms'].get(s, 0.0):10.2f}" for s in stages))
    print(f"\nprofile sampling, {peer['profiles']} profiles x {peer['points']} points: one cv2.remap "
          f"{peer['one_remap_ms']:.3f} ms, one per profile {peer['remap_per_profile_ms']:.3f} ms "
          f"(x{peer['per_profile_over_one']:.1f})")


def _metrics(accuracy: list[dict], times: list[dict], peer: dict) -> dict:
    out = {}
    for r in times:
        out[f"features.hand21.320x240.{r['method']}.median_ms"] = r["median_ms"]
    for r in accuracy:
        cond = r["condition"].replace(". ", "_").replace("@", "_at_")
        for key in ("valid_share", "angle_median_deg", "angle_p95_deg", "offset_median_px", "offset_p95_px",
                    "within_1deg_1px_share", "tip_median_px"):
            out[f"features.{cond}.{r['method']}.{key}"] = r[key]
    out["features.sampling.one_remap_ms"] = peer["one_remap_ms"]
    out["features.sampling.remap_per_profile_ms"] = peer["remap_per_profile_ms"]
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a few frames per sequence; no JSON unless --out")
    parser.add_argument("--out", type=Path, default=None, help=f"JSON path (default {DEFAULT_OUT.relative_to(REPO)})")
    parser.add_argument("--vs-reference", action="store_true",
                        help=f"only the front end vs its reference copy (JSON: {VS_REFERENCE_OUT.relative_to(REPO)})")
    parser.add_argument("--sync-dispatch", action="store_true",
                        help="JAX's CPU calls on the calling thread (jaxhand.enable_sync_dispatch, as the CLI runs)")
    add_runtime_option(parser)
    args = parser.parse_args(argv)
    apply_runtime(args)
    if args.sync_dispatch:
        jh.enable_sync_dispatch()
    cv2.setNumThreads(1)
    env = bench_environment()
    print(f"feature benchmark: {env['cpu']} ({env['cpu_count']} cores, load {env['load_average_1min_start']:.1f}), "
          f"1 thread, opencv {env['opencv']}, shapely {env['shapely']}, "
          f"commit {env['commit']}{' (dirty)' if env['dirty'] else ''}")
    if args.vs_reference:
        vs_ref = versus_reference(args.quick)
        print_versus_reference(vs_ref)
        frame = whole_frame(args.quick)
        print_whole_frame(frame)
        data = {"benchmark": "features_vs_reference", "environment": env, "quick": args.quick,
                "front_end_vs_reference": vs_ref, "whole_frame": frame,
                "metrics": {**_reference_metrics(vs_ref), "features.hand21.whole_frame.frames_per_s_cpu":
                            frame["new_frames_per_s_cpu"]}}
        out = args.out if args.out is not None else (None if args.quick else VS_REFERENCE_OUT)
    else:
        print(HEADER)
        accuracy = evaluate(args.quick)
        times, peer = timing(args.quick)
        vs_ref = versus_reference(args.quick)
        print_tables(accuracy, times, peer)
        print_versus_reference(vs_ref)
        data = {"benchmark": "features", "environment": env, "quick": args.quick,
                "config": {"image": repr(ImageConfig()), "render": {"antialias": 5, "size": "320x240"},
                           "noise_sigma": NOISE_SIGMA, "occluded_share": list(OCCLUDED_SHARE)},
                "accuracy": accuracy, "timing": times, "sampling_peer": peer, "front_end_vs_reference": vs_ref,
                "metrics": {**_metrics(accuracy, times, peer), **_reference_metrics(vs_ref)}}
        out = args.out if args.out is not None else (None if args.quick else DEFAULT_OUT)
    if out is not None:
        write_json(data, out)
        print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
