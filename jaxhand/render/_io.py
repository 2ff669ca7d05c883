"""Sequence folders: PNG frames, cameras, the model and a ground-truth JSON, written frame by frame.

Layout (one camera)::

    OUTDIR/README.md  ground_truth.json  model.json  camera.json  frame_0000.png ...

and with several cameras one folder each (``OUTDIR/cam0/frame_0000.png``, ``OUTDIR/cam0/camera.json``)
plus ``OUTDIR/cameras.json`` holding the whole rig. While frames are being written, the records go to
``ground_truth.partial.jsonl`` (first line: the header; then one line per frame, flushed), so an
interrupted run keeps what it wrote; at the end ``ground_truth.json`` (header + ``frames``) replaces it.
:func:`load_sequence` reads either.
"""

from __future__ import annotations

import json
import sys
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from .._errors import InputError, JaxhandError, OutputExistsError
from ..camera import camera_from_dict, camera_to_dict, save_camera
from ..kinematics import project_pose
from ..model import Model, load_model, save_model
from ._config import RenderConfig
from ._frame import RenderResult, render_frame
from ._presets import Sequence

__all__ = ["write_sequence", "load_sequence", "SequenceFolder", "FORMAT", "FORMAT_VERSION"]

FORMAT = "jaxhand-synth"
FORMAT_VERSION = 1
_GT = "ground_truth.json"
_PARTIAL = "ground_truth.partial.jsonl"
_PX_DECIMALS = 5  # 1e-5 px: far below any image measurement, keeps the JSON readable


def _cam_dir(n_cams: int, c: int) -> str:
    return "" if n_cams == 1 else f"cam{c}/"


def _unit(model: Model, i: int) -> str:
    return {"angle": "deg", "length": "mm", "quat": "1"}[model.q_kinds[i]]


def _q_to_json(model: Model, q: np.ndarray) -> dict:
    """Named state; angles in degrees, lengths in mm, the quaternion unitless."""
    vals = np.where(model.is_angle, np.degrees(q), q)
    return {n: float(v) for n, v in zip(model.q_names, vals)}


def _q_from_json(model: Model, d: dict, where: str) -> np.ndarray:
    missing = [n for n in model.q_names if n not in d]
    if missing:
        raise InputError(f"{where}: q lacks {missing}")
    vals = np.array([float(d[n]) for n in model.q_names])
    return np.where(model.is_angle, np.radians(vals), vals)


def _px(a) -> list:
    return np.round(np.asarray(a, float), _PX_DECIMALS).tolist()


def _header(seq: Sequence, config: RenderConfig) -> dict:
    m = seq.model
    n_cams = len(seq.cameras)
    joint_frames = [m.frame_names[f] for f in range(m.n_frames) if m.q_index[f] >= 0]
    cams = []
    for c, cam in enumerate(seq.cameras):
        cams.append({"name": f"cam{c}", "file": f"{_cam_dir(n_cams, c)}camera.json", "camera": camera_to_dict(cam)})
    return {
        "format": FORMAT, "format_version": FORMAT_VERSION, "name": seq.name, "description": seq.description,
        "model": {"name": m.name, "file": "model.json"},
        "n_frames": seq.n_frames, "image_size": list(seq.size),
        "q_names": list(m.q_names), "q_units": [_unit(m, i) for i in range(m.n_q)],
        "joint_names": joint_frames, "link_names": list(m.link_names), "tip_names": list(m.tip_names),
        "cameras": cams, "render": config.to_dict(),
    }


def _view_record(model: Model, camera, q: np.ndarray, image: str, res: RenderResult) -> dict:
    v = project_pose(model, camera, q)
    jp, jd = np.asarray(v.joints_px), np.asarray(v.joints_depth)
    sp, ep = np.asarray(v.link_start_px), np.asarray(v.link_end_px)
    ld, rp = np.asarray(v.link_depth), np.asarray(v.link_radius_px)
    tp, td = np.asarray(v.tips_px), np.asarray(v.tips_depth)
    joints = {model.frame_names[f]: {"px": _px(jp[f]), "depth_mm": float(jd[f])}
              for f in range(model.n_frames) if model.q_index[f] >= 0}
    links = {n: {"start_px": _px(sp[k]), "end_px": _px(ep[k]), "depth_mm": [float(ld[k, 0]), float(ld[k, 1])],
                 "radius_px": round(float(rp[k]), _PX_DECIMALS), "visible_fraction": float(res.visible_fraction[k]),
                 "visible_px": int(res.visible_px[k]), "alone_px": int(res.alone_px[k])}
             for k, n in enumerate(model.link_names)}
    tips = {n: {"px": _px(tp[k]), "depth_mm": float(td[k])} for k, n in enumerate(model.tip_names)}
    return {"image": image, "joints": joints, "tips": tips, "links": links}


def _write_png(path: Path, image: np.ndarray) -> None:
    try:
        ok = cv2.imwrite(str(path), image)
    except cv2.error as err:
        raise InputError(f"{path}: cannot write image ({err})") from err
    if not ok:
        raise InputError(f"{path}: cannot write image")


def _partial_records(out: Path) -> list[dict]:
    """The records of an interrupted run's partial log (header first), or [] if there is none."""
    partial = out / _PARTIAL
    if (out / _GT).exists() or not partial.is_file():
        return []
    lines = []
    for s in partial.read_text().splitlines():
        try:
            lines.append(json.loads(s))
        except json.JSONDecodeError:   # the last line of a run killed while writing it
            break
    return lines


def _prepare(out: Path, n_cams: int, overwrite: bool, resume: bool, header: dict) -> list[dict]:
    """Make ``out`` ready and return the frame records an interrupted run left to resume from."""
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: exists and is not a folder")
    if resume:
        records = _partial_records(out)
        if not records:
            why = "it is complete" if (out / _GT).exists() else "it holds no interrupted run"
            raise InputError(f"{out}: nothing to resume ({why})")
        if records[0] != json.loads(json.dumps(header)):
            diff = sorted(k for k in set(header) | set(records[0]) if records[0].get(k) != header.get(k))
            raise OutputExistsError(f"{out}: cannot resume: the interrupted run had other settings "
                                    f"({', '.join(diff)}); start again with the overwrite option")
        return records[1:]
    if out.is_dir() and any(out.iterdir()):
        if not overwrite:
            done = len(_partial_records(out)) - 1
            what = (f"holds an interrupted run ({done} of {header['n_frames']} frames): resume it or overwrite it"
                    if done >= 0 else "is not empty: choose another folder or overwrite its frames")
            raise OutputExistsError(f"{out}: {what}")
        # Remove the frames and maps of an earlier run so that a shorter run leaves no stale ones.
        for pattern in ("frame_*.png", "maps_*.npz", "cam*/frame_*.png", "cam*/maps_*.npz", _GT, _PARTIAL):
            for p in out.glob(pattern):
                p.unlink()
    out.mkdir(parents=True, exist_ok=True)
    for c in range(n_cams if n_cams > 1 else 0):
        (out / f"cam{c}").mkdir(exist_ok=True)
    return []


def write_sequence(seq: Sequence, out, config: RenderConfig | None = None, *, maps: bool = False,
                   overwrite: bool = False, resume: bool = False, progress: bool | None = None) -> Path:
    """Render every frame of a sequence into a folder with its ground truth.

    Frames, maps and ground-truth records are written as soon as each frame is rendered. An
    interruption (Ctrl-C, SIGTERM, a full disk) leaves the folder consistent: every frame whose
    record is in the partial log has its images, and no image lacks its record.

    Args:
        seq: the sequence (:func:`make_preset` or your own :class:`Sequence`).
        out: output folder (created; an existing non-empty one needs ``overwrite``).
        config: render settings (default shaded on black).
        maps: also save each view's link-ID (int16, -1 background) and depth (float32 mm, inf on
            background) maps as ``maps_NNNN.npz`` next to its frame.
        overwrite: allow a non-empty folder; frames and maps of an earlier run are deleted first.
        resume: continue an interrupted run of the same sequence and settings from its next frame.
        progress: show a progress bar (default: when stderr is a terminal).

    Returns:
        The path of ``ground_truth.json``.

    Raises:
        InputError: the folder is not usable, a file cannot be written, or there is nothing to
            resume; :class:`OutputExistsError` (an InputError) for a non-empty folder.
    """
    config = RenderConfig() if config is None else config
    out = Path(out)
    n_cams = len(seq.cameras)
    header = _header(seq, config)
    frames = _prepare(out, n_cams, overwrite, resume, header)
    try:
        if not frames:
            save_model(seq.model, out / "model.json")
            if n_cams == 1:
                save_camera(seq.cameras[0], out / "camera.json")
            else:
                save_camera(seq.cameras, out / "cameras.json")
                for c, cam in enumerate(seq.cameras):
                    save_camera(cam, out / f"cam{c}" / "camera.json")
            (out / "README.md").write_text(_readme(seq, config, maps))
        _render_frames(seq, out, config, maps, frames, header, progress)
        path = out / _GT
        tmp = path.with_suffix(".tmp")
        tmp.write_text(_dump_gt(header, frames))
        tmp.replace(path)
    except OSError as err:
        raise InputError(f"{out}: cannot write ({err.strerror or err}); the {len(frames)} finished frames are kept: "
                         "make room and resume") from err
    (out / _PARTIAL).unlink()
    return path


def _render_frames(seq: Sequence, out: Path, config: RenderConfig, maps: bool, frames: list, header: dict,
                   progress: bool | None) -> None:
    """Render the frames after ``frames`` (the records already written), appending each record to
    the partial log once its files exist; a frame cut short has its files removed."""
    from tqdm import tqdm

    n_cams = len(seq.cameras)
    show = sys.stderr.isatty() if progress is None else progress
    done = len(frames)
    with (out / _PARTIAL).open("w") as log, tqdm(
            total=seq.n_frames, initial=done, desc=f"synth {seq.name}", unit="frame", disable=not show) as bar:
        # Written whole again on resume, which drops a record cut off by the interruption.
        log.write("".join(json.dumps(r) + "\n" for r in [header, *frames]))
        log.flush()
        for i in range(done, seq.n_frames):
            q = np.asarray(seq.q[i], float)
            written: list[Path] = []
            try:
                views = []
                for c, cam in enumerate(seq.cameras):
                    name = f"{_cam_dir(n_cams, c)}frame_{i:04d}.png"
                    written.append(out / name)
                    res = render_frame(seq.model, cam, q, config, frame_index=i)
                    _write_png(out / name, res.image)
                    if maps:
                        written.append(out / f"{_cam_dir(n_cams, c)}maps_{i:04d}.npz")
                        np.savez_compressed(written[-1], link_id=res.link_id, depth=res.depth.astype(np.float32))
                    views.append(_view_record(seq.model, cam, q, name, res))
                rec = {"index": i, "time_s": float(seq.times_s[i]), "q": _q_to_json(seq.model, q), "views": views}
                log.write(json.dumps(rec) + "\n")
                log.flush()
            except BaseException:
                for p in written:   # this frame has no record: leave none of its files
                    p.unlink(missing_ok=True)
                raise
            frames.append(rec)
            bar.update(1)


def _dump_gt(header: dict, frames: list) -> str:
    """The ground-truth JSON with one header field per line and one frame record per line."""
    lines = [f"  {json.dumps(k)}: {json.dumps(v)}," for k, v in header.items()]
    body = ",\n".join(f"    {json.dumps(f)}" for f in frames)
    return "{\n" + "\n".join(lines) + '\n  "frames": [\n' + body + "\n  ]\n}\n"


def _readme(seq: Sequence, config: RenderConfig, maps: bool) -> str:
    n_cams = len(seq.cameras)
    w, h = seq.size
    where = ("frame_NNNN.png and camera.json in this folder" if n_cams == 1 else
             "camK/frame_NNNN.png and camK/camera.json per camera K; cameras.json holds the rig")
    lines = [
        f"# Synthetic sequence `{seq.name}`",
        "",
        f"{seq.description}",
        "",
        f"Written by `jaxhand synth` / `jaxhand.render.write_sequence` (format `{FORMAT}` version "
        f"{FORMAT_VERSION}): {seq.n_frames} frames of "
        f"{w}x{h} 8-bit grey PNG ({config.mode}), {n_cams} camera(s), model `{seq.model.name}`.",
        "",
        "## Files",
        "",
        f"- Images: {where}. Pixel (x, y) is column x, row y, origin at the centre of the top-left pixel.",
        "- `camera.json` / `cameras.json`: cameras in the format of `jaxhand.camera.save_camera` "
        "(`p_cam = R p_world + t`, camera x right, y down, z forward; depth = p_cam.z in mm).",
        "- `model.json`: the kinematic model (jaxhand model file).",
        "- `ground_truth.json`: the header (`q_names`, `q_units`, `joint_names`, `link_names`, `tip_names`, "
        "`cameras`, `render` settings) and `frames`, one record per frame:",
        "  - `index`, `time_s`; `q`: the true state by joint name (angles in degrees, lengths in mm, the palm "
        "quaternion unitless);",
        "  - `views`, one per camera in camera order: `image` (path relative to this folder); `joints`: "
        "projected centre (`px`) and `depth_mm` of every moving joint; `tips`: the same for every tip centre; "
        "`links`: per link the projected axis ends (`start_px`, `end_px`), `depth_mm` of both ends, `radius_px`, "
        "and the visibility: `visible_fraction` = `visible_px` / `alone_px`, the pixels showing the link over "
        "the pixels its pill covers when drawn alone (both inside the image). Neighbouring phalanges share "
        "their joint spheres, so an unoccluded link typically shows 0.6-0.95.",
    ]
    if maps:
        lines.append("- `maps_NNNN.npz` next to each frame: `link_id` (int16, -1 on background) and `depth` "
                     "(float32 mm, inf on background) at every pixel centre.")
    lines += ["", "Load it with `jaxhand.render.load_sequence(folder)`.", ""]
    return "\n".join(lines)


@dataclass(frozen=True)
class SequenceFolder:
    """A sequence folder read back by :func:`load_sequence`.

    Attributes:
        root: the folder.
        name, description: from the header.
        model: the model (from ``model.json``).
        cameras: one camera per view.
        q: (frames, n_q) ground-truth states (radians, mm).
        times_s: (frames,) frame times.
        image_paths: per camera, the frame paths in order.
        visible_fraction: (frames, cams, links) link visibility.
        complete: False when read from an interrupted run's partial log.
        ground_truth: the parsed JSON (header and frame records) for anything else.
    """

    root: Path
    name: str
    description: str
    model: Model
    cameras: tuple
    q: np.ndarray
    times_s: np.ndarray
    image_paths: tuple
    visible_fraction: np.ndarray
    complete: bool
    ground_truth: dict

    @property
    def n_frames(self) -> int:
        return len(self.q)

    def image(self, frame: int, camera: int = 0) -> np.ndarray:
        """The (H, W) uint8 image of a frame seen by a camera."""
        path = self.image_paths[camera][frame]
        img = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        if img is None:
            raise InputError(f"{path}: cannot read image")
        return img

    def sequence(self) -> Sequence:
        """The model, cameras and states as a :class:`Sequence` (to re-render or extend)."""
        return Sequence(self.name, self.model, self.cameras, self.q, self.times_s, self.description)


def load_sequence(folder) -> SequenceFolder:
    """Read a folder written by :func:`write_sequence` (or ``jaxhand synth``).

    A run interrupted before its end is read from its partial log (``complete`` is then False).

    Raises:
        InputError: a missing folder or file, or a ground-truth file that is not this format.
    """
    root = Path(folder)
    if not root.is_dir():
        raise InputError(f"{root}: not a folder")
    gt_path, partial = root / _GT, root / _PARTIAL
    try:
        if gt_path.is_file():
            gt = json.loads(gt_path.read_text())
            src, complete = gt_path, True
        elif partial.is_file():
            lines = [json.loads(s) for s in partial.read_text().splitlines() if s.strip()]
            if not lines:
                raise InputError(f"{partial}: empty")
            gt = {**lines[0], "frames": lines[1:]}
            src, complete = partial, False
        else:
            raise InputError(f"{root}: no {_GT} (is this a folder written by `jaxhand synth`?)")
    except json.JSONDecodeError as err:
        raise InputError(f"{root}: cannot parse the ground truth: {err}") from err
    if not isinstance(gt, dict) or gt.get("format") != FORMAT:
        raise InputError(f"{src}: field 'format' must be {FORMAT!r}")
    if gt.get("format_version") != FORMAT_VERSION:
        raise InputError(f"{src}: unsupported format_version {gt.get('format_version')!r} (expected {FORMAT_VERSION})")
    try:
        model = load_model(root / gt["model"]["file"])
        cameras = tuple(camera_from_dict(c["camera"], f"{src}: cameras[{k}]") for k, c in enumerate(gt["cameras"]))
        frames = gt["frames"]
        q = np.array([_q_from_json(model, f["q"], f"{src}: frames[{i}]") for i, f in enumerate(frames)])
        q = q.reshape(len(frames), model.n_q)
        times = np.array([float(f["time_s"]) for f in frames])
        paths = tuple(tuple(root / f["views"][c]["image"] for f in frames) for c in range(len(cameras)))
        vis = np.array([[[f["views"][c]["links"][n]["visible_fraction"] for n in model.link_names]
                         for c in range(len(cameras))] for f in frames]).reshape(len(frames), len(cameras),
                                                                                model.n_links)
    except (KeyError, IndexError, TypeError, ValueError) as err:
        if isinstance(err, JaxhandError):
            raise
        raise InputError(f"{src}: malformed ground truth ({type(err).__name__}: {err})") from err
    except OSError as err:
        raise InputError(f"{root}: cannot read {err.filename}: {err.strerror}") from err
    return SequenceFolder(root=root, name=gt.get("name", ""), description=gt.get("description", ""), model=model,
                          cameras=cameras, q=q, times_s=times, image_paths=paths, visible_fraction=vis,
                          complete=complete, ground_truth=gt)

