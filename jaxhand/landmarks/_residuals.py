"""Landmark (keypoint) residuals: 2-D in pixels per camera, 3-D in mm, stacked after the link and
tip residuals of :mod:`jaxhand.residuals`.

For landmark ``i`` at model point ``p_i(q)`` (:mod:`._convention`):

- 2-D, camera c: ``sqrt(w_ci) * (pi_c(p_i(q)) - x_ci)``, two entries (x, y) in pixels;
- 3-D: ``sqrt(v_i) * (p_i(q) - X_i)`` in mm, three entries, with ``p_i`` in the world frame or
  in the frame of the rig's first camera (``Landmarks.frame_3d``).

Layout (static): for each camera in rig order ``2 * 21`` entries (point-major, then x, y), then
``3 * 21`` entries of the 3-D points. Weights multiply (a detector's confidence, or an inverse
variance); a masked point, or one the model lacks, gives exact zeros, and its observed numbers are
replaced before any arithmetic, so NaN in a masked slot reaches neither residual nor Jacobian.
A 3-D weight is in px^2/mm^2: it says how many pixels of 2-D error one millimetre is worth.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float

from .._errors import InputError
from ..camera import as_rig
from ..kinematics import pose as pose_at
from ..model import Model
from ..residuals import ResidualArgs, point_jacobian, residuals, residuals_and_jacobian
from ..solve.internal import SparsePattern, lane_contract, lane_frames, lane_point_jacobian, lane_root, point_dependence
from ._convention import POINT_NAMES, LandmarkMap, landmark_map, landmark_offsets, landmark_positions

__all__ = ["Landmarks", "LandmarkArgs", "make_landmarks", "make_landmark_args", "landmark_residuals",
           "landmark_residuals_and_jacobian", "stacked_residuals", "stacked_residuals_and_jacobian",
           "landmark_residual_labels", "FRAMES_3D"]

N_POINTS = len(POINT_NAMES)
FRAMES_3D = ("camera", "world")


class Landmarks(eqx.Module):
    """Observed landmarks of one frame (traced arrays; ``frame_3d`` static). Batched fits give
    every array a leading batch axis.

    Attributes:
        px: (cams, 21, 2) pixel positions (x, y), origin at the centre of the top-left pixel.
        px_valid: (cams, 21) True where the point was observed in that camera.
        px_weight: (cams, 21) weight of each 2-D point (e.g. a confidence), >= 0.
        mm: (21, 3) 3-D positions, mm.
        mm_valid: (21,) True where the 3-D point is given.
        mm_weight: (21,) weight of each 3-D point, px^2 per mm^2.
        frame_3d: static. ``"camera"`` (the rig's first camera) or ``"world"``.
    """

    px: Float[Array, "*b cams 21 2"]
    px_valid: Bool[Array, "*b cams 21"]
    px_weight: Float[Array, "*b cams 21"]
    mm: Float[Array, "*b 21 3"]
    mm_valid: Bool[Array, "*b 21"]
    mm_weight: Float[Array, "*b 21"]
    frame_3d: str = eqx.field(static=True, default="camera")


def make_landmarks(px=None, *, n_cameras: int | None = None, px_valid=None, px_weight=None, mm=None, mm_valid=None,
                   mm_weight=1.0, frame_3d: str = "camera") -> Landmarks:
    """Landmarks of one frame (or a batch: leading axes before ``(cams, 21, 2)``) from arrays.

    Missing points may be NaN: they are masked out (``px_valid`` defaults to "finite").

    Args:
        px: (cams, 21, 2) or (21, 2) for one camera; None for no 2-D points.
        n_cameras: cameras when ``px`` is None (default 1).
        px_valid, px_weight: (cams, 21) masks and weights (default: finite, 1).
        mm: (21, 3) 3-D points or None; mm_valid, mm_weight likewise.
        frame_3d: frame of ``mm``: ``"camera"`` (the first camera's) or ``"world"``.

    Raises:
        InputError: wrong shapes, negative or non-finite weights, unknown frame.
    """
    if frame_3d not in FRAMES_3D:
        raise InputError(f"frame_3d: expected one of {', '.join(FRAMES_3D)}, got {frame_3d!r}")
    if px is None:
        nc = 1 if n_cameras is None else int(n_cameras)
        px = np.full((nc, N_POINTS, 2), np.nan)
    px = np.asarray(px, dtype=float)
    if px.ndim == 2:   # one camera
        px = px[None]
    if px.ndim < 3 or px.shape[-2:] != (N_POINTS, 2):
        raise InputError(f"landmarks px: expected shape (cams, {N_POINTS}, 2), got {px.shape}")
    batch = px.shape[:-3]
    nc = px.shape[-3]
    valid = np.all(np.isfinite(px), -1)
    if px_valid is not None:
        valid = valid & np.asarray(px_valid, bool)
    weight = np.broadcast_to(np.asarray(1.0 if px_weight is None else px_weight, float), batch + (nc, N_POINTS))
    if mm is None:
        mm = np.full(batch + (N_POINTS, 3), np.nan)
    mm = np.asarray(mm, dtype=float)
    if mm.shape != batch + (N_POINTS, 3):
        raise InputError(f"landmarks mm: expected shape {batch + (N_POINTS, 3)}, got {mm.shape}")
    mvalid = np.all(np.isfinite(mm), -1)
    if mm_valid is not None:
        mvalid = mvalid & np.asarray(mm_valid, bool)
    mweight = np.broadcast_to(np.asarray(mm_weight, float), batch + (N_POINTS,))
    for name, w in (("px_weight", weight), ("mm_weight", mweight)):
        if not np.all(np.isfinite(w)) or np.any(w < 0):
            raise InputError(f"landmarks {name}: weights must be finite and >= 0")
    return Landmarks(px=jnp.asarray(np.where(valid[..., None], px, 0.0)), px_valid=jnp.asarray(valid),
                     px_weight=jnp.asarray(np.array(weight)), mm=jnp.asarray(np.where(mvalid[..., None], mm, 0.0)),
                     mm_valid=jnp.asarray(mvalid), mm_weight=jnp.asarray(np.array(mweight)), frame_3d=frame_3d)


class LandmarkArgs(eqx.Module):
    """The optimistix ``args`` of :func:`stacked_residuals`.

    Attributes:
        model, cameras: the model and rig.
        lmap: where the landmarks sit on the model.
        landmarks: the observed :class:`Landmarks`.
        edges: optional :class:`~jaxhand.residuals.ResidualArgs` of link and tip features; their
            residuals come first in the stack. None: landmarks only.
    """

    model: Model
    cameras: tuple
    lmap: LandmarkMap
    landmarks: Landmarks
    edges: ResidualArgs | None = None


def make_landmark_args(model: Model, cameras, landmarks: Landmarks, *, lmap: LandmarkMap | None = None,
                       edges: ResidualArgs | None = None) -> LandmarkArgs:
    """Bundle the residuals' inputs, checking the landmarks against the rig.

    Raises:
        InputError: the landmarks' camera count differs from the rig's.
    """
    rig = as_rig(cameras)
    if not isinstance(landmarks, Landmarks):
        raise InputError(f"landmarks: expected Landmarks, got {type(landmarks).__name__}")
    if landmarks.px.shape[-3] != len(rig):
        raise InputError(f"landmarks: {landmarks.px.shape[-3]} camera(s) of 2-D points for a rig of {len(rig)}")
    return LandmarkArgs(model=model, cameras=rig, lmap=landmark_map(model) if lmap is None else lmap,
                        landmarks=landmarks, edges=edges)


def _weights(args: LandmarkArgs, dtype):
    lm = args.landmarks
    present = jnp.asarray(np.array(args.lmap.present))
    w2 = jnp.where(lm.px_valid & present, lm.px_weight, 0.0).astype(dtype)
    w3 = jnp.where(lm.mm_valid & present, lm.mm_weight, 0.0).astype(dtype)
    return jnp.sqrt(w2), jnp.sqrt(w3)


def _to_frame_3d(args: LandmarkArgs, p_world):
    if args.landmarks.frame_3d == "camera":
        return args.cameras[0].to_camera(p_world)
    return p_world


def landmark_residuals(q: Float[Array, " nq"], args: LandmarkArgs, pose=None) -> Float[Array, " r"]:
    """The landmark residuals at state q: every camera's 2-D entries (px), then the 3-D ones (mm
    times sqrt(weight))."""
    model = args.model
    pose = pose_at(model, q) if pose is None else pose
    p = landmark_positions(model, args.lmap, pose, q)
    s2, s3 = _weights(args, p.dtype)
    out = []
    for c, cam in enumerate(args.cameras):
        px, _ = cam.project(p)
        out.append(((px - args.landmarks.px[c].astype(p.dtype)) * s2[c][:, None]).reshape(-1))
    out.append(((_to_frame_3d(args, p) - args.landmarks.mm.astype(p.dtype)) * s3[:, None]).reshape(-1))
    return jnp.concatenate(out)


def _jacobian_frames(model: Model, lmap: LandmarkMap) -> np.ndarray:
    """Per point, a frame with the same moving ancestors: the root's points use a fixed frame
    that hangs off the base (moved by the base only), or frame 0 when there is none (such a
    model has no wrist: the point is absent and its rows are zero)."""
    frames = np.array(lmap.frame, dtype=int)
    fixed_roots = [f for f in range(model.n_frames) if model.parents[f] < 0 and model.q_index[f] < 0]
    return np.where(frames < 0, fixed_roots[0] if fixed_roots else 0, frames)


def _pixels_and_jacobian(camera, points):
    """Pixels of world points and d pixel / d p_world (forward-mode through the camera alone)."""
    def one(p):
        px = camera.project(p)[0]
        return px, px

    J, px = jax.vmap(jax.jacfwd(one, has_aux=True))(points)
    return px, J


def landmark_residuals_and_jacobian(q: Float[Array, " nq"], args: LandmarkArgs, pose=None
                                    ) -> tuple[Float[Array, " r"], Float[Array, "r nq"]]:
    """:func:`landmark_residuals` and their Jacobian from the geometric Jacobian of the landmark
    points (:func:`jaxhand.residuals.point_jacobian`) chained with each camera's."""
    model = args.model
    pose = pose_at(model, q) if pose is None else pose
    p = landmark_positions(model, args.lmap, pose, q)
    Jp = point_jacobian(model, q, pose.frames, p, _jacobian_frames(model, args.lmap))     # (21, 3, nq)
    s2, s3 = _weights(args, p.dtype)
    rs, Js = [], []
    for c, cam in enumerate(args.cameras):
        px, dpx = _pixels_and_jacobian(cam, p)
        rs.append(((px - args.landmarks.px[c].astype(p.dtype)) * s2[c][:, None]).reshape(-1))
        Js.append((jnp.einsum("pij,pjq->piq", dpx, Jp) * s2[c][:, None, None]).reshape(-1, model.n_q))
    if args.landmarks.frame_3d == "camera":
        R = args.cameras[0].R.astype(p.dtype)
        J3 = jnp.einsum("ij,pjq->piq", R, Jp)
    else:
        J3 = Jp
    rs.append(((_to_frame_3d(args, p) - args.landmarks.mm.astype(p.dtype)) * s3[:, None]).reshape(-1))
    Js.append((J3 * s3[:, None, None]).reshape(-1, model.n_q))
    return jnp.concatenate(rs), jnp.concatenate(Js)


def _dependence(model: Model, lmap: LandmarkMap) -> np.ndarray:
    """(21, n_q) static: which q entries move each (present) landmark."""
    return point_dependence(model, _jacobian_frames(model, lmap)) & np.array(lmap.present)[:, None]


def _row_major(dep: np.ndarray, width: int) -> np.ndarray:
    """Positions, in a (pairs, width) array of (point, q) pairs, of the compact order of rows
    (point, component) then q entries."""
    start = np.concatenate([[0], np.cumsum(dep.sum(axis=1))])
    return np.array([t * width + a for i in range(dep.shape[0]) for a in range(width)
                     for t in range(start[i], start[i + 1])], dtype=int)


def lane_jacobian_pattern(model: Model, lmap: LandmarkMap, n_cameras: int, *, use_3d: bool = True) -> SparsePattern:
    """The static nonzero pattern of :func:`lane_residuals_and_jacobian`'s J (absent points: none)."""
    dep = _dependence(model, lmap)
    blocks = [np.repeat(dep, 2, axis=0)] * n_cameras + ([np.repeat(dep, 3, axis=0)] if use_3d else [])
    return SparsePattern(np.concatenate(blocks))


def lane_residuals_and_jacobian(q: Float[Array, "nq B"], args: LandmarkArgs, *, use_3d: bool = True
                                ) -> tuple[Float[Array, "r B"], Float[Array, "nnz B"]]:
    """:func:`landmark_residuals_and_jacobian` of B problems at once, lanes last: ``q`` is
    (n_q, B), ``args.landmarks`` has a leading batch axis B, and J comes as its structural
    nonzeros in the order of :func:`lane_jacobian_pattern` (kernels of
    :mod:`jaxhand.solve.internal`). ``use_3d`` (static) False leaves out the 3-D rows, for a batch
    without any 3-D point (their residuals are zero: the cost is the same)."""
    model, lm = args.model, args.landmarks
    R, p = lane_frames(model, q)
    frame = np.array(args.lmap.frame, dtype=int)
    R_root, p_root = lane_root(model, q)
    R_pt = jnp.where((frame < 0)[:, None, None, None], R_root, R[np.maximum(frame, 0)])     # (21, 3, 3, B)
    p_pt = jnp.where((frame < 0)[:, None, None], p_root, p[np.maximum(frame, 0)])
    local = landmark_offsets(model, args.lmap, q.dtype)
    P = lane_contract(R_pt, local[:, None, :, None], axis=2) + p_pt                        # (21, 3, B)
    dep = _dependence(model, args.lmap)
    pair_p = np.nonzero(dep)[0]
    Jp = lane_point_jacobian(model, q, R, p, P, _jacobian_frames(model, args.lmap))         # (pairs, 3, B)
    s2, s3 = jax.vmap(lambda one: _weights(eqx.tree_at(lambda a: a.landmarks, args, one), q.dtype))(lm)
    B = q.shape[-1]
    P_rows = jnp.moveaxis(P, -1, 0).reshape(-1, 3)                                           # (B * 21, 3)
    rs, Js = [], []
    for c, cam in enumerate(args.cameras):
        px, dpx = _pixels_and_jacobian(cam, P_rows)
        px = jnp.moveaxis(px.reshape(B, N_POINTS, 2), 0, -1)                                 # (21, 2, B)
        dpx = jnp.moveaxis(dpx.reshape(B, N_POINTS, 2, 3), 0, -1)                            # (21, 2, 3, B)
        w = s2[:, c].T                                                                       # (21, B)
        rs.append(((px - jnp.moveaxis(lm.px[:, c].astype(q.dtype), 0, -1)) * w[:, None]).reshape(-1, B))
        Jc = lane_contract(dpx[pair_p], Jp[:, None], axis=2) * w[pair_p][:, None]           # (pairs, 2, B)
        Js.append(Jc.reshape(-1, B)[_row_major(dep, 2)])
    if use_3d:
        w3 = s3.T
        if lm.frame_3d == "camera":
            cam0 = args.cameras[0]
            R0 = cam0.R.astype(q.dtype)[None, :, :, None]
            P3 = lane_contract(R0, P[:, None], axis=2) + cam0.t.astype(q.dtype)[None, :, None]
            J3 = lane_contract(R0, Jp[:, None], axis=2)
        else:
            P3, J3 = P, Jp
        rs.append(((P3 - jnp.moveaxis(lm.mm.astype(q.dtype), 0, -1)) * w3[:, None]).reshape(-1, B))
        Js.append((J3 * w3[pair_p][:, None]).reshape(-1, B)[_row_major(dep, 3)])
    return jnp.concatenate(rs), jnp.concatenate(Js)


def stacked_residuals(q: Float[Array, " nq"], args: LandmarkArgs) -> Float[Array, " r"]:
    """Link and tip residuals (when ``args.edges`` is set), then the landmark residuals: one stack
    (optimistix signature)."""
    lm = landmark_residuals(q, args)
    if args.edges is None:
        return lm
    return jnp.concatenate([residuals(q, args.edges), lm])


def stacked_residuals_and_jacobian(q: Float[Array, " nq"], args: LandmarkArgs):
    """:func:`stacked_residuals` and its Jacobian (geometric for both parts)."""
    r, J = landmark_residuals_and_jacobian(q, args)
    if args.edges is None:
        return r, J
    r0, J0 = residuals_and_jacobian(q, args.edges)
    return jnp.concatenate([r0, r]), jnp.concatenate([J0, J])


def landmark_residual_labels(n_cameras: int) -> list[str]:
    """A name per landmark residual entry (``cam0/lm/index_tip/x``, ``3d/lm/wrist/z``)."""
    out = [f"cam{c}/lm/{n}/{a}" for c in range(n_cameras) for n in POINT_NAMES for a in "xy"]
    return out + [f"3d/lm/{n}/{a}" for n in POINT_NAMES for a in "xyz"]
