"""Plots of joint angles over time (thesis figs. 6.2, 6.4, 6.6).

Figures are built with matplotlib's object API (``matplotlib.figure.Figure``), which needs no
display and leaves the user's pyplot backend alone (notebooks keep their inline figures).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from .._errors import InputError
from ..model import Model

__all__ = ["plot_joint_angles", "joint_groups", "plot_line"]


def joint_groups(model: Model) -> dict[str, list[int]]:
    """q entries grouped by digit (the name before the first underscore), base entries first."""
    groups: dict[str, list[int]] = {}
    for i, name in enumerate(model.q_names):
        groups.setdefault(name.split("_")[0], []).append(i)
    return groups


def plot_joint_angles(model: Model, times_s, q_est, path: str | Path, *, q_truth=None, q_raw=None,
                      seen=None, seen_level: float = 0.5, title: str | None = None) -> Path:
    """One panel per digit: estimates (solid) against ground truth (dotted) over time.

    Args:
        q_est: (frames, n_q) filtered estimates (radians/mm as in q).
        q_truth: optional (frames, n_q) ground truth, drawn dotted in the same colour.
        q_raw: optional (frames, n_q) unfiltered solver output, drawn thin and faded.
        seen: optional (frames, n_q) seen shares (:attr:`jaxhand.track.StepReport.seen`): a
            stretch where a joint's share is below ``seen_level`` is drawn as a shaded band in
            its colour, the frames it was estimated without being seen.
    """
    t = np.asarray(times_s)
    if seen is not None and np.shape(seen) != np.shape(q_est):
        raise InputError(f"seen: expected {np.shape(q_est)} shares (frames, n_q) like the estimates, "
                         f"got shape {np.shape(seen)}")
    groups = joint_groups(model)
    conv = np.where(model.is_angle, 180.0 / np.pi, 1.0)
    fig = Figure(figsize=(8, 2.1 * len(groups)))
    axes = fig.subplots(len(groups), 1, sharex=True, squeeze=False)
    for ax, (digit, idx) in zip(axes[:, 0], groups.items()):
        for n, i in enumerate(idx):
            color = f"C{n}"
            if q_raw is not None:
                ax.plot(t, np.asarray(q_raw)[:, i] * conv[i], color=color, lw=0.6, alpha=0.35)
            ax.plot(t, np.asarray(q_est)[:, i] * conv[i], color=color, lw=1.4, label=model.q_names[i])
            if seen is not None:
                unseen = np.asarray(seen)[:, i] < seen_level
                ax.fill_between(t, 0, 1, where=unseen, color=color, alpha=0.12, lw=0, step="mid",
                                transform=ax.get_xaxis_transform())
            if q_truth is not None:
                ax.plot(t, np.asarray(q_truth)[:, i] * conv[i], color=color, lw=1.2, ls=":")
        unit = "deg" if model.is_angle[idx].all() else "deg / mm"
        ax.set_ylabel(f"{digit} [{unit}]")
        ax.legend(fontsize=7, loc="upper left", ncol=min(len(idx), 5), frameon=False)
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("time [s]")
    fig.suptitle(title or f"{model.name}: estimates (solid)" + (" vs ground truth (dotted)" if q_truth is not None
                                                                  else "")
                 + ("; shaded: not seen" if seen is not None else ""))
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110)
    return path


def plot_line(ax, line, color, xlim, ylim, lw: float = 1.5) -> None:
    """Draw the image line a x + b y = rho (a feature's ``(a, b, rho)``) across the box ``xlim`` x ``ylim``
    on matplotlib axes, solving for y when the line is closer to horizontal and for x otherwise."""
    a, b, rho = (float(v) for v in line)
    if abs(b) > abs(a):
        xs = np.array(xlim, float)
        ax.plot(xs, (rho - a * xs) / b, color=color, lw=lw)
    else:
        ys = np.array(ylim, float)
        ax.plot((rho - b * ys) / a, ys, color=color, lw=lw)
