"""``jaxhand track`` (track a video or image folders) and ``jaxhand demo`` (render, track, report)."""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np

from ._errors import InputError
from .track import TrackConfig, load_track_config

__all__ = ["register", "run_demo", "print_summary", "track_config_from_args"]


def register(sub) -> None:
    p = sub.add_parser("track", help="track a model through a video or image folder(s)",
                       description="Track MODEL through INPUT (a video file or an image folder per camera, or a "
                                   "'jaxhand synth' folder, which also supplies cameras, model and ground truth).")
    p.add_argument("inputs", nargs="+", metavar="INPUT")
    p.add_argument("--model", help="built-in model name or model file (default: the synth folder's model)")
    p.add_argument("--init", default=None, help="initial pose: 'default', name=deg pairs, all values, or a .json "
                                                "(default: a synth folder's first ground-truth frame, else default)")
    p.add_argument("--camera", action="append", help="camera JSON file (once per camera, or one rig file)")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--config", metavar="TOML", help="tracking settings (a TrackConfig TOML file, see "
                                                    "jaxhand.save_track_config); the flags below override it")
    defaults = TrackConfig()   # --help shows the defaults of the config itself
    p.add_argument("--method",
                   help=f"feature search (see jaxhand.image.SEARCH_NAMES; default: {defaults.image.method})")
    p.add_argument("--solver", help=f"gn | gn_eta | lm_fixed | lm | bounded (default: {defaults.solver})")
    p.add_argument("--steps", type=int,
                   help=f"solver iterations per frame (1: thesis fast mode; default: {defaults.fit.max_steps})")
    p.add_argument("--theta", type=float, help="g-h-k discount factor per frame at --theta-rate frames/s (scaled to "
                                               f"the input's rate; default: {defaults.filter.theta})")
    p.add_argument("--theta-rate", type=float, help="frame rate (Hz) at which --theta holds; 0: --theta is per frame "
                                                    f"at any rate (default: {defaults.filter.theta_rate_hz})")
    p.add_argument("--no-filter", action="store_true", help="report the raw solve, predict with it")
    p.add_argument("--reacquire", metavar="DEG,...",
                   help="search again for a lost phalanx with its joint turned by these angles, e.g. 15,30,45 "
                        "(ImageConfig.reacquire_deg; default: "
                        f"{','.join(f'{a:g}' for a in defaults.image.reacquire_deg) or 'never'})")
    p.add_argument("--width-gain", type=float,
                   help="estimate the phalanx widths from the images with this gain per frame (thesis app. E; "
                        "0.05-0.2 when the model's radii may be off; 0: keep the model's; "
                        f"default: {defaults.image.width_gain})")
    p.add_argument("--fps", type=float, default=25.0, help="frame rate of image folders")
    p.add_argument("--truth", help="ground truth: a synth ground_truth.json (default: the synth folder's)")
    p.add_argument("--max-frames", type=int, help="stop after N frames")
    p.add_argument("--no-video", action="store_true", help="skip the overlay video")
    p.set_defaults(func=_track)
    d = sub.add_parser("demo", help="render a built-in sequence, track it, write and print the report")
    d.add_argument("--out", default="demo_out", help="output folder")
    d.add_argument("--preset", default="two_finger_occlusion", help="synthetic sequence to render and track")
    d.add_argument("--frames", type=int, default=80, help="frames to render (the motion is the same for any count)")
    d.set_defaults(func=_demo)


def _resolve(args):
    from .camera import load_camera
    from .io import open_frames
    from .model import get_model
    from .render import load_sequence

    inputs = [Path(p) for p in args.inputs]
    synth = None
    if len(inputs) == 1 and inputs[0].is_dir() and ((inputs[0] / "ground_truth.json").exists()
                                                   or (inputs[0] / "ground_truth.partial.jsonl").exists()):
        synth = load_sequence(inputs[0])
    model = get_model(args.model) if args.model else (synth.model if synth else None)
    if model is None:
        raise InputError("--model is required unless INPUT is a 'jaxhand synth' folder")
    if args.camera:
        cameras = tuple(c for path in args.camera for c in load_camera(path))
    elif synth is not None:
        cameras = synth.cameras
    else:
        raise InputError("--camera is required unless INPUT is a 'jaxhand synth' folder")
    if synth is not None:
        inputs = [Path(paths[0]).parent for paths in synth.image_paths]
    if len(inputs) != len(cameras):
        raise InputError(f"{len(cameras)} camera(s) but {len(inputs)} input(s): give one input per camera")
    fps = args.fps
    if synth is not None and len(synth.times_s) > 1:
        fps = 1.0 / float(synth.times_s[1] - synth.times_s[0])
    sources = open_frames(inputs, fps=fps)
    truth = None
    if args.truth:
        truth = load_sequence(Path(args.truth).parent).q
    elif synth is not None:
        truth = synth.q
    return model, cameras, sources, truth, synth


def track_config_from_args(args) -> TrackConfig:
    """The run's :class:`~jaxhand.TrackConfig`: ``--config`` (or the defaults), then every flag
    given on the command line on top of it."""
    config = load_track_config(args.config) if args.config else TrackConfig()
    changes: dict = {}
    for flag, section, key in (("solver", None, "solver"), ("steps", "fit", "max_steps"), ("theta", "filter", "theta"),
                               ("theta_rate", "filter", "theta_rate_hz"), ("method", "image", "method"),
                               ("width_gain", "image", "width_gain")):
        value = getattr(args, flag)
        if value is not None:
            (changes.setdefault(section, {}) if section else changes)[key] = value
    if args.no_filter:
        changes.setdefault("filter", {})["enabled"] = False
    if args.reacquire is not None:
        try:
            changes.setdefault("image", {})["reacquire_deg"] = [float(a) for a in args.reacquire.split(",")
                                                                if a.strip()]
        except ValueError:
            raise InputError(f"--reacquire: expected angles in degrees separated by commas, got {args.reacquire!r}"
                             ) from None
    return config.merged(changes) if changes else config


def _track(args) -> int:
    from .io import parse_pose
    from .track import track_sequence

    config = track_config_from_args(args)   # first: a bad settings file fails before any frame is read
    model, cameras, sources, truth, synth = _resolve(args)
    if args.init is None and synth is not None:
        q0 = np.asarray(synth.q[0])
    else:
        q0 = parse_pose(model, args.init)
    summary = track_sequence(model, cameras, sources, q0, args.out, config=config, truth=truth,
                             video=not args.no_video, max_frames=args.max_frames)
    print_summary(summary, Path(args.out))
    return 0


def print_summary(summary: dict, out: Path, file=None) -> None:
    """A short human-readable account of a tracking run and where its files are."""
    file = sys.stdout if file is None else file
    print(f"tracked {summary['frames']} frames of {summary['model']} "
          f"({summary.get('frames_per_second_end_to_end', 0):.1f} frames/s end to end, "
          f"{summary.get('frames_per_second_steady', 0):.1f} frames/s steady); "
          f"lost frames: {summary.get('lost_frames', 0)}", file=file)
    if "median_ms_per_stage" in summary:
        print("median ms per stage: " + ", ".join(f"{k} {v:.2f}" for k, v in summary["median_ms_per_stage"].items()),
              file=file)
    if "accuracy_filtered" in summary:
        a = summary["accuracy_filtered"]
        print(f"filtered joint error: mean {a['joint_error_deg']['mean']:.2f} deg, max "
              f"{a['joint_error_deg']['max']:.2f} deg; tip error mean {a['tip_error_px']['mean']:.2f} px", file=file)
    for name in ("angles.csv", "results.npz", "summary.json", "overlay.mp4", "angles.png"):
        if (out / name).exists():
            print(f"  {out / name}", file=file)


def run_demo(out: str | Path, preset: str = "two_finger_occlusion", frames: int = 80) -> dict:
    """Render ``preset``, track it with the thesis's proposed method and write the report."""
    from .render import RenderConfig, make_preset, write_sequence

    out = Path(out)
    seq = make_preset(preset, frames=frames)
    t0 = time.perf_counter()
    write_sequence(seq, out / "sequence", RenderConfig(antialias=3), overwrite=True, progress=False)
    print(f"rendered {frames} frames of {preset!r} in {time.perf_counter() - t0:.1f} s -> {out / 'sequence'}")
    from .cli import build_parser

    args = build_parser().parse_args(["track", str(out / "sequence"), "--out", str(out / "track")])
    _track(args)
    return json.loads((out / "track" / "summary.json").read_text())


def _demo(args) -> int:
    run_demo(args.out, args.preset, args.frames)
    return 0
