"""Landmark files: MediaPipe's JSON and jaxhand's plain CSV/JSON.

Pixel convention: jaxhand's pixel origin is the centre of the top-left pixel. MediaPipe's
coordinates are normalised coordinates times the image size, whose (0, 0) is the top-left
*corner* of the image, so 0.5 px is subtracted from both x and y on loading. jaxhand's own files
use jaxhand's convention (no shift).

**MediaPipe JSON** (``jaxhand landmarks`` writes it; see ``data/real/README.md``): ``joint_names``
(the 21 names), ``summary.size`` ([width, height]) and ``summary.fps``, and per entry of ``frames``
``{"frame": i, "hands": [{"landmarks_px": [[x, y, z], ...21], "score": s,
"handedness_unmirrored": "Right", ...}]}``. MediaPipe's relative depth and its ``world_m`` are
not positions in the camera frame and are not used as 3-D landmarks.

**Plain CSV**: a header, then one row per point, ``frame,point,x,y[,z][,confidence]``:

- without a ``z`` column, ``x, y`` are pixels;
- with a ``z`` column, ``x, y, z`` are a 3-D point in mm in the camera frame, and optional
  ``u, v`` columns give its pixels;
- ``confidence`` (>= 0, default 1) is the point's weight.

Point names are :data:`~jaxhand.landmarks.POINT_NAMES`.

**Plain JSON**: ``{"format": "jaxhand-landmarks", "format_version": 1, "image_size": [w, h],
"fps": 30, "rows": [{"frame": 0, "point": "wrist", "x": .., "y": .., "confidence": ..}, ...]}``
with the CSV's columns as keys (``image_size`` and ``fps`` optional).

Bad input: an unknown point name, a duplicate point, a landmark list that is not 21 points or a
non-numeric value is an error naming the file, frame and point; NaN coordinates mask that point;
frames missing between the first and the last become frames with no points, and points a
frame does not list are masked; a frame with two
hands keeps the one nearest the previous frame's (the first frame: the highest score). All of
these are listed in :attr:`LandmarkSequence.notes`.
"""

from __future__ import annotations

import csv
import dataclasses
import difflib
import json
from pathlib import Path

import numpy as np

from .._errors import InputError, finite_number
from ..camera import scaled_pixels
from ._convention import POINT_NAMES
from ._residuals import Landmarks, make_landmarks

__all__ = ["LandmarkSequence", "load_landmarks", "save_landmarks_csv", "mirror_x", "LandmarkFileError"]

FORMAT_VERSION = 1
N = len(POINT_NAMES)


class LandmarkFileError(InputError):
    """A landmark file is malformed; the message names file, frame and point."""


@dataclasses.dataclass
class LandmarkSequence:
    """Landmarks of consecutive frames from one camera (host-side NumPy arrays).

    Attributes:
        frames: (T,) frame numbers, consecutive.
        px: (T, 21, 2) pixels (jaxhand convention), NaN where missing.
        confidence: (T, 21) weights in [0, 1] (0 where missing).
        mm: (T, 21, 3) 3-D points in the camera frame (mm), or None.
        image_size: (width, height) if the file says, else None.
        fps: frames per second if the file says, else None.
        handedness: "left" / "right" (of the real hand, unmirrored) if the file says, else None.
        notes: what was skipped or chosen (missing frames, NaN points, two-hand frames).
        source: the file name.
    """

    frames: np.ndarray
    px: np.ndarray
    confidence: np.ndarray
    mm: np.ndarray | None = None
    image_size: tuple[int, int] | None = None
    fps: float | None = None
    handedness: str | None = None
    notes: dict = dataclasses.field(default_factory=dict)
    source: str = ""

    def __len__(self) -> int:
        return len(self.frames)

    @property
    def valid(self) -> np.ndarray:
        return np.all(np.isfinite(self.px), -1)

    def resized(self, size, new_size) -> LandmarkSequence:
        """The landmarks of the video resized from ``size`` to ``new_size`` (width, height), as
        :func:`jaxhand.camera.scale_camera` resizes its camera (pixel centres at integers)."""
        return dataclasses.replace(self, px=scaled_pixels(self.px, size, new_size),
                                   image_size=(int(new_size[0]), int(new_size[1])))

    def to_landmarks(self, *, mirror_cx: float | None = None, mm_weight: float = 1.0) -> Landmarks:
        """Batched :class:`Landmarks` (T, 1, 21, 2), the confidences as weights; with
        ``mirror_cx`` the x coordinates are mirrored about that column (:func:`mirror_x`)."""
        px = self.px if mirror_cx is None else mirror_x(self.px, mirror_cx)
        mm = self.mm
        if mm is not None and mirror_cx is not None:
            mm = mm * np.array([-1.0, 1.0, 1.0])
        return make_landmarks(px[:, None], px_weight=self.confidence[:, None], mm=mm, mm_weight=mm_weight)

    def slice(self, start: int, stop: int) -> LandmarkSequence:
        sl = slice(start, stop)
        return dataclasses.replace(self, frames=self.frames[sl], px=self.px[sl], confidence=self.confidence[sl],
                                   mm=None if self.mm is None else self.mm[sl])


def mirror_x(px: np.ndarray, cx: float) -> np.ndarray:
    """Pixels mirrored about the column ``cx`` (x -> 2 cx - x): a right hand's landmarks become a
    left hand's seen by the mirrored camera. With a camera whose principal point is at ``cx`` and
    no rotation, fitting the mirrored points gives the same joint angles."""
    out = np.array(px, dtype=float, copy=True)
    out[..., 0] = 2.0 * cx - out[..., 0]
    return out


def _suggest(name: str) -> str:
    close = difflib.get_close_matches(name, POINT_NAMES, n=1)
    return f" (did you mean {close[0]!r}?)" if close else f"; valid names: {', '.join(POINT_NAMES)}"


def _num(v, src, what) -> float:
    try:
        return float(v)
    except (TypeError, ValueError) as err:
        raise LandmarkFileError(f"{src}: {what}: not a number: {v!r}") from err


def _fill(frames_seen: dict[int, dict], src: str, has_mm: bool, has_px: bool, notes: dict):
    if not frames_seen:
        raise LandmarkFileError(f"{src}: no landmarks")
    f0, f1 = min(frames_seen), max(frames_seen)
    frames = np.arange(f0, f1 + 1)
    T = len(frames)
    px = np.full((T, N, 2), np.nan)
    mm = np.full((T, N, 3), np.nan) if has_mm else None
    conf = np.zeros((T, N))
    for f, pts in frames_seen.items():
        t = f - f0
        for i, (p2, p3, c) in pts.items():
            if p2 is not None:
                px[t, i] = p2
            if p3 is not None and mm is not None:
                mm[t, i] = p3
            conf[t, i] = c
    missing = [int(f) for f in frames if f not in frames_seen]
    if missing:
        notes["missing_frames"] = missing
    absent = sum(N - len(pts) for pts in frames_seen.values())
    if absent:
        notes["absent_points"] = int(absent)
    nan = sum(1 for pts in frames_seen.values() for p2, p3, _ in pts.values()
              if (p2 is not None and not np.all(np.isfinite(p2))) or (p3 is not None and not np.all(np.isfinite(p3))))
    if nan:
        notes["nan_points"] = int(nan)
    conf = np.where(np.all(np.isfinite(px), -1) | (mm is not None and np.all(np.isfinite(mm), -1)), conf, 0.0)
    if not has_px:
        px[:] = np.nan
    return frames, px, mm, conf


def _rows_to_sequence(rows, src: str, header: set[str]) -> tuple:
    need = {"frame", "point"}
    if not need <= header:
        raise LandmarkFileError(f"{src}: needs the columns frame, point and x, y (or u, v); got {sorted(header)}")
    has_mm = "z" in header
    has_px = ("u" in header and "v" in header) or (not has_mm and {"x", "y"} <= header)
    if not has_px and not has_mm:
        raise LandmarkFileError(f"{src}: needs x, y (pixels), or x, y, z (mm) with optional u, v (pixels)")
    known = {"frame", "point", "x", "y", "z", "u", "v", "confidence"}
    unknown = header - known
    if unknown:
        raise LandmarkFileError(f"{src}: unknown column(s) {sorted(unknown)}; valid: {', '.join(sorted(known))}")
    seen: dict[int, dict] = {}
    for k, row in enumerate(rows):
        where = f"{src}: row {k + 1}"
        try:
            frame = int(row["frame"])
        except (TypeError, ValueError) as err:
            raise LandmarkFileError(f"{where}: frame: not an integer: {row.get('frame')!r}") from err
        name = str(row["point"]).strip()
        if name not in POINT_NAMES:
            raise LandmarkFileError(f"{where} (frame {frame}): unknown point {name!r}{_suggest(name)}")
        i = POINT_NAMES.index(name)
        if i in seen.setdefault(frame, {}):
            raise LandmarkFileError(f"{where}: frame {frame}: point {name!r} appears twice")
        if has_mm:
            p3 = np.array([_num(row[c], where, c) for c in "xyz"])
            p2 = np.array([_num(row["u"], where, "u"), _num(row["v"], where, "v")]) if has_px else None
        else:
            p2, p3 = np.array([_num(row["x"], where, "x"), _num(row["y"], where, "y")]), None
        c = _num(row.get("confidence", 1.0), where, "confidence") if row.get("confidence", "") != "" else 1.0
        if not np.isfinite(c) or c < 0:
            raise LandmarkFileError(f"{where}: confidence must be finite and >= 0, got {c}")
        seen[frame][i] = (p2, p3, c)
    return seen, has_mm, has_px


def _load_csv(path: Path) -> LandmarkSequence:
    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        header = {h.strip() for h in (reader.fieldnames or [])}
        rows = [{k.strip(): v for k, v in r.items() if k is not None} for r in reader]
    notes: dict = {}
    seen, has_mm, has_px = _rows_to_sequence(rows, str(path), header)
    frames, px, mm, conf = _fill(seen, str(path), has_mm, has_px, notes)
    return LandmarkSequence(frames=frames, px=px, confidence=conf, mm=mm, notes=notes, source=path.name)


def _load_plain_json(data: dict, path: Path) -> LandmarkSequence:
    version = data.get("format_version")
    if version != FORMAT_VERSION:
        raise LandmarkFileError(f"{path}: format_version must be {FORMAT_VERSION}, got {version!r}")
    known = {"format", "format_version", "image_size", "fps", "handedness", "rows"}
    unknown = set(data) - known
    if unknown:
        raise LandmarkFileError(f"{path}: unknown key(s) {sorted(unknown)}; valid: {', '.join(sorted(known))}")
    rows = data.get("rows")
    if not isinstance(rows, list) or not all(isinstance(r, dict) for r in rows):
        raise LandmarkFileError(f"{path}: 'rows' must be a list of objects")
    header = set().union(*(set(r) for r in rows)) if rows else set()
    notes: dict = {}
    seen, has_mm, has_px = _rows_to_sequence(rows, str(path), header)
    frames, px, mm, conf = _fill(seen, str(path), has_mm, has_px, notes)
    return LandmarkSequence(frames=frames, px=px, confidence=conf, mm=mm,
                            image_size=_image_size(data.get("image_size"), f"{path}: image_size"),
                            fps=_fps(data.get("fps"), f"{path}: fps"), handedness=data.get("handedness"), notes=notes,
                            source=path.name)


def _whole(value, where: str) -> int:
    """A JSON whole number (a frame index, an image side), or a one-line error naming ``where``."""
    if not finite_number(value) or float(value) != int(value):
        raise LandmarkFileError(f"{where}: expected a whole number, got {value!r}")
    return int(value)


def _image_size(value, where: str) -> tuple[int, int] | None:
    """``[width, height]`` from a file (None where it does not say), or a one-line error."""
    if value is None:
        return None
    if not isinstance(value, list) or len(value) != 2:
        raise LandmarkFileError(f"{where}: expected [width, height], got {value!r}")
    return _whole(value[0], where), _whole(value[1], where)


def _fps(value, where: str) -> float | None:
    """A frame rate from a file (None where it does not say), or a one-line error."""
    if value is None:
        return None
    if not (finite_number(value) and value > 0):
        raise LandmarkFileError(f"{where}: expected a frame rate > 0, got {value!r}")
    return float(value)


def _score(value) -> float:
    """A hand's detection score (0 where the file gives none or no number)."""
    return float(value) if finite_number(value) else 0.0


def _hand_points(hand, where: str) -> np.ndarray:
    """One MediaPipe hand's 21 (x, y) pixels (image-corner origin), or a one-line error."""
    try:
        lm = np.asarray(hand.get("landmarks_px", []), dtype=float)
    except (TypeError, ValueError):
        lm = np.zeros((0,))
    if lm.ndim != 2 or lm.shape[0] != N or lm.shape[1] < 2 or np.any(np.isinf(lm[:, :2])):
        raise LandmarkFileError(f"{where}: expected {N} landmarks of (x, y[, z]), NaN where missing, got "
                                f"{'shape ' + str(lm.shape) if lm.size else 'none'}")
    return lm[:, :2]


def _load_mediapipe(data: dict, path: Path) -> LandmarkSequence:
    names = data.get("joint_names")
    if names is not None and (not isinstance(names, list) or names != list(POINT_NAMES)):
        raise LandmarkFileError(f"{path}: joint_names differ from the 21-point convention: {names!r}")
    frames_in = data.get("frames")
    if not isinstance(frames_in, list):
        raise LandmarkFileError(f"{path}: 'frames' must be a list")
    summary = data.get("summary", {}) or {}
    if not isinstance(summary, dict):
        raise LandmarkFileError(f"{path}: 'summary' must be an object")
    seen: dict[int, dict] = {}
    notes: dict = {}
    two_hands, prev, hand_labels = [], None, []
    for k, fr in enumerate(frames_in):
        if not isinstance(fr, dict) or "frame" not in fr:
            raise LandmarkFileError(f"{path}: frames[{k}]: expected an object with 'frame' and 'hands'")
        f = _whole(fr["frame"], f"{path}: frames[{k}]: frame")
        hands = fr.get("hands") or []
        if not isinstance(hands, list) or not all(isinstance(h, dict) for h in hands):
            raise LandmarkFileError(f"{path}: frame {f}: 'hands' must be a list of objects")
        # image-corner origin -> centre of the top-left pixel
        arrs = [_hand_points(hand, f"{path}: frame {f}: hand {h}") - 0.5 for h, hand in enumerate(hands)]
        if not arrs:
            continue
        if len(arrs) > 1:
            two_hands.append(f)
            if prev is None:
                best = int(np.argmax([_score(h.get("score")) for h in hands]))
            else:
                best = int(np.argmin([np.nanmean(np.linalg.norm(a - prev, axis=-1)) for a in arrs]))
        else:
            best = 0
        prev = arrs[best]
        hand_labels.append(hands[best].get("handedness_unmirrored"))
        seen[f] = {i: (arrs[best][i], None, 1.0) for i in range(N)}
    if two_hands:
        notes["two_hand_frames"] = two_hands
    frames, px, mm, conf = _fill(seen, str(path), False, True, notes)
    labels = [x for x in hand_labels if isinstance(x, str)]
    hand = max(set(labels), key=labels.count).lower() if labels else None
    return LandmarkSequence(frames=frames, px=px, confidence=conf, mm=None,
                            image_size=_image_size(summary.get("size"), f"{path}: summary.size"),
                            fps=_fps(summary.get("fps"), f"{path}: summary.fps"), handedness=hand, notes=notes,
                            source=path.name)


def load_landmarks(path: str | Path) -> LandmarkSequence:
    """Read a MediaPipe JSON, a plain JSON or a plain CSV landmark file (see the module docstring).

    Raises:
        LandmarkFileError: naming the file, frame and point.
    """
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as err:
        raise LandmarkFileError(f"{path}: cannot read landmark file ({err.strerror})") from err
    if path.suffix.lower() == ".csv":
        return _load_csv(path)
    try:
        data = json.loads(text)
    except json.JSONDecodeError as err:
        raise LandmarkFileError(f"{path}: cannot parse JSON: {err}") from err
    if not isinstance(data, dict):
        raise LandmarkFileError(f"{path}: expected a JSON object")
    if "rows" in data or data.get("format") == "jaxhand-landmarks":
        return _load_plain_json(data, path)
    if "frames" in data:
        return _load_mediapipe(data, path)
    raise LandmarkFileError(f"{path}: neither a MediaPipe landmark file ('frames') nor a jaxhand one ('rows')")


def save_landmarks_csv(seq: LandmarkSequence, path: str | Path) -> Path:
    """Write a sequence as a plain CSV (pixels; 3-D points as x, y, z with the pixels as u, v)."""
    path = Path(path)
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        if seq.mm is None:
            w.writerow(["frame", "point", "x", "y", "confidence"])
        else:
            w.writerow(["frame", "point", "u", "v", "x", "y", "z", "confidence"])
        for t, fr in enumerate(seq.frames):
            for i, name in enumerate(POINT_NAMES):
                row = [int(fr), name, *(f"{v:.4f}" for v in seq.px[t, i])]
                if seq.mm is not None:
                    row += [f"{v:.4f}" for v in seq.mm[t, i]]
                w.writerow(row + [f"{seq.confidence[t, i]:.4f}"])
    return path
