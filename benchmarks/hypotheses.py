"""Frames/s against the number of hypotheses (starts solved per frame), and their accuracy.

The hand21 sequence of thesis §6.2.2 (``full_hand_spread_flex``, one orthographic camera) is
rendered once; the tracker runs it with that experiment's settings in ``benchmarks/tracking.py``
(iMWPLLS front end, bounded solver, 20 steps; ``--method`` picks another search) for 1, 2, 4 and 8
starts per frame
(:class:`~jaxhand.track.HypothesisConfig`: the prediction alone; + the last solve; + 2 flips; + 6
flips), and once per count with exact features (``ExactFrontEnd``, 0.5 px noise), where the solve
is the whole cost. Per run: median ms per stage over the steady frames (the front end
``features``, the vmapped ``solve``, the front end's ``score``, the host's ``filter``, the
per-joint ``seen`` share), process CPU ms per frame, frames/s, and the mean joint error (deg);
the JSON also has the front end's parts
(``features.*``). Peers in the same process, one run
after the other. ``--experiments`` instead runs ``benchmarks/tracking.py``'s experiments (its
``--quick`` length) with the default settings and each ``--settings`` of ``benchmarks/devset.py``.

    .venv/bin/python benchmarks/hypotheses.py                      # -> results/hypotheses.json
    .venv/bin/python benchmarks/hypotheses.py --frames 20 --no-json
    .venv/bin/python benchmarks/hypotheses.py --coarse-steps 2 --no-json   # coarse to fine
    .venv/bin/python benchmarks/hypotheses.py --experiments --settings hyp4,hyp8+carry
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import tracking  # noqa: E402  (benchmarks/tracking.py: its experiments and settings)
from _common import RESULTS, add_runtime_option, apply_runtime, environment, format_table, write_json  # noqa: E402
from devset import SETTINGS  # noqa: E402

from jaxhand.render import RenderConfig, make_preset, render_frame  # noqa: E402
from jaxhand.track import ExactFrontEnd, ImageFrontEnd, TrackConfig, Tracker, accuracy_summary  # noqa: E402

#: Starts per frame -> the hypotheses section that gives that many.
COUNTS = {1: {}, 2: {"last_solve": True}, 4: {"last_solve": True, "flips": 2}, 8: {"last_solve": True, "flips": 6}}
STAGES = ("features", "solve", "score", "filter", "seen")


def _track(seq, images, frontend, config: TrackConfig) -> dict:
    tracker = Tracker(seq.model, seq.cameras, frontend, config, dt_s=float(seq.times_s[1] - seq.times_s[0]))
    state, reports, cpu = tracker.init(seq.q[0]), [], []
    for k, imgs in enumerate(images):
        c0 = time.process_time()
        state, rep = tracker.step(state, imgs, k, float(seq.times_s[k]))
        cpu.append(time.process_time() - c0)
        reports.append(rep)
    steady = reports[1:]   # frame 0 pays for compilation
    wall = [sum(v for key, v in r.timings_s.items() if "." not in key) for r in steady]
    acc = accuracy_summary(seq.model, seq.cameras, np.stack([r.q_filtered for r in reports]), seq.q[:len(reports)])
    parts = sorted({key for r in steady for key in r.timings_s if key.startswith("features.")})
    return {"starts": reports[-1].starts, "frames": len(reports), "fps": 1.0 / float(np.median(wall)),
            "cpu_ms_per_frame": 1e3 * float(np.median(cpu[1:])),
            "median_ms": {s: 1e3 * float(np.median([r.timings_s.get(s, 0.0) for r in steady])) for s in STAGES},
            "frontend_median_ms": {p: 1e3 * float(np.median([r.timings_s.get(p, 0.0) for r in steady]))
                                   for p in parts},
            "compile_s": sum(v for key, v in reports[0].timings_s.items() if "." not in key),
            "joint_error_mean_deg": acc["joint_error_deg"]["mean"], "lost_frames": sum(r.lost for r in reports)}


def speed(args) -> list[dict]:
    seq = make_preset("full_hand_spread_flex", frames=args.frames, size=args.size)
    images = [[render_frame(seq.model, c, q, RenderConfig(antialias=3)).image for c in seq.cameras] for q in seq.q]
    rows = []
    exp = next(e for e in tracking.EXPERIMENTS if e.name == "full_hand_spread_flex")
    for n, hyp in COUNTS.items():
        # tracking.py's settings for this sequence (iMWPLLS, bounded, 20 steps; --method WSSD: the
        # defaults' front end); coarse_steps does nothing to one start
        config = tracking.track_config(exp.solver, exp.steps, 0.85, exp.reextract).merged(
            {"hypotheses": {**hyp, "coarse_steps": args.coarse_steps}, "image": {"method": args.method}})
        for features in ("image", "exact"):
            frontend = (ImageFrontEnd(seq.model, seq.cameras, config.image) if features == "image" else
                        ExactFrontEnd(seq.model, seq.cameras, seq.q, noise_px=0.5, seed=0))
            r = {"hypotheses": n, "features": features, **_track(seq, images, frontend, config)}
            rows.append(r)
            print(f"{n} starts, {features}: {r['fps']:.1f} frames/s, solve {r['median_ms']['solve']:.2f} ms, "
                  f"features {r['median_ms']['features']:.2f} ms, {r['joint_error_mean_deg']:.2f} deg", flush=True)
    return rows


def experiments(args) -> list[dict]:
    rows = []
    for exp in tracking.EXPERIMENTS:
        seq = make_preset(exp.name, frames=args.frames, size=args.size)
        images = [[render_frame(seq.model, c, q, RenderConfig(antialias=3)).image for c in seq.cameras] for q in seq.q]
        base = tracking.track_config(exp.solver, exp.steps, 0.85, exp.reextract)
        for setting in ["default"] + args.settings.split(","):
            config = base.merged(SETTINGS[setting])
            frontend = ImageFrontEnd(seq.model, seq.cameras, tracking.image_config(exp.method, exp, args))
            r = {"sequence": exp.name, "setting": setting, **_track(seq, images, frontend, config)}
            rows.append(r)
            print(f"{exp.name} {setting}: {r['joint_error_mean_deg']:.2f} deg, {r['lost_frames']} lost, "
                  f"{r['fps']:.1f} frames/s", flush=True)
    return rows


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--frames", type=int, default=None, help="frames per sequence (default 40; 12 with --experiments)")
    p.add_argument("--size", default="320x240", help="image size WxH")
    p.add_argument("--experiments", action="store_true", help="benchmarks/tracking.py's experiments per setting")
    p.add_argument("--settings", default="hyp4,hyp8+carry", help="with --experiments: devset.py settings")
    p.add_argument("--coarse-steps", type=int, default=0, help="HypothesisConfig.coarse_steps of the runs with "
                   "several starts (default 0: every start solved in full)")
    p.add_argument("--method", default="imwplls", help="front-end search of the speed runs (default: the hand21 "
                   "experiment's, imwplls)")
    p.add_argument("--no-json", action="store_true")
    add_runtime_option(p)
    args = p.parse_args(argv)
    apply_runtime(args)
    args.frames = args.frames or (12 if args.experiments else 40)
    args.width_gain, args.reacquire = 0.0, None   # tracking.image_config's command-line overrides: none
    if args.experiments:
        rows = experiments(args)
        table = [[r["sequence"], r["setting"], f"{r['joint_error_mean_deg']:.2f}", str(r["lost_frames"]),
                  f"{r['fps']:.1f}"] for r in rows]
        print(format_table(table, ["sequence", "setting", "mean deg", "lost", "frames/s"]))
        name = "hypotheses_experiments.json"
    else:
        rows = speed(args)
        table = [[str(r["hypotheses"]), r["features"], f"{r['fps']:.1f}", f"{r['cpu_ms_per_frame']:.1f}",
                  *(f"{r['median_ms'][s]:.2f}" for s in STAGES), f"{r['compile_s']:.1f}",
                  f"{r['joint_error_mean_deg']:.2f}"] for r in rows]
        print(format_table(table, ["starts", "features", "frames/s", "CPU ms", *(f"{s} ms" for s in STAGES),
                                   "compile s", "mean deg"]))
        name = "hypotheses.json"
    if not args.no_json:
        write_json({"environment": environment(), "frames": args.frames, "size": args.size,
                    "coarse_steps": args.coarse_steps, "method": args.method, "runs": rows},
                   RESULTS / name)


if __name__ == "__main__":
    main()
