"""A hinge that turns back at its fold is passed through instead (:attr:`HypothesisConfig.fold_passage_deg`).

One camera sees a link turned a little past its fold (the angle at which the link lies across the
viewing ray) as it sees it turned as far short of it: the image cannot tell the two sides apart
(:func:`~jaxhand.track._hypotheses.fold_turns`). A finger opening from a fist crosses that angle;
when its estimate lags, the solve is pulled to the near side's mirror image of the truth and the
estimate turns back at the fold, then follows the mirror image on out. Fingers seldom stop and turn
back right at the one angle where the view cannot follow them, and pass through it all the time; so
where an estimate came fast towards a fold and turns back there, the tracker tries the pose with
that hinge reflected across the fold and keeps it unless the image supports it less.

Each frame's signed offset of every hinge from its fold is kept for :data:`WINDOW` frames
(:func:`push`); :func:`turned_back` reads them.
"""

from __future__ import annotations

import numpy as np

__all__ = ["WINDOW", "push", "turned_back", "crossed"]

#: Frames of fold offsets kept: the approach (``APPROACH`` frames before the nearest one), the
#: nearest one and the ``AFTER`` frames since, over which the hinge moved away again.
APPROACH = 3
AFTER = 2
WINDOW = APPROACH + 1 + AFTER


def push(history: np.ndarray | None, offsets_deg: np.ndarray) -> np.ndarray:
    """``history`` (at most :data:`WINDOW` rows, oldest first; None: none yet) with this frame's
    offsets (m,) appended and the oldest rows dropped."""
    row = np.asarray(offsets_deg, float)[None]
    return row if history is None else np.concatenate([history, row])[-WINDOW:]


def turned_back(history: np.ndarray | None, near_deg: float, speed_deg: float) -> np.ndarray:
    """(m,) bool: the hinges whose offset from their fold (``history``, deg, (WINDOW, m)) came
    nearer by at least ``speed_deg`` per frame over :data:`APPROACH` frames, to within ``near_deg``,
    and moved away on each of the :data:`AFTER` frames since, all on one side of the fold (a NaN
    offset, where the link never lies across the ray, never counts)."""
    if history is None or len(history) < WINDOW:
        return np.zeros(0 if history is None else history.shape[1], bool)
    d, nearest = np.abs(history), APPROACH
    with np.errstate(invalid="ignore"):
        one_side = np.all(np.sign(history) == np.sign(history[-1]), axis=0) & np.all(np.isfinite(history), axis=0)
        away = np.all(np.diff(d[nearest - 1:], axis=0) * np.array([-1] + [1] * AFTER)[:, None] > 0, axis=0)
        return (one_side & away & (d[nearest] <= near_deg) & (d[0] - d[nearest] >= APPROACH * speed_deg))


def crossed(before: float, turn: float, after: float) -> bool:
    """Whether a hinge at ``before`` (rad), its fold ``turn`` away (rad), lies on the fold's other
    side at ``after``."""
    return bool(turn != 0 and np.sign(after - (before + turn)) == np.sign(turn))
