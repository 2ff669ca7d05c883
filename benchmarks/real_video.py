"""`jaxhand track --landmarks` on the real video (data/real/): how many frames the model sits on the fingers.

The hand is a right hand seen by a webcam of about 60 deg horizontal field of view
(data/real/README.md). The model: ``hand27_right`` calibrated to the video's MediaPipe landmarks
(the whole-sequence fit with one hand shape, :func:`jaxhand.landmarks.fit_landmark_sequence`),
whose per-frame poses are the landmark poses of every run (what ``fit_landmark_poses`` fits; one
fit shared by the runs). Runs, each from frame 0's landmark pose:

- ``a``: no restarts;
- ``b``: ``--landmarks`` with restarts on the tracker's loss flag;
- ``b15``: also restart where the pose's landmark points lie a median > 15 px off (``--restart-px 15``);
- ``c<W>``: ``b`` + ``--fuse-landmarks W``;
- ``c<W>nf``: ``c<W>`` with ``--no-filter`` (the raw solve reported and predicted from), for the
  first weight;
- ``r``: ``b`` with the robust preset and the foreground learned from the sequence
  (``image.score.foreground = "sequence"``: the video's camera is still); ``rc<W>``: ``r`` +
  ``--fuse-landmarks W``, for the first weight;
- ``l``: ``r`` with the robust-limits preset instead of robust; ``lc<W>``: ``l``
  + ``--fuse-landmarks W``, for the first weight;
- ``t``, ``tc<W>``: ``l``, ``lc<W>`` with the robust-temporal preset instead of robust-limits (the
  sequence foreground reads the video in colour);
- ``g``, ``gc<W>``: ``t``, ``tc<W>`` with ``image.silhouette_term.cover_gate_px = 10``: the arm's
  outline, far outside every pill, stops pulling the model down it;
- ``s``, ``sc<W>``: ``t``, ``tc<W>`` with the skin foreground fitted in the first frame
  (``image.score.foreground = "skin"``; the video is read in colour).

The runs with the learned or the skin foreground (``r``, ``l``, ``t``, ``g``, ``s`` and their fused runs) track
the calibrated model with a palm and a forearm (:func:`jaxhand.model.add_palm`): the foreground sees them.

``--scale S`` tracks the video resized by S (runs named ``<run>@S``), the camera with it
(:func:`jaxhand.camera.scale_camera`) and the landmark pixels the fused runs use; the agreement
is measured at the video's own size either way.

On the fingers: every one of the 21 projected model landmark points (joint centres, fingertips
on the skin, the wrist) within 15 px of MediaPipe's (``jaxhand.landmarks.landmark_agreement``).
Writes ``benchmarks/results/real_video.json``; the runs' folders (overlay videos) go to ``--out``.

    PYTHONPATH=. .venv/bin/python benchmarks/real_video.py [--frames N] [--weights 1,10] [--out DIR]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from pathlib import Path

import numpy as np
from _common import REPO, RESULTS, environment, format_table, load_average, write_json

from jaxhand.camera import scale_camera, scaled_pixels
from jaxhand.io import open_frames
from jaxhand.landmarks import LandmarkPoses, camera_from_fov, fit_landmark_sequence, landmark_agreement, load_landmarks
from jaxhand.landmarks import projected_landmarks as project
from jaxhand.model import add_palm, get_model
from jaxhand.track import FilterConfig, LandmarkConfig, TrackConfig, track_sequence

VIDEO = REPO / "data" / "real" / "human_hand_video.mp4"
LANDMARKS = REPO / "data" / "real" / "human_hand_video.mediapipe.json"


def calibrated_poses(frames: int) -> tuple:
    """The calibrated model and its :class:`LandmarkPoses` from one whole-sequence fit."""
    seq = load_landmarks(LANDMARKS).slice(0, frames)
    camera = camera_from_fov(seq.image_size, 60.0)
    t0 = time.perf_counter()
    fit = fit_landmark_sequence(get_model("hand27_right"), camera, seq.to_landmarks(), shape="auto")
    fit_s = time.perf_counter() - t0
    usable = seq.valid.sum(-1) >= 11
    err = np.linalg.norm(project(fit.model, camera, fit.q) - seq.px, axis=-1)[usable]
    poses = LandmarkPoses(frames=seq.frames, q=fit.q, usable=usable, px=seq.px, confidence=seq.confidence,
                          median_px=float(np.nanmedian(err)), source=seq.source, notes=seq.notes, fit="sequence",
                          fit_s=fit_s)
    return fit.model, camera, poses


def runs(weights) -> dict[str, TrackConfig]:
    out = {"a": LandmarkConfig(restart=False), "b": LandmarkConfig(), "b15": LandmarkConfig(restart_px=15.0)}
    out.update({f"c{w:g}": LandmarkConfig(fuse_weight=w) for w in weights})
    out = {k: TrackConfig(landmarks=v) for k, v in out.items()}
    if weights:
        out[f"c{weights[0]:g}nf"] = TrackConfig(landmarks=LandmarkConfig(fuse_weight=weights[0]),
                                                 filter=FilterConfig(enabled=False))
    robust = TrackConfig().preset("robust").merged({"image": {"score": {"foreground": "sequence"}}})
    out["r"] = dataclasses.replace(robust, landmarks=LandmarkConfig())
    if weights:
        out[f"rc{weights[0]:g}"] = dataclasses.replace(robust, landmarks=LandmarkConfig(fuse_weight=weights[0]))
    limits = TrackConfig().preset("robust-limits").merged({"image": {"score": {"foreground": "sequence"}}})
    out["l"] = dataclasses.replace(limits, landmarks=LandmarkConfig())
    if weights:
        out[f"lc{weights[0]:g}"] = dataclasses.replace(limits, landmarks=LandmarkConfig(fuse_weight=weights[0]))
    temporal = TrackConfig().preset("robust-temporal").merged({"image": {"score": {"foreground": "sequence"}}})
    out["t"] = dataclasses.replace(temporal, landmarks=LandmarkConfig())
    if weights:
        out[f"tc{weights[0]:g}"] = dataclasses.replace(temporal, landmarks=LandmarkConfig(fuse_weight=weights[0]))
    gated = temporal.merged({"image": {"silhouette_term": {"cover_gate_px": 10.0}}})
    out["g"] = dataclasses.replace(gated, landmarks=LandmarkConfig())
    if weights:
        out[f"gc{weights[0]:g}"] = dataclasses.replace(gated, landmarks=LandmarkConfig(fuse_weight=weights[0]))
    skin = TrackConfig().preset("robust-temporal").merged({"image": {"score": {"foreground": "skin"}}})
    out["s"] = dataclasses.replace(skin, landmarks=LandmarkConfig())
    if weights:
        out[f"sc{weights[0]:g}"] = dataclasses.replace(skin, landmarks=LandmarkConfig(fuse_weight=weights[0]))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=621, help="frames of the video to track (default: all 621)")
    ap.add_argument("--weights", default="1,10", help="--fuse-landmarks weights of the c runs")
    ap.add_argument("--runs", default=None,
                    help="comma-separated subset of a,b,b15,c<W>,c<W>nf,r,rc<W>,l,lc<W>,t,tc<W>,s,sc<W>")
    ap.add_argument("--out", default="/tmp/jaxhand_real_video", help="folder for the runs' outputs")
    ap.add_argument("--forearm-mm", type=float, default=40.0,
                    help="forearm length of the learned-foreground runs' palm model (default 40: the wrist bends)")
    ap.add_argument("--scale", type=float, default=1.0, help="track the video resized by this factor (default 1)")
    ap.add_argument("--extra", default="", help="a trial change (JSON) merged over every run's settings")
    ap.add_argument("--merge", action="store_true", help="add the runs to those of an earlier results file")
    args = ap.parse_args()
    weights = [float(w) for w in args.weights.split(",") if w]
    todo = runs(weights)
    if args.runs:
        todo = {k: v for k, v in todo.items() if k in args.runs.split(",")}
    if args.extra:   # merged over the chosen runs only: a change for the robust ones need not fit the others
        todo = {k: v.merged(json.loads(args.extra)) for k, v in todo.items()}
    load0 = load_average()
    model, camera, poses = calibrated_poses(args.frames)
    print(f"calibration + landmark poses: {poses.fit_s:.0f} s, median {poses.median_px:.2f} px")
    path = RESULTS / ("real_video.json" if args.frames == 621 else f"real_video_{args.frames}.json")
    earlier = json.loads(path.read_text())["runs"] if args.merge and path.exists() else {}
    results = {"frames": args.frames, "model": "hand27_right calibrated to the video's landmarks",
               "camera": "pinhole, 60 deg horizontal field of view", "on_fingers_rule":
               "all 21 projected model landmark points within 15 px of MediaPipe's",
               "landmark_fit": {"s": poses.fit_s, "median_px": poses.median_px}, "runs": earlier}
    alone = landmark_agreement(model, camera, poses, poses.frames, poses.q)
    results["landmark_fit"]["agreement"] = alone
    print(f"the landmark poses alone: on the fingers in {alone['frames_on_fingers']}/{alone['frames_compared']} frames")
    rows = []
    palm_model = add_palm(model, forearm_mm=args.forearm_mm)
    cam_s = scale_camera(camera, args.scale)
    poses_s = dataclasses.replace(poses, px=scaled_pixels(poses.px, camera.size, cam_s.size))
    for name, config in todo.items():
        lm = config.landmarks
        palm = config.image.score.foreground in ("sequence", "skin")
        sources = open_frames([VIDEO], fps=30.0, sizes=[cam_s.size], scale=args.scale,
                              colour=config.image.score.reads_colour)
        s = track_sequence(palm_model if palm else model, (cam_s,), sources, None, Path(args.out) / name, config=config,
                           landmarks=poses_s, max_frames=args.frames, overwrite=True)
        done = np.load(Path(args.out) / name / "results.npz")
        ag = landmark_agreement(model, camera, poses, done["frame"], done["q"])
        key = name if args.scale == 1.0 else f"{name}@{args.scale:g}"
        results["runs"][key] = {"config": {"restart": lm.restart, "restart_px": lm.restart_px,
                                            "fuse_weight": lm.fuse_weight, "filter": config.filter.enabled,
                                            "palm": palm and f"forearm {args.forearm_mm:g} mm",
                                            "scale": args.scale},
                                 "load_average": {"start": load0, "end": load_average()},
                                 "agreement": ag, "restarts": s["landmarks"]["restarts"],
                                 "restart_frames": s["landmarks"]["restart_frames"], "lost_frames": s["lost_frames"],
                                 "frames_per_second_steady": s["frames_per_second_steady"],
                                 "frames_per_second_end_to_end": s["frames_per_second_end_to_end"],
                                 "median_ms_per_stage": s["median_ms_per_stage"]}
        rows.append([key, lm.restart, f"{lm.restart_px:g}", f"{lm.fuse_weight:g}", config.filter.enabled,
                     f"{ag['frames_on_fingers']}/{ag['frames_compared']}", f"{ag['share_on_fingers']:.3f}",
                     f"{ag['median_px']:.1f}", f"{ag['share_points_within']:.3f}", s["landmarks"]["restarts"],
                     s["lost_frames"], f"{s['frames_per_second_steady']:.2f}"])
        print(format_table(rows, ["run", "restart", "restart_px", "fuse", "filter", "on fingers", "share", "median px",
                                  "points <= 15 px", "restarts", "lost", "frames/s"]))
        results["environment"] = environment()
        results["load_average"] = {"start": load0, "end": load_average()}
        write_json(results, path)


if __name__ == "__main__":
    main()
