"""The DigitEyes 3D mouse (DigitEyes §6.1): a tracked ``mouse3d`` hand drives a 3-D cursor.

The cursor is a "mouse pole" standing on the ground plane: the palm position in the table plane
sets the pole's base, the height of the index fingertip above the table sets the pole's height
(the cursor sits on top), and the abduction of the thumb and of the ring finger act as two
buttons, pressed when the joint moves past a threshold from its rest angle.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ._errors import InputError
from .kinematics import forward
from .model import Model

__all__ = ["MouseState", "mouse_state"]


@dataclasses.dataclass(frozen=True)
class MouseState:
    """Pole base (x, y) in the table plane (mm), pole height (mm) and the two buttons."""

    base_xy_mm: np.ndarray
    height_mm: float
    thumb_button: bool
    ring_button: bool


def mouse_state(model: Model, q, *, button_threshold_deg: float = 12.0, gain: float = 1.0) -> MouseState:
    """Map a state of the ``mouse3d`` model to the 3-D mouse.

    Args:
        q: the hand state (palm_x, palm_y, palm_yaw, index joints, ring and thumb abduction).
        button_threshold_deg: abduction (absolute, from 0) that presses a button.
        gain: scale from hand millimetres to cursor units (DigitEyes used a simple scaling).
    """
    needed = ("palm_x", "palm_y", "ring_abd", "thumb_abd")
    if model.base_kind != "planar" or not all(n in model.q_names for n in needed):
        raise InputError(f"mouse_state needs the planar-palm 'mouse3d' model, got {model.name!r}")
    q = np.asarray(q, float)
    pose = forward(model, q)
    mount = np.asarray(model.T_world_mount)
    tip_table = mount[:3, :3].T @ (np.asarray(pose.tips[model.tip_names.index("index_dip")]) - mount[:3, 3])
    thr = np.radians(button_threshold_deg)
    return MouseState(base_xy_mm=gain * q[[model.q_lookup("palm_x"), model.q_lookup("palm_y")]],
                      height_mm=float(gain * tip_table[2]),
                      thumb_button=bool(abs(q[model.q_lookup("thumb_abd")]) > thr),
                      ring_button=bool(abs(q[model.q_lookup("ring_abd")]) > thr))
