"""Running the tracker over a sequence and writing its report.

:func:`track_sequence` reads frames from one source per camera, steps the :class:`Tracker`,
writes every finished frame at once (``angles.csv``, ``results.npz`` checkpoints), draws the
overlay video (solver estimate in blue, filtered estimate in red, visibility windows in green,
like thesis fig. 6.1), and at the end writes the joint-angle plots (against ground truth when
given, like thesis figs. 6.2 and 6.6) and ``summary.json`` with accuracy and timing.
"""

from __future__ import annotations

import contextlib
import dataclasses
import sys
import time
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path

import cv2
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import ArrayLike, Float
from tqdm import tqdm

from .. import kinematics
from .._errors import InputError, JaxhandWarning
from ..camera import Camera, Perspective, as_rig
from ..image import ImageState
from ..io import FrameSource, ResultWriter, pose_to_dict
from ..kinematics import forward, project_pose
from ..model import Model
from ..score import foreground_for
from ..viz import VideoWriter, draw_view, plot_joint_angles
from ._config import TrackConfig, config_to_dict
from ._frontend import AbstractFrontEnd, ImageFrontEnd, image_front_end
from ._landmarks import LandmarkRun
from ._review import Review
from ._seen import scored_joints, seen_summary, unseen_links
from ._state import StepReport
from ._tracker import Tracker

__all__ = ["track_sequence", "accuracy_summary", "frame_tip_error_px", "loss_flag_quality"]

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
        dim = None if report.seen is None else unseen_links(model, report.seen)   # grey: not seen
        draw_view(bgr, project_pose(model, cam, report.q_filtered), RED, dim=dim)
        cv2.putText(bgr, f"{report.frame}", (4, 14), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (255, 255, 255), 1, cv2.LINE_AA)
        if report.lost:
            cv2.putText(bgr, "LOST", (4, 30), cv2.FONT_HERSHEY_SIMPLEX, 0.45, RED, 1, cv2.LINE_AA)
        tiles.append(bgr)
    h = max(t.shape[0] for t in tiles)
    return np.hstack([cv2.copyMakeBorder(t, 0, h - t.shape[0], 0, 0, cv2.BORDER_CONSTANT) for t in tiles])


@eqx.filter_jit
def _tips_px(model: Model, cameras, q):
    """(frames, n_q) states -> (cams, frames, tips, 2) projected tips."""
    tips = jax.vmap(lambda x: kinematics.pose(model, x).tips)(q)
    return jnp.stack([c.project(tips)[0] for c in cameras])


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
    rig = as_rig(cameras)
    q_est, q_truth = np.asarray(q_est), np.asarray(q_truth)
    tip_err = np.linalg.norm(np.asarray(_tips_px(model, rig, q_est)) - np.asarray(_tips_px(model, rig, q_truth)),
                             axis=-1)   # (cams, frames, tips): one batched call, not one per frame
    joints = scored_joints(model)
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


def frame_tip_error_px(model: Model, cameras: Camera | Sequence[Camera], q_est: Float[ArrayLike, "frames nq"],
                       q_truth: Float[ArrayLike, "frames nq"]) -> np.ndarray:
    """(frames,) the mean 2-D distance (px) of the estimated tips from the true ones, over tips and cameras."""
    rig = as_rig(cameras)
    est, true = (np.asarray(_tips_px(model, rig, np.asarray(q, float))) for q in (q_est, q_truth))
    return np.linalg.norm(est - true, axis=-1).mean(axis=(0, 2))


def loss_flag_quality(tip_error_px, confidence, lost, *, bad_px: float = 8.0, good_px: float = 3.0) -> dict:
    """How well the loss flag marks bad frames (issue 13): a frame is *flagged* when it is lost or
    its confidence is below 0.5; of the frames whose mean tip error exceeds ``bad_px`` the share
    flagged (should be high), of those below ``good_px`` the share flagged (should be low).
    Shares are None where no frame falls in the class."""
    err = np.asarray(tip_error_px, float)
    flagged = np.asarray(lost, bool) | (np.asarray(confidence, float) < 0.5)
    bad, good = err > bad_px, err < good_px

    def share(sel):
        return float(flagged[sel].mean()) if sel.any() else None

    return {"bad_px": bad_px, "good_px": good_px, "frames_bad": int(bad.sum()), "flagged_bad": share(bad),
            "frames_good": int(good.sum()), "flagged_good": share(good), "frames_flagged": int(flagged.sum())}


def track_sequence(model: Model, cameras, sources, q0, out_dir: str | Path, frontend: AbstractFrontEnd | None = None,
                   *, config: TrackConfig | None = None, truth: np.ndarray | None = None, video: bool = True,
                   progress: bool | None = None, max_frames: int | None = None, overwrite: bool = False,
                   resume: bool = False, proposals: Callable[[int], np.ndarray | None] | None = None,
                   landmarks=None) -> dict:
    """Track ``model`` through ``sources`` (one :class:`~jaxhand.io.FrameSource` per camera, or
    any iterables of :class:`~jaxhand.io.Frame` with ``fps`` and ``len``).

    An interruption (Ctrl-C; SIGTERM under the CLI) stops the run cleanly: every finished frame
    stays in ``angles.csv`` and ``results.npz``, ``summary.json`` says ``"interrupted": true`` and
    at which frame, the video is closed, and the :class:`KeyboardInterrupt` is raised again with
    a one-line account. ``resume=True`` continues such a run after its last finished frame: the
    tracker restarts at that frame's filtered pose with zero velocity (the summary's ``"resumed"``
    says so), and the video of the rest goes to ``overlay_from_NNNN.mp4``.

    With ``landmarks`` (:mod:`jaxhand.track._landmarks`) the run starts from the first frame's
    landmark pose when ``q0`` is None (a given ``q0`` wins), restarts from a lost frame's
    landmark pose (``config.landmarks.restart``) and, with ``config.landmarks.fuse_weight``,
    adds each frame's landmarks to its solve; ``summary.json`` reports the restarts and how the
    poses sit on the landmarks (``"landmarks"``).

    Args:
        q0: initial state (validated against the limits; ignored when resuming); None: the
            landmark pose of the first frame (needs ``landmarks``).
        out_dir: where ``angles.csv``, ``results.npz``, ``summary.json``, ``overlay.mp4`` and
            ``angles.png`` go (created if needed).
        frontend: the front end (default: an :class:`~jaxhand.ImageFrontEnd` with ``config.image``).
        config: the run's settings, written whole into ``summary.json`` (``"config"``).
        truth: optional (frames, n_q) ground truth for plots and the accuracy summary.
        progress: show a progress bar (default: when stderr is a terminal).
        max_frames: stop after this many frames (>= 1).
        overwrite: replace an earlier run in ``out_dir`` (else it is an error to mix runs).
        resume: continue the interrupted run in ``out_dir``.
        proposals: ``frame -> (k, n_q)`` extra starting poses of that frame (or None), e.g. a
            landmark fit; they join the hypotheses (:attr:`TrackConfig.hypotheses`). The summary
            counts the re-initialisations (frames not lost after a lost one) and the winning starts.
        landmarks: a :class:`~jaxhand.landmarks.LandmarkSequence` of the first camera (fitted
            here, ``config.landmarks.fit``) or its fitted :class:`~jaxhand.landmarks.LandmarkPoses`.

    Returns:
        The summary written to ``summary.json``.

    Raises:
        InputError: bad arguments, truth that does not fit, a folder that cannot be written
            (a full disk: the finished frames are kept); :class:`~jaxhand.OutputExistsError`
            for a folder holding an earlier run.
        KeyboardInterrupt: interrupted, after the files are finished.
    """
    config = TrackConfig() if config is None else config
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    cameras = as_rig(cameras)
    if max_frames is not None and max_frames < 1:
        raise InputError(f"max_frames: expected a count >= 1, got {max_frames}")
    if overwrite and resume:
        raise InputError("overwrite and resume exclude each other: choose one")
    n = len(sources[0]) if max_frames is None else min(len(sources[0]), max_frames)
    truth = None if truth is None else _check_truth(model, truth, n)
    fps = sources[0].fps
    frontend = image_front_end(model, cameras, config.image, sources, n) if frontend is None else frontend
    if isinstance(frontend, ImageFrontEnd):   # the report records the settings the run used
        config = dataclasses.replace(config, image=frontend.config)
    tracker = Tracker(model, cameras, frontend, config, dt_s=1.0 / fps)
    lm = None if landmarks is None else LandmarkRun(model, cameras[0], landmarks, config.landmarks, n)
    if q0 is None and not resume:
        if lm is None:
            raise InputError("q0: give an initial pose (or landmarks to start from)")
        q0 = lm.first_pose(0)
    if not resume:
        state = tracker.init(q0)
        _check_view(model, cameras, state.q_last)
        if isinstance(frontend, ImageFrontEnd):
            _check_fit(model, cameras, sources, state.q_last)
            if lm is None:
                _check_background(config, sources)
    if isinstance(frontend, ImageFrontEnd) and frontend.config.score.needs_colour:
        _check_colour(frontend.config.score, sources)
    with ResultWriter(out, model, overwrite=overwrite, resume=resume) as writer:
        resumed = None
        if resume:
            if writer.last_frame is None:
                raise InputError(f"{out}: nothing to resume (the earlier run finished no frame)")
            q0 = writer.last_q
            state = tracker.init(q0)
            resumed = {"after_frame": writer.last_frame,
                       "state": f"re-initialised at the filtered pose of frame {writer.last_frame} with zero "
                                "velocity (the filter's velocity and the front end's templates start afresh)"}
        return _run(model, cameras, sources, tracker, state, writer, out, n, fps, config, truth, video, progress,
                    q0, resumed, proposals, lm)


def _check_view(model: Model, cameras, q) -> None:
    """Every perspective camera sees the hand at ``q`` in front of it (not behind, not around it)."""
    pose = forward(model, q)
    ends = np.concatenate([np.asarray(pose.link_start), np.asarray(pose.link_end)])
    radius = np.concatenate([np.asarray(model.link_radius_mm)] * 2)
    for k, cam in enumerate(cameras):
        if not isinstance(cam, Perspective):
            continue
        centre = np.asarray(cam.to_camera(ends))[:, 2]
        depth = centre - radius
        if depth.min() <= 0:
            where = "behind" if centre.max() <= 0 else "around"
            i = int(np.argmin(depth)) % model.n_links
            raise InputError(f"camera {k} (perspective): the hand at the initial pose lies {where} the camera "
                             f"(link {model.link_names[i]!r} at {depth.min() + radius[i]:.0f} mm depth, "
                             f"radius {radius[i]:.0f} mm): check the camera's R and t (world to camera, mm; the "
                             "camera looks along its +z) or the initial pose (--init)")


def _first_images(sources) -> list | None:
    try:
        frames = next(iter(zip(*sources)))
    except (StopIteration, TypeError):
        return None
    return [f.image for f in frames]


#: The check of the initial pose knows dark backgrounds only: the darker of Otsu's two classes must
#: average below this grey level (the thesis's and the dev set's clean frames: 0), where the hand is
#: the bright class. On a lit room (a real video: a grey wall, a white ceiling) it says nothing.
DARK_BACKGROUND_GREY = 40.0


def _otsu(image) -> tuple[float, float] | None:
    """Otsu's threshold of a grey uint8 frame and the mean grey of its darker class (the
    background of a bright hand on a dark scene), or None for any other frame or a flat one."""
    if image is None or image.ndim != 2 or image.dtype != np.uint8 or int(image.max()) == int(image.min()):
        return None
    level, _ = cv2.threshold(image, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    return float(level), float(image[image <= level].mean())


def _fit_score(model: Model, cam, q, image: np.ndarray) -> float | None:
    """The share of points along the projected link axes that land on the image's foreground
    (brighter than Otsu's threshold; 0 when no point lands inside), or None when the image is
    flat or its background is not dark (:data:`DARK_BACKGROUND_GREY`)."""
    otsu = _otsu(image)
    if otsu is None or otsu[1] > DARK_BACKGROUND_GREY:
        return None
    level = otsu[0]
    pose = forward(model, q)
    f = np.linspace(0.15, 0.85, 5)[None, :, None]
    start, end = np.asarray(pose.link_start)[:, None], np.asarray(pose.link_end)[:, None]
    px = np.asarray(cam.project((start + f * (end - start)).reshape(-1, 3))[0])
    h, w = image.shape
    inside = (px[:, 0] >= 0) & (px[:, 0] <= w - 1) & (px[:, 1] >= 0) & (px[:, 1] <= h - 1)
    if not inside.any():
        return 0.0
    xy = np.round(px[inside]).astype(int)
    return float(np.mean(image[xy[:, 1], xy[:, 0]] > level)) * float(inside.mean())


def _check_fit(model: Model, cameras, sources, q) -> None:
    """Warn when a camera's projection of the initial pose does not fit its input's first frame
    (cameras and inputs in the wrong order, or the wrong camera file); a cheap check."""
    if not all(isinstance(s, FrameSource) for s in sources):   # an iterator would lose its first frame
        return
    images = _first_images(sources)
    if images is None or len(images) != len(cameras):
        return
    score = [[_fit_score(model, cam, q, img) if cam.size == img.shape[1::-1] else None for img in images]
             for cam in cameras]
    for k in range(len(cameras)):
        own = score[k][k]
        if own is None or own >= 0.5:
            continue
        better = [j for j in range(len(images)) if j != k and score[k][j] is not None and score[k][j] > own + 0.25]
        hint = (f"; it fits input {better[0]}'s frame better ({score[k][better[0]]:.0%}): are the inputs in the "
                "order of the cameras?") if better else ": check the camera file, the input and the initial pose"
        warnings.warn(f"camera {k}: only {own:.0%} of the model's projected link axes at the initial pose lie on "
                      f"the bright foreground of input {k}'s first frame{hint}", JaxhandWarning, stacklevel=3)


def _check_background(config: TrackConfig, sources) -> None:
    """Warn when settings that read no foreground (the defaults: the documents' edge tracker)
    meet a first frame whose background is not dark: that tracker was made for a bright hand on
    a dark scene, and on other images it slides off the fingers without knowing it."""
    image = config.image
    if image.silhouette_term.enabled or image.score.enabled or config.support.enabled:
        return
    if not all(isinstance(s, FrameSource) for s in sources):   # an iterator would lose its first frame
        return
    for k, frame in enumerate(_first_images(sources) or ()):
        grey = frame if frame is None or frame.ndim == 2 else cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
        otsu = _otsu(grey)
        if otsu is not None and otsu[1] > DARK_BACKGROUND_GREY:
            warnings.warn(f"input {k}: the first frame's background is not dark (its darker half averages grey "
                          f"{otsu[1]:.0f}); these settings are the documents' edge tracker, made for a hand on a "
                          "dark background: on other images use --preset robust-temporal (add --foreground "
                          "sequence over clutter; README: 'Which settings, and what to expect')",
                          JaxhandWarning, stacklevel=3)
            return


def _check_colour(section, sources) -> None:
    """A foreground that reads colour fails on grey first frames before any output is written
    (:func:`jaxhand.score.foreground_for` names the problem)."""
    for image in _first_images(sources) or ():
        if image is not None:
            foreground_for(section, image)


def _check_truth(model: Model, truth, n: int) -> np.ndarray:
    try:
        t = np.asarray(truth, float)
    except (TypeError, ValueError) as err:
        raise InputError(f"truth: cannot read as numbers ({err})") from None
    if t.ndim != 2 or t.shape[1] != model.n_q:
        raise InputError(f"truth: expected (frames, {model.n_q}) values for {model.name!r} "
                         f"({', '.join(model.q_names)}), got shape {t.shape}: is it the truth of another model?")
    if len(t) < n:
        raise InputError(f"truth: {len(t)} frame(s) but the input has {n}: give the truth of this input "
                         "(or --max-frames)")
    return t


class _Timings:
    """Per-frame stage timings of this session's frames, in growing float arrays."""

    def __init__(self):
        self.data: dict[str, np.ndarray] = {}
        self.n = 0
        self.hypotheses: dict[str, int] = {}   # the winning kind of start -> frames
        self.reinitialisations = 0

    def tally(self, report: StepReport) -> None:
        """Count the frame's winning start and whether it re-initialised the track."""
        self.hypotheses[report.hypothesis] = self.hypotheses.get(report.hypothesis, 0) + 1
        self.reinitialisations += bool(report.reinitialised)

    def add(self, timings) -> None:
        """One frame's stage timings; a stage that did not run on a frame (or first runs late:
        the step after a lost stretch) counts 0 s there."""
        for k, v in timings.items():
            col = self.data.setdefault(k, np.zeros(256))
            if len(col) <= self.n:
                col = self.data[k] = np.concatenate([col, np.zeros(max(len(col), self.n + 1))])
            col[self.n] = v
        self.n += 1

    def steady(self) -> dict[str, np.ndarray]:
        """Every stage's timings but the first frame's (which pays for compilation)."""
        lo = 1 if self.n > 1 else 0
        return {k: v[lo:self.n] for k, v in self.data.items()}


def _run(model, cameras, sources, tracker, state, writer, out, n, fps, config, truth, video, progress, q0,
         resumed, proposals=None, lm=None) -> dict:
    vw = None
    start = 0 if resumed is None else resumed["after_frame"] + 1
    timings = _Timings()
    count = 0
    frame = start   # the frame being worked on
    started = time.perf_counter()
    stop: BaseException | None = None
    bar = tqdm(total=n, initial=min(start, n), desc="tracking", unit="frame",
               disable=not (sys.stderr.isatty() if progress is None else progress))
    video_name = "overlay.mp4" if resumed is None else f"overlay_from_{start:04d}.mp4"
    review = Review(tracker, None if lm is None else lm.review_step(tracker))
    restarts: set[int] = set()
    emitted = 0

    def emit(images, rep: StepReport) -> None:   # a frame final: to the files and the video
        nonlocal vw, emitted
        emitted += 1
        marks = {} if lm is None else {"restarted": rep.frame in restarts}
        writer.write(rep.frame, rep.time_s, rep.q_filtered, rep.confidence, rep.lost, q_pred=rep.q_pred,
                     q_solved=rep.q_solved, cost=rep.cost, rms_px=rep.rms_px, iterations=rep.iterations,
                     **marks, **({} if rep.seen is None else {"seen": rep.seen}))
        if video:
            tile = _overlay(model, cameras, images, rep)
            if lm is not None:
                lm.draw(tile, rep.frame)
            if vw is None:
                vw = VideoWriter(out / video_name, fps, tile.shape[1::-1])
            vw.write(tile)
            if emitted == 1 or rep.frame % max(1, n // 4) == 0:
                cv2.imwrite(str(out / f"overlay_{rep.frame:04d}.png"), tile)

    try:
        for frames in zip(*sources):
            frame = frames[0].index
            if frame >= n:
                break
            if frame < start:
                continue
            bad = [f.error for f in frames if f.image is None]
            if bad:
                for held in review.flush():   # a review does not reach across a gap
                    emit(*held)
                writer.skip(frame, "; ".join(bad))
                print(f"jaxhand track: skipping frame {frame}: {'; '.join(bad)}", file=sys.stderr)
                bar.update(1)
                continue
            images = [f.image for f in frames]
            extra_starts = None if proposals is None else proposals(frame)
            if lm is None:
                state, rep = tracker.step(state, images, frame, frames[0].time_s, extra_starts)
            else:
                state, rep, restarted = lm.step(tracker, state, images, frame, frames[0].time_s, extra_starts)
                if restarted:
                    restarts.add(rep.frame)
            count += 1
            timings.add(rep.timings_s)
            timings.tally(rep)
            for held in review.push(state, images, rep):
                emit(*held)
            bar.update(1)
        else:
            frame = n
    except KeyboardInterrupt as err:
        stop = err
    except InputError as err:
        if not isinstance(err.__cause__, OSError):
            raise
        stop = err   # the folder cannot be written (a full disk): finish what can be finished
    finally:
        with contextlib.suppress(InputError):   # the frames still held by the review are final too
            for held in review.flush():
                emit(*held)
        bar.close()
        if vw is not None:
            vw.close()
    elapsed = time.perf_counter() - started
    summary = _summary(model, cameras, tracker, state, writer, out, fps, config, truth, q0, timings, count,
                       elapsed, resumed)
    if review.frames:
        summary["review"] = review.summary()
    if lm is not None:
        cols = writer.arrays()
        summary["landmarks"] = lm.summary(cols["frame"], cols["q"]) if len(writer) else lm.summary([], [])
    if stop is not None:
        summary.update({"interrupted": True, "interrupted_at_frame": int(frame),
                        "stopped_by": "interrupt" if isinstance(stop, KeyboardInterrupt) else str(stop)})
        done = f"{len(writer)} finished frame(s) in {out} are kept"
        if isinstance(stop, KeyboardInterrupt):
            with contextlib.suppress(InputError):   # a full disk too: the interruption is what to report
                writer.close(summary)
            raise KeyboardInterrupt(f"stopped at frame {frame}; the {done}: rerun with --resume to continue") \
                from None
        with contextlib.suppress(InputError):
            writer.close(summary)
        raise InputError(f"{stop}; stopped at frame {frame}: make room and rerun with --resume") from stop
    summary["interrupted"] = False
    return writer.close(summary)


def _summary(model, cameras, tracker, state, writer, out, fps, config, truth, q0, timings, count, elapsed,
             resumed) -> dict:
    cols = writer.arrays()
    summary: dict = {"frames": len(writer), "fps_input": fps, "config": config_to_dict(config),
                     "front_end": type(tracker.frontend).__name__,
                     "theta_per_frame": tracker.theta,
                     "initial_pose": pose_to_dict(model, q0)}
    if resumed is not None:
        summary["resumed"] = {**resumed, "frames_this_run": count}
    if count:
        steady = timings.steady()
        top = [k for k in steady if "." not in k]
        summary.update({
            "wall_s": elapsed,
            "frames_per_second_end_to_end": count / elapsed,
            "frames_per_second_steady": len(steady[top[0]]) / float(sum(steady[k].sum() for k in top)),
            "median_ms_per_stage": {k: 1e3 * float(np.median(steady[k])) for k in sorted(steady)},
        })
    if len(writer):
        lost = cols["lost"].astype(bool)
        summary.update({
            "frames_before_first_loss": int(cols["frame"][np.argmax(lost)]) if lost.any() else len(writer),
            "lost_frames": int(lost.sum()),
            "mean_confidence": float(np.mean(cols["confidence"])),
            "mean_iterations": float(np.mean(cols["iterations"])),
            "reinitialisations": timings.reinitialisations,
            "hypothesis_wins": dict(sorted(timings.hypotheses.items())),
        })
        idx, q_f, q_s, times = cols["frame"], cols["q"], cols["q_solved"], cols["time_s"]
        q_t = None if truth is None else np.asarray(truth)[idx]
        if q_t is not None:
            summary["accuracy_filtered"] = accuracy_summary(model, cameras, q_f, q_t)
            summary["accuracy_solved"] = accuracy_summary(model, cameras, q_s, q_t)
            summary["loss_flag"] = loss_flag_quality(frame_tip_error_px(model, cameras, q_f, q_t),
                                                     cols["confidence"], lost)
        if "seen" in cols:
            summary["seen"] = seen_summary(model, cols["seen"], q_f, q_t)
        plot_joint_angles(model, times, q_f, out / "angles.png", q_truth=q_t, q_raw=q_s, seen=cols.get("seen"))
    rims = getattr(tracker.frontend, "rims_px", None)
    if rims is not None:   # per camera, the silhouette term's rim_px measured at the first pose ("auto")
        summary["silhouette_rim_px_measured"] = [float(r) for r in rims]
    radius = state.frontend_state.radius_mm if isinstance(state.frontend_state, ImageState) else None
    if radius is not None:   # the front end's phalanx width estimate (ImageConfig.width_gain)
        summary["link_radius_mm_estimated"] = dict(zip(model.link_names, np.asarray(radius, float).tolist()))
        summary["link_radius_mm_model"] = dict(zip(model.link_names, np.asarray(model.link_radius_mm).tolist()))
    return summary
