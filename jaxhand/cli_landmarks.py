"""``jaxhand fit-landmarks`` (fit a model to a landmark file) and ``jaxhand landmarks`` (run
MediaPipe on a video, in MediaPipe's own environment)."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from ._errors import InputError, JaxhandError

__all__ = ["register", "MEDIAPIPE_HELP"]

#: What ``jaxhand landmarks`` says when MediaPipe is not importable (one line).
MEDIAPIPE_HELP = (
    "mediapipe is not importable here; MediaPipe 0.10.21 (the last release that ships its hand model and "
    "runs offline) pins numpy<2 and its own opencv and jax, so it needs its own environment: run "
    "`make mediapipe` (or: python3.11 -m venv .venv-mediapipe && .venv-mediapipe/bin/pip install "
    "mediapipe==0.10.21 'numpy<2'), then: jaxhand landmarks VIDEO -o FILE --python .venv-mediapipe/bin/python")


def register(sub) -> None:
    p = sub.add_parser("fit-landmarks", help="fit a hand model to 21-point landmarks (MediaPipe JSON, CSV, JSON)",
                       description="Fit MODEL to every frame of LANDMARKS: frame 0 from several starts, each later "
                                   "frame from the previous, then the whole sequence as one problem with a smoothness "
                                   "term and one hand shape. Writes angles.csv, results.npz, summary.json, "
                                   "overlay.mp4 and angles.png into --out.")
    p.add_argument("landmarks", metavar="LANDMARKS")
    p.add_argument("--model", default="hand27", help="built-in model name or model file (default hand27)")
    p.add_argument("--camera", help="camera JSON file (default: a pinhole camera with --fov-deg)")
    p.add_argument("--fov-deg", type=float, default=60.0, help="horizontal field of view without --camera")
    p.add_argument("--image-size", help="WIDTHxHEIGHT when neither the file, --camera nor --video gives it")
    p.add_argument("--video", help="video to draw the overlay on (default: a blank canvas)")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--hand", choices=("auto", "left", "right"), default="auto",
                   help="the filmed hand (default: the file's handedness, else the model's); a hand of the other "
                        "side than the model's is fitted mirrored")
    p.add_argument("--model-hand", choices=("left", "right"), default=None,
                   help="handedness of --model (default: the model's own, else left as the built-in hands)")
    p.add_argument("--no-shape", action="store_true", help="keep the model's phalanx lengths and palm")
    p.add_argument("--smooth", type=float, default=20.0, help="smoothness weight, px per rad of change per frame")
    p.add_argument("--max-frames", type=int, default=None, help="fit only the first N frames")
    p.add_argument("--steps", type=int, default=60, help="most iterations of the whole-sequence solve")
    p.add_argument("--init", choices=("auto", "track", "paths"), default="auto",
                   help="start of the whole-sequence solve: 'paths' chooses each finger's mirror branch from the "
                        "whole sequence (slower), 'track' fits frame after frame, 'auto' is 'paths' (default)")
    p.add_argument("--save-model", help="write the fitted (calibrated) model to this .toml/.json file")
    p.add_argument("--no-video", action="store_true", help="skip the overlay video")
    p.set_defaults(func=run_fit_landmarks)

    q = sub.add_parser("landmarks", help="run MediaPipe Hands on a video and write its landmark JSON",
                       description="Run MediaPipe Hands (0.10.21) on VIDEO and write the landmark JSON that "
                                   "fit-landmarks reads. MediaPipe is never a jaxhand dependency: pass --python "
                                   "with the interpreter of its own environment (make mediapipe).")
    q.add_argument("video", metavar="VIDEO")
    q.add_argument("-o", "--out", required=True, help="output .json")
    q.add_argument("--python", help="python of a MediaPipe environment (default: this one, if it has mediapipe)")
    q.set_defaults(func=run_landmarks)


def run_landmarks(args) -> int:
    from .landmarks import mediapipe_producer

    video = Path(args.video)
    if not video.exists():
        raise InputError(f"{video}: no such video")
    if args.python:
        py = Path(args.python)
        if not py.exists():
            raise InputError(f"--python {py}: no such interpreter; {MEDIAPIPE_HELP}")
        rc = subprocess.call([str(py), mediapipe_producer.__file__, str(video), str(args.out)])
        if rc != 0:
            raise JaxhandError(f"the MediaPipe run in {py} failed (exit status {rc})")
        print(f"wrote {args.out}")
        return 0
    try:
        import mediapipe  # noqa: F401
    except ImportError:
        raise JaxhandError(MEDIAPIPE_HELP) from None
    rc = mediapipe_producer.produce(str(video), str(args.out))
    if rc == 0:
        print(f"wrote {args.out}")
    return rc


def _image_size(args, seq, cameras):
    if cameras is not None:
        return cameras[0].size
    if seq.image_size is not None:
        return seq.image_size
    if args.image_size:
        try:
            w, h = (int(v) for v in args.image_size.lower().split("x"))
        except ValueError as err:
            raise InputError(f"--image-size: expected WIDTHxHEIGHT, got {args.image_size!r}") from err
        return (w, h)
    if args.video:
        import cv2

        cap = cv2.VideoCapture(args.video)
        w, h = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
        cap.release()
        if w > 0 and h > 0:
            return (w, h)
    raise InputError("the image size is unknown: pass --camera, --image-size WxH or --video")


def _mirror_view(view, cx: float):
    import equinox as eqx
    import jax.numpy as jnp

    def mx(a):
        return jnp.asarray(a).at[..., 0].set(2 * cx - jnp.asarray(a)[..., 0])

    return eqx.tree_at(lambda v: (v.joints_px, v.link_start_px, v.link_end_px, v.tips_px), view,
                       (mx(view.joints_px), mx(view.link_start_px), mx(view.link_end_px), mx(view.tips_px)))


def run_fit_landmarks(args) -> int:
    import jax.numpy as jnp

    from .camera import load_camera, save_camera
    from .io import ResultWriter
    from .kinematics import project_pose
    from .landmarks import (
        BUILTIN_HANDEDNESS,
        SequenceConfig,
        camera_from_fov,
        fit_landmark_sequence,
        load_landmarks,
        projected_landmarks,
        save_calibrated_model,
    )
    from .model import get_model
    from .viz import draw_view, plot_joint_angles

    model = get_model(args.model)
    seq = load_landmarks(args.landmarks)
    if args.max_frames is not None:
        if args.max_frames < 1:
            raise InputError(f"--max-frames: expected >= 1, got {args.max_frames}")
        seq = seq.slice(0, args.max_frames)
    cameras = load_camera(args.camera) if args.camera else None
    if cameras is not None and len(cameras) != 1:
        raise InputError(f"--camera {args.camera}: fit-landmarks takes one camera, the file has {len(cameras)}")
    size = _image_size(args, seq, cameras)
    camera = cameras[0] if cameras is not None else camera_from_fov(size, args.fov_deg)
    model_hand = args.model_hand or (model.handedness if model.handedness in ("left", "right") else BUILTIN_HANDEDNESS)
    hand = seq.handedness if args.hand == "auto" else args.hand
    mirror = hand is not None and hand != model_hand
    cx = float((size[0] - 1) / 2)
    if mirror and cameras is not None:
        cx = float(np.asarray(camera.K)[0, 2]) if hasattr(camera, "K") else float(np.asarray(camera.center)[0])
    landmarks = seq.to_landmarks(mirror_cx=cx if mirror else None)
    if args.steps < 1:
        raise InputError(f"--steps: expected >= 1, got {args.steps}")
    config = SequenceConfig(max_steps=args.steps, smooth_px_per_rad=args.smooth)
    t0 = time.perf_counter()
    fit = fit_landmark_sequence(model, camera, landmarks, shape=None if args.no_shape else "auto", config=config,
                                init=args.init)
    fit_s = time.perf_counter() - t0

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    save_camera(camera, out / "camera.json")
    px_fit = projected_landmarks(fit.model, camera, fit.q)
    if mirror:
        px_fit[..., 0] = 2 * cx - px_fit[..., 0]
    err = np.linalg.norm(px_fit - seq.px, axis=-1)                      # NaN where not observed
    valid = np.isfinite(err)
    lo, hi = np.asarray(model.q_lower), np.asarray(model.q_upper)
    inside = bool(np.all((fit.q >= lo - 1e-9) & (fit.q <= hi + 1e-9)))
    fps = float(seq.fps or 30.0)
    with ResultWriter(out, model, checkpoint_every=max(len(seq), 1)) as writer:
        for t, frame in enumerate(seq.frames):
            conf = float(np.mean(seq.confidence[t]))
            lost = not valid[t].any()
            if lost:
                writer.skip(int(frame), "no landmarks")
            writer.write(int(frame), frame / fps, fit.q[t], conf, lost, q_init=fit.q_init[t], px_fit=px_fit[t],
                         px_obs=np.nan_to_num(seq.px[t], nan=-1.0), err_px=np.nan_to_num(err[t], nan=-1.0))
        summary = writer.close({
            "landmarks": seq.source, "frames": len(seq), "camera": "camera.json",
            "camera_source": args.camera or f"pinhole, {args.fov_deg:g} deg horizontal field of view",
            "hand": hand, "model_hand": model_hand, "mirrored": mirror,
            "median_px": float(np.median(err[valid])) if valid.any() else None,
            "p95_px": float(np.percentile(err[valid], 95)) if valid.any() else None,
            "mean_px": float(np.mean(err[valid])) if valid.any() else None,
            "frames_per_s": len(seq) / fit_s, "fit_s": fit_s, "timings_s": fit.timings_s,
            "init": fit.init,
            "within_limits": inside, "sequence_iterations": int(fit.result.iterations),
            "sequence_converged": bool(fit.result.converged), "cost": float(fit.result.cost),
            "start_cost": float(fit.result.start_cost), "first_frame_start_costs": fit.start_costs.tolist(),
            "best_start": fit.best_start,
            "shape": None if fit.shape is None else dict(zip(fit.shape.names, fit.theta.tolist())),
            "notes": seq.notes})
    plot_joint_angles(model, seq.frames / fps, fit.q, out / "angles.png", q_raw=fit.q_init,
                      title=f"{model.name} fitted to {seq.source} (thin: frame by frame)")
    if args.save_model:
        save_calibrated_model(fit.model, args.save_model)
    if not args.no_video:
        _write_overlay(out / "overlay.mp4", args.video, fit, camera, seq, px_fit, size, fps, mirror, cx,
                       draw_view, project_pose, jnp)
    print(f"fit-landmarks: {len(seq)} frames, median {summary['median_px']:.2f} px, p95 {summary['p95_px']:.2f} px, "
          f"{summary['frames_per_s']:.1f} frames/s -> {out}")
    return 0


def _write_overlay(path, video, fit, camera, seq, px_fit, size, fps, mirror, cx, draw_view, project_pose, jnp):
    import cv2

    from .viz import VideoWriter, draw_points

    cap = cv2.VideoCapture(video) if video else None
    if cap is not None and not cap.isOpened():
        raise InputError(f"--video {video}: cannot open")
    with VideoWriter(path, fps, tuple(size)) as vw:
        for t, frame in enumerate(seq.frames):
            img = None
            if cap is not None:
                if t == 0 and frame > 0:
                    cap.set(cv2.CAP_PROP_POS_FRAMES, int(frame))
                ok, img = cap.read()
                img = img if ok else None
            if img is None:
                img = np.full((size[1], size[0], 3), 40, np.uint8)
            view = project_pose(fit.model, camera, jnp.asarray(fit.q[t]))
            if mirror:
                view = _mirror_view(view, cx)
            draw_view(img, view, (255, 160, 0), outline=True, thickness=2)
            draw_points(img, seq.px[t], (0, 255, 0), 4)
            draw_points(img, px_fit[t], (0, 0, 255), 3)
            cv2.putText(img, f"frame {int(frame)}", (10, 30), cv2.FONT_HERSHEY_SIMPLEX, 0.8, (255, 255, 255), 2)
            vw.write(img)
    if cap is not None:
        cap.release()


if __name__ == "__main__":  # pragma: no cover
    from .cli import main

    sys.exit(main(["fit-landmarks", *sys.argv[1:]]))
