"""Per-frame candidate evidence for the loss flag (issue 13), with the truth, for the robust preset.

Tracks each dev-set sequence like ``benchmarks/devset.py --settings robust --no-exact`` and keeps,
per frame: every start's solved pose and merit, the winner, the prediction, the solve, the
reported estimate, the residual RMS, the valid share, the confidence, the features' valid slots,
the per-link image scores of the solve, and the truth. Writes an ``.npz`` for offline analysis.

    PYTHONPATH=. .venv/bin/python benchmarks/loss_signals.py --out /tmp/loss_signals.npz
"""

from __future__ import annotations

import argparse
import dataclasses
import pickle
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import REPO  # noqa: E402

import jaxhand.track._tracker as tracker_module  # noqa: E402
from jaxhand.io import load_devset, open_frames  # noqa: E402
from jaxhand.score import foreground_for, image_evidence, rasterize, score_silhouette  # noqa: E402
from jaxhand.score._silhouette import capsules_from_model  # noqa: E402
from jaxhand.track import ImageFrontEnd, TrackConfig, Tracker  # noqa: E402

SEQUENCES = ("open_close", "index_over_middle", "thumb_opposition", "fast_spread", "wave_two_cameras")


def run(name: str, frames: int | None) -> list[dict]:
    seq = load_devset(REPO / "data" / "mujoco" / name)
    m, cams = seq.model, seq.truth.cameras
    config = TrackConfig().preset("robust")
    frontend = ImageFrontEnd(m, cams, config.image)
    tracker = Tracker(m, cams, frontend, config, dt_s=1 / seq.truth.fps)
    rec: dict = {}
    section = dataclasses.replace(config.image.score, foreground="auto")
    orig_choose, orig_cands, orig_extract = tracker_module.choose, tracker._hypotheses.candidates, frontend.extract

    def choose(merit, scores=None):
        rec["merit"], rec["scores"] = np.asarray(merit), None if scores is None else np.asarray(scores)
        return orig_choose(merit, scores)

    def candidates(*a, **k):
        c = orig_cands(*a, **k)
        rec["qs"] = np.asarray(c.solved.q)
        rec["term_merit"] = np.asarray(c.solved.term_merit)
        rec["rms_all"] = np.asarray(c.solved.rms_px)
        return c

    def extract(*a, **k):
        r = orig_extract(*a, **k)
        rec.setdefault("features", []).append([{f: np.asarray(getattr(x, f)) for f in
                                                 ("line_valid", "line_weight", "tip_valid", "tip_weight")}
                                                for x in r.features])
        return r

    tracker_module.choose, tracker._hypotheses.candidates, frontend.extract = choose, candidates, extract
    folders = [seq.folder / Path(f[0]).parent for f in seq.truth.image_files]
    images = open_frames(folders, fps=seq.truth.fps)
    state = tracker.init(seq.truth.q[0])
    n = len(seq.truth.q) if frames is None else min(frames, len(seq.truth.q))
    out = []
    it = zip(*images)
    t0 = time.time()
    for k in range(n):
        ims = [f.image for f in next(it)]
        rec.clear()
        state, rep = tracker.step(state, ims, k)
        ev = [image_evidence(im, foreground_for(section, im), section.silhouette) for im in ims]
        link_scores = []
        for cam, e in zip(cams, ev):
            sil = rasterize(capsules_from_model(m, rep.q_solved), cam,
                            rim_points=config.image.score.silhouette.rim_points)
            link_scores.append(score_silhouette(sil, e, config.image.score.silhouette).link_score)
        out.append({"sequence": name, "frame": k, "q_true": np.asarray(seq.truth.q[k]), "q_pred": rep.q_pred,
                    "q_solved": rep.q_solved, "q_filtered": rep.q_filtered, "rms_px": rep.rms_px,
                    "valid_share": rep.valid_share, "confidence": rep.confidence, "lost": rep.lost,
                    "image_score": rep.image_score, "hypothesis": rep.hypothesis, "link_scores": link_scores,
                    **{k2: v for k2, v in rec.items()}})
    print(name, n, f"{time.time() - t0:.0f}s", flush=True)
    return out


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--only", default=",".join(SEQUENCES))
    p.add_argument("--frames", type=int, default=None)
    p.add_argument("--out", default="/tmp/loss_signals.pkl")
    args = p.parse_args(argv)
    rows = []
    for name in args.only.split(","):
        rows += run(name, args.frames)
        with open(args.out, "wb") as fh:
            pickle.dump(rows, fh)


if __name__ == "__main__":
    main()
