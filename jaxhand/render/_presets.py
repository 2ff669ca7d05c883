"""Synthetic sequences: a model, its cameras and a ground-truth state per frame.

The named presets reproduce the experiments of the documents in ``shared/seeds``:

- ``two_finger_occlusion`` — thesis §6.1, Fig. 6.1: middle and index fingers (Table 6.1) flexing
  in a plane tilted 45 degrees towards an orthographic camera, the index in front of the middle
  finger. The two fingers flex through different ranges and out of phase, so the index covers the
  middle finger partly and by an amount that changes through the sequence.
- ``full_hand_spread_flex`` — thesis §6.2.2, Fig. 6.5/6.6: the 21-DOF hand (Table 6.2), palm facing
  the camera, tilted 45 degrees. The thumb stays still; the fingers first spread, then the little
  finger hyper-extends while the index flexes and ring and middle move to poses in between. As in
  Fig. 6.6 the DIP angle equals the PIP angle throughout.
- ``index_thumb_grasp`` — thesis §6.2.1, Fig. 6.3/6.4: index and thumb (Table 2.3) seen from the
  side; twice they spread and grasp together, then move independently of each other.
- ``two_camera_hand`` — DigitEyes §6.2: the 27-DOF hand on a free palm that rotates and translates
  while the fingers flex and spread, seen by two perspective cameras about 450 mm (1.5 ft) apart
  whose optical axes verge on the hand at about 45 degrees of elevation.
- ``mouse3d`` — DigitEyes §6.1: the 3D-mouse hand flat on the table, one perspective camera at about
  45 degrees to the table top. Four phases as in DigitEyes Fig. 9: the index is raised and lowered
  twice; it is raised and held while the thumb, then the ring finger, abducts ("button" events);
  the palm moves in the table plane at a constant finger height; finally everything moves at once.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import jax.numpy as jnp
import numpy as np

from .._errors import InputError
from ..camera import Orthographic, Perspective, look_at_rotation
from ..kinematics import forward, validate_q
from ..model import Model, builtin_model
from ._trajectory import joint_trajectory

__all__ = ["Sequence", "make_preset", "preset_names", "PRESET_DESCRIPTIONS", "parse_size", "fit_orthographic",
           "fit_perspective"]


@dataclass(frozen=True)
class Sequence:
    """A synthetic sequence with exact ground truth.

    Attributes:
        name: preset or user name.
        model: the model that moves.
        cameras: one camera per view (all of the same image size).
        q: (frames, n_q) ground-truth states (radians, mm; a free base's quaternion is unit).
        times_s: (frames,) time of each frame (s).
        description: what the sequence shows and where it comes from.
    """

    name: str
    model: Model
    cameras: tuple
    q: np.ndarray
    times_s: np.ndarray
    description: str = ""

    def __post_init__(self):
        q = np.asarray(self.q, float)
        if q.ndim != 2 or q.shape[1] != self.model.n_q:
            raise InputError(f"Sequence.q: expected shape (frames, {self.model.n_q}), got {q.shape}")
        if np.shape(self.times_s) != (len(q),):
            raise InputError(f"Sequence.times_s: expected shape ({len(q)},), got {np.shape(self.times_s)}")
        if not self.cameras:
            raise InputError("Sequence.cameras: at least one camera is needed")
        for i, row in enumerate(q):
            validate_q(self.model, row, name=f"Sequence.q[{i}]")

    @property
    def n_frames(self) -> int:
        return len(self.q)

    @property
    def size(self) -> tuple[int, int]:
        """Image size (width, height) of the first camera."""
        return tuple(self.cameras[0].size)


def parse_size(size) -> tuple[int, int]:
    """(width, height) from a pair or a ``"WxH"`` string; both must be positive integers."""
    if isinstance(size, str):
        parts = size.lower().split("x")
        try:
            w, h = (int(p) for p in parts)
        except ValueError:
            raise InputError(f"size: expected WxH with two positive integers (e.g. 320x240), got {size!r}") from None
    else:
        try:
            w, h = size
        except (TypeError, ValueError):
            raise InputError(f"size: expected (width, height), got {size!r}") from None
        if int(w) != w or int(h) != h:
            raise InputError(f"size: width and height must be integers, got {size!r}")
        w, h = int(w), int(h)
    if w < 8 or h < 8 or w > 8192 or h > 8192:
        raise InputError(f"size: width and height must lie in 8..8192 pixels, got {w}x{h}")
    return w, h


# ---- cameras that frame a whole sequence ----

def _pill_extent_points(model: Model, qs: np.ndarray):
    """Axis ends of every link over all states (2 frames links, 3) and their radii."""
    # One jitted call per state: compiled once per model structure, whatever the frame count
    # (a vmap over the states would compile again for every new count).
    poses = [forward(model, jnp.asarray(q, dtype=jnp.float64)) for q in np.atleast_2d(qs)]
    pts = np.concatenate([np.asarray(p.link_start) for p in poses] + [np.asarray(p.link_end) for p in poses])
    rad = np.tile(np.asarray(model.link_radius_mm), 2 * len(poses))
    return pts, rad


def fit_orthographic(model: Model, qs, size, *, R=None, margin: float = 0.08) -> Orthographic:
    """An orthographic camera with rotation R (default identity) that keeps every pill of every
    state in ``qs`` (n_q,) or (frames, n_q) inside the image with the given margin (fraction of the
    image size)."""
    R = np.eye(3) if R is None else np.asarray(R, float)
    pts, rad = _pill_extent_points(model, np.atleast_2d(qs))
    # Grow each axis end by its radius along the camera's x and y axes so the outline fits.
    grown = np.concatenate([pts + s * rad[:, None] * R[j] for j in (0, 1) for s in (-1, 1)])
    return Orthographic.fit(grown, size=size, R=R, margin=margin)


def fit_perspective(model: Model, qs, size, eyes, *, up=(0.0, -1.0, 0.0), margin: float = 0.08
                    ) -> tuple[Perspective, ...]:
    """Identical pinhole cameras at ``eyes`` (k, 3) mm, each aimed so that the pills of the states
    ``qs`` are centred in its image, with the one focal length that keeps every pill inside every
    image with the given margin; ``up`` is the world direction shown up.

    Raises:
        InputError: a pill reaches behind a camera.
    """
    w, h = size
    eyes = np.atleast_2d(np.asarray(eyes, float))
    if eyes.ndim != 2 or eyes.shape[1] != 3 or not np.all(np.isfinite(eyes)):
        raise InputError(f"eyes: expected camera centres of shape (k, 3) in mm, got shape {eyes.shape}")
    pts, rad = _pill_extent_points(model, np.atleast_2d(qs))
    target = 0.5 * (pts.min(0) + pts.max(0))
    half = np.array([(w - 1) / 2, (h - 1) / 2]) * (1 - 2 * margin)
    poses, f = [], np.inf
    for eye in eyes:
        aim = target
        for _ in range(4):  # re-aim at the middle of the normalised image extent; converges in a few steps
            R = look_at_rotation(eye, aim, up)
            p = (pts - eye) @ R.T
            if np.any(p[:, 2] - rad <= 1.0):
                raise InputError("camera placement: a pill reaches behind the camera")
            # Normalised image coordinates x/z, grown by the radius seen at that depth.
            grow = (rad / p[:, 2])[:, None]
            lo = (p[:, :2] / p[:, 2:3] - grow).min(0)
            hi = (p[:, :2] / p[:, 2:3] + grow).max(0)
            mid = 0.5 * (lo + hi)
            aim = eye + R.T @ np.array([mid[0], mid[1], 1.0])
        # Extent about the principal point (the centre of the image) in the final orientation.
        f = min(f, float(np.min(half / np.maximum(np.maximum(-lo, hi), 1e-9))))
        poses.append((R, eye))
    K = np.array([[f, 0.0, (w - 1) / 2], [0.0, f, (h - 1) / 2], [0.0, 0.0, 1.0]])
    return tuple(Perspective(K=K, R=R, t=-R @ eye, size=(w, h)) for R, eye in poses)


# ---- key poses ----

def _key(model: Model, base=None, **values) -> np.ndarray:
    """A state from ``base`` (default: the model's default) with named entries set; angles in degrees,
    lengths in mm."""
    q = np.array(model.q_default if base is None else base, float)
    for name, v in values.items():
        i = model.q_lookup(name)
        q[i] = np.radians(v) if model.is_angle[i] else v
    return q


def _finger(prefix: str, mcp, pip, dip=None, abd=None) -> dict:
    d = {f"{prefix}_mcp": mcp, f"{prefix}_pip": pip, f"{prefix}_dip": pip if dip is None else dip}
    if abd is not None:
        d[f"{prefix}_abd"] = abd
    return d


def _times(frames: int, dt_s: float, key_fractions) -> tuple[np.ndarray, np.ndarray]:
    times = np.arange(frames) * dt_s
    key_times = np.asarray(key_fractions, float) * max(times[-1], dt_s)
    return times, key_times


def _quat_axis_angle(axis, angle_deg) -> np.ndarray:
    a = np.asarray(axis, float)
    a = a / np.linalg.norm(a)
    h = np.radians(angle_deg) / 2
    return np.concatenate([[np.cos(h)], np.sin(h) * a])


def _quat_mul(p, q) -> np.ndarray:
    w1, x1, y1, z1 = p
    w2, x2, y2, z2 = q
    return np.array([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])


def _rot_x(deg: float) -> np.ndarray:
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    return np.array([[1.0, 0, 0], [0, c, -s], [0, s, c]])


# Tilt of thesis §6: the plane of motion turned 45 degrees about the image's horizontal axis with its
# top towards the camera (points above the centre come nearer: camera z = cos 45 z + sin 45 y, y down).
_TILT_45 = _rot_x(45.0)


# ---- the presets ----

def _two_finger_occlusion(frames: int, size) -> Sequence:
    m = builtin_model("two_fingers")
    # The tilt shows the index (nearer the camera) slightly below the middle finger. The sequence
    # starts and ends with the two fingers apart (index straight, middle flexed), so both are seen
    # unoccluded where the tracker captures its templates; in between the index flexes across the
    # middle finger, whose covered part grows, shrinks and moves along it, never covering it whole.
    keys = [
        _key(m, **_finger("middle", -35, -40, -30), **_finger("index", 10, -5, 0)),
        _key(m, **_finger("middle", -40, -45, -30), **_finger("index", -20, -30, -20)),
        _key(m, **_finger("middle", -60, -60, -40), **_finger("index", -50, -45, -30)),
        _key(m, **_finger("middle", -25, -35, -25), **_finger("index", -5, -20, -15)),
        _key(m, **_finger("middle", -40, -40, -30), **_finger("index", 5, -10, -5)),
    ]
    times, key_times = _times(frames, 0.04, [0.0, 0.25, 0.5, 0.75, 1.0])
    q = joint_trajectory(m, keys, key_times, times)
    cam = fit_orthographic(m, q, size, R=_TILT_45)
    return Sequence("two_finger_occlusion", m, (cam,), q, times, PRESET_DESCRIPTIONS["two_finger_occlusion"])


def _full_hand_spread_flex(frames: int, size) -> Sequence:
    m = builtin_model("hand21")
    straight = _key(m, **_finger("little", 0, 0, abd=0), **_finger("ring", 0, 0, abd=0),
                    **_finger("middle", 0, 0, abd=0), **_finger("index", 0, 0, abd=0))
    spread = _key(m, straight, little_abd=25, ring_abd=10, middle_abd=10, index_abd=20)
    # Hyper-extended little finger, flexed index, ring and middle in between (PIP = DIP, Fig. 6.6).
    flexed = _key(m, spread, **_finger("little", 40, 0), **_finger("ring", 15, -15), **_finger("middle", -25, -40),
                  **_finger("index", -60, -75))
    times, key_times = _times(frames, 0.04, [0.0, 0.08, 0.4, 0.92, 1.0])
    q = joint_trajectory(m, [straight, straight, spread, flexed, flexed], key_times, times)
    cam = fit_orthographic(m, q, size, R=_TILT_45)
    return Sequence("full_hand_spread_flex", m, (cam,), q, times, PRESET_DESCRIPTIONS["full_hand_spread_flex"])


def _index_thumb_grasp(frames: int, size) -> Sequence:
    m = builtin_model("index_thumb")

    def pose(index, thumb):
        return _key(m, **dict(zip(("index_mcp", "index_pip", "index_dip"), index)),
                    **dict(zip(("thumb_cmc", "thumb_mcp", "thumb_ip"), thumb)))

    # The fingers are 50 mm apart at their bases, so a pinch needs only small flexions; the two
    # grasps close to about 1 mm between the pills without interpenetrating.
    open_ = pose((35, -5, 0), (20, 10, 15))
    keys = [open_,
            pose((5, -30, -20), (15, -30, -36)),    # pinch, index bent at the PIP
            open_,
            pose((-10, 0, 0), (5, -20, -24)),       # pinch, index straight
            open_,
            pose((-5, -60, -45), (20, 10, 15)),     # the index flexes alone
            pose((40, 0, 0), (-5, -40, -60)),       # the index extends while the thumb flexes
            pose((15, -15, -10), (10, 0, 0))]
    times, key_times = _times(frames, 0.04, np.linspace(0.0, 1.0, len(keys)))
    q = joint_trajectory(m, keys, key_times, times)
    cam = fit_orthographic(m, q, size)
    return Sequence("index_thumb_grasp", m, (cam,), q, times, PRESET_DESCRIPTIONS["index_thumb_grasp"])


def _two_camera_hand(frames: int, size) -> Sequence:
    m = builtin_model("hand27")
    q0 = np.asarray(m.q_default)  # palm facing -z, fingers along -y (up in an upright view)
    relaxed = _key(m, **_finger("little", -5, -10, abd=5), **_finger("ring", -5, -10, abd=3),
                   **_finger("middle", -5, -10, abd=3), **_finger("index", -5, -10, abd=5))

    def palm(base, quat_world, t_mm, **fingers):
        q = _key(m, base, **fingers)
        q[:4] = _quat_mul(quat_world, q0[:4])
        q[4:7] = t_mm
        return q

    ident = np.array([1.0, 0, 0, 0])
    # Rotations stay within 20 degrees so that neither camera sees the palm edge-on (DigitEyes
    # notes the motion must avoid occlusions, which limits the range of travel).
    keys = [
        palm(relaxed, ident, (0, 0, 0)),
        palm(relaxed, _quat_axis_angle((0, 0, 1), 15), (25, -10, 0), **_finger("index", -25, -30),
             **_finger("middle", -15, -20)),
        palm(relaxed, _quat_axis_angle((1, 0, 0), -20), (-15, 15, 30), little_abd=20, ring_abd=10, middle_abd=10,
             index_abd=20),
        palm(relaxed, _quat_axis_angle((0, 1, 0), -12), (-25, 0, -20), **_finger("little", -25, -30),
             **_finger("ring", -20, -25), thumb_cmc_ra=-55, thumb_mcp=-20),
        palm(relaxed, _quat_axis_angle((0.5, -1, 1), 15), (15, -15, 15), **_finger("index", 10, -5),
             **_finger("middle", -20, -30)),
        palm(relaxed, ident, (0, 0, 0)),
    ]
    times, key_times = _times(frames, 0.1, np.linspace(0.0, 1.0, len(keys)))
    q = joint_trajectory(m, keys, key_times, times)
    # Two identical cameras 450 mm (1.5 ft) apart, 650 mm from the hand and 45 degrees above it,
    # verging on it. "Above" is -y (the fingers point along -y) and the palm faces -z, the cameras.
    d, half_base = 650.0, 225.0
    elev = np.sqrt(d**2 - half_base**2) / np.sqrt(2)
    pts = _pill_extent_points(m, q)[0]
    centre = 0.5 * (pts.min(0) + pts.max(0))
    eyes = [centre + np.array([side * half_base, -elev, -elev]) for side in (-1.0, 1.0)]
    cams = fit_perspective(m, q, size, eyes, up=(0.0, -1.0, 0.0))
    return Sequence("two_camera_hand", m, cams, q, times, PRESET_DESCRIPTIONS["two_camera_hand"])


def _mouse3d(frames: int, size) -> Sequence:
    m = builtin_model("mouse3d")
    rest = _key(m, index_mcp=5, index_pip=-10, index_dip=-5, ring_abd=0, thumb_abd=0)
    up = _key(m, rest, index_mcp=40, index_pip=-5, index_dip=0)

    def at(base, x=0.0, y=0.0, yaw=0.0, **kw):
        return _key(m, base, palm_x=x, palm_y=y, palm_yaw=yaw, **kw)

    mid = _key(m, rest, index_mcp=22, index_pip=-8, index_dip=-3)
    schedule = [
        # Phase 1 (0-0.28): raise and lower the index twice.
        (0.0, rest), (0.07, up), (0.14, rest), (0.21, up), (0.28, rest),
        # Phase 2 (0.3-0.4): raise and hold; the thumb, then the ring finger, click like buttons.
        (0.32, up), (0.345, at(up, thumb_abd=-25)), (0.37, up), (0.385, at(up, ring_abd=15)), (0.4, up),
        # Phase 3 (0.4-0.7): the palm moves in the table plane at a constant finger height.
        (0.475, at(up, x=40, y=30, yaw=10)), (0.55, at(up, x=-40, y=40, yaw=-10)), (0.625, at(up, x=-30, y=-30, yaw=5)),
        (0.7, up),
        # Phase 4 (0.7-1): everything at once.
        (0.8, at(up, x=35, y=-20, yaw=-15, thumb_abd=-20, ring_abd=10)),
        (0.9, at(rest, x=-25, y=25, yaw=12, thumb_abd=10, ring_abd=-10)),
        (1.0, at(mid, x=10, y=10)),
    ]
    fr = [t for t, _ in schedule]
    keys = [k for _, k in schedule]
    times, key_times = _times(frames, 0.1, fr)
    q = joint_trajectory(m, keys, key_times, times)
    # One camera 600 mm from the hand, looking down at the table at 45 degrees from behind the wrist
    # and 35 degrees to the thumb side, so the index rises visibly and hides the ring finger little.
    pts = _pill_extent_points(m, q)[0]
    centre = 0.5 * (pts.min(0) + pts.max(0))
    az = np.radians(35.0)
    eye = centre + 600.0 * np.array([np.sin(az) * np.sqrt(0.5), -np.cos(az) * np.sqrt(0.5), np.sqrt(0.5)])
    cams = fit_perspective(m, q, size, [eye], up=(0.0, 0.0, 1.0))
    return Sequence("mouse3d", m, cams, q, times, PRESET_DESCRIPTIONS["mouse3d"])


PRESET_DESCRIPTIONS = {
    "two_finger_occlusion": "thesis §6.1: middle and index fingers (Table 6.1) flexing in a plane tilted 45 deg "
                            "towards an orthographic camera, the index partly occluding the middle finger",
    "full_hand_spread_flex": "thesis §6.2.2: 21-DOF hand tilted 45 deg, thumb still; the fingers spread, then the "
                             "little finger hyper-extends while the index flexes (PIP = DIP)",
    "index_thumb_grasp": "thesis §6.2.1: index and thumb seen from the side, spreading and grasping twice, then "
                         "moving independently",
    "two_camera_hand": "DigitEyes §6.2: 27-DOF hand with palm rotation and translation seen by two verging "
                       "perspective cameras 450 mm apart",
    "mouse3d": "DigitEyes §6.1: 3D-mouse hand on a table seen by one camera at 45 deg; index raised and lowered, "
               "thumb and ring 'buttons', palm moved in the plane, then all at once",
}

_PRESETS: dict[str, tuple[Callable[[int, tuple[int, int]], Sequence], int]] = {
    "two_finger_occlusion": (_two_finger_occlusion, 80),
    "full_hand_spread_flex": (_full_hand_spread_flex, 100),
    "index_thumb_grasp": (_index_thumb_grasp, 120),
    "two_camera_hand": (_two_camera_hand, 100),
    "mouse3d": (_mouse3d, 150),
}


def preset_names() -> tuple[str, ...]:
    """Names accepted by :func:`make_preset`."""
    return tuple(_PRESETS)


def make_preset(name: str, *, frames: int | None = None, size=(320, 240)) -> Sequence:
    """A named synthetic sequence (see the module docstring for what each one shows).

    Args:
        name: one of :func:`preset_names`.
        frames: number of frames (default: the preset's own, 80 to 150, the lengths
            ``benchmarks/tracking.py`` measures); the motion is the same for any count, sampled
            more or less finely (fewer frames: faster motion).
        size: image size (width, height) or ``"WxH"``; the cameras frame the whole motion.

    Raises:
        InputError: an unknown name (listing the valid ones), fewer than 2 frames or a bad size.
    """
    if name not in _PRESETS:
        raise InputError(f"unknown preset {name!r}; valid presets: {', '.join(_PRESETS)}")
    make, default_frames = _PRESETS[name]
    n = default_frames if frames is None else frames
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 2:
        raise InputError(f"frames: expected an integer >= 2, got {frames!r}")
    return make(int(n), parse_size(size))
