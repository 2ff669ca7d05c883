"""Whole-sequence landmark fits on the MuJoCo dev set's truth points (``data/mujoco/``).

Input per sequence: the truth's 2-D points (``points_px``, per camera), the 21 points in
MediaPipe's order, plus Gaussian noise (``--noise-px``, seeded per sequence). The model is the
dev set's own (``models/hand.xml`` through :func:`jaxhand.io.load_devset`: the palm fixed in the
hand frame, the cameras of ``truth.json``), and the landmark map is told that this data's tips
are the distal caps' centres (``landmark_map(model, tips="cap_centre")``). The fit is
:func:`jaxhand.landmarks.fit_landmark_sequence` with the model's shape kept (``shape=None``).

Runs: every single-camera sequence with its camera; ``wave_two_cameras`` with both cameras and
with each alone. Per run: mean and max absolute error (deg) over the moving joints (those whose
truth moves) and the mean over all joints, the same mean for the start the sequence solve began
from, the median distance (px) of the fitted points to the noisy input points, and frames/s of
the whole fit (first call: compilation included, as a user's run).

    PYTHONPATH=. .venv/bin/python benchmarks/landmarks_devset.py [--only open_close] [--frames 40] [--seed 1]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import REPO, RESULTS, environment, format_table, load_average, write_json  # noqa: E402

from jaxhand.io import load_devset  # noqa: E402
from jaxhand.landmarks import (  # noqa: E402
    SequenceConfig,
    fit_landmark_sequence,
    landmark_map,
    make_landmarks,
    projected_landmarks,
)

SEQUENCES = ("open_close", "index_over_middle", "thumb_opposition", "fast_spread", "open_close_noise_clutter",
             "wave_two_cameras")


def noisy_points(seq, noise_px: float, seed: int) -> np.ndarray:
    """(cams, frames, 21, 2) truth points plus Gaussian noise, seeded by ``seed`` and the sequence."""
    rng = np.random.default_rng([seed, SEQUENCES.index(seq.name)])
    return seq.truth.points_px + rng.normal(0.0, noise_px, seq.truth.points_px.shape)


def fit_run(seq, px: np.ndarray, cams: list[int], frames: int, config: SequenceConfig, init: str) -> dict:
    """One whole-sequence fit of ``seq``'s first ``frames`` frames seen by cameras ``cams``."""
    m = seq.model
    lmap = landmark_map(m, tips="cap_centre")
    lm = make_landmarks(np.moveaxis(px[cams, :frames], 0, 1))
    rig = tuple(seq.cameras[c] for c in cams)
    t0 = time.perf_counter()
    fit = fit_landmark_sequence(m, rig, lm, shape=None, lmap=lmap, config=config, init=init)
    seconds = time.perf_counter() - t0
    q_true = seq.truth.q[:frames]
    moving = (np.ptp(q_true, axis=0) > 1e-6) & np.asarray(m.is_angle)
    err = np.degrees(np.abs(fit.q - q_true))
    err0 = np.degrees(np.abs(fit.q_init - q_true))
    dist = np.concatenate([np.linalg.norm(projected_landmarks(m, rig[k], fit.q, lmap=lmap) - px[c, :frames], axis=-1)
                           .ravel() for k, c in enumerate(cams)])
    per_joint = err[:, moving].mean(axis=0)
    names = np.array(m.q_names)[moving]
    worst = np.argsort(per_joint)[::-1][:3]
    return {"sequence": seq.name, "cameras": [seq.truth.camera_names[c] for c in cams], "frames": frames,
            "moving_joints": int(moving.sum()),
            "mean_deg": float(err[:, moving].mean()), "max_deg": float(err[:, moving].max()),
            "mean_all_joints_deg": float(err.mean()), "start_mean_deg": float(err0[:, moving].mean()),
            "median_px": float(np.median(dist)), "p95_px": float(np.percentile(dist, 95)),
            "frames_per_s": frames / seconds, "seconds": seconds, "timings_s": fit.timings_s,
            "iterations": int(fit.result.iterations), "converged": bool(fit.result.converged),
            "worst_joints_deg": {str(names[i]): float(per_joint[i]) for i in worst},
            "dip_pip_ratio": [float(x) for x in np.asarray(fit.result.dip_pip_ratio)]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default=None, help="comma-separated sequences (default: all)")
    ap.add_argument("--frames", type=int, default=None, help="first N frames of each sequence (default: all)")
    ap.add_argument("--noise-px", type=float, default=2.0, help="Gaussian noise on the truth points (px)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--smooth", type=float, default=30.0, help="SequenceConfig.smooth_px_per_rad")
    ap.add_argument("--accel", type=float, default=0.0, help="SequenceConfig.accel_px_per_rad")
    ap.add_argument("--dip-pip", type=float, default=11.5, help="SequenceConfig.dip_pip_px_per_rad")
    ap.add_argument("--dip-pip-ratio", type=float, default=2.0 / 3.0, help="SequenceConfig.dip_pip_ratio")
    ap.add_argument("--dip-pip-prior", type=float, default=20.0,
                    help="SequenceConfig.dip_pip_ratio_prior_px (> 0: the ratio is estimated)")
    ap.add_argument("--rest", type=float, default=3.0, help="SequenceConfig.branch_rest_px_per_rad (0: off)")
    ap.add_argument("--steps", type=int, default=300, help="SequenceConfig.max_steps")
    ap.add_argument("--init", default="auto", help="fit_landmark_sequence's init")
    ap.add_argument("--json", default="landmarks_devset.json", help="file in benchmarks/results/ ('' : none)")
    args = ap.parse_args()
    config = SequenceConfig(smooth_px_per_rad=args.smooth, accel_px_per_rad=args.accel, max_steps=args.steps,
                            dip_pip_px_per_rad=args.dip_pip, dip_pip_ratio=args.dip_pip_ratio,
                            dip_pip_ratio_prior_px=args.dip_pip_prior, branch_rest_px_per_rad=args.rest)
    load0 = load_average()
    runs = []
    for name in (args.only.split(",") if args.only else SEQUENCES):
        seq = load_devset(REPO / "data" / "mujoco" / name)
        frames = seq.n_frames if args.frames is None else min(args.frames, seq.n_frames)
        px = noisy_points(seq, args.noise_px, args.seed)
        for cams in ([[0, 1], [0], [1]] if len(seq.cameras) > 1 else [[0]]):
            r = fit_run(seq, px, cams, frames, config, args.init)
            runs.append(r)
            print(f"{name} {'+'.join(r['cameras'])}: mean {r['mean_deg']:.2f} deg, max {r['max_deg']:.1f}, "
                  f"median {r['median_px']:.2f} px, {r['seconds']:.0f} s", flush=True)
    rows = [[r["sequence"], "+".join(r["cameras"]), r["frames"], f"{r['mean_deg']:.2f}", f"{r['max_deg']:.1f}",
             f"{r['mean_all_joints_deg']:.2f}", f"{r['start_mean_deg']:.2f}", f"{r['median_px']:.2f}",
             f"{r['frames_per_s']:.1f}", r["iterations"]] for r in runs]
    print(format_table(rows, ["sequence", "cameras", "frames", "mean deg (moving)", "max deg (moving)",
                              "mean deg (all)", "start mean deg", "median px", "frames/s", "iterations"]))
    if args.json:
        write_json({"noise_px": args.noise_px, "seed": args.seed, "tips": "cap_centre", "init": args.init,
                    "config": {"smooth_px_per_rad": args.smooth, "accel_px_per_rad": args.accel,
                               "max_steps": args.steps, "dip_pip_px_per_rad": args.dip_pip,
                               "dip_pip_ratio": args.dip_pip_ratio, "dip_pip_ratio_prior_px": args.dip_pip_prior,
                               "branch_rest_px_per_rad": args.rest},
                    "frames_per_s_note": "first call per run, compilation included",
                    "runs": runs, "environment": environment(),
                    "load_average": {"start": load0, "end": load_average()}}, RESULTS / args.json)


if __name__ == "__main__":
    main()
