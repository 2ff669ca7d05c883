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
import math

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
    """The static part of a (model, camera) pair as a ``jax.jit`` static argument, hashed once, with
    the layout of its arrays: they travel packed in one flat array per dtype, so a call hands the
    compiled program two arguments instead of every leaf of the model and camera."""

    def __init__(self, static, arrays):
        self.static = static
        leaves, self.treedef = jax.tree_util.tree_flatten(static)
        self.leaves = tuple(leaves)
        arrays, self.array_def = jax.tree_util.tree_flatten(arrays)
        self.dtypes = tuple(sorted({np.dtype(a.dtype).str for a in arrays}))
        self.layout = tuple((self.dtypes.index(np.dtype(a.dtype).str), tuple(a.shape)) for a in arrays)
        self._hash = hash((self.treedef, self.leaves, self.array_def, self.layout))

    def __hash__(self) -> int:
        return self._hash

    def __eq__(self, other) -> bool:
        return (isinstance(other, _Structure) and self._hash == other._hash and self.treedef == other.treedef
                and self.leaves == other.leaves and self.array_def == other.array_def
                and self.layout == other.layout)

    def pack(self, arrays) -> tuple:
        """One flat device array per dtype holding every array leaf (values unchanged)."""
        flat = [np.ravel(np.asarray(a)) for a in jax.tree_util.tree_leaves(arrays)]
        return tuple(jax.device_put(np.concatenate([f for f, (g, _) in zip(flat, self.layout) if g == k]
                                                   or [np.zeros(0, k)]))
                     for k in range(len(self.dtypes)))

    def unpack(self, packed):
        """The (model, camera) pair back from :meth:`pack`'s arrays (traced: slices and reshapes)."""
        at = [0] * len(packed)
        leaves = []
        for g, shape in self.layout:
            n = math.prod(shape)
            leaves.append(packed[g][at[g]:at[g] + n].reshape(shape))
            at[g] += n
        return eqx.combine(jax.tree_util.tree_unflatten(self.array_def, leaves), self.static)


@functools.partial(jax.jit, static_argnums=0)
def _view(structure: _Structure, packed, q):
    """The link ends, depths, radii and tips of ``project_pose`` packed in one flat array (one
    conversion to NumPy instead of one per output; packing copies the values unchanged)."""
    model, camera = structure.unpack(packed)
    v = project_pose(model, camera, q)
    return jnp.concatenate([a.astype(float).ravel() for a in (v.link_start_px, v.link_end_px, v.link_depth,
                                                               v.link_radius_px, v.tips_px)])


_SPLITS: dict[tuple[int, int], tuple[Model, object, _Structure, tuple]] = {}


def predicted_geometry(model: Model, camera, q: np.ndarray) -> Geometry:
    """:func:`~jaxhand.kinematics.project_pose` of ``q``'s link ends, depths, radii and tips, as NumPy."""
    key = (id(model), id(camera))
    hit = _SPLITS.get(key)
    if hit is None or hit[0] is not model or hit[1] is not camera:
        arrays, static = eqx.partition((model, camera), eqx.is_array)
        structure = _Structure(static, arrays)
        hit = (model, camera, structure, structure.pack(arrays))
        if len(_SPLITS) >= 8:   # a tracker calls with one model and rig; width estimation makes a new model each frame
            _SPLITS.pop(next(iter(_SPLITS)))
        _SPLITS[key] = hit
    flat = np.asarray(_view(hit[2], hit[3], np.asarray(q, float)))
    L = model.n_links  # the packed order of _view; plain slices (np.split costs more than the rest)
    return Geometry(start=flat[:2 * L].reshape(L, 2), end=flat[2 * L:4 * L].reshape(L, 2),
                    depth=flat[4 * L:6 * L].reshape(L, 2), radius=flat[6 * L:7 * L], tips=flat[7 * L:].reshape(-1, 2))
