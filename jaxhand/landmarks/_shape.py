"""Hand-shape parameters: per-phalanx length scales and the palm's joint placement.

A :class:`HandShape` says which numbers of a model the shape vector ``theta`` changes:

- one scale per link (phalanx): the link's length, and the DH ``a`` of every child frame placed
  at the link's end (the next joint), are multiplied by it; radii are kept;
- palm offsets (mm): for every frame hanging off the root (a digit's base on the palm), an
  offset of its DH ``a`` (across the palm) and ``d`` (out of the palm plane), and for each of its
  children with a non-zero ``a`` (the palm length to the MCP) an offset of that ``a``.

``theta = [scales (links), offsets (palm)]``; the nominal shape is ones and zeros.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from ..model import Model

__all__ = ["HandShape", "hand_shape", "apply_shape"]


class HandShape(eqx.Module):
    """Which model numbers the shape vector changes (all static).

    Attributes:
        link_children: per link, the frames whose DH ``a`` is the link's length.
        palm: (frame, column) pairs of the DH entries the palm offsets move (column 1: a, 2: d).
        names: a readable name per entry of theta (``index_pip:scale``, ``index_aux:a_mm``).
    """

    link_children: tuple[tuple[int, ...], ...] = eqx.field(static=True)
    palm: tuple[tuple[int, int], ...] = eqx.field(static=True)
    names: tuple[str, ...] = eqx.field(static=True)

    @property
    def n_scales(self) -> int:
        return len(self.link_children)

    @property
    def size(self) -> int:
        return len(self.link_children) + len(self.palm)

    def nominal(self, dtype=float) -> np.ndarray:
        return np.concatenate([np.ones(self.n_scales), np.zeros(len(self.palm))]).astype(dtype)


def hand_shape(model: Model, *, palm: bool = True) -> HandShape:
    """The shape parameters of ``model`` (every link scaled; palm offsets unless ``palm=False``)."""
    dh = np.asarray(model.dh)
    length = np.asarray(model.link_length_mm)
    children = []
    for li, f in enumerate(model.link_frame):
        kids = tuple(c for c in range(model.n_frames) if model.parents[c] == f
                     and abs(dh[c, 1] - length[li]) < 1e-9 * max(1.0, length[li]))
        children.append(kids)
    entries = []
    scaled = {c for kids in children for c in kids}
    if palm:
        for f in range(model.n_frames):
            if model.parents[f] >= 0:
                continue
            entries += [(f, 1), (f, 2)]
            entries += [(c, 1) for c in range(model.n_frames) if model.parents[c] == f and abs(dh[c, 1]) > 1e-9
                        and c not in scaled]
    names = tuple(f"{n}:scale" for n in model.link_names) + tuple(
        f"{model.frame_names[f]}:{'a' if col == 1 else 'd'}_mm" for f, col in entries)
    return HandShape(link_children=tuple(children), palm=tuple(entries), names=names)


def apply_shape(model: Model, shape: HandShape, theta: Float[Array, " p"]) -> Model:
    """The model with shape ``theta`` applied (traceable; same structure, so same compiled code)."""
    theta = jnp.asarray(theta)
    s = theta[:shape.n_scales]
    dh = model.dh.astype(theta.dtype)
    # Per frame, the scale of the link whose end it sits at (1 where none): a gather, so the
    # shape's derivative flows without a scatter-multiply.
    factor = np.full(model.n_frames, shape.n_scales, dtype=int)
    for li, kids in enumerate(shape.link_children):
        factor[list(kids)] = li
    s1 = jnp.concatenate([s, jnp.ones((1,), theta.dtype)])
    dh = dh.at[:, 1].set(dh[:, 1] * s1[factor])
    if shape.palm:
        pr = np.array([f for f, _ in shape.palm])
        pc = np.array([c for _, c in shape.palm])
        dh = dh.at[pr, pc].add(theta[shape.n_scales:])
    return eqx.tree_at(lambda m: (m.dh, m.link_length_mm), model, (dh, model.link_length_mm.astype(theta.dtype) * s))
