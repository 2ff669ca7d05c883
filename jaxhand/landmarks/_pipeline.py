"""From landmark frames to a fitted sequence: the first frame from several starts, each later
frame from the one before, then the whole-sequence fit; calibration writes a model file.

Steps of :func:`fit_landmark_sequence`:

1. frame 0 (the first frame with landmarks) from several starts, batched: for a free palm,
   the palm placed at the wrist landmark at the depth where the model's wrist-to-middle-MCP
   length has its observed pixel length, rolled so that this segment points the observed way,
   turned by 0, 90, 180 and 270 degrees about the viewing ray, each palm towards and away from
   the camera (8 starts); the lowest cost wins;
2. every later frame from the previous result (one compiled ``lax.scan``; a frame without
   landmarks keeps the previous state);
2b. (``init="paths"``, the default) every frame also from fixed joint starts, and per
   independent block of joints (each finger, given the palm) the smoothest low-cost path through
   the candidates (:func:`~jaxhand.landmarks.smoothest_paths`), one per smoothness scale of
   ``path_scales``: one camera's mirror branches are chosen from the whole sequence, not from
   frame 0;
3. :func:`~jaxhand.landmarks.fit_sequence` over all frames from each path, with the temporal
   smoothness term and (with ``shape``) one hand shape shared by every frame. With several
   paths, each block keeps the solve of least cost (:func:`~jaxhand.landmarks.block_costs`, with
   the branch choice's rest prior of the configuration) and one more solve starts from these
   blocks together (with a shape, which couples the blocks, the solve of least total cost is
   kept).
"""

from __future__ import annotations

import dataclasses
import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._errors import InputError
from ..camera import Orthographic, Perspective, as_rig
from ..kinematics import pose as pose_at
from ..model import Model, model_from_dict, model_to_dict, save_model
from ..solve import StateSpace
from ._convention import POINT_NAMES, LandmarkMap, landmark_map, landmark_positions
from ._fit import BatchConfig, _as_float_landmarks, batch_lm, fit_landmarks_batch
from ._paths import block_costs, independent_blocks, smoothest_paths
from ._residuals import LandmarkArgs, Landmarks, landmark_residuals_and_jacobian
from ._sequence import SequenceConfig, SequenceResult, fit_sequence
from ._shape import HandShape, apply_shape, hand_shape

__all__ = ["SEQUENCE_INITS", "PATH_SCALES", "initial_starts", "track_landmarks", "fit_landmark_sequence", "SequenceFit",
           "calibrate_landmarks", "save_calibrated_model", "projected_landmarks", "camera_from_fov"]


#: How :func:`fit_landmark_sequence` starts the whole-sequence solve: ``"track"`` (frame by
#: frame), ``"paths"`` (also the smoothest paths through fixed starts), ``"auto"`` (``"paths"``;
#: on a free palm too since the real video's fingers were measured in their mirror branches with
#: ``"track"``, benchmarks/README.md 2026-12-07).
SEQUENCE_INITS = ("auto", "track", "paths")

#: Smoothness scales of the paths of ``init="paths"`` (:func:`~jaxhand.landmarks.smoothest_paths`):
#: on the dev set's open_close copies the full weight left the ring finger in its mirror branch
#: where a tenth of it found the right one, and the thumb the other way round
#: (benchmarks/README.md, landmarks_devset.py, 2026-12-02).
PATH_SCALES = (1.0, 0.1)


def camera_from_fov(size, fov_deg: float = 60.0) -> Perspective:
    """A pinhole camera at the world origin looking along +z with the given horizontal field of
    view, its principal point at the image centre ((w - 1) / 2, (h - 1) / 2)."""
    w, h = (int(v) for v in size)
    if not 1.0 < fov_deg < 179.0:
        raise InputError(f"fov_deg: expected a value in (1, 179), got {fov_deg}")
    f = 0.5 * w / np.tan(np.radians(fov_deg) / 2)
    K = np.array([[f, 0, (w - 1) / 2], [0, f, (h - 1) / 2], [0, 0, 1.0]])
    return Perspective(K=K, R=np.eye(3), t=np.zeros(3), size=(w, h))


def _quat_from_matrix(R: np.ndarray) -> np.ndarray:
    """(w, x, y, z) of a rotation matrix (Shepperd's method, the largest-pivot branch)."""
    t = np.trace(R)
    cands = [1 + t, 1 + 2 * R[0, 0] - t, 1 + 2 * R[1, 1] - t, 1 + 2 * R[2, 2] - t]
    i = int(np.argmax(cands))
    s = np.sqrt(cands[i]) * 2
    if i == 0:
        q = [s / 4, (R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s]
    elif i == 1:
        q = [(R[2, 1] - R[1, 2]) / s, s / 4, (R[0, 1] + R[1, 0]) / s, (R[0, 2] + R[2, 0]) / s]
    elif i == 2:
        q = [(R[0, 2] - R[2, 0]) / s, (R[0, 1] + R[1, 0]) / s, s / 4, (R[1, 2] + R[2, 1]) / s]
    else:
        q = [(R[1, 0] - R[0, 1]) / s, (R[0, 2] + R[2, 0]) / s, (R[1, 2] + R[2, 1]) / s, s / 4]
    q = np.array(q)
    return q / np.linalg.norm(q)


def _rot(axis: int, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    R = np.eye(3)
    R[i, i], R[i, j], R[j, i], R[j, j] = c, -s, s, c
    return R


def initial_starts(model: Model, camera, px: np.ndarray, *, lmap: LandmarkMap | None = None) -> np.ndarray:
    """Starting states for one frame's 2-D landmarks ``px`` (21, 2) in ``camera``: (8, n_q) for a
    free palm (see the module docstring), the model's default (1, n_q) otherwise."""
    q0 = np.asarray(model.q_default, float)
    if model.base_kind != "free":
        return q0[None]
    lmap = landmark_map(model) if lmap is None else lmap
    wi, mi = POINT_NAMES.index("wrist"), POINT_NAMES.index("middle_mcp")
    P = np.asarray(landmark_positions(model, lmap, pose_at(model, jnp.asarray(q0)), jnp.asarray(q0)))
    R_cam = np.asarray(camera.R)
    if not np.all(np.isfinite(px[[wi, mi]])):
        return q0[None]
    seg_px = px[mi] - px[wi]
    length_mm = float(np.linalg.norm(P[mi] - P[wi]))
    if isinstance(camera, Perspective):
        f = float(np.asarray(camera.K)[0, 0])
        depth = f * length_mm / max(float(np.linalg.norm(seg_px)), 1.0)
    else:
        depth = 500.0
    wrist_world = np.asarray(camera.unproject(jnp.asarray(px[wi]), jnp.asarray(depth)))
    # The default palm's wrist-to-middle-MCP direction in the camera frame, and the observed one.
    R0 = _default_palm(model)
    d_model = R_cam @ (P[mi] - P[wi])
    phi_model = np.arctan2(d_model[1], d_model[0])
    phi_obs = np.arctan2(seg_px[1], seg_px[0])
    starts = []
    for flip in (False, True):
        for k in range(4):
            # R_world_palm = R_cam^T Rz(roll) R_cam R0 [Ry(pi) when flipped]: a roll about the
            # viewing ray, the flip turning the palm away about the palm's own finger axis.
            roll = _rot(2, phi_obs - phi_model + k * np.pi / 2)
            R = R_cam.T @ roll @ R_cam @ R0
            if flip:
                axis = R0.T @ (P[mi] - P[wi]) / length_mm
                K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
                R = R @ (np.eye(3) + 2 * K @ K)   # a half turn about the finger axis
            q = q0.copy()
            M = np.asarray(model.T_world_mount)
            q[:4] = _quat_from_matrix(M[:3, :3].T @ R)          # base_pose = T_world_mount @ T(q)
            q[4:7] = M[:3, :3].T @ (wrist_world - M[:3, 3])     # the root sits at the wrist landmark
            starts.append(q)
    return np.stack(starts)


def _default_palm(model: Model) -> np.ndarray:
    """R_world_root of the model at its default state."""
    from ..kinematics import base_pose

    return np.asarray(base_pose(model, jnp.asarray(model.q_default)))[:3, :3]


@eqx.filter_jit
def _track_jit(model, rig, lmap, landmarks, q0, config):
    space = StateSpace.of(model)

    def fn(q, lm):
        return landmark_residuals_and_jacobian(q, LandmarkArgs(model=model, cameras=rig, lmap=lmap, landmarks=lm))

    def step(q, lm):
        one = jax.tree_util.tree_map(lambda x: x[None], lm)
        res = batch_lm(fn, one, q[None], space, config)
        return res.q[0], (res.q[0], res.cost[0], res.iterations[0])

    _, out = jax.lax.scan(step, q0, landmarks)
    return out


def track_landmarks(model: Model, cameras, landmarks: Landmarks, q0, *, config: BatchConfig | None = None,
                    lmap: LandmarkMap | None = None):
    """Fit frame after frame, each from the previous result (frame 0 from ``q0``): (q (T, n_q),
    cost (T,), iterations (T,)). ``lmap``: where the landmarks sit (default skin tips)."""
    config = BatchConfig(chunk=1) if config is None else dataclasses.replace(config, chunk=1)
    rig = as_rig(cameras)
    lmap = landmark_map(model) if lmap is None else lmap
    q, cost, it = _track_jit(model, rig, lmap, _as_float_landmarks(landmarks),
                             jnp.asarray(np.asarray(q0, float)), config)
    return np.array(q), np.array(cost), np.array(it)


@dataclasses.dataclass
class SequenceFit:
    """What :func:`fit_landmark_sequence` returns (host-side NumPy).

    Attributes:
        q: (T, n_q) fitted states; q_init: (T, n_q) the frame-by-frame fits it started from.
        model: the model with the fitted shape (the input model when no shape was fitted).
        theta: (p,) the shape (empty without); shape: its :class:`HandShape` or None.
        result: the :class:`SequenceResult` of the whole-sequence solve (None without it).
        start_costs: (starts,) frame 0's cost from each start; best_start: the chosen one.
        timings_s: seconds per stage (first frame, frame by frame, sequence), compile included.
        init: the start that ran, ``"track"`` or ``"paths"`` ("auto" resolved).
    """

    q: np.ndarray
    q_init: np.ndarray
    model: Model
    theta: np.ndarray
    shape: HandShape | None
    result: SequenceResult | None
    start_costs: np.ndarray
    best_start: int
    timings_s: dict
    init: str


def fit_landmark_sequence(model: Model, cameras, landmarks: Landmarks, *, shape: HandShape | None | str = "auto",
                          config: SequenceConfig | None = None, batch_config: BatchConfig | None = None,
                          q0=None, sequence: bool = True, lmap: LandmarkMap | None = None,
                          init: str = "auto", path_scales=PATH_SCALES) -> SequenceFit:
    """Fit a whole landmark sequence (see the module docstring).

    Args:
        landmarks: (T, cams, 21, 2) batched :class:`Landmarks`.
        shape: a :class:`HandShape`, None (keep the model's shape) or "auto" (every phalanx
            scaled and the palm placement, :func:`~jaxhand.landmarks.hand_shape`).
        q0: optional (n_q,) start of frame 0 instead of the automatic starts.
        sequence: run step 3, the whole-sequence solve (False: the frame-by-frame fits are the
            result, ``shape`` is not fitted and ``result`` is None).
        lmap: where the landmarks sit on the model (default ``landmark_map(model)``: skin tips;
            ``landmark_map(model, tips="cap_centre")`` for data whose tips are cap centres).
        init: one of :data:`SEQUENCE_INITS` (step 2b).
        path_scales: the smoothness scales of step 2b's paths (each a sequence solve).

    Raises:
        InputError: shapes, an unknown ``shape`` or ``init``, no frame with landmarks.
    """
    if init not in SEQUENCE_INITS:
        raise InputError(f"init: expected one of {', '.join(SEQUENCE_INITS)}, got {init!r}")
    if init == "auto":
        init = "paths"
    lmap = landmark_map(model) if lmap is None else lmap
    rig = as_rig(cameras)
    if landmarks.px.ndim != 4:
        raise InputError(f"landmarks.px: expected (frames, cams, 21, 2), got {landmarks.px.shape}")
    if isinstance(shape, str):
        if shape != "auto":
            raise InputError(f"shape: expected a HandShape, None or 'auto', got {shape!r}")
        shape = hand_shape(model)
    valid = np.asarray(landmarks.px_valid).any(axis=(1, 2))
    if not valid.any():
        raise InputError("landmarks: no frame has any landmark")
    first = int(np.argmax(valid))
    times = {}
    t = time.perf_counter()
    if q0 is None:
        starts = initial_starts(model, rig[0], np.where(np.asarray(landmarks.px_valid)[first, 0][:, None],
                                                        np.asarray(landmarks.px)[first, 0], np.nan), lmap=lmap)
    else:
        starts = np.asarray(q0, float)[None]
    one = jax.tree_util.tree_map(lambda x: jnp.broadcast_to(x[first], (len(starts),) + x.shape[1:]), landmarks)
    res0 = fit_landmarks_batch(model, rig, one, starts, config=batch_config, lmap=lmap)
    costs = np.asarray(res0.cost)
    best = int(np.argmin(costs))
    q_first = np.asarray(res0.q)[best]
    times["first_frame_s"] = time.perf_counter() - t
    t = time.perf_counter()
    q_init, _, _ = track_landmarks(model, rig, landmarks, q_first, config=batch_config, lmap=lmap)
    q_init[:first] = q_first
    times["frame_by_frame_s"] = time.perf_counter() - t
    if init == "paths":
        t = time.perf_counter()
        paths = smoothest_paths(model, rig, landmarks, lmap, candidates=q_init[None], config=config,
                                batch_config=batch_config, scales=tuple(path_scales))
        times["paths_s"] = time.perf_counter() - t
    else:
        paths = q_init[None]
    q_init = paths[0]
    if not sequence:
        return SequenceFit(q=q_init, q_init=q_init, model=model, theta=np.zeros(0), shape=None, result=None,
                           start_costs=costs, best_start=best, timings_s=times, init=init)
    t = time.perf_counter()
    fits = [fit_sequence(model, rig, landmarks, p, shape=shape, config=config, lmap=lmap) for p in paths]
    res = min(fits, key=lambda r: float(r.cost))
    if len(fits) > 1 and shape is None:
        costs = np.stack([block_costs(model, rig, landmarks, lmap, config, np.asarray(r.q), np.asarray(r.dip_pip_ratio))
                          for r in fits])                                       # (paths, blocks)
        pick = np.argmin(costs, axis=0)
        if np.any(pick != pick[0]):
            q_init = np.array(paths[0])
            q_best = np.array(fits[0].q)
            for block, k in zip(independent_blocks(model, lmap), pick):
                q_init[:, block] = paths[k][:, block]
                q_best[:, block] = np.asarray(fits[k].q)[:, block]
            res = fit_sequence(model, rig, landmarks, q_best, shape=None, config=config, lmap=lmap)
        else:
            q_init = paths[pick[0]]
            res = fits[pick[0]]
    jax.block_until_ready(res)
    times["sequence_s"] = time.perf_counter() - t
    theta = np.asarray(res.theta)
    fitted = model if shape is None else apply_shape(model, shape, jnp.asarray(theta))
    return SequenceFit(q=np.asarray(res.q), q_init=q_init, model=fitted, theta=theta, shape=shape, result=res,
                       start_costs=costs, best_start=best, timings_s=times, init=init)


def calibrate_landmarks(model: Model, cameras, landmarks: Landmarks, q_init, *, palm: bool = True,
                        config: SequenceConfig | None = None) -> tuple[Model, SequenceResult, HandShape]:
    """Hand calibration: per-phalanx length scales and the palm's joint placement shared by every
    frame, with every frame's pose, solved jointly (:func:`~jaxhand.landmarks.fit_sequence`
    without smoothness, since the frames need not be consecutive).

    Args:
        landmarks: (T, cams, 21, 2) batched :class:`Landmarks` (3-D points help: one camera alone
            leaves the hand's overall size ambiguous with its depth).
        q_init: (T, n_q) starting poses (e.g. :func:`~jaxhand.landmarks.fit_landmarks_batch` results).

    Returns:
        (calibrated model, the solve's result, the shape parametrisation).
    """
    shape = hand_shape(model, palm=palm)
    config = SequenceConfig(smooth_px_per_rad=0.0, smooth_px_per_mm=0.0, scale_prior_px=1.0,
                            offset_prior_px_per_mm=0.1, max_steps=100) if config is None else config
    res = fit_sequence(model, cameras, landmarks, q_init, shape=shape, config=config)
    return apply_shape(model, shape, res.theta), res, shape


def save_calibrated_model(model: Model, path, *, description: str | None = None):
    """Write a (calibrated) model with :func:`jaxhand.save_model` under the name ``<name>_calibrated``."""
    d = model_to_dict(jax.tree_util.tree_map(lambda x: np.asarray(x) if isinstance(x, jax.Array) else x, model))
    d["name"] = d["name"] if d["name"].endswith("_calibrated") else d["name"] + "_calibrated"
    d["description"] = description or f"{d.get('description', '')} (calibrated from landmarks)".strip()
    return save_model(model_from_dict(d, source=str(path)), path)


@eqx.filter_jit
def _project_all(model, camera, lmap, Q):
    def one(q):
        p = landmark_positions(model, lmap, pose_at(model, q), q)
        return camera.project(p)[0]

    return jax.vmap(one)(Q)


def projected_landmarks(model: Model, camera: Perspective | Orthographic, q, *,
                        lmap: LandmarkMap | None = None) -> np.ndarray:
    """(T, 21, 2) pixels of the model's landmark points at states q (T, n_q) in one camera
    (``lmap`` default: skin tips)."""
    lmap = landmark_map(model) if lmap is None else lmap
    return np.array(_project_all(model, camera, lmap, jnp.asarray(np.atleast_2d(q))))
