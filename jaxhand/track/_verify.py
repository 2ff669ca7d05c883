"""A doubtful finger searched again from starts of its own (:attr:`HypothesisConfig.verify_below`).

The frame's starts are all solved against one set of features, searched around the prediction:
a finger that has folded the wrong way keeps the features that back the wrong fold, and a start
near the true pose loses against them. Here each start of the weakest finger gets features
searched around itself and a solve from itself, and the candidates are judged by the image's
support of every finger (:func:`~jaxhand.track._support.finger_supports`), which does not depend
on where the features were searched.
"""

from __future__ import annotations

import numpy as np

from ._hypotheses import finger_starts

__all__ = ["verify_starts", "fold_rows", "beats", "holds"]


def fold_rows(folds: np.ndarray, q: np.ndarray, joints: np.ndarray) -> np.ndarray:
    """The rows of ``folds`` (fold starts of ``q``, one hinge reflected in each:
    :func:`~jaxhand.track._hypotheses.fold_starts`) that move one of ``joints``, (m, n_q)."""
    folds = np.asarray(folds, float).reshape(-1, len(q))
    moved = np.abs(folds - q)[:, joints].max(axis=1, initial=0.0) > 1e-9
    return folds[moved]


def verify_starts(q: np.ndarray, joints: np.ndarray, bends_deg, lower: np.ndarray, upper: np.ndarray,
                  folds: np.ndarray, q_trusted: np.ndarray | None) -> np.ndarray:
    """The starts of a doubtful finger (q entries ``joints``), (k, n_q): ``q`` with the finger bent
    by each of ``bends_deg`` (:func:`~jaxhand.track._hypotheses.finger_starts`), with each of its
    hinges reflected across its fold (:func:`fold_rows`), and with its joints at ``q_trusted``
    (the last trusted pose; None: left out), all clipped into the limits."""
    rows = [finger_starts(q, joints, bends_deg, lower, upper), fold_rows(folds, q, joints)]
    if q_trusted is not None:
        back = np.asarray(q, float).copy()
        back[joints] = np.asarray(q_trusted, float)[joints]
        rows.append(back[None])
    return np.clip(np.concatenate(rows), lower, upper)


def beats(candidate: dict[int, float], current: dict[int, float], margin: float) -> bool:
    """Whether the finger supports ``candidate`` beat ``current``: its weakest finger is supported
    more, by at least ``margin``, than the weakest of ``current``, and no finger that both judge
    loses more than ``margin``."""
    return holds(candidate, current, margin) and min(candidate.values()) >= min(current.values()) + margin


def holds(candidate: dict[int, float], current: dict[int, float], margin: float) -> bool:
    """Whether the finger supports ``candidate`` hold up against ``current``: no finger that both
    judge loses more than ``margin`` (a pose the image cannot tell from the current one)."""
    if not candidate or not current:
        return False
    return all(candidate[f] >= current[f] - margin for f in current if f in candidate)
