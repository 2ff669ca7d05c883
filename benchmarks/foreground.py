"""Foreground models on the dev set's cluttered copy against the true foreground: IoU per frame and ms per mask.

The cluttered copy (``data/mujoco/open_close_noise_clutter``) shows the same hand as the clean
``open_close`` over a textured plane with blur and noise, so the clean frames thresholded at 20 are
its true foreground. Compared per frame: the histogram threshold (``"auto"`` on grey frames), the
plain median of the frames (:meth:`BackgroundForeground.from_frames`), and
:class:`SequenceBackground` (the ``"sequence"`` foreground) from its anchored mode alone and while
the true poses are observed after each frame (as the tracker observes its estimates). Writes
``results/foreground.json`` and ``results/foreground.png`` (one frame: the image, then each
model's mask with missed hand pixels blue and extra ones red). ``--masks DIR`` also writes every
frame's mask per model, and the true one, as ``DIR/<model>/NNN.png``: ``jaxhand track
data/mujoco/open_close_noise_clutter --masks DIR/<model> ...`` then tracks on exactly those masks.

Run: ``PYTHONPATH=. .venv/bin/python benchmarks/foreground.py`` (about 20 s).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import cv2
import numpy as np

import jaxhand as jh
from jaxhand.io import load_devset, open_frames
from jaxhand.score import (
    BackgroundForeground,
    ScoreSection,
    camera_numbers,
    capsules_from_model,
    foreground_for,
    rasterize,
    sequence_foreground,
)

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import REPO, RESULTS, environment, format_table, write_json  # noqa: E402

DEVSET = REPO / "data" / "mujoco"


def _iou(mask: np.ndarray, truth: np.ndarray) -> float:
    return float((mask & truth).sum() / max((mask | truth).sum(), 1))


def _picture(image: np.ndarray, masks: dict, truth: np.ndarray) -> np.ndarray:
    panels = [cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)]
    for name, mask in masks.items():
        p = np.zeros(image.shape + (3,), np.uint8)
        p[mask & truth] = (150, 150, 150)
        p[truth & ~mask] = (255, 80, 0)    # missed: blue
        p[mask & ~truth] = (0, 0, 255)     # extra: red
        cv2.putText(p, name, (4, 14), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (255, 255, 255), 1, cv2.LINE_AA)
        panels.append(p)
    return np.hstack(panels)


def _slug(name: str) -> str:
    """A model's name as a folder name: ``"sequence, true poses observed"`` -> ``sequence_true_poses_observed``."""
    return "_".join(name.replace(",", " ").split())


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frame", type=int, default=20, help="the frame drawn in foreground.png")
    ap.add_argument("--sequence-frames", type=int, default=60, help="frames the sequence models learn from")
    ap.add_argument("--masks", type=Path, default=None, metavar="DIR",
                    help="write every frame's mask per model (and the true one) under DIR, for jaxhand track --masks")
    args = ap.parse_args(argv)
    jh.enable_x64()
    seq = load_devset(DEVSET / "open_close_noise_clutter")
    (source,) = open_frames(DEVSET / "open_close_noise_clutter" / "frames")
    (clean,) = open_frames(DEVSET / "open_close" / "frames")
    truths = {f.index: f.image > 20 for f in clean}
    cam = seq.truth.cameras[0]
    numbers = camera_numbers(cam)
    spread = source.spread(args.sequence_frames)
    t0 = time.perf_counter()
    learned = sequence_foreground(seq.model, cam, seq.truth.q[0], spread)
    build_s = time.perf_counter() - t0
    models = {"threshold": foreground_for(ScoreSection(foreground="threshold"), spread[0]),
              "median": BackgroundForeground.from_frames(spread),
              "sequence, mode only": sequence_foreground(seq.model, cam, seq.truth.q[0], spread),
              "sequence, true poses observed": learned}
    iou = {name: [] for name in models}
    missed = {name: [] for name in models}
    extra = {name: [] for name in models}
    ms = {name: [] for name in models}
    folders = {} if args.masks is None else {name: args.masks / _slug(name) for name in [*models, "true"]}
    for folder in folders.values():
        folder.mkdir(parents=True, exist_ok=True)
    picture = None
    for f in source:
        masks = {}
        for name, model in models.items():
            t0 = time.perf_counter()
            masks[name] = model.mask(f.image).astype(bool)
            ms[name].append(1e3 * (time.perf_counter() - t0))
            iou[name].append(_iou(masks[name], truths[f.index]))
            missed[name].append(int((truths[f.index] & ~masks[name]).sum()))
            extra[name].append(int((masks[name] & ~truths[f.index]).sum()))
        for name, folder in folders.items():
            cv2.imwrite(str(folder / f"{f.index:03d}.png"), 255 * (truths[f.index] if name == "true" else masks[name])
                        .astype(np.uint8))
        if f.index == args.frame:
            picture = _picture(f.image, masks, truths[f.index])
        q = np.asarray(seq.truth.q[f.index])
        learned.observe(f.image, rasterize(capsules_from_model(seq.model, q), numbers).mask)
    rows, records = [], {}
    for name in models:
        a = np.asarray(iou[name])
        records[name] = {"iou_min": float(a.min()), "iou_median": float(np.median(a)), "iou_max": float(a.max()),
                         "iou_per_frame": a.round(4).tolist(), "missed_px_median": float(np.median(missed[name])),
                "extra_px_median": float(np.median(extra[name])), "ms_per_mask_median": float(np.median(ms[name]))}
        rows.append([name, f"{a.min():.3f}", f"{np.median(a):.3f}", f"{a.max():.3f}", f"{np.median(missed[name]):.0f}",
                     f"{np.median(extra[name]):.0f}", f"{np.median(ms[name]):.2f}"])
    print(format_table(rows, ["foreground", "IoU min", "IoU median", "IoU max", "missed px median",
                              "extra px median", "ms per mask"]))
    print(f"SequenceBackground built from {len(spread)} frames in {build_s:.2f} s")
    if picture is not None:
        cv2.imwrite(str(RESULTS / "foreground.png"), picture)
    write_json({"sequence": "open_close_noise_clutter", "truth": "open_close frames > 20",
                "sequence_frames": len(spread), "build_s": build_s, "frame_drawn": args.frame,
                "models": records, "environment": environment()}, RESULTS / "foreground.json")


if __name__ == "__main__":
    main()
