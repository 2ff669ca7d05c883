"""The 21-point hand landmark convention and where each point sits on a model.

The order is MediaPipe's and OpenPose's: the wrist; the thumb's CMC, MCP, IP and tip; then the
index, middle, ring and little fingers' MCP, PIP, DIP and tip (:data:`POINT_NAMES`).

What a landmark is, on the model:

- a joint landmark (CMC, MCP, PIP, DIP, IP) is the origin of the joint's frame;
- a fingertip landmark is, by default (``tips="skin"``), on the skin at the end of the finger,
  which a detector sees. The model's tip is the centre of the distal pill's cap, so the landmark
  lies one pill radius further along the distal axis: ``origin + (length + radius) * axis``.
  Data whose tips are the cap centres themselves (a renderer's ground truth, such as the MuJoCo
  dev set's ``*_tip``) say so with ``tips="cap_centre"``: ``origin + length * axis``;
- the wrist is not a finger joint: it is a point fixed to the palm, the origin of a frame named
  ``palm`` when the model has one (an imported MJCF hand), else of the root frame of the hand
  (the built-in hands' palm rows start there, the finger bases 68-85 mm from it).

Frames are found by name: a joint landmark sits on the first frame of its joint (``index_mcp``,
or ``index_mcp_abd`` when the joint is split into abduction and flexion frames, as an MJCF hand's
hinges are); a fingertip extends the link carried by the distal joint's frame (``<finger>_dip``,
``thumb_ip``), whatever that link is called.

A :class:`LandmarkMap` stores, for each of the 21 names, the frame it is attached to, the link
whose length and radius it extends along (tips only) and a fixed offset in that frame. Points a
model lacks (an index-only model has no thumb) are absent: their residuals are always zero.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._errors import InputError
from ..kinematics import Pose, base_pose
from ..model import Model

__all__ = ["POINT_NAMES", "FINGERS", "LandmarkMap", "landmark_map", "landmark_positions", "landmark_offsets",
           "BUILTIN_HANDEDNESS", "TIP_CONVENTIONS"]

FINGERS = ("index", "middle", "ring", "little")
#: The 21 landmark names in MediaPipe/OpenPose order.
POINT_NAMES: tuple[str, ...] = ("wrist", "thumb_cmc", "thumb_mcp", "thumb_ip", "thumb_tip") + tuple(
    f"{f}_{j}" for f in FINGERS for j in ("mcp", "pip", "dip", "tip"))

#: Handedness of the built-in hand models (hand21, hand27): seen palm-on with the fingers up
#: (the built-in mount), the thumb is on the image's left, which is a left hand. A right hand's
#: landmarks are fitted mirrored (see :func:`jaxhand.landmarks.mirror_x`); a test checks it.
BUILTIN_HANDEDNESS = "left"

#: Where a fingertip landmark is: on the skin one radius past the cap centre (a detector's), or the
#: cap centre itself (a renderer's ground truth).
TIP_CONVENTIONS = ("skin", "cap_centre")

# Frame names that can carry each joint landmark, first match wins.
_JOINT_FRAMES = {
    "thumb_cmc": ("thumb_cmc_pa", "thumb_cmc", "thumb_abd", "thumb_cmc_abd"),
    "thumb_mcp": ("thumb_mcp_ab", "thumb_mcp", "thumb_mcp_abd"),
    "thumb_ip": ("thumb_ip",),
    **{f"{f}_mcp": (f"{f}_mcp", f"{f}_mcp_abd") for f in FINGERS},
    **{f"{f}_{j}": (f"{f}_{j}",) for f in FINGERS for j in ("pip", "dip")},
}
# The distal joint whose frame carries each fingertip's link.
_TIP_JOINTS = {"thumb_tip": "thumb_ip", **{f"{f}_tip": f"{f}_dip" for f in FINGERS}}


class LandmarkMap(eqx.Module):
    """Where the 21 landmarks sit on a model.

    Attributes:
        frame: static (21,). Frame each point is attached to; -1: the root (palm) frame.
        link: static (21,). Link along whose axis the point extends (fingertips); -1: none.
        present: static (21,). False where the model has no such point (its residuals are 0).
        offset_mm: traced (21, 3). Offset of the point in its frame, mm.
        tips: static. ``"skin"``: a fingertip lies ``length + radius`` along its link;
            ``"cap_centre"``: ``length`` (:data:`TIP_CONVENTIONS`).
    """

    frame: tuple[int, ...] = eqx.field(static=True)
    link: tuple[int, ...] = eqx.field(static=True)
    present: tuple[bool, ...] = eqx.field(static=True)
    offset_mm: Float[Array, "21 3"] = eqx.field(converter=jnp.asarray)
    tips: str = eqx.field(static=True, default="skin")

    def __check_init__(self):
        if self.tips not in TIP_CONVENTIONS:
            raise InputError(f"landmark map tips: expected one of {', '.join(TIP_CONVENTIONS)}, got {self.tips!r}")

    @property
    def names(self) -> tuple[str, ...]:
        return POINT_NAMES

    @property
    def jacobian_frame(self) -> np.ndarray:
        """Frame whose ancestors move each point (static): the root's points move with the base
        only, so any frame hanging off the base with no joint stands in; here the point's own
        frame, or -1 kept for the root (handled by the Jacobian)."""
        return np.array(self.frame, dtype=int)


def _joint_frame(names: tuple[str, ...], point: str) -> int:
    return next((names.index(c) for c in _JOINT_FRAMES[point] if c in names), -1)


def landmark_map(model: Model, *, tips: str = "skin") -> LandmarkMap:
    """The 21-point convention on ``model`` (built-in hands, and models using their frame names or
    an MJCF hand's, see the module docstring).

    The wrist is present when the model is a hand (it has two or more finger or thumb bases), at
    the ``palm`` frame's origin, or the root's when there is no such frame.

    Args:
        tips: where the data's fingertips are, one of :data:`TIP_CONVENTIONS`.

    Raises:
        InputError: an unknown ``tips``.
    """
    if tips not in TIP_CONVENTIONS:
        raise InputError(f"tips: expected one of {', '.join(TIP_CONVENTIONS)}, got {tips!r}")
    names = model.frame_names
    frame, link, present = [], [], []
    bases = sum(_joint_frame(names, pn) >= 0 for pn in ("thumb_cmc",) + tuple(f"{f}_mcp" for f in FINGERS))
    for pn in POINT_NAMES:
        if pn == "wrist":
            frame.append(names.index("palm") if "palm" in names else -1)
            link.append(-1)
            present.append(bases >= 2)
        elif pn in _TIP_JOINTS:
            fi = _joint_frame(names, _TIP_JOINTS[pn])
            li = model.link_frame.index(fi) if fi >= 0 and fi in model.link_frame else -1
            frame.append(fi if li >= 0 else -1)
            link.append(li)
            present.append(li >= 0)
        else:
            fi = _joint_frame(names, pn)
            frame.append(fi)
            link.append(-1)
            present.append(fi >= 0)
    return LandmarkMap(frame=tuple(frame), link=tuple(link), present=tuple(present),
                       offset_mm=np.zeros((len(POINT_NAMES), 3)), tips=tips)


def landmark_offsets(model: Model, lmap: LandmarkMap, dtype) -> Float[Array, "21 3"]:
    """Each landmark in its frame (mm): the map's offset, plus ``length + radius`` (skin tips) or
    ``length`` (cap-centre tips) along the link axis for a fingertip."""
    link = np.array(lmap.link, dtype=int)
    axis = np.array(model.link_axis, dtype=int)[np.maximum(link, 0)] if model.n_links else np.zeros(21, int)
    if model.n_links:
        length = model.link_length_mm + (model.link_radius_mm if lmap.tips == "skin" else 0.0)
        reach = jnp.where(link >= 0, length[np.maximum(link, 0)], 0.0)
    else:
        reach = jnp.zeros(21, dtype)
    return lmap.offset_mm.astype(dtype) + reach[:, None].astype(dtype) * jnp.asarray(np.eye(3)[axis], dtype)


def landmark_positions(model: Model, lmap: LandmarkMap, pose: Pose, q: Float[Array, " nq"]) -> Float[Array, "21 3"]:
    """World positions (mm) of the 21 landmarks at a pose (absent points: the root's origin)."""
    frame = np.array(lmap.frame, dtype=int)
    T_root = base_pose(model, q)
    T = jnp.where((frame < 0)[:, None, None], T_root, pose.frames[np.maximum(frame, 0)])      # (21, 4, 4)
    local = landmark_offsets(model, lmap, T.dtype)
    return jnp.einsum("pij,pj->pi", T[:, :3, :3], local) + T[:, :3, 3]
