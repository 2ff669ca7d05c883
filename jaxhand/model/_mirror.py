"""Mirror images of models: a left hand from a right one and back.

The mirror image reflects the world through its y-z plane (``S_world = diag(-1, 1, 1)``) and
re-expresses every frame with its z axis reversed (``S = diag(1, 1, -1)``), so that all frames
stay right-handed: ``T'_world_frame = S_world T_world_frame S``. Conjugating Craig's transform
by ``S`` negates alpha and d and keeps a and theta, so a revolute joint keeps its q: the mirrored
model at the same joint angles is the mirror image of the original (``p' = S_world p`` for every
frame origin, link end, tip and occluder end). Links along x or y keep their axis.

Two kinds of entries change sign (:func:`mirror_q` maps a state across): a prismatic joint's
displacement, and the free base's quaternion (w, x, y, z) -> (w, -x, -y, z) and translation
(tx, ty, tz) -> (tx, ty, -tz). A planar base keeps (x, y, yaw).
"""

from __future__ import annotations

import dataclasses

import jax.numpy as jnp
import numpy as np

from .._errors import InputError
from ._model import AXES, Model

__all__ = ["mirror_model", "mirror_q"]

_OTHER = {"right": "left", "left": "right", "none": "none"}


def _sign_of_q(model: Model) -> np.ndarray:
    """+1/-1 per q entry: how an entry maps onto the mirrored model's (see the module docstring)."""
    sign = np.ones(model.n_q)
    if model.base_kind == "free":
        sign[:7] = [1, -1, -1, 1, 1, 1, -1]
    for f, k in enumerate(model.joint_kinds):
        if k == "prismatic":
            sign[model.q_index[f]] = -1.0
    return sign


def mirror_q(model: Model, q):
    """The state of ``mirror_model(model)`` that mirrors state ``q`` of ``model`` (an involution).

    Revolute joints and a planar base keep their values; prismatic joints and the free base's
    quaternion x, y and translation z change sign. Works on batches (``q[..., n_q]``).
    """
    return jnp.asarray(q) * _sign_of_q(model)


def _mirrored_name(model: Model, handedness: str) -> str:
    for old in ("right", "left"):
        if model.name.endswith(f"_{old}"):
            return model.name[: -len(old)] + _OTHER[old]
    return f"{model.name}_{handedness}" if handedness != "none" else f"{model.name}_mirrored"


def mirror_model(model: Model, *, name: str | None = None) -> Model:
    """The mirror image of ``model``: a left hand from a right hand (and back).

    The handedness swaps ("none" stays "none") and the name follows (``hand21`` -> ``hand21_left``
    for a right hand, ``x_left`` <-> ``x_right``) unless ``name`` is given. Frame, link and joint
    names, limits of revolute joints and all pill sizes are kept; see the module docstring for
    the geometry and :func:`mirror_q` for the entries that change sign.

    Raises:
        InputError: a link lies along its frame's z axis (its mirror image would point along -z,
            which a link cannot express).
    """
    z_links = [model.link_names[k] for k, a in enumerate(model.link_axis) if AXES[a] == "z"]
    if z_links:
        raise InputError(f"mirror_model: {model.name!r}: links along their frame's z axis cannot be mirrored: "
                         f"{', '.join(z_links)}")
    handedness = _OTHER[model.handedness]
    sign = jnp.asarray(_sign_of_q(model))
    lo, hi = model.q_lower * sign, model.q_upper * sign
    S3 = jnp.asarray(np.diag([1.0, 1.0, -1.0]))        # frame side: z reversed
    S4 = np.diag([1.0, 1.0, -1.0, 1.0])
    S4_world = np.diag([-1.0, 1.0, 1.0, 1.0])           # world side: through the y-z plane
    dh = model.dh * jnp.asarray([-1.0, 1.0, -1.0, 1.0])
    mount = jnp.asarray(S4_world) @ model.T_world_mount @ jnp.asarray(S4)
    pre = jnp.asarray(S4) @ model.T_pre_transform @ jnp.asarray(S4)
    return dataclasses.replace(
        model, name=name or _mirrored_name(model, handedness), handedness=handedness, dh=dh, T_world_mount=mount,
        q_lower=jnp.minimum(lo, hi), q_upper=jnp.maximum(lo, hi), q_default=model.q_default * sign,
        T_pre_transform=pre, occluder_start_mm=model.occluder_start_mm @ S3,
        occluder_end_mm=model.occluder_end_mm @ S3)
