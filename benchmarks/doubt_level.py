"""The reported confidence's doubt level (``loss.doubt_level``) chosen on recorded dev-set runs.

Reads ``devset.py`` result files, recovers each frame's own tracker confidence from the reported
one (the run's ``loss.doubt_level`` undone), and for each candidate level gives the loss flag's hit
rates (issue 13: >= 90 % of the frames with a mean tip error over 8 px flagged lost or under 0.5,
<= 5 % of those under 3 px), pooled over the runs and apart for the first and second half of the
seeds, so that a level chosen on one half is checked on the other. The tracking itself does not
depend on the level (the tracker decides by its own confidence), so recorded runs answer exactly.
Writes ``benchmarks/results/doubt_level.json``.

    .venv/bin/python benchmarks/doubt_level.py devset_rt_seeds6_a.json devset_rt_seeds6_b.json \\
        devset_rt_thumb_seeds6.json devset_rt_clutter_seeds6.json
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import RESULTS, environment, format_table, write_json  # noqa: E402

from jaxhand.track import loss_flag_quality, reported_confidence  # noqa: E402

LEVELS = (0.5, 0.6, 0.7, 0.75, 0.8, 0.85, 0.9)


def own_confidence(reported: np.ndarray, level: float) -> np.ndarray:
    """The tracker's own confidence behind ``reported`` ones made with ``level`` (the inverse of
    :func:`jaxhand.track.reported_confidence`)."""
    c = np.asarray(reported, float)
    return np.where(c <= 0.5, 2.0 * level * c, level + 2.0 * (c - 0.5) * (1.0 - level))


def frames(runs: list[dict]) -> dict[str, np.ndarray]:
    """Every image run's frames: tip error (px), own confidence, lost, seed, sequence."""
    cols: dict[str, list] = {"tip": [], "own": [], "lost": [], "seed": [], "sequence": []}
    for r in runs:
        if r["features"] != "image":
            continue
        level = r["config"]["loss"].get("doubt_level", 0.5)
        n = len(r["per_frame_tip_px"])
        cols["tip"].append(r["per_frame_tip_px"])
        cols["own"].append(own_confidence(r["per_frame_confidence"], level))
        cols["lost"].append(r["per_frame_lost"])
        cols["seed"].append([r["seed"]] * n)
        cols["sequence"].append([r["sequence"]] * n)
    return {k: np.concatenate(v) for k, v in cols.items()}


def rates(f: dict[str, np.ndarray], sel: np.ndarray, level: float) -> dict:
    shown = np.array([reported_confidence(c, level) for c in f["own"][sel]])
    return loss_flag_quality(f["tip"][sel], shown, f["lost"][sel].astype(bool))


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("files", nargs="+", help="devset.py result files under benchmarks/results/")
    p.add_argument("--levels", default=",".join(map(str, LEVELS)), help="comma-separated doubt levels")
    args = p.parse_args(argv)
    runs = [r for name in args.files for r in json.loads((RESULTS / name).read_text())["runs"]]
    f = frames(runs)
    seeds = np.unique(f["seed"])
    half = f["seed"] < seeds[len(seeds) // 2] if len(seeds) > 1 else np.ones(len(f["seed"]), bool)
    parts = {"all": np.ones(len(half), bool), "first seeds": half, "last seeds": ~half}
    rows, out = [], []
    for level in (float(x) for x in args.levels.split(",")):
        rec = {"level": level, **{name: rates(f, sel, level) for name, sel in parts.items() if sel.any()}}
        out.append(rec)
        row = [f"{level:g}"]
        for name in parts:
            q = rec.get(name)
            row += ["-", "-"] if q is None else [
                f"{round((q['flagged_bad'] or 0) * q['frames_bad'])} / {q['frames_bad']}",
                f"{round((q['flagged_good'] or 0) * q['frames_good'])} / {q['frames_good']}"]
        rows.append(row)
    print(format_table(rows, ["doubt level", *[f"{n}: {k}" for n in parts for k in (">8px flagged", "<3px flagged")]]))
    write_json({"environment": environment(), "files": args.files, "levels": out}, RESULTS / "doubt_level.json")


if __name__ == "__main__":
    main()
