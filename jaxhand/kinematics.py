"""Forward kinematics: q -> frame poses, link axes, tips and pill ends, in world, camera and pixels.

All functions are pure and jit-compatible; :func:`forward` and :func:`project_pose` are the
jitted entry points. The tree is composed one depth level at a time (a static loop unrolled
while tracing), so one compiled program serves every model of the same structure.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from ._errors import InputError
from .camera import Camera
from .model import Model

__all__ = ["dh_transform", "dh_transforms", "quat_to_rotation", "base_pose", "frame_poses", "Pose", "View",
           "pose", "forward", "project_pose", "check_q_shape", "views", "link_points", "validate_q", "random_q",
           "clip_q", "normalize_q", "clip_to_limits", "normalize_quaternion", "Pills", "occluder_pills", "all_pills",
           "pixel_scale"]


def dh_transform(alpha, a, d, theta):
    """Craig's modified DH link transform (thesis eq. 2.1): RotX(alpha) TransX(a) RotZ(theta) TransZ(d)."""
    ca, sa, ct, st = jnp.cos(alpha), jnp.sin(alpha), jnp.cos(theta), jnp.sin(theta)
    zero, one = jnp.zeros_like(ct), jnp.ones_like(ct)
    return jnp.stack([
        jnp.stack([ct, -st, zero, a * one], -1),
        jnp.stack([st * ca, ct * ca, -sa * one, -sa * d], -1),
        jnp.stack([st * sa, ct * sa, ca * one, ca * d], -1),
        jnp.stack([zero, zero, zero, one], -1),
    ], -2)


def dh_transforms(model: Model, q: Float[ArrayLike, " nq"]) -> Float[Array, "frames 4 4"]:
    """T_parent_frame of every frame at state q, in one batched call.

    Frames in ``model.pre_transform_frames`` get their fixed transform first:
    ``T_parent_frame = T_pre_transform @ DH``. Models without any keep the plain DH program.
    """
    idx = np.array(model.q_index)
    qf = jnp.where(idx >= 0, q[np.maximum(idx, 0)], 0.0)  # joint value per frame (0 for fixed)
    revolute = np.array([k == "revolute" for k in model.joint_kinds])
    prismatic = np.array([k == "prismatic" for k in model.joint_kinds])
    dh = model.dh
    theta = dh[:, 3] + jnp.where(revolute, qf, 0.0)
    d = dh[:, 2] + jnp.where(prismatic, qf, 0.0)
    T = dh_transform(dh[:, 0], dh[:, 1], d, theta)
    if model.pre_transform_frames:  # static: absent from the program of a plain DH model
        idx = np.array(model.pre_transform_frames)
        T = T.at[idx].set(model.T_pre_transform.astype(T.dtype) @ T[idx])
    return T


def quat_to_rotation(quat: Float[ArrayLike, 4]) -> Float[Array, "3 3"]:
    """Rotation matrix of a (w, x, y, z) quaternion, normalised first (zero maps to identity)."""
    n = jnp.linalg.norm(quat)
    # Guard: a zero quaternion has no direction; use the identity (both branches finite).
    w, x, y, z = jnp.where(n > 0, quat / jnp.where(n > 0, n, 1.0), jnp.array([1.0, 0.0, 0.0, 0.0], quat.dtype))
    return jnp.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def base_pose(model: Model, q: Float[ArrayLike, " nq"]) -> Float[Array, "4 4"]:
    """T_world_root = T_world_mount @ base motion (identity, free palm or planar palm)."""
    if model.base_kind == "fixed":
        return model.T_world_mount
    T = jnp.eye(4, dtype=q.dtype)
    if model.base_kind == "free":
        T = T.at[:3, :3].set(quat_to_rotation(q[:4])).at[:3, 3].set(q[4:7])
    else:  # planar: translation in the mount's x-y plane and yaw about its z
        c, s = jnp.cos(q[2]), jnp.sin(q[2])
        T = T.at[:2, :2].set(jnp.array([[c, -s], [s, c]])).at[0, 3].set(q[0]).at[1, 3].set(q[1])
    return model.T_world_mount @ T


def frame_poses(model: Model, q: Float[ArrayLike, " nq"]) -> Float[Array, "frames 4 4"]:
    """T_world_frame for every frame, composed one depth level at a time."""
    T_parent_frame = dh_transforms(model, q)
    T_root = base_pose(model, q)
    T_world = jnp.zeros_like(T_parent_frame)
    for level in model.levels:  # static: unrolled while tracing
        idx = np.array(level)
        parent = np.array([model.parents[i] for i in level])
        T_parent = jnp.where((parent < 0)[:, None, None], T_root, T_world[np.maximum(parent, 0)])
        T_world = T_world.at[idx].set(T_parent @ T_parent_frame[idx])
    return T_world


class Pose(eqx.Module):
    """World-frame geometry of a model at one state (mm).

    ``link_start``/``link_end`` are the two ends of each link axis (the pill's cylinder axis, whose
    hemispheres are centred on them); ``tips`` are the ends of the tip links (tip centres).
    """

    frames: Float[Array, "*b frames 4 4"]
    link_start: Float[Array, "*b links 3"]
    link_end: Float[Array, "*b links 3"]
    tips: Float[Array, "*b tips 3"]


def pose(model: Model, q: Float[ArrayLike, " nq"]) -> Pose:
    """Frame poses, link axes and tip centres in world coordinates (unjitted, for traced use;
    :func:`forward` is its jitted form)."""
    T = frame_poses(model, q)
    lf = np.array(model.link_frame, dtype=int)
    axis = np.array(model.link_axis, dtype=int)
    start = T[lf, :3, 3]
    end = start + model.link_length_mm[:, None] * T[lf, :3, axis]
    tips = end[np.array(model.tip_links, dtype=int)]
    return Pose(frames=T, link_start=start, link_end=end, tips=tips)


def check_q_shape(model: Model, q, name: str = "q") -> None:
    """Boundary check of a state given to a public entry point: shape ``(n_q,)`` always, finite
    values whenever ``q`` holds numbers (under ``jax.jit`` it holds tracers and only the shape
    is checked).

    Raises:
        InputError: naming the expected shape and the model, or the first non-finite entry.
    """
    shape = tuple(np.shape(q))
    if shape != (model.n_q,):
        raise InputError(f"{name}: expected shape ({model.n_q},) for {model.name!r} (q order: "
                         f"{', '.join(model.q_names[:4])}{', ...' if model.n_q > 4 else ''}), got {shape}")
    try:
        values = np.asarray(q)
    except jax.errors.TracerArrayConversionError:   # traced: values are checked where they enter
        return
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        raise InputError(f"{name}: entry {model.q_names[bad[0]]!r} is {values[bad[0]]} (q must be finite)")


_forward = eqx.filter_jit(pose)


def forward(model: Model, q: Float[ArrayLike, " nq"]) -> Pose:
    """Frame poses, link axes and tip centres in world coordinates (jitted; q is checked first).

    Raises:
        InputError: q is not of shape ``(n_q,)`` or not finite.
    """
    check_q_shape(model, q)
    return _forward(model, q)


class Pills(eqx.Module):
    """Pills in world coordinates (mm): segment ends and radii."""

    start: Float[Array, "*b pills 3"]
    end: Float[Array, "*b pills 3"]
    radius_mm: Float[Array, "*b pills"]


def occluder_pills(model: Model, pose: Pose) -> Pills:
    """World ends and radii of the model's occluder-only pills (palm, forearm) at ``pose``.

    They carry no link or tip features; the image front end uses them for visibility, search
    windows and the silhouette. Empty (zero pills) for a model without occluders.
    """
    T = pose.frames[..., np.array(model.occluder_frame, dtype=int), :, :]
    R, t = T[..., :3, :3], T[..., :3, 3]
    start = jnp.einsum("...ij,...j->...i", R, model.occluder_start_mm.astype(T.dtype)) + t
    end = jnp.einsum("...ij,...j->...i", R, model.occluder_end_mm.astype(T.dtype)) + t
    radius = jnp.broadcast_to(model.occluder_radius_mm.astype(T.dtype), start.shape[:-1])
    return Pills(start=start, end=end, radius_mm=radius)


def all_pills(model: Model, pose: Pose) -> Pills:
    """Every pill of the model at ``pose``: the links first (in link order), then the occluders."""
    occ = occluder_pills(model, pose)
    radius = jnp.broadcast_to(model.link_radius_mm.astype(pose.link_start.dtype), pose.link_start.shape[:-1])
    return Pills(start=jnp.concatenate([pose.link_start, occ.start], -2),
                 end=jnp.concatenate([pose.link_end, occ.end], -2),
                 radius_mm=jnp.concatenate([radius, occ.radius_mm], -1))


def link_points(pose: Pose, fractions: Float[ArrayLike, " k"]) -> Float[Array, "links k 3"]:
    """Points at the given fractions (0 = start, 1 = end) along every link axis."""
    f = jnp.asarray(fractions)[None, :, None]
    return pose.link_start[:, None] + f * (pose.link_end - pose.link_start)[:, None]


class View(eqx.Module):
    """A pose seen by one camera: pixels (x, y) and depth (mm) of joints, link ends and tips."""

    joints_px: Float[Array, "frames 2"]
    joints_depth: Float[Array, " frames"]
    link_start_px: Float[Array, "links 2"]
    link_end_px: Float[Array, "links 2"]
    link_depth: Float[Array, "links 2"]
    tips_px: Float[Array, "tips 2"]
    tips_depth: Float[Array, " tips"]
    link_radius_px: Float[Array, " links"]


def pixel_scale(camera: Camera, p_world: Float[ArrayLike, "*n 3"]) -> Float[Array, " *n"]:
    """Pixels per mm at world points: the length of the image of a short segment across the
    viewing ray there (the geometric mean of the projection's two scales; exact for orthographic
    cameras)."""
    J = camera.pixel_jacobian(p_world)
    return jnp.abs(jnp.linalg.det(J @ jnp.swapaxes(J, -1, -2))) ** 0.25


def _view(model: Model, camera: Camera, pose: Pose) -> View:
    jp, jd = camera.project(pose.frames[:, :3, 3])
    sp, sd = camera.project(pose.link_start)
    ep, ed = camera.project(pose.link_end)
    tp, td = camera.project(pose.tips)
    # Radius in pixels at the link's mid depth.
    radius_px = model.link_radius_mm * pixel_scale(camera, 0.5 * (pose.link_start + pose.link_end))
    return View(joints_px=jp, joints_depth=jd, link_start_px=sp, link_end_px=ep, link_depth=jnp.stack([sd, ed], -1),
                tips_px=tp, tips_depth=td, link_radius_px=radius_px)


@eqx.filter_jit
def _project_pose(model: Model, camera: Camera, q: Float[ArrayLike, " nq"]) -> View:
    return _view(model, camera, pose(model, q))


def project_pose(model: Model, camera: Camera, q: Float[ArrayLike, " nq"]) -> View:
    """The model at state q seen by one camera (jitted; q is checked first).

    Raises:
        InputError: q is not of shape ``(n_q,)`` or not finite.
    """
    check_q_shape(model, q)
    return _project_pose(model, camera, q)


def views(model: Model, cameras, q) -> tuple[View, ...]:
    """One :class:`View` per camera of a rig."""
    from .camera import as_rig

    return tuple(project_pose(model, c, q) for c in as_rig(cameras))


# ---- boundary helpers (NumPy) ----

def validate_q(model: Model, q, *, name: str = "q", within_limits: bool = False) -> np.ndarray:
    """Check a user state vector: shape (n_q,), finite, and optionally inside the joint limits.

    Raises:
        InputError: naming the offending entry by its joint name.
    """
    try:
        arr = np.asarray(q, dtype=float)
    except (TypeError, ValueError) as err:
        raise InputError(f"{name}: cannot convert to a float array ({err})") from err
    if arr.shape != (model.n_q,):
        raise InputError(f"{name}: expected shape ({model.n_q},) for model {model.name!r}, got {arr.shape}")
    bad = ~np.isfinite(arr)
    if bad.any():
        raise InputError(f"{name}: non-finite value for {model.q_names[int(np.argmax(bad))]!r}")
    if within_limits:
        lo, hi = np.asarray(model.q_lower), np.asarray(model.q_upper)
        out = (arr < lo - 1e-12) | (arr > hi + 1e-12)
        if out.any():
            i = int(np.argmax(out))
            conv = np.degrees if model.is_angle[i] else float
            unit = " deg" if model.is_angle[i] else ""
            raise InputError(f"{name}: {model.q_names[i]!r} = {conv(arr[i]):.6g}{unit} lies outside its limits "
                             f"[{conv(lo[i]):.6g}, {conv(hi[i]):.6g}]{unit}")
    return arr


def normalize_quaternion(q, has_quaternion: bool):
    """q with its leading (w, x, y, z) quaternion scaled to unit norm when ``has_quaternion``
    (static); the one normalisation rule of the kinematics, the solvers and the tracker."""
    if not has_quaternion:
        return q
    quat = q[..., :4]
    n = jnp.linalg.norm(quat, axis=-1, keepdims=True)
    # Guard: a zero quaternion cannot be normalised; it stays zero (the kinematics map it to the
    # identity), and the safe denominator keeps both branches finite.
    safe = jnp.where(n > 0, n, 1.0)
    return q.at[..., :4].set(jnp.where(n > 0, quat / safe, quat))


def clip_to_limits(q, lower, upper, has_quaternion: bool):
    """q clipped into [lower, upper], every entry but a quaternion's (whose box is implied by
    its unit norm): the one clip rule of the kinematics, the solvers and the tracker."""
    if not has_quaternion:
        return jnp.clip(q, lower, upper)
    bounded = np.arange(q.shape[-1]) >= 4   # static: all but the quaternion's entries
    return jnp.where(bounded, jnp.clip(q, lower, upper), q)


def normalize_q(model: Model, q):
    """q with the free base's quaternion renormalised to unit length (identity otherwise)."""
    return normalize_quaternion(q, model.base_kind == "free")


def clip_q(model: Model, q):
    """q clipped into the joint limits (:func:`clip_to_limits`), quaternion renormalised."""
    free = model.base_kind == "free"
    return normalize_quaternion(clip_to_limits(q, model.q_lower, model.q_upper, free), free)


def random_q(model: Model, rng: np.random.Generator, n: int | None = None, *, margin: float = 0.0,
             translation_mm: float = 50.0) -> np.ndarray:
    """Random states within the joint limits (uniform, shrunk by ``margin`` of each range).

    A free base gets a uniformly random unit quaternion and a translation within
    ``translation_mm`` of its default; a planar base keeps (x, y) within that distance too.
    """
    shape = () if n is None else (n,)
    lo, hi = np.asarray(model.q_lower), np.asarray(model.q_upper)
    span = hi - lo
    q = rng.uniform(lo + margin * span, hi - margin * span, size=shape + (model.n_q,))
    q0 = np.asarray(model.q_default)
    if model.base_kind == "free":
        quat = rng.normal(size=shape + (4,))
        q[..., :4] = quat / np.linalg.norm(quat, axis=-1, keepdims=True)
        q[..., 4:7] = q0[4:7] + rng.uniform(-translation_mm, translation_mm, size=shape + (3,))
    elif model.base_kind == "planar":
        q[..., :2] = q0[:2] + rng.uniform(-translation_mm, translation_mm, size=shape + (2,))
    return q
