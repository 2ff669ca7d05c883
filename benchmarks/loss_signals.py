"""Per-frame candidate evidence for the loss flag (issue 13), with the truth, on the robust preset.

Tracks each dev-set sequence as ``benchmarks/devset.py --settings robust --no-exact`` does (or
with another ``--preset``), with
the support rule off (it changes no estimate, only the confidence), and keeps per frame: the
mean tip error of the estimate against the truth (px), the confidence and loss flag without the
support rule, and the candidate evidence the tracker can compute without the truth:

- ``spread_px``: the largest mean tip distance (px) of a start whose merit is at least 0.9 of the
  best from the winning start (hypothesis disagreement);
- ``rms_px``: the solve's residual RMS; ``valid_share``: its valid feature slots;
- ``jump_px``: the largest tip distance between the prediction and the solve;
- ``term_merit``: the silhouette term's merit at the winner;
- ``support``: the weakest finger's image support (:func:`jaxhand.track._support.weakest_finger`);
- ``unexplained_m{1,2,3}``: the largest unexplained foreground blob (px) beyond a margin of 1-3 px.

Writes ``benchmarks/results/loss_signals.json``; ``benchmarks/loss_rule.py`` analyses it.

    PYTHONPATH=. .venv/bin/python benchmarks/loss_signals.py
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import REPO, RESULTS, add_runtime_option, apply_runtime, environment, write_json  # noqa: E402

import jaxhand.track._tracker as tracker_module  # noqa: E402
from jaxhand import kinematics  # noqa: E402
from jaxhand.io import load_devset, open_frames  # noqa: E402
from jaxhand.score import capsules_from_model, foreground_for, rasterize  # noqa: E402
from jaxhand.track import PRESETS, ImageFrontEnd, TrackConfig, Tracker  # noqa: E402
from jaxhand.track._support import finger_of_link, largest_unexplained_px, weakest_finger  # noqa: E402

SEQUENCES = ("open_close", "index_over_middle", "thumb_opposition", "fast_spread", "wave_two_cameras")


def _tips_px(model, cams, qs) -> np.ndarray:
    """(k, tips, 2) tips of the states ``qs`` (k, n_q) in every camera, (cams, k, tips, 2)."""
    tips = jax.vmap(lambda x: kinematics.pose(model, x).tips)(jnp.asarray(np.atleast_2d(qs)))
    return np.asarray(jnp.stack([c.project(tips)[0] for c in cams]))


def _spread(model, cams, qs, merit, q_win, share: float = 0.9) -> float:
    """The largest mean tip distance (px) from ``q_win`` of the starts within ``share`` of the best merit."""
    near = np.asarray(merit) >= share * np.max(merit)
    d = np.linalg.norm(_tips_px(model, cams, qs[near]) - _tips_px(model, cams, q_win), axis=-1).mean(0)
    return float(d.mean(-1).max())


def run(name: str, frames: int | None, preset: str = "robust") -> list[dict]:
    seq = load_devset(REPO / "data" / "mujoco" / name)
    m, cams = seq.model, seq.truth.cameras
    config = TrackConfig().preset(preset).merged({"support": {"enabled": False}})
    frontend = ImageFrontEnd(m, cams, config.image)
    tracker = Tracker(m, cams, frontend, config, dt_s=1 / seq.truth.fps)
    finger = finger_of_link(m)
    section = dataclasses.replace(config.image.score, foreground="auto")   # the support's foreground
    seen: dict = {}
    choose, candidates = tracker_module.choose, tracker._hypotheses.candidates

    def keep_choice(merit, scores=None):   # the starts' merits, as the tracker judges them
        seen["merit"] = np.asarray(merit)
        return choose(merit, scores)

    def keep_candidates(*a, **k):
        c = candidates(*a, **k)
        seen["qs"], seen["term_merit"] = np.asarray(c.solved.q), np.asarray(c.solved.term_merit)
        return c

    tracker_module.choose, tracker._hypotheses.candidates = keep_choice, keep_candidates
    try:
        folders = [seq.folder / Path(f[0]).parent for f in seq.truth.image_files]
        images = zip(*open_frames(folders, fps=seq.truth.fps))
        state = tracker.init(seq.truth.q[0])
        n = len(seq.truth.q) if frames is None else min(frames, len(seq.truth.q))
        rows = []
        for k in range(n):
            ims = [f.image for f in next(images)]
            seen.clear()
            state, rep = tracker.step(state, ims, k)
            tips = _tips_px(m, cams, np.stack([seq.truth.q[k], rep.q_filtered, rep.q_pred, rep.q_solved]))
            err = np.linalg.norm(tips[:, 1] - tips[:, 0], axis=-1).mean(0)
            winner = int(np.argmax(seen["merit"]))
            row = {"sequence": name, "frame": k, "tip_error_px": float(err.mean()), "confidence": rep.confidence,
                   "lost": rep.lost, "rms_px": rep.rms_px, "valid_share": rep.valid_share,
                   "jump_px": float(np.linalg.norm(tips[:, 2] - tips[:, 3], axis=-1).mean(0).max()),
                   "spread_px": _spread(m, cams, seen["qs"], seen["merit"], seen["qs"][winner]),
                   "term_merit": float(seen["term_merit"][winner])}
            measured = frontend.support(ims, rep.q_filtered, None)
            row["support"] = weakest_finger(measured.link_score, finger)
            caps = capsules_from_model(m, rep.q_filtered)
            masks = [(foreground_for(section, im).mask(im), rasterize(caps, cam).mask) for cam, im in zip(cams, ims)]
            for margin in (1, 2, 3):
                row[f"unexplained_m{margin}"] = max(largest_unexplained_px(f, s, margin) for f, s in masks)
            rows.append(row)
    finally:
        tracker_module.choose = choose
    print(name, n, flush=True)
    return rows


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--only", default=",".join(SEQUENCES))
    p.add_argument("--frames", type=int, default=None)
    p.add_argument("--json", default="loss_signals.json", help="file name under benchmarks/results/")
    p.add_argument("--preset", default="robust", choices=tuple(PRESETS), help="the tracker's preset")
    add_runtime_option(p)
    args = p.parse_args(argv)
    apply_runtime(args)
    rows = []
    for name in args.only.split(","):
        rows += run(name, args.frames, args.preset)
    write_json({"environment": environment(), "preset": args.preset, "frames": rows}, RESULTS / args.json)


if __name__ == "__main__":
    main()
