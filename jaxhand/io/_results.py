"""Result writers: ``angles.csv`` row by row, ``results.npz`` checkpoints, ``summary.json``.

Each finished frame is appended to ``angles.csv`` and flushed at once, so a run that stops
midway keeps every finished frame. ``results.npz`` (every per-frame array) is rewritten every
``checkpoint_every`` frames and at the end; ``summary.json`` is written by :meth:`close`. Both
are written to a temporary file first and renamed over the old one, so a reader (or a run
stopped mid-write, or a full disk) never sees half a file, and no temporary file stays behind.

The per-frame values are kept in growing NumPy columns (a few hundred bytes a frame), not as
one object per frame, so a long run's memory is what its outputs need.

A folder that holds an earlier run is refused unless the writer is told to ``overwrite`` it
(its run files are deleted first) or to ``resume`` it (the rows of ``results.npz`` are read
back, ``angles.csv`` is cut to the same frames and appended to).
"""

from __future__ import annotations

import contextlib
import csv
import io
import json
import math
import os
from pathlib import Path

import numpy as np

from .._errors import InputError, OutputExistsError
from ..model import Model

__all__ = ["ResultWriter", "read_angles_csv", "q_columns", "RUN_FILES", "atomic_write"]

#: The files of a tracking run in its folder (``overlay*`` images and videos as well).
RUN_FILES = ("angles.csv", "results.npz", "summary.json", "angles.png")


def q_columns(model: Model) -> list[str]:
    """CSV column names of q: angles in degrees (``_deg``), lengths in mm (``_mm``)."""
    unit = {"angle": "_deg", "length": "_mm", "quat": ""}
    return [n + unit[k] for n, k in zip(model.q_names, model.q_kinds)]


def _user_units(model: Model, q: np.ndarray) -> np.ndarray:
    return np.where(model.is_angle, np.degrees(q), q)


def atomic_write(path: str | Path, write) -> None:
    """Call ``write(binary_file)`` on ``<stem>.tmp<suffix>`` beside ``path``, then rename it over
    ``path``; on any error the temporary file is removed and the old ``path`` left as it was."""
    path = Path(path)
    tmp = path.with_name(f"{path.stem}.tmp{path.suffix}")
    try:
        with open(tmp, "wb") as f:
            write(f)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


class _Columns:
    """Per-frame values in growing arrays (capacity doubles), one array per key."""

    def __init__(self):
        self._data: dict[str, np.ndarray] = {}
        self.n = 0

    def append(self, values: dict) -> None:
        for key, value in values.items():
            v = np.asarray(value)
            col = self._data.get(key)
            if col is None:
                col = self._data[key] = np.zeros((max(64, 2 * self.n),) + v.shape, v.dtype)
            elif len(col) <= self.n:
                grown = np.zeros((2 * len(col),) + col.shape[1:], col.dtype)
                grown[:self.n] = col[:self.n]
                col = self._data[key] = grown
            col[self.n] = v
        self.n += 1

    def arrays(self) -> dict[str, np.ndarray]:
        return {k: v[:self.n] for k, v in self._data.items()}

    def __len__(self) -> int:
        return self.n


class ResultWriter:
    """Writes a tracking run's results into ``out_dir`` frame by frame.

    Args:
        out_dir: folder (created if needed).
        model: the tracked model (column names and units).
        checkpoint_every: rewrite ``results.npz`` every this many frames.
        overwrite: delete an earlier run's files in ``out_dir`` first.
        resume: continue the run in ``out_dir`` after its last frame in ``results.npz``
            (:attr:`last_frame`, :attr:`last_q`).

    Raises:
        OutputExistsError: ``out_dir`` holds an earlier run and neither flag is given.
        InputError: there is nothing to resume, it is of another model, or a file cannot be written.
    """

    def __init__(self, out_dir: str | Path, model: Model, checkpoint_every: int = 50, *, overwrite: bool = False,
                 resume: bool = False):
        self.out = Path(out_dir)
        self.out.mkdir(parents=True, exist_ok=True)
        self.model = model
        self.checkpoint_every = checkpoint_every
        self.columns = _Columns()
        self.skipped: list[dict] = []
        self.resumed_after: int | None = None
        header = ["frame", "time_s", *q_columns(model), "confidence", "lost"]
        existing = [name for name in RUN_FILES if (self.out / name).exists()]
        if resume:
            self._reopen(header)
        else:
            if existing and not overwrite:
                raise OutputExistsError(f"{self.out}: holds an earlier tracking run ({', '.join(existing)})")
            for p in [self.out / n for n in RUN_FILES] + sorted(self.out.glob("overlay*")):
                with contextlib.suppress(FileNotFoundError):
                    p.unlink()
            self._guard("angles.csv", lambda: self._open_csv("w", header))

    def _guard(self, name: str, fn):
        try:
            return fn()
        except OSError as err:
            raise InputError(f"{self.out / name}: cannot write ({err.strerror or err}); "
                             f"the {len(self.columns)} finished frames are kept") from err

    def _open_csv(self, mode: str, header: list[str] | None) -> None:
        self._csv_file = open(self.out / "angles.csv", mode, newline="")  # noqa: SIM115 (closed in close())
        self._csv = csv.writer(self._csv_file)
        if header is not None:
            self._csv.writerow(header)
        self._csv_file.flush()

    def _reopen(self, header: list[str]) -> None:
        npz = self.out / "results.npz"
        if not npz.exists():
            raise InputError(f"{self.out}: nothing to resume (no results.npz of an earlier run)")
        try:
            with np.load(npz) as data:
                saved = {k: data[k] for k in data.files}
        except (OSError, ValueError) as err:
            raise InputError(f"{npz}: cannot read ({err})") from err
        names = tuple(str(n) for n in saved.pop("q_names", ()))
        if names != tuple(self.model.q_names):
            raise InputError(f"{npz}: the earlier run tracked other joints ({', '.join(names)}) than "
                             f"{self.model.name!r} ({', '.join(self.model.q_names)})")
        n = len(saved.get("frame", ()))
        for i in range(n):
            self.columns.append({k: v[i] for k, v in saved.items()})
        try:
            self.skipped = list(json.loads((self.out / "summary.json").read_text()).get("frames_skipped", []))
        except (OSError, ValueError, AttributeError):
            self.skipped = []
        if n:
            self.resumed_after = int(saved["frame"][-1])
        last = self.resumed_after
        self.skipped = [s for s in self.skipped if last is None or s.get("frame", 0) <= last]
        # angles.csv may hold frames after the last checkpoint: cut it to the frames of results.npz
        keep = set(saved.get("frame", np.zeros(0, int)).tolist())
        rows = []
        with contextlib.suppress(OSError), open(self.out / "angles.csv", newline="") as f:
            rows = [r for r in list(csv.reader(f))[1:] if r and r[0].lstrip("-").isdigit() and int(r[0]) in keep]
        text = io.StringIO(newline="")
        csv.writer(text).writerows([header, *rows])
        self._guard("angles.csv", lambda: atomic_write(self.out / "angles.csv",
                                                       lambda f: f.write(text.getvalue().encode())))
        self._guard("angles.csv", lambda: self._open_csv("a", None))

    @property
    def last_frame(self) -> int | None:
        """The last frame written (after a resume: of the earlier run), or None."""
        return int(self.columns.arrays()["frame"][-1]) if len(self.columns) else None

    @property
    def last_q(self) -> np.ndarray | None:
        """The reported (filtered) q of :attr:`last_frame`, or None."""
        return self.columns.arrays()["q"][-1].copy() if len(self.columns) else None

    def __len__(self) -> int:
        return len(self.columns)

    def arrays(self) -> dict[str, np.ndarray]:
        """Every per-frame column written so far (views; copy to keep)."""
        return self.columns.arrays()

    def write(self, frame: int, time_s: float, q: np.ndarray, confidence: float, lost: bool, **arrays) -> None:
        """Append one frame: the reported (filtered) q in the CSV; q and ``arrays`` in the NPZ.

        Raises:
            InputError: a non-finite q, or the folder cannot be written (a full disk: the frames
                before this one are kept).
        """
        q = np.asarray(q, float)
        if not np.all(np.isfinite(q)):
            raise InputError(f"frame {frame}: refusing to write a non-finite state")

        def row():
            self._csv.writerow([frame, f"{time_s:.6f}", *(f"{v:.6f}" for v in _user_units(self.model, q)),
                                f"{confidence:.4f}", int(lost)])
            self._csv_file.flush()

        self._guard("angles.csv", row)
        self.columns.append({"frame": frame, "time_s": time_s, "q": q, "confidence": confidence, "lost": lost,
                             **arrays})
        if len(self.columns) % self.checkpoint_every == 0:
            self._write_npz()

    def skip(self, frame: int, reason: str) -> None:
        """Record a frame that could not be processed (reported in summary.json)."""
        self.skipped.append({"frame": frame, "reason": reason})

    def _write_npz(self) -> None:
        arrays = self.columns.arrays()
        self._guard("results.npz", lambda: atomic_write(
            self.out / "results.npz", lambda f: np.savez(f, q_names=np.array(self.model.q_names), **arrays)))

    def _close_files(self) -> None:
        if not self._csv_file.closed:
            with contextlib.suppress(OSError):
                self._csv_file.close()

    def close(self, summary: dict) -> dict:
        """Flush everything and write ``summary.json`` (``summary`` plus frame counts)."""
        self._close_files()
        if len(self.columns):
            self._write_npz()
        full = {"model": self.model.name, "frames_written": len(self.columns), "frames_skipped": self.skipped,
                **summary}
        text = (json.dumps(_jsonable(full), indent=2) + "\n").encode()
        self._guard("summary.json", lambda: atomic_write(self.out / "summary.json", lambda f: f.write(text)))
        return full

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        if not self._csv_file.closed:  # stopped early: keep the NPZ in step with the CSV
            self._close_files()
            if len(self.columns):
                with contextlib.suppress(InputError):   # a full disk: the last checkpoint stays
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
