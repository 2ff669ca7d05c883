"""Development sets with ground truth: ``truth.json`` + image folders (``data/mujoco/``'s format).

A sequence folder holds ``truth.json`` (cameras, fps, and per frame the joint angles by name, 3-D
and 2-D points, visibility figures) and the frames it names (``frames/NNN.png``, or
``frames_cam0/`` and ``frames_cam1/`` for two cameras); ``data/mujoco/README.md`` describes every
field. :func:`load_truth` reads any such ``truth.json``; :func:`load_devset` reads a whole
sequence folder, with its model (the MJCF the truth names, unless another model is given).

Array layouts (NumPy, host side): ``q`` is (frames, n_q) in the model's q order;
per-camera figures lead with the camera axis, e.g. ``points_px`` is (cams, frames, points, 2) in
jaxhand's pixel convention (origin at the centre of the top-left pixel, which is the dev set's).
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any

import numpy as np

from .._errors import InputError, JaxhandError
from ..camera import Perspective
from ..model import Model, get_model, load_mjcf

__all__ = ["Truth", "DevSequence", "load_truth", "load_devset"]


@dataclasses.dataclass(frozen=True)
class Truth:
    """Ground truth of one sequence (host NumPy arrays; see the module docstring for layouts).

    Attributes:
        sequence: the sequence's name; ``description`` its text.
        fps: frames per second; ``time_s`` (frames,) the time of each frame.
        q_names: the q order of ``q`` (the model's, or the file's joint order without a model).
        q: (frames, n_q) joint values (rad; a model's base entries are the identity base pose).
        joint_names: the file's joint order; ``joint_angles`` (frames, joints) in that order (rad).
        cameras: one :class:`Perspective` per camera; ``camera_names`` their names.
        image_files: per camera, the frame files relative to the sequence folder.
        point_names: the 2-D/3-D points (``wrist``, ``<finger>_mcp`` ... ``<finger>_tip``).
        points_world: (frames, points, 3) mm in the hand (world) frame.
        points_cam: (cams, frames, points, 3) mm in each camera's frame.
        points_px: (cams, frames, points, 2) pixels (x, y).
        point_visible: (cams, frames, points) bool.
        phalanx_names: the rendered links of the figures below.
        visible_fraction, visible_fraction_excl_adjacent: (cams, frames, phalanges).
        edge_visible: (cams, frames, phalanges, 2) the [left, right] edge figures.
        isolated_pixels, visible_pixels: (cams, frames, phalanges) pixel counts.
        occluders: per camera, per frame, ``{phalanx: {geom: pixels}}``.
        checks, variant: the file's ``checks`` and ``variant`` entries, as read.
    """

    sequence: str
    description: str
    fps: float
    time_s: np.ndarray
    q_names: tuple[str, ...]
    q: np.ndarray
    joint_names: tuple[str, ...]
    joint_angles: np.ndarray
    cameras: tuple[Perspective, ...]
    camera_names: tuple[str, ...]
    image_files: tuple[tuple[str, ...], ...]
    point_names: tuple[str, ...]
    points_world: np.ndarray
    points_cam: np.ndarray
    points_px: np.ndarray
    point_visible: np.ndarray
    phalanx_names: tuple[str, ...]
    visible_fraction: np.ndarray
    visible_fraction_excl_adjacent: np.ndarray
    edge_visible: np.ndarray
    isolated_pixels: np.ndarray
    visible_pixels: np.ndarray
    occluders: tuple[tuple[dict[str, dict[str, int]], ...], ...]
    checks: dict[str, Any]
    variant: Any

    @property
    def n_frames(self) -> int:
        return len(self.time_s)

    @property
    def n_cameras(self) -> int:
        return len(self.cameras)

    def point_index(self, name: str) -> int:
        """Index of a point by name; the error lists the valid names."""
        try:
            return self.point_names.index(name)
        except ValueError:
            raise KeyError(f"{self.sequence}: no point {name!r}; valid: {', '.join(self.point_names)}") from None

    def tip_points(self, model: Model) -> np.ndarray:
        """Index into ``point_names`` of each of ``model``'s tips, in ``model.tip_names`` order.

        The dev set names a finger's tip point ``<finger>_tip`` and its links ``<finger>_...``
        (``index_distal``), so a tip link's finger is the first word of its name.

        Raises:
            KeyError: a tip whose finger has no ``_tip`` point.
        """
        return np.array([self.point_index(f"{n.split('_')[0]}_tip") for n in model.tip_names], dtype=int)


@dataclasses.dataclass(frozen=True)
class DevSequence:
    """A development-set sequence: model, cameras, frame files per camera and ground truth."""

    name: str
    folder: Path
    model: Model
    truth: Truth
    image_paths: tuple[tuple[Path, ...], ...]

    @property
    def cameras(self) -> tuple[Perspective, ...]:
        return self.truth.cameras

    @property
    def fps(self) -> float:
        return self.truth.fps

    @property
    def n_frames(self) -> int:
        return self.truth.n_frames

    @property
    def frame_folders(self) -> tuple[Path, ...]:
        """The image folder of each camera (for :func:`jaxhand.io.open_frames`)."""
        return tuple(paths[0].parent for paths in self.image_paths)


def _fail(src: str, msg: str) -> InputError:
    return InputError(f"{src}: {msg}")


def _camera(src: str, c: dict, size: tuple[int, int]) -> Perspective:
    convention = str(c.get("convention", "")).lower()
    if convention and "centre of the top-left pixel" not in convention and "center of the top-left pixel" \
            not in convention:
        raise _fail(src, f"camera {c.get('name')!r}: unsupported pixel convention {c.get('convention')!r} "
                    "(expected (0, 0) at the centre of the top-left pixel)")
    try:
        return Perspective(K=np.asarray(c["K"], float), R=np.asarray(c["R_world_to_cam"], float),
                           t=np.asarray(c["t_world_to_cam"], float), size=size)
    except KeyError as err:
        raise _fail(src, f"camera {c.get('name')!r}: missing field {err.args[0]!r}") from err
    except (TypeError, ValueError, JaxhandError) as err:
        raise _fail(src, f"camera {c.get('name')!r}: {err}") from err


def load_truth(path: str | Path, model: Model | None = None) -> Truth:
    """Read a dev-set ``truth.json`` (any sequence of ``data/mujoco/``'s format).

    Args:
        path: the ``truth.json`` file, or its sequence folder.
        model: the q order of ``Truth.q`` (joints looked up by name in ``joint_angles``); None
            gives the file's joint order.

    Raises:
        InputError: unreadable or malformed file, or a model joint the truth does not have; the
            message names the file and the field.
    """
    path = Path(path)
    if path.is_dir():
        path = path / "truth.json"
    src = str(path)
    try:
        t = json.loads(path.read_text())
    except OSError as err:
        raise _fail(src, f"cannot read truth file ({err.strerror})") from err
    except json.JSONDecodeError as err:
        raise _fail(src, f"cannot parse: {err}") from err
    try:
        return _truth(src, t, model)
    except KeyError as err:
        raise _fail(src, f"missing field {err.args[0]!r}") from err


def _truth(src: str, t: dict, model: Model | None) -> Truth:
    frames = t["frames"]
    if not isinstance(frames, list) or not frames:
        raise _fail(src, "field 'frames' must be a non-empty list")
    size = (int(t["image_size"]["width"]), int(t["image_size"]["height"]))
    cams = t["cameras"]
    n_cams = len(cams)
    cameras = tuple(_camera(src, c, size) for c in cams)
    joint_names = tuple(t["joint_names"])
    point_names = tuple(t["point_names"])
    phalanx_names = tuple(t.get("phalanx_names", ()))
    joint_angles = np.array([[f["joint_angles"][n] for n in joint_names] for f in frames], dtype=float)
    if model is None:
        q_names, q = joint_names, joint_angles
    else:
        q_names = model.q_names
        q = np.zeros((len(frames), model.n_q))
        if model.base_kind == "free":
            q[:, 0] = 1.0  # identity quaternion: the truth's world frame is the hand frame
        missing = [n for n in model.q_names[model.n_base_q:] if n not in joint_names]
        if missing:
            raise _fail(src, f"model {model.name!r} has joints the truth does not: {', '.join(missing)} "
                        f"(the truth's joints: {', '.join(joint_names)})")
        for i, n in enumerate(model.q_names[model.n_base_q:], start=model.n_base_q):
            q[:, i] = joint_angles[:, joint_names.index(n)]

    def per_cam(key: str) -> list[str]:
        return [f"{key}_cam{c}" for c in range(n_cams)] if n_cams > 1 else [key]

    def points(key: str, f: dict) -> list:
        return [f[key][n] for n in point_names]

    def phal(key: str, field: str, f: dict) -> list:
        return [f[key][n][field] for n in phalanx_names]

    file_keys = per_cam("file")
    pk, ck, vk, hk = per_cam("points_px"), per_cam("points_cam"), per_cam("point_visible"), per_cam("phalanges")
    fps = float(t["fps"])
    time_s = np.array([f.get("time_s", i / fps) for i, f in enumerate(frames)], dtype=float)
    return Truth(
        sequence=str(t.get("sequence", Path(src).parent.name)), description=str(t.get("description", "")),
        fps=fps, time_s=time_s, q_names=tuple(q_names), q=q, joint_names=joint_names, joint_angles=joint_angles,
        cameras=cameras, camera_names=tuple(str(c.get("name", f"cam{k}")) for k, c in enumerate(cams)),
        image_files=tuple(tuple(f[k] for f in frames) for k in file_keys),
        point_names=point_names,
        points_world=np.array([points("points_world", f) for f in frames], dtype=float),
        points_cam=np.array([[points(k, f) for f in frames] for k in ck], dtype=float),
        points_px=np.array([[points(k, f) for f in frames] for k in pk], dtype=float),
        point_visible=np.array([[points(k, f) for f in frames] for k in vk], dtype=bool),
        phalanx_names=phalanx_names,
        visible_fraction=np.array([[phal(k, "visible_fraction", f) for f in frames] for k in hk], dtype=float),
        visible_fraction_excl_adjacent=np.array(
            [[phal(k, "visible_fraction_excl_adjacent", f) for f in frames] for k in hk], dtype=float),
        edge_visible=np.array([[phal(k, "edge_visible", f) for f in frames] for k in hk], dtype=float),
        isolated_pixels=np.array([[phal(k, "isolated_pixels", f) for f in frames] for k in hk], dtype=int),
        visible_pixels=np.array([[phal(k, "visible_pixels", f) for f in frames] for k in hk], dtype=int),
        occluders=tuple(tuple({n: dict(f[k][n]["occluders"]) for n in phalanx_names} for f in frames) for k in hk),
        checks=dict(t.get("checks", {})), variant=t.get("variant"),
    )


def _handedness_next_to(mjcf: Path) -> str:
    """"right"/"left" when the dev set's ``hand.json`` beside the MJCF says so, else "none"."""
    try:
        text = str(json.loads(mjcf.with_name("hand.json").read_text()).get("frame", "")).lower()
    except (OSError, json.JSONDecodeError, AttributeError):
        return "none"
    return "right" if "right hand" in text else "left" if "left hand" in text else "none"


def load_devset(folder: str | Path, model: Model | str | Path | None = None) -> DevSequence:
    """Read one dev-set sequence folder (``data/mujoco/open_close`` ...): model, cameras, frames, truth.

    Args:
        folder: the sequence folder (holding ``truth.json``).
        model: None imports the MJCF the truth names (``truth.json -> model``, with the
            handedness ``hand.json`` beside it states); else a built-in name, a model file or a Model.

    Raises:
        InputError: malformed truth, missing frame files, or a model joint the truth lacks.
        ModelFileError: the model cannot be read.
    """
    folder = Path(folder)
    path = folder / "truth.json"
    if model is None:
        try:
            rel = json.loads(path.read_text())["model"]
        except OSError as err:
            raise _fail(str(path), f"cannot read truth file ({err.strerror})") from err
        except (json.JSONDecodeError, KeyError, TypeError) as err:
            raise _fail(str(path), "cannot find the model: field 'model' (the MJCF's path) is missing") from err
        mjcf = (folder / rel).resolve()
        m = load_mjcf(mjcf, handedness=_handedness_next_to(mjcf))
    else:
        m = get_model(model)
    truth = load_truth(path, m)
    image_paths = tuple(tuple(folder / f for f in files) for files in truth.image_files)
    missing = [p for paths in image_paths for p in paths if not p.is_file()]
    if missing:
        raise _fail(str(folder), f"{len(missing)} frame file(s) missing, the first {missing[0]}")
    return DevSequence(name=truth.sequence, folder=folder, model=m, truth=truth, image_paths=image_paths)
