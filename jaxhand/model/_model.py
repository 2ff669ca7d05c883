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

__all__ = ["Model", "JOINT_KINDS", "BASE_KINDS", "AXES"]

JOINT_KINDS = ("revolute", "prismatic", "fixed")
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

    q layout: the base entries first (``BASE_Q_NAMES``), then one entry per moving frame in frame
    order. Every frame may carry a pill (cylinder + hemispheres) along one of its axes starting
    at the frame origin; a link flagged as a tip gives a tip feature at its far end.

    Static fields (changing them recompiles): name, frame_names, parents, joint_kinds, q_index,
    base_kind, q_names, link_names, link_frame, link_axis, tip_links.
    Traced fields (arrays): dh, T_world_mount, q_lower, q_upper, q_default, link_length_mm,
    link_radius_mm.
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

    def __check_init__(self):
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

    def structure(self) -> tuple:
        """Everything static about the model; equal structures share compiled code."""
        return (self.name, self.frame_names, self.parents, self.joint_kinds, self.q_index, self.base_kind,
                self.q_names, self.link_names, self.link_frame, self.link_axis, self.tip_links)

    def with_lengths(self, scale: float) -> Model:
        """The same structure with every length scaled (DH a and d, mount, pills, prismatic limits)."""
        lengths = jnp.asarray(np.where(self.is_angle | (np.array(self.q_kinds) == "quat"), 1.0, scale))
        dh = self.dh.at[:, 1:3].multiply(scale)
        mount = self.T_world_mount.at[:3, 3].multiply(scale)
        return eqx.tree_at(
            lambda m: (m.dh, m.T_world_mount, m.link_length_mm, m.link_radius_mm, m.q_lower, m.q_upper, m.q_default),
            self,
            (dh, mount, self.link_length_mm * scale, self.link_radius_mm * scale,
             self.q_lower * lengths, self.q_upper * lengths, self.q_default * lengths),
        )
