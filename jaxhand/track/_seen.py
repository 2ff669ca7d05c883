"""Which joints a frame saw: per q entry, the share of image information the frame's features
give it (:func:`~jaxhand.track._compiled.seen_at`), reported per frame (:attr:`StepReport.seen`)
and summarised per run, so that a joint the image did not show is reported as estimated by the
priors, not as measured."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

from ..features import Features
from ..model import Model
from ._compiled import _Static, join_constants, seen_at, split_constants

__all__ = ["SeenProgram", "seen_summary", "scored_joints", "unseen_links", "SEEN_LEVEL"]

#: A q entry counts as seen on a frame when its share reaches this.
SEEN_LEVEL = 0.5


@functools.partial(jax.jit, static_argnums=0)
def _seen_jit(static: _Static, consts: tuple, feats: tuple, q):
    model, rig, fractions = join_constants(static, consts)
    return seen_at(model, rig, tuple(Features(*f) for f in feats), q, fractions)


class SeenProgram:
    """:func:`~jaxhand.track._compiled.seen_at` of one tracker's model and cameras, compiled once.

    Args:
        model, rig: the model and the cameras.
        fractions: the link-point fractions of the solve's link residuals.
    """

    def __init__(self, model: Model, rig: tuple, fractions):
        fractions = jnp.asarray(fractions)
        self._consts, self._static = split_constants((model, rig, fractions))
        self._dtype = np.dtype(fractions.dtype)   # the working precision: q goes in as a host array of it

    def __call__(self, feats: tuple, q) -> np.ndarray:
        """(n_q,) each entry's seen share in [0, 1] at ``q`` with ``feats`` (one tuple of
        :data:`~jaxhand.track._compiled.FEATURE_FIELDS` arrays per camera)."""
        return np.asarray(_seen_jit(self._static, self._consts, feats, np.asarray(q, self._dtype)))


def unseen_links(model: Model, seen) -> np.ndarray:
    """(n_links,) whether each link's own joint went unseen (share under :data:`SEEN_LEVEL`); a
    link on a frame without a joint of its own counts as seen."""
    own = np.asarray(model.q_index)[np.asarray(model.link_frame, int)]
    return (own >= 0) & (np.asarray(seen, float)[np.maximum(own, 0)] < SEEN_LEVEL)


def scored_joints(model: Model) -> list[int]:
    """The revolute joints other than the palm's (those :func:`accuracy_summary` scores)."""
    return [i for i, k in enumerate(model.q_kinds) if k == "angle" and not model.q_names[i].startswith("palm")]


def seen_summary(model: Model, seen, q_est=None, q_truth=None) -> dict:
    """Per joint, the share of frames on which it was seen (share >= :data:`SEEN_LEVEL`), the joints
    unseen on most frames, and with ``q_truth`` the mean error (deg) of the (frame, joint) entries
    seen and of those not: how far to trust a joint the image did not show.

    Args:
        seen: (frames, n_q) per-frame seen shares (:attr:`StepReport.seen`).
        q_est, q_truth: optional (frames, n_q) estimates and ground truth (rad).
    """
    seen = np.asarray(seen, float)
    joints = scored_joints(model)
    shown = seen[:, joints] >= SEEN_LEVEL
    share = shown.mean(axis=0)
    out: dict = {"level": SEEN_LEVEL,
                 "share_of_frames": {model.q_names[i]: float(s) for i, s in zip(joints, share)},
                 "mostly_unseen": [model.q_names[i] for i, s in zip(joints, share) if s < 0.5],
                 "unseen_entries_share": float(1.0 - shown.mean()) if shown.size else 0.0}
    if q_truth is not None:
        err = np.degrees(np.abs(np.asarray(q_est, float) - np.asarray(q_truth, float)))[:, joints]
        out["error_deg_seen"] = float(err[shown].mean()) if shown.any() else None
        out["error_deg_unseen"] = float(err[~shown].mean()) if (~shown).any() else None
    return out
