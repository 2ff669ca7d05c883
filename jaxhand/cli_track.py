"""``jaxhand track`` (track a video or image folders) and ``jaxhand demo`` (render, track, report)."""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np

from ._errors import InputError
from .score import FOREGROUNDS
from .track import PRESETS, TrackConfig, load_track_config

__all__ = ["register", "run_demo", "print_summary", "track_config_from_args"]


def register(sub) -> None:
    from .image import SEARCH_NAMES
    from .render import preset_names
    from .solve import SOLVERS

    p = sub.add_parser("track", help="track a model through a video or image folder(s)",
                       description="Track MODEL through INPUT (a video file or an image folder per camera, a "
                                   "'jaxhand synth' folder, or a dev-set sequence folder holding truth.json, such as "
                                   "data/mujoco/open_close; the last two also supply cameras, model, frame rate and "
                                   "ground truth).")
    p.add_argument("inputs", nargs="+", metavar="INPUT")
    p.add_argument("--model", help="built-in model name or model file (default: the synth or dev-set folder's model)")
    p.add_argument("--init", default=None, help="initial pose: 'default', name=deg pairs, all values, or a .json "
                                                "(default: a synth or dev-set folder's first ground-truth frame, "
                                                "else default)")
    p.add_argument("--camera", action="append", help="camera JSON file (once per camera, or one rig file)")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--overwrite", action="store_true", help="replace an earlier run in --out")
    p.add_argument("--resume", action="store_true",
                   help="continue an interrupted run in --out (same inputs and settings) after its last finished "
                        "frame; the tracker restarts there at the filtered pose with zero velocity")
    p.add_argument("--config", metavar="TOML", help="tracking settings (a TrackConfig TOML file, see "
                                                    "jaxhand.save_track_config); the flags below override it")
    p.add_argument("--preset", choices=tuple(PRESETS),
                   help="named settings on top of --config or the defaults: 'robust' for images jaxhand did not "
                        "draw (the silhouette term, six starts per frame; slower), 'robust-limits' the same with "
                        "soft limits inside the joint ranges and the weakest finger restarted after a doubtful "
                        "frame, 'robust-temporal' that with a temporal prior and the thumb held towards rest where one "
                        "camera cannot see it (a loss flag that means more), "
                        "'coupled' the DIP-PIP coupling alone (no drift on "
                        "long slow runs), 'thesis' the documents' tracker (default: thesis)")
    defaults = TrackConfig()   # --help shows the defaults of the config itself
    p.add_argument("--method",
                   help=f"feature search: {' | '.join(SEARCH_NAMES)} (default: {defaults.image.method})")
    p.add_argument("--solver", help=f"{' | '.join(SOLVERS)} (default: {defaults.solver})")
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
    p.add_argument("--foreground", choices=FOREGROUNDS,
                   help="which pixels show the hand, for the silhouette term and the image score: 'sequence' "
                        "learns a still camera's background from the sequence and the tracked poses (cluttered "
                        "backgrounds), 'threshold' a dark background, 'skin' colour video (the hand's colour fitted "
                        "in the first frame at the first pose), 'background' needs "
                        "[image.score] background_image in --config (default: the settings', "
                        f"{defaults.image.score.foreground}; 'auto' where a preset's silhouette term needs one)")
    p.add_argument("--masks", action="append", metavar="DIR",
                   help="a folder of foreground masks (once per camera; one image per frame, in the frames' order; "
                        "nonzero: the hand), e.g. from a segmentation network: read instead of --foreground's model "
                        "wherever a foreground is read (the silhouette term, the score, the support)")
    p.add_argument("--mask-rim", metavar="PX|auto", default=None,
                   help="how far (px) the foreground falls short of the hand's outline (negative: reaches beyond "
                        "it), taken out in the silhouette term ([image.silhouette_term] rim_px); 'auto': measured "
                        "at the initial pose, which must then be right, and written to summary.json. For masks "
                        "eroded or grown by a segmentation network (default: the settings', 0)")
    p.add_argument("--fps", type=float, default=25.0, help="frame rate of image folders")
    p.add_argument("--scale", type=float, default=1.0,
                   help="track the frames resized by this factor in (0, 1], the cameras and --landmarks with them "
                        "(e.g. 0.5 for a 1280x720 video: the searches' pixel settings suit a finger some 10-20 px "
                        "wide, and it runs faster); the outputs and the landmark agreement are at that size")
    p.add_argument("--truth", help="ground truth: a 'jaxhand synth' ground_truth.json or its folder, or a dev-set "
                                   "truth.json or its folder (data/mujoco/README.md; default: the input folder's)")
    p.add_argument("--max-frames", type=int, metavar="N", help="stop after N frames (N >= 1)")
    p.add_argument("--no-video", action="store_true", help="skip the overlay video")
    p.add_argument("--landmarks", metavar="FILE",
                   help="21-point landmarks of the first camera's input (MediaPipe JSON, or jaxhand's CSV/JSON: "
                        "jaxhand.landmarks): every frame's landmark pose is fitted first; the run starts from the "
                        "first frame's (--init, if given, wins) and restarts from a lost frame's")
    p.add_argument("--fuse-landmarks", type=float, metavar="WEIGHT",
                   help="add every frame's landmarks to its solve beside the edges, each point weighted by WEIGHT "
                        f"times its confidence (needs --landmarks; default: {defaults.landmarks.fuse_weight:g}, off)")
    p.add_argument("--no-restart", action="store_true", help="with --landmarks: never restart from the landmarks")
    p.add_argument("--restart-px", type=float, metavar="PX",
                   help="with --landmarks: also restart where the reported pose's landmark points lie a median of "
                        f"more than PX from the frame's landmarks (default: {defaults.landmarks.restart_px:g}, never)")
    p.set_defaults(func=_track)
    d = sub.add_parser("demo", help="render a built-in sequence, track it, write and print the report",
                       description="Render a synthetic sequence (PRESET) into OUT/sequence, track it with the default "
                                   "settings into OUT/track (replacing an earlier demo there) and print the report: "
                                   "accuracy against the exact ground truth, speed, lost frames.")
    d.add_argument("--out", default="demo_out", help="output folder (default: demo_out)")
    d.add_argument("--preset", default="two_finger_occlusion", choices=preset_names(), metavar="PRESET",
                   help=f"synthetic sequence to render and track: {', '.join(preset_names())} "
                        "(default: two_finger_occlusion)")
    d.add_argument("--frames", type=int, default=80,
                   help="frames to render (the motion is the same for any count; default: 80)")
    d.set_defaults(func=_demo)


def _is_devset(folder: Path) -> bool:
    return folder.is_dir() and (folder / "truth.json").is_file()


def _is_synth(folder: Path) -> bool:
    return folder.is_dir() and ((folder / "ground_truth.json").exists()
                                or (folder / "ground_truth.partial.jsonl").exists())


def _resolve(args, colour: bool = False):
    from .camera import load_camera, scale_camera
    from .io import load_devset, open_frames
    from .model import get_model
    from .render import load_sequence

    inputs = [Path(p) for p in args.inputs]
    synth = dev = None
    if len(inputs) == 1 and _is_synth(inputs[0]):
        synth = load_sequence(inputs[0])
    elif len(inputs) == 1 and _is_devset(inputs[0]):
        dev = load_devset(inputs[0], model=args.model or None)
    folder = synth if synth is not None else dev
    model = get_model(args.model) if args.model else (folder.model if folder is not None else None)
    if model is None:
        raise InputError("--model is required unless INPUT is a 'jaxhand synth' or a dev-set folder")
    if args.camera:
        cameras = tuple(c for path in args.camera for c in load_camera(path))
    elif folder is not None:
        cameras = tuple(folder.cameras)
    else:
        raise InputError("--camera is required unless INPUT is a 'jaxhand synth' or a dev-set folder")
    if folder is not None:
        inputs = [Path(paths[0]).parent for paths in folder.image_paths]
    if len(inputs) != len(cameras):
        raise InputError(f"{len(cameras)} camera(s) but {len(inputs)} input(s): give one input per camera")
    fps = args.fps
    if synth is not None and len(synth.times_s) > 1:
        fps = 1.0 / float(synth.times_s[1] - synth.times_s[0])
    elif dev is not None:
        fps = dev.fps
    if not (np.isfinite(args.scale) and 0 < args.scale <= 1):
        raise InputError(f"--scale: expected a factor in (0, 1] (e.g. 0.5 for half size), got {args.scale:g}")
    native = cameras[0].size
    if args.scale != 1.0:
        cameras = tuple(scale_camera(c, args.scale) for c in cameras)
    sources = open_frames(inputs, fps=fps, sizes=[c.size for c in cameras], scale=args.scale, colour=colour)
    truth = None
    if args.truth:
        truth = load_truth_arg(args.truth, model)
    elif synth is not None:
        truth = synth.q
    elif dev is not None:
        truth = dev.truth.q
    if truth is not None:
        n = len(sources[0]) if args.max_frames is None else min(len(sources[0]), args.max_frames)
        where = f"--truth {args.truth}" if args.truth else f"{inputs[0]}: the ground truth"
        if len(truth) < n:
            raise InputError(f"{where} has {len(truth)} frame(s) but the input has {n}: give the truth of this "
                             "input (or track fewer frames with --max-frames)")
    q_first = None if folder is None else (synth.q[0] if synth is not None else dev.truth.q[0])
    return model, cameras, sources, truth, q_first, native


def given_masks(folders, sources) -> list:
    """``--masks``: one :class:`~jaxhand.score.MaskForeground` per camera from its folder of mask
    images (natural order), matched to that camera's frames."""
    from .io import FrameSource
    from .score import MaskForeground

    if len(folders) != len(sources):
        raise InputError(f"--masks: {len(folders)} folder(s) for {len(sources)} camera(s): give one per camera")
    out = []
    for folder, source in zip(folders, sources):
        files = FrameSource(folder).files
        if files is None:
            raise InputError(f"--masks {folder}: expected a folder of mask images, not a video")
        try:
            out.append(MaskForeground((f.image for f in source), files))
        except InputError as err:
            raise InputError(f"--masks {folder}: {err}") from None
    return out


def load_truth_arg(path: str | Path, model) -> np.ndarray:
    """The (frames, n_q) ground truth of ``--truth PATH`` in ``model``'s q order: a ``jaxhand synth``
    ``ground_truth.json`` or its folder, or a dev-set ``truth.json`` (``data/mujoco/``'s format) or
    its folder.

    Raises:
        InputError: a missing or unreadable file, or the truth of another model (naming both).
    """
    from .io import load_truth
    from .render import load_sequence

    p = Path(path)
    if not p.exists():
        raise InputError(f"--truth {p}: no such file or folder")
    if _is_synth(p) or (p.is_file() and p.name in ("ground_truth.json", "ground_truth.partial.jsonl")):
        seq = load_sequence(p if p.is_dir() else p.parent)
        if tuple(seq.model.q_names) != tuple(model.q_names):
            raise InputError(f"--truth {p}: the truth of model {seq.model.name!r} ({', '.join(seq.model.q_names)}), "
                             f"but the tracked model is {model.name!r} ({', '.join(model.q_names)})")
        return np.asarray(seq.q)
    if _is_devset(p) or (p.is_file() and p.suffix == ".json"):
        try:
            return np.asarray(load_truth(p, model).q)
        except InputError as err:
            raise InputError(f"--truth: {err}") from None
    raise InputError(f"--truth {p}: neither a 'jaxhand synth' ground_truth.json (or its folder) nor a dev-set "
                     "truth.json (or its folder; data/mujoco/README.md)")


_FLAG_FIELDS = (("solver", "--solver", None, "solver"), ("steps", "--steps", "fit", "max_steps"),
                ("theta", "--theta", "filter", "theta"), ("theta_rate", "--theta-rate", "filter", "theta_rate_hz"),
                ("method", "--method", "image", "method"), ("width_gain", "--width-gain", "image", "width_gain"),
                ("fuse_landmarks", "--fuse-landmarks", "landmarks", "fuse_weight"),
                ("restart_px", "--restart-px", "landmarks", "restart_px"))


def _flag_error(flag: str, key: str, err: InputError) -> InputError:
    """``err`` of the config field behind ``flag``, reworded to name the flag."""
    msg = str(err)
    head, sep, rest = msg.partition(": ")
    if sep and " " not in head:   # "fit.max_steps: ..." or "ImageConfig.method: ..."
        msg = rest
    for name in (key, key.removesuffix("_hz")):
        if msg.startswith(name + " "):
            msg = msg[len(name) + 1:]
            break
    return InputError(f"{flag}: {msg}")


def _mask_rim(text: str) -> float | str:
    if text.strip() == "auto":
        return "auto"
    try:
        return float(text)
    except ValueError:
        raise InputError(f"--mask-rim: expected a number of px or 'auto', got {text!r}") from None


def track_config_from_args(args) -> TrackConfig:
    """The run's :class:`~jaxhand.TrackConfig`: ``--config`` (or the defaults) with ``--preset``
    on top, checked together, then every flag given on the command line on top of that."""
    if args.config:
        config = load_track_config(args.config, args.preset)
    else:
        config = TrackConfig().preset(args.preset) if args.preset else TrackConfig()
    changes: dict = {}
    for attr, flag, section, key in _FLAG_FIELDS:
        value = getattr(args, attr)
        if value is not None:
            one = {section: {key: value}} if section else {key: value}
            try:
                config.merged(one)
            except InputError as err:
                raise _flag_error(flag, key, err) from None
            (changes.setdefault(section, {}) if section else changes)[key] = value
    if args.no_filter:
        changes.setdefault("filter", {})["enabled"] = False
    if args.foreground is not None:
        changes.setdefault("image", {})["score"] = {"foreground": args.foreground}
    if args.no_restart:
        changes.setdefault("landmarks", {})["restart"] = False
    if args.mask_rim is not None:
        rim = _mask_rim(args.mask_rim)
        try:
            config.merged({"image": {"silhouette_term": {"rim_px": rim}}})
        except InputError as err:
            raise _flag_error("--mask-rim", "rim_px", err) from None
        changes.setdefault("image", {})["silhouette_term"] = {"rim_px": rim}
    if args.reacquire is not None:
        try:
            angles = [float(a) for a in args.reacquire.split(",") if a.strip()]
        except ValueError:
            raise InputError(f"--reacquire: expected angles in degrees separated by commas, got {args.reacquire!r}"
                             ) from None
        try:
            config.merged({"image": {"reacquire_deg": angles}})
        except InputError as err:
            raise _flag_error("--reacquire", "reacquire_deg", err) from None
        changes.setdefault("image", {})["reacquire_deg"] = angles
    return config.merged(changes) if changes else config


def _track(args) -> int:
    from ._errors import OutputExistsError
    from .cli import out_dir
    from .io import parse_pose
    from .track import image_front_end, track_sequence

    config = track_config_from_args(args)   # first: a bad settings file fails before any frame is read
    if args.max_frames is not None and args.max_frames < 1:
        raise InputError(f"--max-frames: expected a count >= 1, got {args.max_frames}")
    if args.resume and args.overwrite:
        raise InputError("--resume and --overwrite exclude each other: choose one")
    if (args.fuse_landmarks is not None or args.no_restart or args.restart_px is not None) and not args.landmarks:
        raise InputError("--fuse-landmarks, --no-restart and --restart-px act on landmarks: give --landmarks FILE")
    out = out_dir(args.out)
    model, cameras, sources, truth, q_first, native = _resolve(args, colour=config.image.score.reads_colour)
    landmarks = None
    if args.landmarks:
        from .landmarks import load_landmarks

        landmarks = load_landmarks(args.landmarks)
        if args.scale != 1.0:
            landmarks = landmarks.resized(native, cameras[0].size)
    if args.init is None and landmarks is not None:
        q0 = None   # the first frame's landmark pose
    elif args.init is None and q_first is not None:
        q0 = np.asarray(q_first)
    else:
        q0 = parse_pose(model, args.init)
    frontend = None
    if args.masks:
        if not (config.image.score.enabled or config.image.silhouette_term.enabled or config.support.enabled):
            raise InputError("--masks: these settings read no foreground (no score, silhouette term or support): "
                             "add --preset robust-temporal, or --foreground auto for the score")
        frontend = image_front_end(model, cameras, config.image, sources, args.max_frames,
                                   foregrounds=given_masks(args.masks, sources))
    try:
        summary = track_sequence(model, cameras, sources, q0, out, frontend, config=config, truth=truth,
                                 video=not args.no_video, max_frames=args.max_frames, overwrite=args.overwrite,
                                 resume=args.resume, landmarks=landmarks)
    except OutputExistsError as err:
        raise InputError(f"--out {err} (--resume continues an interrupted run, --overwrite replaces it)") from None
    if args.resume and "resumed" in summary:
        print(f"resumed after frame {summary['resumed']['after_frame']}: {summary['resumed']['state']}")
    print_summary(summary, out)
    return 0


def print_summary(summary: dict, out: Path, file=None) -> None:
    """A short human-readable account of a tracking run and where its files are."""
    file = sys.stdout if file is None else file
    print(f"tracked {summary['frames']} frames of {summary['model']} "
          f"({summary.get('frames_per_second_end_to_end', 0):.1f} frames/s end to end, "
          f"{summary.get('frames_per_second_steady', 0):.1f} frames/s steady); "
          f"lost frames: {summary.get('lost_frames', 0)}", file=file)
    if "landmarks" in summary:
        lm = summary["landmarks"]
        on = lm["agreement"]
        print(f"landmarks: {lm['restarts']} restart(s); on the fingers (all 21 points within {on['radius_px']:g} px) "
              f"in {on.get('frames_on_fingers', 0)} of {on['frames_compared']} frames, median "
              f"{on.get('median_px', float('nan')):.1f} px", file=file)
    if "review" in summary:
        r = summary["review"]
        print(f"review: {r['reviews']} jump(s) of over {r['jump_deg']:g} deg tracked back ({r['s']:.1f} s), "
              f"{r['met']} met the forward track, {r['frames_revised']} frame(s) revised", file=file)
    if "median_ms_per_stage" in summary:
        print("median ms per stage: " + ", ".join(f"{k} {v:.2f}" for k, v in summary["median_ms_per_stage"].items()),
              file=file)
    if "accuracy_filtered" in summary:
        a = summary["accuracy_filtered"]
        print(f"filtered joint error: mean {a['joint_error_deg']['mean']:.2f} deg, max "
              f"{a['joint_error_deg']['max']:.2f} deg; tip error mean {a['tip_error_px']['mean']:.2f} px", file=file)
    if "seen" in summary:
        seen = summary["seen"]
        hidden = ", ".join(seen["mostly_unseen"]) or "none"
        line = (f"joints not seen: {100 * seen['unseen_entries_share']:.0f}% of joint-frames, the priors alone placed "
                f"them; unseen on most frames: {hidden}")
        if seen.get("error_deg_seen") is not None and seen.get("error_deg_unseen") is not None:
            line += f"; error seen {seen['error_deg_seen']:.2f} deg, unseen {seen['error_deg_unseen']:.2f} deg"
        print(line, file=file)
    for name in ("angles.csv", "results.npz", "summary.json", "overlay.mp4", "angles.png"):
        if (out / name).exists():
            print(f"  {out / name}", file=file)
    for path in sorted(out.glob("overlay_from_*.mp4")):   # the video of a resumed run's rest
        print(f"  {path}", file=file)


def run_demo(out: str | Path, preset: str = "two_finger_occlusion", frames: int = 80) -> dict:
    """Render ``preset``, track it with the thesis's proposed method and write the report."""
    from .render import RenderConfig, make_preset, write_sequence

    out = Path(out)
    seq = make_preset(preset, frames=frames)
    t0 = time.perf_counter()
    write_sequence(seq, out / "sequence", RenderConfig(antialias=3), overwrite=True)   # a bar on a terminal
    print(f"rendered {frames} frames of {preset!r} in {time.perf_counter() - t0:.1f} s -> {out / 'sequence'}")
    from .cli import build_parser

    args = build_parser().parse_args(["track", str(out / "sequence"), "--out", str(out / "track"), "--overwrite"])
    _track(args)
    return json.loads((out / "track" / "summary.json").read_text())


def _demo(args) -> int:
    run_demo(args.out, args.preset, args.frames)
    return 0
