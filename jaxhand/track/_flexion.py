"""The flexion hinges of a hand's planar fingers, and the soft limit on their extension side."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from ..kinematics import pose
from ..model import Model
from ..priors import SoftLimits
from ._support import finger_of_frame

__all__ = ["flexion_hinges", "hyperextension_limits", "thumb_joints"]


def flexion_hinges(model: Model, finger_of_frame: np.ndarray) -> dict[int, np.ndarray]:
    """Per planar finger (:func:`~jaxhand.track._support.finger_of_frame`), the q entries of its
    flexion hinges: the revolute joints whose axis, at the default pose, is parallel (to 25 deg) to
    the axis of the finger's last hinge (a hand's MCP flexion, PIP and DIP). A finger is planar
    when at most one of its hinges is not a flexion hinge (its abduction): bending its flexion
    hinges together follows its motion. A thumb, with two abduction hinges, is left out."""
    axes = np.asarray(pose(model, jnp.asarray(model.q_default)).frames)[:, :3, 2]
    hinges = [f for f in range(len(model.parents))
              if model.joint_kinds[f] == "revolute" and model.q_index[f] >= model.n_base_q]
    out = {}
    for g in np.unique(finger_of_frame[finger_of_frame >= 0]):
        own = [f for f in hinges if finger_of_frame[f] == g]
        flexion = [f for f in own if abs(axes[f] @ axes[own[-1]]) > np.cos(np.radians(25))]
        if flexion and len(own) - len(flexion) <= 1:
            out[int(g)] = np.array([model.q_index[f] for f in flexion], int)
    return out


def thumb_joints(model: Model) -> np.ndarray:
    """The q entries of the revolute joints of every finger that is not planar
    (:func:`flexion_hinges`): a hand's thumb."""
    fingers = finger_of_frame(model)
    planar = flexion_hinges(model, fingers)
    return np.array(sorted(model.q_index[f] for f in range(len(model.parents))
                           if model.joint_kinds[f] == "revolute" and model.q_index[f] >= model.n_base_q
                           and fingers[f] >= 0 and int(fingers[f]) not in planar), int)


def hyperextension_limits(model: Model, weight: float, start_deg: float) -> SoftLimits:
    """Soft limits (:class:`jaxhand.priors.SoftLimits`) on the extension side of every planar
    finger's flexion hinges (the narrower side of each range), ``start_deg`` past straight (or at
    the hard limit, if nearer); the flexion side is left to the hard limits."""
    joints = np.concatenate([j for j in flexion_hinges(model, finger_of_frame(model)).values()] or [np.zeros(0, int)])
    lo, hi = np.asarray(model.q_lower)[joints], np.asarray(model.q_upper)[joints]
    flex_up = np.abs(hi) >= np.abs(lo)   # flexion towards the upper limit: extension is below zero
    start = np.radians(start_deg)
    lower = np.where(flex_up, np.maximum(lo, -start), lo - 1.0)   # the flexion side: never reached
    upper = np.where(flex_up, hi + 1.0, np.minimum(hi, start))
    dtype = model.q_lower.dtype
    return SoftLimits(index=tuple(int(j) for j in joints), lower=jnp.asarray(lower, dtype),
                      upper=jnp.asarray(upper, dtype), margin=jnp.zeros(len(joints), dtype),
                      weight=jnp.full(len(joints), weight, dtype))
