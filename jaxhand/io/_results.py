"""Result writers: ``angles.csv`` row by row, ``results.npz`` checkpoints, ``summary.json``.

Each finished frame is appended to ``angles.csv`` and flushed at once, so a run that stops
midway keeps every finished frame. ``results.npz`` (every per-frame array) is rewritten every
``checkpoint_every`` frames and at the end; ``summary.json`` is written by :meth:`close`.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np

from .._errors import InputError
from ..model import Model

__all__ = ["ResultWriter", "read_angles_csv", "q_columns"]


def q_columns(model: Model) -> list[str]:
    """CSV column names of q: angles in degrees (``_deg``), lengths in mm (``_mm``)."""
    unit = {"angle": "_deg", "length": "_mm", "quat": ""}
    return [n + unit[k] for n, k in zip(model.q_names, model.q_kinds)]


def _user_units(model: Model, q: np.ndarray) -> np.ndarray:
    return np.where(model.is_angle, np.degrees(q), q)


class ResultWriter:
    """Writes a tracking run's results into ``out_dir`` frame by frame.

    Args:
        out_dir: folder (created if needed).
        model: the tracked model (column names and units).
        checkpoint_every: rewrite ``results.npz`` every this many frames.
    """

    def __init__(self, out_dir: str | Path, model: Model, checkpoint_every: int = 50):
        self.out = Path(out_dir)
        self.out.mkdir(parents=True, exist_ok=True)
        self.model = model
        self.checkpoint_every = checkpoint_every
        self.rows: dict[str, list] = {}
        self._csv_file = open(self.out / "angles.csv", "w", newline="")  # noqa: SIM115 (closed in close())
        self._csv = csv.writer(self._csv_file)
        self._csv.writerow(["frame", "time_s", *q_columns(model), "confidence", "lost"])
        self._csv_file.flush()
        self.skipped: list[dict] = []

    def write(self, frame: int, time_s: float, q: np.ndarray, confidence: float, lost: bool, **arrays) -> None:
        """Append one frame: the reported (filtered) q in the CSV; q and ``arrays`` in the NPZ."""
        q = np.asarray(q, float)
        if not np.all(np.isfinite(q)):
            raise InputError(f"frame {frame}: refusing to write a non-finite state")
        self._csv.writerow([frame, f"{time_s:.6f}", *(f"{v:.6f}" for v in _user_units(self.model, q)),
                            f"{confidence:.4f}", int(lost)])
        self._csv_file.flush()
        for key, value in {"frame": frame, "time_s": time_s, "q": q, "confidence": confidence, "lost": lost,
                           **arrays}.items():
            self.rows.setdefault(key, []).append(np.asarray(value))
        if len(self.rows["frame"]) % self.checkpoint_every == 0:
            self._write_npz()

    def skip(self, frame: int, reason: str) -> None:
        """Record a frame that could not be processed (reported in summary.json)."""
        self.skipped.append({"frame": frame, "reason": reason})

    def _write_npz(self) -> None:
        arrays = {k: np.stack(v) for k, v in self.rows.items()}
        tmp = self.out / "results.tmp.npz"
        np.savez(tmp, q_names=np.array(self.model.q_names), **arrays)
        tmp.replace(self.out / "results.npz")

    def close(self, summary: dict) -> dict:
        """Flush everything and write ``summary.json`` (``summary`` plus frame counts)."""
        self._csv_file.close()
        if self.rows:
            self._write_npz()
        full = {"model": self.model.name, "frames_written": len(self.rows.get("frame", [])),
                "frames_skipped": self.skipped, **summary}
        (self.out / "summary.json").write_text(json.dumps(_jsonable(full), indent=2) + "\n")
        return full

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        if not self._csv_file.closed:  # interrupted: keep the NPZ in step with the CSV
            self._csv_file.close()
            if self.rows:
                self._write_npz()


def _jsonable(x):
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return _jsonable(x.tolist())
    if isinstance(x, (np.floating, float)):
        return None if not math.isfinite(float(x)) else float(x)
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


def read_angles_csv(path: str | Path) -> dict[str, np.ndarray]:
    """Columns of an ``angles.csv`` as float arrays keyed by header name."""
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    if not rows:
        raise InputError(f"{path}: empty CSV")
    header, data = rows[0], np.array(rows[1:], dtype=float).reshape(-1, len(rows[0]))
    return {h: data[:, i] for i, h in enumerate(header)}
