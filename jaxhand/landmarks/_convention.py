"""The 21-point hand landmark convention and where each point sits on a model.

The order is MediaPipe's and OpenPose's: the wrist; the thumb's CMC, MCP, IP and tip; then the
index, middle, ring and little fingers' MCP, PIP, DIP and tip (:data:`POINT_NAMES`).

What a landmark is, on the model:

- a joint landmark (CMC, MCP, PIP, DIP, IP) is the origin of the joint's frame;
- a fingertip landmark is on the skin at the end of the finger, which a detector sees. The
  model's tip is the centre of the distal pill's cap, so the landmark lies one pill radius
  further along the distal axis: ``origin + (length + radius) * axis``;
- the wrist is not a finger joint: it is a point fixed to the palm (the root frame of the hand;
  the built-in hands' palm rows start there, the finger bases 68-85 mm from it).

A :class:`LandmarkMap` stores, for each of the 21 names, the frame it is attached to, the link
whose length and radius it extends along (tips only) and a fixed offset in that frame. Points a
model lacks (an index-only model has no thumb) are absent: their residuals are always zero.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from ..kinematics import Pose, base_pose
from ..model import Model

__all__ = ["POINT_NAMES", "FINGERS", "LandmarkMap", "landmark_map", "landmark_positions", "landmark_offsets",
           "BUILTIN_HANDEDNESS"]

FINGERS = ("index", "middle", "ring", "little")
#: The 21 landmark names in MediaPipe/OpenPose order.
POINT_NAMES: tuple[str, ...] = ("wrist", "thumb_cmc", "thumb_mcp", "thumb_ip", "thumb_tip") + tuple(
    f"{f}_{j}" for f in FINGERS for j in ("mcp", "pip", "dip", "tip"))

#: Handedness of the built-in hand models (hand21, hand27): seen palm-on with the fingers up
#: (the built-in mount), the thumb is on the image's left, which is a left hand. A right hand's
#: landmarks are fitted mirrored (see :func:`jaxhand.landmarks.mirror_x`); a test checks it.
BUILTIN_HANDEDNESS = "left"

# Frame names that can carry each joint landmark, first match wins.
_JOINT_FRAMES = {
    "thumb_cmc": ("thumb_cmc_pa", "thumb_cmc", "thumb_abd"),
    "thumb_mcp": ("thumb_mcp_ab", "thumb_mcp"),
    "thumb_ip": ("thumb_ip",),
    **{f"{f}_{j}": (f"{f}_{j}",) for f in FINGERS for j in ("mcp", "pip", "dip")},
}
_TIP_LINKS = {"thumb_tip": "thumb_ip", **{f"{f}_tip": f"{f}_dip" for f in FINGERS}}


class LandmarkMap(eqx.Module):
    """Where the 21 landmarks sit on a model.

    Attributes:
        frame: static (21,). Frame each point is attached to; -1: the root (palm) frame.
        link: static (21,). Link whose ``length + radius`` the point extends along that link's
            axis (fingertips); -1: none.
        present: static (21,). False where the model has no such point (its residuals are 0).
        offset_mm: traced (21, 3). Offset of the point in its frame, mm.
    """

    frame: tuple[int, ...] = eqx.field(static=True)
    link: tuple[int, ...] = eqx.field(static=True)
    present: tuple[bool, ...] = eqx.field(static=True)
    offset_mm: Float[Array, "21 3"] = eqx.field(converter=jnp.asarray)

    @property
    def names(self) -> tuple[str, ...]:
        return POINT_NAMES

    @property
    def jacobian_frame(self) -> np.ndarray:
        """Frame whose ancestors move each point (static): the root's points move with the base
        only, so any frame hanging off the base with no joint stands in; here the point's own
        frame, or -1 kept for the root (handled by the Jacobian)."""
        return np.array(self.frame, dtype=int)


def landmark_map(model: Model) -> LandmarkMap:
    """The 21-point convention on ``model`` (built-in hands and any model using their frame names).

    The wrist is present when the model has a palm (two or more finger or thumb bases hang off
    the root), at the root's origin.
    """
    names = model.frame_names
    frame, link, present = [], [], []
    base_children = sum(1 for p in model.parents if p < 0)
    for pn in POINT_NAMES:
        if pn == "wrist":
            ok = base_children >= 2 and any(n.endswith("_mcp") for n in names)
            frame.append(-1)
            link.append(-1)
            present.append(ok)
        elif pn in _TIP_LINKS:
            ln = _TIP_LINKS[pn]
            if ln in model.link_names:
                li = model.link_names.index(ln)
                frame.append(model.link_frame[li])
                link.append(li)
                present.append(True)
            else:
                frame.append(-1)
                link.append(-1)
                present.append(False)
        else:
            fi = next((names.index(c) for c in _JOINT_FRAMES[pn] if c in names), -1)
            frame.append(fi)
            link.append(-1)
            present.append(fi >= 0)
    return LandmarkMap(frame=tuple(frame), link=tuple(link), present=tuple(present),
                       offset_mm=np.zeros((len(POINT_NAMES), 3)))


def landmark_offsets(model: Model, lmap: LandmarkMap, dtype) -> Float[Array, "21 3"]:
    """Each landmark in its frame (mm): the map's offset, plus ``length + radius`` along the
    link axis for a fingertip."""
    link = np.array(lmap.link, dtype=int)
    axis = np.array(model.link_axis, dtype=int)[np.maximum(link, 0)] if model.n_links else np.zeros(21, int)
    if model.n_links:
        reach = jnp.where(link >= 0, (model.link_length_mm + model.link_radius_mm)[np.maximum(link, 0)], 0.0)
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
