"""Synthetic fitting problems: exact (or noisy) features of many poses at once, for fit_batch.

The same features as :func:`jaxhand.features.features_from_pose`, for a stack of states in one
jitted, vmapped projection instead of one call per pose.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..camera import as_rig
from ..features import Features, features_from_points
from ..kinematics import pose as pose_at
from ..model import Model

__all__ = ["features_from_poses"]


@eqx.filter_jit
def _project_all(model: Model, rig: tuple, qs):
    def one(q):
        pose = pose_at(model, q)
        return tuple((cam.project(pose.link_start)[0], cam.project(pose.link_end)[0], cam.project(pose.tips)[0])
                     for cam in rig)

    return jax.vmap(one)(qs)


def features_from_poses(model: Model, cameras, qs, *, noise_px: float = 0.0,
                        rng: np.random.Generator | None = None) -> tuple[Features, ...]:
    """Features of the model at each state of ``qs`` (B, n_q) in every camera, batched.

    As :func:`~jaxhand.features.features_from_pose`: every link line passes through the
    projected link axis and every tip sits on the projected tip centre; with ``noise_px`` > 0
    both axis end points and the tip get independent Gaussian noise of that standard deviation
    (pixels) before the lines are formed. A link whose projection is shorter than 1e-6 px is
    marked invalid.

    Returns:
        One :class:`Features` per camera whose arrays have the leading batch axis B.
    """
    rig = as_rig(cameras)
    qs = jnp.asarray(np.asarray(qs, dtype=float))
    rng = rng if rng is not None else np.random.default_rng(0)
    return tuple(features_from_points(s, e, t, noise_px=noise_px, rng=rng) for s, e, t in _project_all(model, rig, qs))
