"""Drift with time: one slow motion tracked over 80, 2,000 and 8,000 frames (issue 13).

A synthetic preset's path (``two_finger_occlusion`` by default) spread over more frames at the
preset's frame rate, so the longer runs are slower and should be easier if nothing accumulates.
Each frame is rendered as ``jaxhand synth`` renders it (anti-aliasing 1 by default) and tracked
from the true first pose with the default ``TrackConfig`` and with each named variant
(:data:`VARIANTS`, or ``--config`` TOML files) in lockstep on the same image; ``truth-refresh``
re-takes the templates at the true pose instead of the solved one (a diagnostic: what is left
without template drift). Every tracked frame
is appended to ``benchmarks/results/long/<sequence>_<frames>_<variant>.jsonl`` at once, so an
interrupted run (Ctrl-C, or a killed process) keeps what it has; the summaries are computed from
those files: mean absolute error (deg) over the moving joints of the reported estimate and of the
raw solve, per third and per tenth of the planned run, frames lost, mean tip error (px).
They go to ``benchmarks/results/long.json`` (merged with the runs already there).

    .venv/bin/python benchmarks/long.py                                  # 80, 2,000, 8,000 frames, default
    .venv/bin/python benchmarks/long.py --frames 2000 --variants default,no-refresh,no-filter
    .venv/bin/python benchmarks/long.py --frames 2000 --config run.toml  # a variant from a TOML file
    .venv/bin/python benchmarks/long.py --frames 2000 --stop 700 --variants truth-refresh  # first 700 only
    .venv/bin/python benchmarks/long.py --frames 8000 --start 3200 --stop 5600  # a stretch, from the truth
    .venv/bin/python benchmarks/long.py --report                         # re-summarise the JSONL files
    .venv/bin/python benchmarks/tracking.py --long ...                   # the same
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import NamedTuple

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import RESULTS, environment, format_table, write_json  # noqa: E402

from jaxhand.render import RenderConfig, make_preset, render_frame  # noqa: E402
from jaxhand.track import (  # noqa: E402
    PRESETS,
    AbstractFrontEnd,
    ImageFrontEnd,
    Review,
    TrackConfig,
    Tracker,
    accuracy_summary,
    config_to_dict,
    load_track_config,
)

RUNS = RESULTS / "long"


class Variant(NamedTuple):
    """A tracker setting: changes to the default TrackConfig (as in TrackConfig.merged)."""

    changes: dict
    refresh_at_truth: bool = False   # templates re-taken at the true pose (a diagnostic)


VARIANTS = {
    "default": Variant({}),
    "no-refresh": Variant({"refresh_templates": False}),    # templates kept from the first frame
    "no-filter": Variant({"filter": {"enabled": False}}),    # report and predict the raw solve
    "no-refresh+no-filter": Variant({"refresh_templates": False, "filter": {"enabled": False}}),
    "truth-refresh": Variant({}, refresh_at_truth=True),
    "truth-refresh+no-filter": Variant({"filter": {"enabled": False}}, refresh_at_truth=True),
    "no-recentre": Variant({"image": {"template_recentre": False}}),
    "no-reextract": Variant({"reextract": 0}),
    # issue 13's drift fixes (off by default: they cost tracking.py's experiments, benchmarks/README.md):
    # templates re-taken per 0.2 radii of motion, unseen joints' velocity damped; and each alone
    "drift-fix": Variant({"image": {"refresh": {"min_move": 0.2}}, "filter": {"damp_unseen": True}}),
    "refresh-per-motion": Variant({"image": {"refresh": {"min_move": 0.2}}}),
    "damp-unseen": Variant({"filter": {"damp_unseen": True}}),
    # the DIP-PIP coupling in every solve (TrackConfig.preset("coupled")): meets issue 13's target alone
    "coupled": Variant(PRESETS["coupled"]),
    "robust": Variant(PRESETS["robust"]),   # six starts per frame and the silhouette term (slow)
    "robust-limits": Variant(PRESETS["robust-limits"]),
    "robust-temporal": Variant(PRESETS["robust-temporal"]),   # the preset recommended for images jaxhand did not draw
}


class RefreshAtTruth(AbstractFrontEnd):
    """The image front end with its templates re-taken at each frame's true pose rather than
    the solved one: what the tracker does when refreshing cannot carry an error forward."""

    def __init__(self, inner: ImageFrontEnd, truth: np.ndarray):
        self.inner, self.truth, self.frame = inner, truth, 0

    def extract(self, images, q_start, state, frame: int):
        self.frame = frame   # the frame whose refresh follows
        return self.inner.extract(images, q_start, state, frame)

    def refresh(self, images, q, state):
        return self.inner.refresh(images, self.truth[self.frame], state)


class _Run:
    """One tracker on the shared frames and the JSONL file it appends each frame to."""

    def __init__(self, seq, variant: str, config: TrackConfig, refresh_at_truth: bool, header: dict):
        self.seq = seq
        frontend = ImageFrontEnd(seq.model, seq.cameras, config.image)
        if refresh_at_truth:
            frontend = RefreshAtTruth(frontend, seq.q)
        self.tracker = Tracker(seq.model, seq.cameras, frontend, config, dt_s=float(seq.times_s[1] - seq.times_s[0]))
        self.state = self.tracker.init(seq.q[header["start"]])
        self.review = Review(self.tracker)   # the frames before a trusted jump tracked again (hypotheses.review_*)
        self.seconds: dict[int, float] = {}
        self.path = RUNS / f"{seq.name}_{seq.n_frames}_{variant}{_stretch(header)}.jsonl"
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.file = self.path.open("w", buffering=1)   # line-buffered: each frame is on disk when written
        self.file.write(json.dumps({**header, "variant": variant, "config": config_to_dict(config)}) + "\n")

    def step(self, images, k: int) -> None:
        t0 = time.perf_counter()
        self.state, rep = self.tracker.step(self.state, images, k, float(self.seq.times_s[k]))
        self.seconds[k] = time.perf_counter() - t0
        for _, final in self.review.push(self.state, images, rep):
            self.write(final)

    def close(self) -> None:
        """The frames the review still holds, then the file."""
        for _, final in self.review.flush():
            self.write(final)
        self.file.close()

    def write(self, rep) -> None:
        k, seconds = rep.frame, self.seconds.pop(rep.frame)
        qt = self.seq.q[k]
        tip = accuracy_summary(self.seq.model, self.seq.cameras, rep.q_filtered[None], qt[None])["tip_error_px"]
        row = {"k": k, "qf": _rounded(rep.q_filtered), "qs": _rounded(rep.q_solved), "qt": _rounded(qt),
               "lost": bool(rep.lost), "conf": round(float(rep.confidence), 4), "rms": round(float(rep.rms_px), 4),
               "tip": round(tip["mean"], 4), "s": round(seconds, 5)}
        self.file.write(json.dumps(row) + "\n")


def _stretch(run: dict) -> str:
    """The file-name and key suffix of a run over part of the path (``--start``, ``--stop``), so a
    stretch never overwrites the whole run's file or summary; "" for the whole path."""
    start, stop = run.get("start") or 0, run.get("stop")
    return (f"_from{start}" if start else "") + (f"_to{stop}" if stop is not None and stop < run["frames"] else "")


def _rounded(q) -> list[float]:
    return [round(float(v), 7) for v in np.asarray(q)]


def summarise(path: Path) -> dict:
    """The summary of one JSONL run file (complete or not)."""
    lines = path.read_text().splitlines()
    header, rows = json.loads(lines[0]), []
    for line in lines[1:]:
        try:
            rows.append(json.loads(line))
        except json.JSONDecodeError:   # a line cut short by a kill
            break
    start = header.get("start", 0)
    planned, moving = header["frames"] - start, np.asarray(header["moving"])
    out = {k: header[k] for k in ("sequence", "frames", "variant", "antialias", "size", "environment")}
    out.update(start=start, stop=header.get("stop"))
    out.update(frames_done=len(rows), complete=len(rows) == planned)
    if not rows:
        return out
    qt = np.array([r["qt"] for r in rows])
    err = {label: np.degrees(np.abs(np.array([r[key] for r in rows]) - qt))[:, moving]
           for label, key in (("filtered", "qf"), ("raw", "qs"))}
    frame_mean = err["filtered"].mean(axis=1)

    def parts(n: int) -> list[float | None]:
        edges = np.linspace(0, planned, n + 1).round().astype(int)
        return [float(frame_mean[a:b].mean()) if b <= len(rows) else None for a, b in zip(edges[:-1], edges[1:])]

    lost = [r["k"] for r in rows if r["lost"]]
    steady = [r["s"] for r in rows[1:]]
    out.update(
        mean_deg=float(err["filtered"].mean()), max_deg=float(err["filtered"].max()),
        raw_mean_deg=float(err["raw"].mean()), raw_max_deg=float(err["raw"].max()),
        per_joint_mean_deg=dict(zip(header["moving_names"], err["filtered"].mean(axis=0).tolist())),
        thirds_deg=parts(3), tenths_deg=parts(10), lost_frames=len(lost), first_lost=lost[0] if lost else None,
        tip_mean_px=float(np.mean([r["tip"] for r in rows])), confidence_mean=float(np.mean([r["conf"] for r in rows])),
        step_ms_median=1e3 * float(np.median(steady)) if steady else None)
    return out


def _table(summaries: list[dict]) -> str:
    def f(v):
        return "-" if v is None else f"{v:.1f}"

    rows = [[s["sequence"], s["frames"], s["variant"] + _stretch(s).replace("_", " "),
             f"{s['frames_done']}", f"{s.get('mean_deg', float('nan')):.2f}",
             f"{s.get('raw_mean_deg', float('nan')):.2f}", " ".join(f(v) for v in s.get("thirds_deg", [])),
             " ".join(f(v) for v in s.get("tenths_deg", [])), s.get("lost_frames", 0),
             f"{s.get('tip_mean_px', float('nan')):.2f}"] for s in summaries]
    return format_table(rows, ["sequence", "frames", "variant", "done", "mean", "raw", "thirds", "tenths", "lost",
                               "tip px"])


def _save(summaries: list[dict], path: Path) -> None:
    """Merge ``summaries`` into the JSON at ``path`` (runs keyed by sequence, frames and variant)."""
    old = json.loads(path.read_text())["runs"] if path.is_file() else {}
    old.update({f"{s['sequence']}_{s['frames']}_{s['variant']}{_stretch(s)}": s for s in summaries})
    write_json({"runs": dict(sorted(old.items()))}, path)
    print(f"wrote {path}")


def track_long(name: str, frames: int, variants: dict[str, tuple[TrackConfig, bool]], antialias: int, size: str,
               paths: list[Path], stop: int | None = None, start: int = 0) -> None:
    """Render ``name`` over ``frames`` frames and track it (frames ``start`` to ``stop``, from the
    true pose of frame ``start``) with every variant (config, refresh at the truth), appending each
    variant's JSONL file to ``paths``.

    A KeyboardInterrupt goes through after closing the files, which keep every finished frame.
    """
    seq = make_preset(name, frames=frames, size=size)
    moving = (np.ptp(seq.q, axis=0) > 1e-6) & np.asarray(seq.model.is_angle)
    header = {"sequence": name, "frames": frames, "antialias": antialias, "size": size,
              "moving": moving.tolist(), "moving_names": [n for n, m in zip(seq.model.q_names, moving) if m],
              "environment": environment(), "start": start, "stop": stop}
    runs = []
    for v, (c, at_truth) in variants.items():
        runs.append(_Run(seq, v, c, at_truth, header))
        paths.append(runs[-1].path)
    render = RenderConfig(antialias=antialias)
    t0 = time.perf_counter()
    try:
        for k in range(start, frames if stop is None else min(stop, frames)):
            q = seq.q[k]
            images = [render_frame(seq.model, c, q, render).image for c in seq.cameras]
            for r in runs:
                r.step(images, k)
            if k % 500 == 499:
                print(f"  {name} {frames} frames: {k + 1} done, {time.perf_counter() - t0:.0f} s", flush=True)
    finally:
        for r in runs:
            r.close()


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sequence", default="two_finger_occlusion", help="the synthetic preset")
    p.add_argument("--frames", default="80,2000,8000", help="comma-separated run lengths")
    p.add_argument("--variants", default="default", help="comma-separated: " + ", ".join(VARIANTS))
    p.add_argument("--config", action="append", default=[], metavar="TOML",
                   help="a further variant from a TrackConfig TOML file (named after the file)")
    p.add_argument("--antialias", type=int, default=1, help="render samples per pixel per axis (jaxhand synth's 1)")
    p.add_argument("--size", default="320x240", help="image size WxH")
    p.add_argument("--stop", type=int, help="track only up to frame N of each run (files and keys named _toN)")
    p.add_argument("--start", type=int, default=0,
                   help="start tracking at frame N from its true pose (a diagnostic: a later stretch alone)")
    p.add_argument("--report", action="store_true", help="only summarise the JSONL files already written")
    p.add_argument("--json", default="long.json", help="summary file under benchmarks/results/")
    args = p.parse_args(argv)
    interrupted = False
    if args.report:
        paths = sorted(RUNS.glob("*.jsonl"))
    else:
        variants = {v: (TrackConfig().merged(VARIANTS[v].changes), VARIANTS[v].refresh_at_truth)
                    for v in args.variants.split(",") if v}
        variants.update({Path(c).stem: (load_track_config(c), False) for c in args.config})
        paths = []
        try:
            for n in (int(v) for v in args.frames.split(",")):
                track_long(args.sequence, n, variants, args.antialias, args.size, paths, args.stop, args.start)
        except KeyboardInterrupt:
            print("interrupted: summarising the finished frames", flush=True)
            interrupted = True
    summaries = [summarise(q) for q in paths]
    print(_table(summaries))
    _save(summaries, RESULTS / args.json)
    return 130 if interrupted else 0


if __name__ == "__main__":
    raise SystemExit(main())
