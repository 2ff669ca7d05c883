"""Running the tracker over a sequence and writing its report.

:func:`track_sequence` reads frames from one source per camera, steps the :class:`Tracker`,
writes every finished frame at once (``angles.csv``, ``results.npz`` checkpoints), draws the
overlay video (solver estimate in blue, filtered estimate in red, visibility windows in green,
like thesis fig. 6.1), and at the end writes the joint-angle plots (against ground truth when
given, like thesis figs. 6.2 and 6.6) and ``summary.json`` with accuracy and timing.
"""

from __future__ import annotations

import dataclasses
import sys
import time
from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np
from jaxtyping import ArrayLike, Float
from tqdm import tqdm

from ..camera import Camera, as_rig
from ..image import ImageState
from ..io import ResultWriter, pose_to_dict
from ..kinematics import forward, project_pose
from ..model import Model
from ..viz import VideoWriter, draw_view, plot_joint_angles
from ._config import TrackConfig, config_to_dict
from ._frontend import AbstractFrontEnd, ImageFrontEnd
from ._tracker import StepReport, Tracker

__all__ = ["track_sequence", "accuracy_summary"]

BLUE, RED, GREEN = (255, 80, 0), (0, 0, 255), (0, 200, 0)


def _overlay(model: Model, cameras, images, report: StepReport) -> np.ndarray:
    tiles = []
    for c, (cam, img) in enumerate(zip(cameras, images)):
        bgr = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR) if img.ndim == 2 else img.copy()
        windows = report.diagnostics.windows
        if windows is not None and c < len(windows):
            for poly in windows[c]:
                pts = np.asarray(poly, float).reshape(-1, 2)
                if len(pts) >= 3:
                    cv2.polylines(bgr, [np.round(pts * 16).astype(np.int32)], True, GREEN, 1, cv2.LINE_AA, 4)
        draw_view(bgr, project_pose(model, cam, report.q_solved), BLUE, joints=False)
        draw_view(bgr, project_pose(model, cam, report.q_filtered), RED)
        cv2.putText(bgr, f"{report.frame}", (4, 14), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (255, 255, 255), 1, cv2.LINE_AA)
        if report.lost:
            cv2.putText(bgr, "LOST", (4, 30), cv2.FONT_HERSHEY_SIMPLEX, 0.45, RED, 1, cv2.LINE_AA)
        tiles.append(bgr)
    h = max(t.shape[0] for t in tiles)
    return np.hstack([cv2.copyMakeBorder(t, 0, h - t.shape[0], 0, 0, cv2.BORDER_CONSTANT) for t in tiles])


def accuracy_summary(model: Model, cameras: Camera | Sequence[Camera], q_est: Float[ArrayLike, "frames nq"],
                     q_truth: Float[ArrayLike, "frames nq"]) -> dict:
    """Joint errors (deg) and 2-D tip errors (px) of estimates against ground truth.

    The joint errors cover the revolute joints other than the palm's. The palm's own entries
    ("palm*": the mouse's planar palm, a free base's translation) get ``palm_error`` (deg or mm
    per entry), and a free base's orientation ``palm_rotation_deg``, the angle of the rotation
    between the estimated and the true palm (quaternions, either sign).
    """
    q_est, q_truth = np.asarray(q_est, float), np.asarray(q_truth, float)
    err = np.abs(q_est - q_truth)
    angle = model.is_angle
    err_user = np.where(angle, np.degrees(err), err)
    tip_err = []
    for q, qt in zip(q_est, q_truth):
        pe, pt = forward(model, q), forward(model, qt)
        tip_err.append([np.linalg.norm(np.asarray(c.project(pe.tips)[0]) - np.asarray(c.project(pt.tips)[0]), axis=-1)
                        for c in as_rig(cameras)])
    tip_err = np.asarray(tip_err)
    joints = [i for i, k in enumerate(model.q_kinds) if k == "angle" and not model.q_names[i].startswith("palm")]
    out = {
        "joint_error_deg": {"mean": float(err_user[:, joints].mean()), "max": float(err_user[:, joints].max()),
                            "per_joint_mean": {model.q_names[i]: float(err_user[:, i].mean()) for i in joints},
                            "per_joint_max": {model.q_names[i]: float(err_user[:, i].max()) for i in joints}},
        "tip_error_px": {"mean": float(tip_err.mean()), "max": float(tip_err.max())},
    }
    palm = [i for i, (n, k) in enumerate(zip(model.q_names, model.q_kinds)) if n.startswith("palm") and k != "quat"]
    if palm:
        out["palm_error"] = {"per_entry_mean": {model.q_names[i]: float(err_user[:, i].mean()) for i in palm},
                             "per_entry_max": {model.q_names[i]: float(err_user[:, i].max()) for i in palm}}
    if model.base_kind == "free":
        a, b = np.asarray(q_est, float)[:, :4], np.asarray(q_truth, float)[:, :4]
        cos = np.abs(np.sum(a * b, -1)) / (np.linalg.norm(a, axis=-1) * np.linalg.norm(b, axis=-1))
        rot = np.degrees(2.0 * np.arccos(np.clip(cos, 0.0, 1.0)))
        out["palm_rotation_deg"] = {"mean": float(rot.mean()), "max": float(rot.max())}
    return out


def track_sequence(model: Model, cameras, sources, q0, out_dir: str | Path, frontend: AbstractFrontEnd | None = None,
                   *, config: TrackConfig | None = None, truth: np.ndarray | None = None, video: bool = True,
                   progress: bool | None = None, max_frames: int | None = None) -> dict:
    """Track ``model`` through ``sources`` (one :class:`~jaxhand.io.FrameSource` per camera).

    Args:
        q0: initial state (validated against the limits).
        out_dir: where ``angles.csv``, ``results.npz``, ``summary.json``, ``overlay.mp4`` and
            ``angles.png`` go (created if needed).
        frontend: the front end (default: an :class:`~jaxhand.ImageFrontEnd` with ``config.image``).
        config: the run's settings, written whole into ``summary.json`` (``"config"``).
        truth: optional (frames, n_q) ground truth for plots and the accuracy summary.
        progress: show a progress bar (default: when stderr is a terminal).
        max_frames: stop after this many frames.

    Returns:
        The summary written to ``summary.json``.
    """
    config = TrackConfig() if config is None else config
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    cameras = as_rig(cameras)
    n = len(sources[0]) if max_frames is None else min(len(sources[0]), max_frames)
    fps = sources[0].fps
    frontend = ImageFrontEnd(model, cameras, config.image) if frontend is None else frontend
    if isinstance(frontend, ImageFrontEnd):   # the report records the settings the run used
        config = dataclasses.replace(config, image=frontend.config)
    tracker = Tracker(model, cameras, frontend, config, dt_s=1.0 / fps)
    state = tracker.init(q0)
    with ResultWriter(out, model) as writer:
        return _run(model, cameras, sources, tracker, state, writer, out, n, fps, config, truth, video, progress,
                    q0)


def _run(model, cameras, sources, tracker, state, writer, out, n, fps, config, truth, video, progress, q0) -> dict:
    vw = None
    reports: list[StepReport] = []
    first_loss = None
    started = time.perf_counter()
    bar = tqdm(total=n, desc="tracking", unit="frame", disable=not (sys.stderr.isatty() if progress is None
                                                                      else progress))
    try:
        for frames in zip(*sources):
            if frames[0].index >= n:
                break
            bad = [f.error for f in frames if f.image is None]
            if bad:
                writer.skip(frames[0].index, "; ".join(bad))
                print(f"jaxhand track: skipping frame {frames[0].index}: {'; '.join(bad)}", file=sys.stderr)
                bar.update(1)
                continue
            images = [f.image for f in frames]
            state, rep = tracker.step(state, images, frames[0].index, frames[0].time_s)
            reports.append(rep)
            if rep.lost and first_loss is None:
                first_loss = rep.frame
            writer.write(rep.frame, rep.time_s, rep.q_filtered, rep.confidence, rep.lost, q_pred=rep.q_pred,
                         q_solved=rep.q_solved, cost=rep.cost, rms_px=rep.rms_px, iterations=rep.iterations)
            if video:
                tile = _overlay(model, cameras, images, rep)
                if vw is None:
                    vw = VideoWriter(out / "overlay.mp4", fps, tile.shape[1::-1])
                vw.write(tile)
                if len(reports) == 1 or rep.frame % max(1, n // 4) == 0:
                    cv2.imwrite(str(out / f"overlay_{rep.frame:04d}.png"), tile)
            bar.update(1)
    finally:
        bar.close()
        if vw is not None:
            vw.close()
    elapsed = time.perf_counter() - started
    summary: dict = {"frames": len(reports), "fps_input": fps, "config": config_to_dict(config),
                     "front_end": type(tracker.frontend).__name__,
                     "theta_per_frame": tracker.theta,
                     "initial_pose": pose_to_dict(model, q0)}
    if reports:
        stages = sorted({k for r in reports for k in r.timings_s})
        steady = reports[1:] if len(reports) > 1 else reports  # the first frame pays for compilation
        summary.update({
            "wall_s": elapsed,
            "frames_per_second_end_to_end": len(reports) / elapsed,
            "frames_per_second_steady": len(steady) / sum(sum(v for k, v in r.timings_s.items() if "." not in k)
                                                         for r in steady),
            "median_ms_per_stage": {k: 1e3 * float(np.median([r.timings_s.get(k, 0.0) for r in steady]))
                                    for k in stages},
            "frames_before_first_loss": first_loss if first_loss is not None else len(reports),
            "lost_frames": int(sum(r.lost for r in reports)),
            "mean_confidence": float(np.mean([r.confidence for r in reports])),
            "mean_iterations": float(np.mean([r.iterations for r in reports])),
        })
        idx = np.array([r.frame for r in reports])
        q_f = np.stack([r.q_filtered for r in reports])
        q_s = np.stack([r.q_solved for r in reports])
        times = np.array([r.time_s for r in reports])
        q_t = None if truth is None else np.asarray(truth)[idx]
        if q_t is not None:
            summary["accuracy_filtered"] = accuracy_summary(model, cameras, q_f, q_t)
            summary["accuracy_solved"] = accuracy_summary(model, cameras, q_s, q_t)
        plot_joint_angles(model, times, q_f, out / "angles.png", q_truth=q_t, q_raw=q_s)
    radius = state.frontend_state.radius_mm if isinstance(state.frontend_state, ImageState) else None
    if radius is not None:   # the front end's phalanx width estimate (ImageConfig.width_gain)
        summary["link_radius_mm_estimated"] = dict(zip(model.link_names, np.asarray(radius, float).tolist()))
        summary["link_radius_mm_model"] = dict(zip(model.link_names, np.asarray(model.link_radius_mm).tolist()))
    return writer.close(summary)
