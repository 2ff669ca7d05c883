"""Render benchmark: milliseconds per synthetic frame, ours against two peers, in one process.

For hand21 (15 pills, poses of the ``full_hand_spread_flex`` preset) and two_fingers (6 pills, poses
of ``two_finger_occlusion``), each seen by an orthographic camera (the preset's, tilted 45 degrees)
and by a perspective camera 600 mm away, at 320x240 and 640x480, both binary and shaded frames are
timed with :func:`jaxhand.render.render_frame` (forward kinematics, ray casting with a z-buffer,
shading, 8-bit output and the ground-truth maps: the whole per-frame cost).

Peers, on the same poses and cameras:

- ``naive``: the same ray-pill maths evaluated on every pixel for every pill (no bounding boxes),
  i.e. ``render_frame(..., use_bbox=False)``; its images equal ours bit for bit (checked).
- ``hull`` (binary only): thesis app. C.1, each pill's surface sampled (two spheres of 16 x 9
  points: a pill is the convex hull of its end spheres), projected, its 2D convex hull painted
  with ``cv2.fillConvexPoly``. Its silhouette's IoU with ours is reported next to its time; it
  produces no depth, link IDs or shading.

Everything runs on one core (OpenCV and BLAS threads set to 1). Times are medians over all poses
and repeats after a warm-up call; the first call (which compiles the jitted forward kinematics) is
reported separately.

Run ``python benchmarks/render.py`` (writes ``benchmarks/results/render.json``) or
``python benchmarks/render.py --quick`` for a smoke run (no JSON unless ``--out`` is given).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):  # one core, before numpy loads
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
from functools import partial  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import REPO, RESULTS, environment, first_call_seconds, time_call, write_json  # noqa: E402

import jaxhand as jh  # noqa: E402

jh.enable_x64()
from jaxhand.render import RenderConfig, fit_perspective, make_preset, render_frame  # noqa: E402
from jaxhand.render._frame import pill_geometry  # noqa: E402

DEFAULT_OUT = RESULTS / "render.json"
CASES = (("hand21", "full_hand_spread_flex"), ("two_fingers", "two_finger_occlusion"))
SIZES = ((320, 240), (640, 480))
MODES = ("binary", "shaded")
KINDS = ("orthographic", "perspective")


def _sphere_points(n_lon: int = 16, n_lat: int = 9) -> np.ndarray:
    lat = np.linspace(-np.pi / 2, np.pi / 2, n_lat)
    lon = np.linspace(0, 2 * np.pi, n_lon, endpoint=False)
    la, lo = np.meshgrid(lat, lon)
    return np.stack([np.cos(la) * np.cos(lo), np.cos(la) * np.sin(lo), np.sin(la)], -1).reshape(-1, 3)


_UNIT_SPHERE = _sphere_points()


def _project_numpy(camera, pts: np.ndarray) -> np.ndarray:
    """Pixels of world points with the camera's numbers in NumPy (no per-call JAX dispatch)."""
    p = pts @ np.asarray(camera.R, float).T + np.asarray(camera.t, float)
    if isinstance(camera, jh.Orthographic):
        return float(camera.scale) * p[..., :2] + np.asarray(camera.center, float)
    u = p @ np.asarray(camera.K, float).T
    return u[..., :2] / u[..., 2:3]


def hull_silhouette(model, camera, q) -> np.ndarray:
    """Thesis app. C.1 peer: per pill, the convex hull of its projected surface points, painted."""
    w, h = camera.size
    start, end, radius = pill_geometry(model, q)
    img = np.zeros((h, w), np.uint8)
    shift = 4  # sub-pixel vertices: OpenCV takes fixed-point coordinates with 4 fractional bits
    # Surface samples of every pill (its two end spheres), projected in one call: (links, 2 S, 2).
    pts = np.concatenate([start[:, None] + radius[:, None, None] * _UNIT_SPHERE,
                          end[:, None] + radius[:, None, None] * _UNIT_SPHERE], axis=1)
    px = np.round(_project_numpy(camera, pts) * (1 << shift)).astype(np.int32)
    for k in range(len(px)):  # the thesis paints one polygon per pill
        cv2.fillConvexPoly(img, cv2.convexHull(px[k]), 255, cv2.LINE_8, shift)
    return img


def _median_ms(fn, args_list, repeats: int) -> float:
    """Median milliseconds of one call of ``fn`` over every argument tuple, ``repeats`` passes."""
    samples = [time_call(lambda args=args: fn(*args))[0] for _ in range(repeats) for args in args_list]
    return 1e3 * statistics.median(samples)


def _cameras(model, preset, size):
    seq = make_preset(preset, frames=20, size=size)
    ortho = seq.cameras[0]
    pts = np.concatenate([np.asarray(jh.forward(model, q).link_end) for q in seq.q])
    centre = 0.5 * (pts.min(0) + pts.max(0))
    eye = centre + np.array([150.0, -250.0, -520.0])  # ~600 mm away, above and to the side
    (persp,) = fit_perspective(model, seq.q, size, [eye])
    return seq.q, {"orthographic": ortho, "perspective": persp}


def bench_environment() -> dict:
    """``_common.environment`` with this benchmark's extras: one thread, OpenCV, jaxhand."""
    env = environment(watched=("jaxhand/render", "benchmarks/render.py"))
    env.update(threads=1, opencv=cv2.__version__, jaxhand=jh.__version__)
    return env


def run(quick: bool) -> dict:
    cv2.setNumThreads(1)
    n_poses, repeats, naive_poses = (4, 1, 2) if quick else (20, 3, 5)
    results = []
    for model_name, preset in CASES:
        model = jh.builtin_model(model_name)
        for size in SIZES:
            qs, cams = _cameras(model, preset, size)
            poses = qs[np.linspace(0, len(qs) - 1, n_poses).round().astype(int)]
            for kind in KINDS:
                cam = cams[kind]
                for mode in MODES:
                    cfg = RenderConfig(mode=mode)
                    first_ms = 1e3 * first_call_seconds(partial(render_frame, model, cam, poses[0], cfg))
                    ours = _median_ms(render_frame, [(model, cam, q, cfg) for q in poses], repeats)
                    few = poses[np.linspace(0, n_poses - 1, naive_poses).round().astype(int)]
                    naive = _median_ms(partial(render_frame, use_bbox=False), [(model, cam, q, cfg) for q in few], 1)
                    same = all(np.array_equal(render_frame(model, cam, q, cfg).image,
                                              render_frame(model, cam, q, cfg, use_bbox=False).image) for q in few)
                    row = {"model": model_name, "camera": kind, "size": f"{size[0]}x{size[1]}", "mode": mode,
                           "ours_median_ms": ours, "ours_first_call_ms": first_ms, "naive_median_ms": naive,
                           "naive_over_ours": naive / ours, "naive_identical": same}
                    if mode == "binary":
                        row["hull_median_ms"] = _median_ms(hull_silhouette, [(model, cam, q) for q in poses], repeats)
                        ious = []
                        for q in poses:
                            a = render_frame(model, cam, q, cfg).image > 0
                            b = hull_silhouette(model, cam, q) > 0
                            ious.append((a & b).sum() / max((a | b).sum(), 1))
                        row["hull_iou_min"] = float(min(ious))
                        row["hull_over_ours"] = row["hull_median_ms"] / ours
                    results.append(row)
                    print(_format_row(row), flush=True)
    return {"benchmark": "render", "environment": bench_environment(), "quick": quick,
            "poses": n_poses, "repeats": repeats, "results": results,
            "metrics": {f"render.{r['model']}.{r['camera']}.{r['size']}.{r['mode']}.median_ms": r["ours_median_ms"]
                        for r in results}}


HEADER = (f"{'model':12s} {'camera':12s} {'size':8s} {'mode':7s} {'ours ms':>8s} {'first ms':>9s} "
          f"{'naive ms':>9s} {'naive/ours':>10s} {'hull ms':>8s} {'hull IoU':>8s}")


def _format_row(r: dict) -> str:
    hull = (f"{r['hull_median_ms']:8.2f} {r['hull_iou_min']:8.3f}" if "hull_median_ms" in r else f"{'-':>8s} {'-':>8s}")
    return (f"{r['model']:12s} {r['camera']:12s} {r['size']:8s} {r['mode']:7s} {r['ours_median_ms']:8.2f} "
            f"{r['ours_first_call_ms']:9.1f} {r['naive_median_ms']:9.1f} {r['naive_over_ours']:10.1f} {hull}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="few poses and repeats; no JSON unless --out")
    parser.add_argument("--out", type=Path, default=None, help=f"JSON path (default {DEFAULT_OUT.relative_to(REPO)})")
    args = parser.parse_args(argv)
    env = bench_environment()
    print(f"render benchmark: {env['cpu']} ({env['cpu_count']} cores, load {env['load_average_1min_start']:.1f}), "
          f"1 thread, numpy {env['numpy']}, opencv {env['opencv']}, "
          f"commit {env['commit']}{' (dirty)' if env['dirty'] else ''}")
    print(HEADER)
    data = run(args.quick)
    out = args.out if args.out is not None else (None if args.quick else DEFAULT_OUT)
    if out is not None:
        write_json(data, out)
        print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
