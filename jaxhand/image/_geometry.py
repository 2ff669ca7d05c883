"""The predicted geometry the front end needs from the kinematics, in one compiled call per pose.

:func:`jaxhand.kinematics.project_pose` is an ``equinox.filter_jit`` function: each call splits
the model and camera into arrays and static parts again and hands back eight device arrays, each
converted to NumPy on its own. The front end calls it for every camera, frame and re-acquisition
turn with the same model and camera, so here the split is kept per (model, camera) and the same
projection runs under a plain ``jax.jit`` (its C++ fast path). It returns the whole view, so the
compiled program, and so every bit of it, is the one ``project_pose`` runs.
"""

from __future__ import annotations

import dataclasses
import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..kinematics import project_pose
from ..model import Model

__all__ = ["Geometry", "predicted_geometry"]


@dataclasses.dataclass(frozen=True)
class Geometry:
    """One camera's view of a pose, as NumPy: ``start``, ``end`` (links, 2) link ends (px),
    ``depth`` (links, 2) their depths (mm), ``radius`` (links,) radii (px), ``tips`` (tips, 2) (px)."""

    start: np.ndarray
    end: np.ndarray
    depth: np.ndarray
    radius: np.ndarray
    tips: np.ndarray


class _Structure:
    """The static part of a (model, camera) pair as a ``jax.jit`` static argument, hashed once."""

    def __init__(self, static):
        self.static = static
        leaves, self.treedef = jax.tree_util.tree_flatten(static)
        self.leaves = tuple(leaves)
        self._hash = hash((self.treedef, self.leaves))

    def __hash__(self) -> int:
        return self._hash

    def __eq__(self, other) -> bool:
        return (isinstance(other, _Structure) and self._hash == other._hash and self.treedef == other.treedef
                and self.leaves == other.leaves)


@functools.partial(jax.jit, static_argnums=0)
def _view(structure: _Structure, arrays, q):
    """The link ends, depths, radii and tips of ``project_pose`` packed in one flat array (one
    conversion to NumPy instead of one per output; packing copies the values unchanged)."""
    model, camera = eqx.combine(arrays, structure.static)
    v = project_pose(model, camera, q)
    return jnp.concatenate([a.astype(float).ravel() for a in (v.link_start_px, v.link_end_px, v.link_depth,
                                                               v.link_radius_px, v.tips_px)])


_SPLITS: dict[tuple[int, int], tuple[Model, object, _Structure, object]] = {}


def predicted_geometry(model: Model, camera, q: np.ndarray) -> Geometry:
    """:func:`~jaxhand.kinematics.project_pose` of ``q``'s link ends, depths, radii and tips, as NumPy."""
    key = (id(model), id(camera))
    hit = _SPLITS.get(key)
    if hit is None or hit[0] is not model or hit[1] is not camera:
        arrays, static = eqx.partition((model, camera), eqx.is_array)
        hit = (model, camera, _Structure(static), arrays)
        if len(_SPLITS) >= 8:   # a tracker calls with one model and rig; width estimation makes a new model each frame
            _SPLITS.pop(next(iter(_SPLITS)))
        _SPLITS[key] = hit
    flat = np.asarray(_view(hit[2], hit[3], np.asarray(q, float)))
    L = model.n_links
    start, end, depth, radius, tips = np.split(flat, np.cumsum([2 * L, 2 * L, 2 * L, L]))
    return Geometry(start=start.reshape(L, 2), end=end.reshape(L, 2), depth=depth.reshape(L, 2), radius=radius,
                    tips=tips.reshape(-1, 2))
