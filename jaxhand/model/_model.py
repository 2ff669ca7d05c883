"""The kinematic tree: frames, modified-DH rows, joints, limits, pills, base.

A :class:`Model` is an immutable pytree. Its *structure* (the tree, which q entry drives which
frame, which frames carry pills, which links end in tips, the base kind) is static and part of
every compiled program; its *numbers* (DH parameters, base mount, limits, pill sizes) are
arrays, so a model of the same structure with other lengths reuses compiled code.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._precision import require_x64

__all__ = ["Model", "JOINT_KINDS", "BASE_KINDS", "AXES", "HANDEDNESS"]

JOINT_KINDS = ("revolute", "prismatic", "fixed")
#: ``model.handedness``: a right or left hand, or "none" (not a hand, or not stated).
HANDEDNESS = ("right", "left", "none")
BASE_KINDS = ("fixed", "free", "planar")
AXES = ("x", "y", "z")

#: q entries the base contributes, by base kind, in the order they sit at the front of q.
BASE_Q_NAMES = {
    "fixed": (),
    "free": ("palm_qw", "palm_qx", "palm_qy", "palm_qz", "palm_tx", "palm_ty", "palm_tz"),
    "planar": ("palm_x", "palm_y", "palm_yaw"),
}
#: Kind of each base q entry: "quat" (unitless), "length" (mm) or "angle" (rad).
BASE_Q_KINDS = {
    "fixed": (),
    "free": ("quat",) * 4 + ("length",) * 3,
    "planar": ("length", "length", "angle"),
}


def _empty(*shape):
    """Default factory of an empty traced field (no fixed transforms, no occluders)."""
    return lambda: np.zeros(shape)


def _levels(parents: tuple[int, ...]) -> tuple[tuple[int, ...], ...]:
    depth: list[int] = []
    for p in parents:
        depth.append(0 if p < 0 else depth[p] + 1)
    if not depth:
        return ()
    return tuple(tuple(i for i, d in enumerate(depth) if d == k) for k in range(max(depth) + 1))


class Model(eqx.Module):
    """An articulated model: a tree of modified-DH frames on a fixed, free or planar base.

    Frame ``i`` is placed relative to its parent by Craig's modified DH transform (thesis eq. 2.1)
    ``T = RotX(alpha_{i-1}) TransX(a_{i-1}) RotZ(theta_i) TransZ(d_i)``. A revolute joint adds its q
    entry to ``theta_i``, a prismatic joint to ``d_i``; a fixed (auxiliary) frame has no q entry.
    Frames whose parent is -1 hang off the base, whose world pose is
    ``T_world_mount @ base_motion(q_base)``: identity for a fixed base, quaternion + translation
    for a free palm (DigitEyes §3.1) and (x, y, yaw) in the mount's x-y plane for a planar base.

    A frame listed in ``pre_transform_frames`` has a general fixed transform applied *before* its
    DH transform, ``T_parent_frame = T_pre_transform @ DH``: imported MJCF/URDF bodies use it
    for their offsets and quaternions. With none listed, the kinematics are those of the plain
    DH tree, bit for bit.

    q layout: the base entries first (``BASE_Q_NAMES``), then one entry per moving frame in frame
    order. Every frame may carry a pill (cylinder + hemispheres) along one of its axes starting
    at the frame origin; a link flagged as a tip gives a tip feature at its far end. Occluder
    pills (a palm, a forearm) are attached to a frame as a segment in frame coordinates; they
    hide links and belong to the silhouette, but carry no link or tip features
    (:func:`jaxhand.kinematics.occluder_pills` gives their world ends).

    Static fields (changing them recompiles): name, frame_names, parents, joint_kinds, q_index,
    base_kind, q_names, link_names, link_frame, link_axis, tip_links, pre_transform_frames,
    occluder_names, occluder_frame, handedness.
    Traced fields (arrays): dh, T_world_mount, q_lower, q_upper, q_default, link_length_mm,
    link_radius_mm, T_pre_transform, occluder_start_mm, occluder_end_mm, occluder_radius_mm.
    """

    name: str = eqx.field(static=True)
    frame_names: tuple[str, ...] = eqx.field(static=True)
    parents: tuple[int, ...] = eqx.field(static=True)
    joint_kinds: tuple[str, ...] = eqx.field(static=True)
    q_index: tuple[int, ...] = eqx.field(static=True)
    base_kind: str = eqx.field(static=True)
    q_names: tuple[str, ...] = eqx.field(static=True)
    link_names: tuple[str, ...] = eqx.field(static=True)
    link_frame: tuple[int, ...] = eqx.field(static=True)
    link_axis: tuple[int, ...] = eqx.field(static=True)
    tip_links: tuple[int, ...] = eqx.field(static=True)

    dh: Float[Array, "frames 4"] = eqx.field(converter=jnp.asarray)
    T_world_mount: Float[Array, "4 4"] = eqx.field(converter=jnp.asarray)
    q_lower: Float[Array, " nq"] = eqx.field(converter=jnp.asarray)
    q_upper: Float[Array, " nq"] = eqx.field(converter=jnp.asarray)
    q_default: Float[Array, " nq"] = eqx.field(converter=jnp.asarray)
    link_length_mm: Float[Array, " links"] = eqx.field(converter=jnp.asarray)
    link_radius_mm: Float[Array, " links"] = eqx.field(converter=jnp.asarray)

    #: Static: frames with a fixed transform before their DH transform, in frame order.
    pre_transform_frames: tuple[int, ...] = eqx.field(static=True, default=())
    #: Traced: ``T_parent_pre`` of each frame in ``pre_transform_frames`` (rotation + translation, mm).
    T_pre_transform: Float[Array, "pre 4 4"] = eqx.field(converter=jnp.asarray, default_factory=_empty(0, 4, 4))
    #: Static: names of the occluder-only pills (no link or tip features).
    occluder_names: tuple[str, ...] = eqx.field(static=True, default=())
    #: Static: frame each occluder pill is attached to.
    occluder_frame: tuple[int, ...] = eqx.field(static=True, default=())
    #: Traced: the occluders' segment ends in their frame's coordinates (mm).
    occluder_start_mm: Float[Array, "occluders 3"] = eqx.field(converter=jnp.asarray, default_factory=_empty(0, 3))
    occluder_end_mm: Float[Array, "occluders 3"] = eqx.field(converter=jnp.asarray, default_factory=_empty(0, 3))
    #: Traced: the occluders' radii (mm).
    occluder_radius_mm: Float[Array, " occluders"] = eqx.field(converter=jnp.asarray, default_factory=_empty(0))
    #: Static: "right", "left" or "none" (see :func:`jaxhand.model.mirror_model`).
    handedness: str = eqx.field(static=True, default="none")

    def __check_init__(self):
        require_x64("Model")
        n = len(self.frame_names)
        for field in ("parents", "joint_kinds", "q_index"):
            if len(getattr(self, field)) != n:
                raise ValueError(f"Model.{field}: expected {n} entries, got {len(getattr(self, field))}")
        if self.dh.shape != (n, 4):
            raise ValueError(f"Model.dh: expected shape ({n}, 4), got {self.dh.shape}")
        nq = len(self.q_names)
        for field in ("q_lower", "q_upper", "q_default"):
            if getattr(self, field).shape != (nq,):
                raise ValueError(f"Model.{field}: expected shape ({nq},), got {getattr(self, field).shape}")
        nl = len(self.link_names)
        if len(self.link_frame) != nl or len(self.link_axis) != nl:
            raise ValueError("Model: link_frame and link_axis need one entry per link")
        if self.link_length_mm.shape != (nl,) or self.link_radius_mm.shape != (nl,):
            raise ValueError(f"Model: link_length_mm and link_radius_mm need shape ({nl},)")
        npre = len(self.pre_transform_frames)
        if self.T_pre_transform.shape != (npre, 4, 4):
            raise ValueError(f"Model.T_pre_transform: expected shape ({npre}, 4, 4), got {self.T_pre_transform.shape}")
        no = len(self.occluder_names)
        if len(self.occluder_frame) != no:
            raise ValueError("Model: occluder_frame needs one entry per occluder")
        for field, shape in (("occluder_start_mm", (no, 3)), ("occluder_end_mm", (no, 3)),
                             ("occluder_radius_mm", (no,))):
            if getattr(self, field).shape != shape:
                raise ValueError(f"Model.{field}: expected shape {shape}, got {getattr(self, field).shape}")
        if self.handedness not in HANDEDNESS:
            raise ValueError(f"Model.handedness: expected one of {HANDEDNESS}, got {self.handedness!r}")

    # ---- derived structure (static, cheap) ----
    @property
    def n_q(self) -> int:
        """Length of the state vector q (the free base's quaternion counts 4)."""
        return len(self.q_names)

    @property
    def dof(self) -> int:
        """Degrees of freedom: n_q, less one for a free base's redundant quaternion entry."""
        return self.n_q - (1 if self.base_kind == "free" else 0)

    @property
    def n_base_q(self) -> int:
        return len(BASE_Q_NAMES[self.base_kind])

    @property
    def n_frames(self) -> int:
        return len(self.frame_names)

    @property
    def n_links(self) -> int:
        return len(self.link_names)

    @property
    def n_tips(self) -> int:
        return len(self.tip_links)

    @property
    def n_occluders(self) -> int:
        return len(self.occluder_names)

    @property
    def tip_names(self) -> tuple[str, ...]:
        return tuple(self.link_names[i] for i in self.tip_links)

    @property
    def levels(self) -> tuple[tuple[int, ...], ...]:
        """Frame indices grouped by depth in the tree (level 0 hangs off the base)."""
        return _levels(self.parents)

    @property
    def q_kinds(self) -> tuple[str, ...]:
        """Per q entry: 'quat', 'length' (mm) or 'angle' (rad)."""
        kinds = list(BASE_Q_KINDS[self.base_kind])
        for f, k in enumerate(self.joint_kinds):
            if self.q_index[f] >= 0:
                kinds.append("angle" if k == "revolute" else "length")
        return tuple(kinds)

    @property
    def is_angle(self) -> np.ndarray:
        """Boolean mask over q of the entries in radians (shown in degrees at the edges)."""
        return np.array([k == "angle" for k in self.q_kinds])

    @property
    def ancestors(self) -> np.ndarray:
        """(frames, frames) bool: ``ancestors[f, j]`` is True when frame j is f or above f."""
        a = np.zeros((self.n_frames, self.n_frames), dtype=bool)
        for f in range(self.n_frames):
            j = f
            while j >= 0:
                a[f, j] = True
                j = self.parents[j]
        return a

    def q_lookup(self, name: str) -> int:
        """Index of the q entry called ``name``; the error lists the valid names."""
        try:
            return self.q_names.index(name)
        except ValueError:
            raise KeyError(f"model {self.name!r} has no q entry {name!r}; valid: {', '.join(self.q_names)}") from None

    def frame_lookup(self, name: str) -> int:
        try:
            return self.frame_names.index(name)
        except ValueError:
            raise KeyError(f"model {self.name!r} has no frame {name!r}; valid: {', '.join(self.frame_names)}") from None

    def link_lookup(self, name: str) -> int:
        try:
            return self.link_names.index(name)
        except ValueError:
            raise KeyError(f"model {self.name!r} has no link {name!r}; valid: {', '.join(self.link_names)}") from None

    def occluder_lookup(self, name: str) -> int:
        """Index of the occluder pill called ``name``; the error lists the valid names."""
        try:
            return self.occluder_names.index(name)
        except ValueError:
            raise KeyError(f"model {self.name!r} has no occluder {name!r}; valid: "
                           f"{', '.join(self.occluder_names) or '(none)'}") from None

    def structure(self) -> tuple:
        """Everything static about the model; equal structures share compiled code."""
        return (self.name, self.frame_names, self.parents, self.joint_kinds, self.q_index, self.base_kind,
                self.q_names, self.link_names, self.link_frame, self.link_axis, self.tip_links,
                self.pre_transform_frames, self.occluder_names, self.occluder_frame, self.handedness)

    def with_lengths(self, scale: float) -> Model:
        """The same structure with every length scaled (DH a and d, mount, fixed transforms, pills,
        occluders, prismatic limits)."""
        lengths = jnp.asarray(np.where(self.is_angle | (np.array(self.q_kinds) == "quat"), 1.0, scale))
        dh = self.dh.at[:, 1:3].multiply(scale)
        mount = self.T_world_mount.at[:3, 3].multiply(scale)
        pre = self.T_pre_transform.at[:, :3, 3].multiply(scale)
        return eqx.tree_at(
            lambda m: (m.dh, m.T_world_mount, m.link_length_mm, m.link_radius_mm, m.q_lower, m.q_upper, m.q_default,
                       m.T_pre_transform, m.occluder_start_mm, m.occluder_end_mm, m.occluder_radius_mm),
            self,
            (dh, mount, self.link_length_mm * scale, self.link_radius_mm * scale,
             self.q_lower * lengths, self.q_upper * lengths, self.q_default * lengths, pre,
             self.occluder_start_mm * scale, self.occluder_end_mm * scale, self.occluder_radius_mm * scale),
        )
