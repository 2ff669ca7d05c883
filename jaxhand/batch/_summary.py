"""The batch report: ``batch_summary.csv`` and ``.json`` (one row per job) and a plot.

Each row comes from the job's run record and its ``summary.json`` (the keys
:func:`jaxhand.track.track_sequence` writes: ``frames``, ``frames_per_second_end_to_end``,
``accuracy_filtered.joint_error_deg.mean``, ...); a key a command does not write stays empty.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

from ._manifest import Manifest

__all__ = ["summary_rows", "write_batch_summary", "plot_batch_summary", "COLUMNS"]

#: The report's columns, in order, with the ``summary.json`` path each comes from (None: the run).
COLUMNS = {
    "name": None,
    "command": None,
    "status": None,              # done | skipped (finished earlier) | failed | interrupted | not run
    "frames": "frames",
    "frames_per_second": "frames_per_second_end_to_end",
    "frames_per_second_steady": "frames_per_second_steady",
    "joint_error_deg_mean": "accuracy_filtered.joint_error_deg.mean",
    "joint_error_deg_max": "accuracy_filtered.joint_error_deg.max",
    "tip_error_px_mean": "accuracy_filtered.tip_error_px.mean",
    "lost_frames": "lost_frames",
    "wall_s": None,
    "jit_compiles": None,
    "worker": None,
    "error": None,
    "out": None,
}


def _get(summary: dict, dotted: str):
    value = summary
    for part in dotted.split("."):
        if not isinstance(value, dict) or part not in value:
            return None
        value = value[part]
    return value


def summary_rows(manifest: Manifest, records: dict[str, dict]) -> list[dict]:
    """One row of :data:`COLUMNS` per job of ``manifest``, in its order; ``records`` maps a job's
    name to its run record (:func:`jaxhand.batch.run_job`'s, or ``status`` and ``summary`` for a
    job skipped as finished); a job without one is ``not run``."""
    rows = []
    for job in manifest.jobs:
        rec = records.get(job.name, {"status": "not run"})
        summary = rec.get("summary") or {}
        row = {}
        for col, key in COLUMNS.items():
            row[col] = _get(summary, key) if key else rec.get(col)
        row.update(name=job.name, command=job.command, out=job.name)
        if row["wall_s"] is None and "wall_s" in summary:
            row["wall_s"] = summary["wall_s"]
        rows.append(row)
    return rows


def write_batch_summary(manifest: Manifest, out_dir: str | Path, records: dict[str, dict]) -> list[dict]:
    """Write ``batch_summary.csv``, ``batch_summary.json`` and ``batch_summary.png`` into
    ``out_dir``; returns the rows."""
    out = Path(out_dir)
    rows = summary_rows(manifest, records)
    with open(out / "batch_summary.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(COLUMNS))
        writer.writeheader()
        for row in rows:
            writer.writerow({k: "" if v is None else (f"{v:.6g}" if isinstance(v, float) else v)
                             for k, v in row.items()})
    report = {"format_version": 1, "manifest": str(manifest.path), "jobs": rows,
              "totals": {s: sum(r["status"] == s for r in rows) for s in ("done", "skipped", "failed", "interrupted",
                                                                     "not run")}}
    (out / "batch_summary.json").write_text(json.dumps(report, indent=2) + "\n")
    plot_batch_summary(rows, out / "batch_summary.png")
    return rows


def plot_batch_summary(rows: list[dict], path: str | Path) -> None:
    """Bars per job: frames per second end to end and, where ground truth was given, the mean
    filtered joint error (deg); failed and unrun jobs are labelled in place of a bar."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = [r["name"] for r in rows]
    x = list(range(len(rows)))
    fig, axes = plt.subplots(2, 1, figsize=(max(6.0, 0.5 * len(rows) + 2), 6), sharex=True)
    for ax, col, label in ((axes[0], "frames_per_second", "frames/s (end to end)"),
                           (axes[1], "joint_error_deg_mean", "mean joint error (deg)")):
        values = [r[col] if isinstance(r[col], int | float) and math.isfinite(r[col]) else 0.0 for r in rows]
        ax.bar(x, values, color=["tab:grey" if r["status"] == "skipped" else "tab:blue" for r in rows])
        for i, r in enumerate(rows):
            if r["status"] in ("failed", "interrupted", "not run"):
                ax.text(i, 0, r["status"], rotation=90, ha="center", va="bottom", color="tab:red", fontsize=8)
        ax.set_ylabel(label)
        ax.grid(axis="y", alpha=0.3)
    axes[0].set_title("jaxhand batch: speed and accuracy per job (grey: finished in an earlier run)")
    axes[1].set_xticks(x, names, rotation=45, ha="right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
