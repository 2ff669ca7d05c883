"""Tracking the MuJoCo development set (``data/mujoco/``, images jaxhand did not draw) per setting.

Each sequence is tracked from its true first pose at 30 frames/s with the image front end, and
once with exact features (``ExactFrontEnd``, 0.5 px noise) as the reference, under each named
setting (a change to ``TrackConfig``). Per run: mean and max absolute error (deg) over the moving
joints (those whose truth moves), of the reported estimate (``q_filtered``) and of the raw solve
(``q_solved``) and their mean tip error (px), frames flagged lost, frames/s of the tracker step,
the longest stretch of frames in which one moving joint stays more than 15 deg off, and the loss
flag's quality (the share of frames with a mean tip error over 8 px that are flagged lost or
below 0.5 confidence, and of those under 3 px), and the share of (frame, joint) entries the
features did not see (:func:`jaxhand.track.seen_summary`) with the error of the seen and the
unseen entries apart. With ``--start-deg`` and ``--seeds`` each run
starts off the true pose by seeded noise, and a second table gives the median and range over
seeds: two settings whose ranges overlap have not been told apart. Prints a table and writes
``benchmarks/results/devset.json`` (after each run, so an interrupted run keeps what it measured).

    .venv/bin/python benchmarks/devset.py                                   # default sequences, all settings
    .venv/bin/python benchmarks/devset.py --only open_close --settings default,temporal
    .venv/bin/python benchmarks/devset.py --frames 30 --no-json             # quick look
    .venv/bin/python benchmarks/devset.py --settings robust-limits --extra '{"support": {"judge_power": 2}}'
    .venv/bin/python benchmarks/devset.py --settings robust-limits --start-deg 2 --seeds 3   # the spread from chance
    .venv/bin/python benchmarks/devset.py --only open_close --settings robust-temporal --no-exact --per-frame \
        --overlays /tmp/oc   # each frame's error, confidence and winning start; frames over 8 px drawn
    .venv/bin/python benchmarks/devset.py --only open_close --degrade 0.6,5 --no-exact   # the cluttered copy's
                                                                   # blur and noise without its clutter
    .venv/bin/python benchmarks/devset.py --only open_close_noise_clutter --true-foreground --no-exact
                                                # with a perfect segmentation: what the foreground costs
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import REPO, RESULTS, add_runtime_option, apply_runtime, environment, format_table, write_json  # noqa: E402

from jaxhand.cli_track import given_masks  # noqa: E402
from jaxhand.io import load_devset, open_frames  # noqa: E402
from jaxhand.kinematics import project_pose  # noqa: E402
from jaxhand.render import degrade  # noqa: E402
from jaxhand.score import MaskForeground  # noqa: E402
from jaxhand.track import (  # noqa: E402
    PRESETS,
    ExactFrontEnd,
    Review,
    TrackConfig,
    Tracker,
    accuracy_summary,
    config_to_dict,
    frame_tip_error_px,
    image_front_end,
    loss_flag_quality,
    seen_summary,
)
from jaxhand.viz import draw_view  # noqa: E402

DEVSET = REPO / "data" / "mujoco"
DEGRADE_SEED = 20240925   # the noise seed of the dev set's cluttered copy (data/mujoco/README.md)
SEQUENCES = ("open_close", "index_over_middle", "thumb_opposition", "fast_spread", "wave_two_cameras")

#: Named settings: changes to the default TrackConfig (as in TrackConfig.merged).
SETTINGS = {
    "default": {},
    # TrackConfig.preset("robust")
    "robust": PRESETS["robust"],
    # ... with soft limits from 10 deg inside each joint limit, the weakest finger bent after a
    # frame of confidence under 0.2, loss.valid_share_good 0.5, tips in front of other fingers
    # and each finger's support judged by its tip's link (TrackConfig.preset("robust-limits"))
    "robust-limits": PRESETS["robust-limits"],
    # ... with an information-weighted temporal prior (15 deg, ratio 1) that also judges the starts
    # (prior.temporal_merit 0.1; 2026-12-04)
    "robust-limits+temporal": {**PRESETS["robust-limits"],
                               "prior": {**PRESETS["robust-limits"]["prior"], "temporal_sigma_deg": 15.0,
                                         "temporal_sigma_mm": 10.0, "information_ratio": 1.0,
                                         "temporal_merit": 0.1}},
    # ... and after a doubtful frame (confidence under 0.5) the joints the support saw no link of
    # restart from the last trusted pose (= the "robust-temporal" preset; 2026-12-04, third session)
    "robust-limits+temporal+restore": PRESETS["robust-temporal"],
    # ... as it was before 2026-12-03's second session (no finger starts, the share itself in the confidence)
    "robust-limits-nofinger": {**PRESETS["robust-limits"],
                               "hypotheses": {**PRESETS["robust-limits"]["hypotheses"], "finger_level": 0.0},
                               "loss": {**PRESETS["robust-limits"]["loss"], "valid_share_good": 1.0}},
    # ... with the foreground learned from a still camera's sequence and the tracked poses
    # (jaxhand.score.SequenceBackground since 2026-12-05; before, the sequence's median)
    "robust+sequence": {**PRESETS["robust"], "image": {**PRESETS["robust"]["image"],
                                                       "score": {"foreground": "sequence"}}},
    # robust-temporal with that foreground (`jaxhand track --preset robust-temporal --foreground sequence`)
    "robust-temporal+sequence": {**PRESETS["robust-temporal"],
                                 "image": {**PRESETS["robust-temporal"]["image"],
                                           "score": {**PRESETS["robust-temporal"]["image"]["score"],
                                                     "foreground": "sequence"}}},
    # a fixed-sigma temporal prior around the g-h-k prediction, the g-h-k update reported
    "temporal5+dip": {"prior": {"temporal_sigma_deg": 5.0, "temporal_sigma_mm": 5.0, "dip_pip_weight": 10.0}},
    # the solve with the prior reported (the filter only predicts)
    "temporal10+solve": {"prior": {"temporal_sigma_deg": 10.0, "temporal_sigma_mm": 10.0},
                         "filter": {"report_solve": True}},
    "temporal10+dip+solve": {"prior": {"temporal_sigma_deg": 10.0, "temporal_sigma_mm": 10.0, "dip_pip_weight": 10.0},
                             "filter": {"report_solve": True}},
    # information-weighted (issue 13 item 5)
    "info0.1+solve": {"prior": {"temporal_sigma_deg": 5.0, "temporal_sigma_mm": 5.0, "information_ratio": 0.1},
                      "filter": {"report_solve": True}},
    # multiple hypotheses (issue 13 item 4): 4 starts (prediction, 2 flips, last solve)
    "hyp4": {"hypotheses": {"flips": 2, "last_solve": True}},
    # 8 starts: 4 flips, the last solve, 2 carried runners-up
    "hyp8+carry": {"hypotheses": {"flips": 4, "last_solve": True, "carry": 2}},
    # 4 starts, and 8 more around the last good pose after a lost frame (item 7)
    "hyp4+recover": {"hypotheses": {"flips": 2, "last_solve": True, "recover": 8}},
    # the silhouette as residuals of the solve (ImageConfig.silhouette_term)
    "silhouette": {"image": {"silhouette_term": {"weight": 0.5}}},
    # ... and judging 6 starts (4 flips of 40 deg, the last solve), the solve reported, no hold
    "silhouette+hyp6": {"image": {"silhouette_term": {"weight": 0.5}}, "loss": {"hold": False},
                        "filter": {"report_solve": True},
                        "hypotheses": {"flips": 4, "flip_deg": 40.0, "last_solve": True}},
    # ... and a weak DIP-PIP coupling (sigma 14 deg)
    "silhouette+hyp6+dip": {"image": {"silhouette_term": {"weight": 0.5}}, "loss": {"hold": False},
                            "filter": {"report_solve": True}, "prior": {"dip_pip_weight": 4.0},
                            "hypotheses": {"flips": 4, "flip_deg": 40.0, "last_solve": True}},
    # ... and the visible link sides against the image's edges
    "silhouette+edges+hyp6+dip": {"image": {"silhouette_term": {"weight": 0.5, "edge_weight": 0.5}},
                                  "loss": {"hold": False}, "filter": {"report_solve": True},
                                  "prior": {"dip_pip_weight": 4.0},
                                  "hypotheses": {"flips": 4, "flip_deg": 40.0, "last_solve": True}},
    # ... with 4 starts reflected across their folds instead of the flips
    "silhouette+fold4": {"image": {"silhouette_term": {"weight": 0.5}}, "loss": {"hold": False},
                         "filter": {"report_solve": True}, "hypotheses": {"folds": 4, "last_solve": True}},
    # ... both
    "silhouette+hyp6+fold4": {"image": {"silhouette_term": {"weight": 0.5}}, "loss": {"hold": False},
                              "filter": {"report_solve": True},
                              "hypotheses": {"flips": 4, "flip_deg": 40.0, "folds": 4, "last_solve": True}},
}


def moving_joints(seq) -> np.ndarray:
    """The joint angles whose truth moves in the sequence."""
    return (np.ptp(np.asarray(seq.truth.q), axis=0) > 1e-6) & np.asarray(seq.model.is_angle)


def start_pose(seq, start_deg: float, seed: int) -> np.ndarray:
    """The true first pose, its moving joint angles moved by Gaussian noise of ``start_deg``
    (seeded; 0: the truth itself) and clipped into the limits."""
    q0 = np.asarray(seq.truth.q[0], float).copy()
    if start_deg > 0:
        moving = moving_joints(seq)
        q0[moving] += np.radians(start_deg) * np.random.default_rng(seed).standard_normal(int(moving.sum()))
    return np.clip(q0, np.asarray(seq.model.q_lower), np.asarray(seq.model.q_upper))


#: a frame whose mean tip error exceeds this (px) is drawn by ``--overlays`` (the loss flag's "bad" frames)
BAD_PX = 8.0


def frame_line(seq, k: int, q, rep, tip_px: float, moving: np.ndarray) -> str:
    """One frame of ``--per-frame``: mean error over the moving joints (deg), mean tip error
    (px), confidence, L when flagged lost, the start that won, and the two joints furthest off."""
    e = np.degrees(np.abs(np.asarray(q) - np.asarray(seq.truth.q[k])))
    e[~moving] = 0.0
    worst = " ".join(f"{seq.model.q_names[i]} {e[i]:.0f}" for i in np.argsort(-e)[:2])
    return (f"  {k:4d}  {e[moving].mean():6.2f} deg  {tip_px:6.1f} px  conf {rep.confidence:.2f} "
            f"{'L' if rep.lost else ' '} {rep.hypothesis:10s} {worst}")


def write_overlay(path: Path, seq, image, k: int, q) -> None:
    """The frame (first camera) beside the true pose (green) and the estimate (red) drawn over it."""
    m, cam = seq.model, seq.truth.cameras[0]
    bgr = image if image.ndim == 3 else cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    panels = [bgr]
    for pose, colour in ((seq.truth.q[k], (0, 255, 0)), (q, (0, 0, 255))):
        panels.append(draw_view(bgr.copy(), project_pose(m, cam, pose), colour, outline=True))
    path.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(path), cv2.resize(np.concatenate(panels, 1), None, fx=2, fy=2, interpolation=cv2.INTER_NEAREST))


#: The clean sequence each copy shows (the same hand over black): its frames over TRUE_FG_GREY are
#: the copy's true foreground (``--true-foreground``).
CLEAN_TWIN = {"open_close_noise_clutter": "open_close"}
TRUE_FG_GREY = 20


def true_foregrounds(seq, folders: list[Path]) -> list[MaskForeground]:
    """Per camera, the true foreground of the frames read from ``folders``: the clean twin's frames
    over :data:`TRUE_FG_GREY`, matched to them by content (:class:`jaxhand.score.MaskForeground`)."""
    clean = load_devset(seq.folder.parent / CLEAN_TWIN.get(seq.folder.name, seq.folder.name))
    clean_folders = [clean.folder / Path(f[0]).parent for f in clean.truth.image_files]
    return [MaskForeground((f.image for f in source), [c.image > TRUE_FG_GREY for c in clean_source])
            for source, clean_source in zip(open_frames(folders), open_frames(clean_folders))]


def degraded_copy(seq, blur_px: float, noise: float, out: Path) -> list[Path]:
    """Each camera's frames blurred by ``blur_px`` and with ``noise`` grey levels of Gaussian noise
    (:func:`jaxhand.render.degrade`; one generator over the frames in order, seeded as the dev
    set's cluttered copy), written under ``out``: the cluttered copy's recipe without its clutter."""
    rng = np.random.default_rng(DEGRADE_SEED)
    folders = []
    for c, files in enumerate(seq.truth.image_files):
        folder = out / f"cam{c}"
        folder.mkdir(parents=True)
        for f in files:
            image = cv2.imread(str(seq.folder / f), cv2.IMREAD_GRAYSCALE)
            cv2.imwrite(str(folder / Path(f).name), degrade(image, blur_px, noise, rng))
        folders.append(folder)
    return folders


def track(seq, config: TrackConfig, exact: bool, frames: int | None, noise_px: float = 0.5, q0=None,
          per_frame: bool = False, overlays: Path | None = None, folders: list[Path] | None = None,
          true_fg: bool = False, masks: Path | None = None):
    m, cams = seq.model, seq.truth.cameras
    n = len(seq.truth.q) if frames is None else min(frames, len(seq.truth.q))
    if exact:
        frontend, images = ExactFrontEnd(m, cams, seq.truth.q[:n], noise_px=noise_px, seed=0), None
    else:
        if folders is None:
            folders = [seq.folder / Path(f[0]).parent for f in seq.truth.image_files]
        images = open_frames(folders, fps=seq.truth.fps)
        given = None
        if true_fg:
            given = true_foregrounds(seq, folders)
        elif masks is not None:   # as jaxhand track --masks reads them (one camera)
            given = given_masks([masks], open_frames(folders))
        frontend = image_front_end(m, cams, config.image, images, n, foregrounds=given)
    tracker = Tracker(m, cams, frontend, config, dt_s=1 / seq.truth.fps)
    state = tracker.init(seq.truth.q[0] if q0 is None else q0)
    filt, raw, times, conf, lost_flags, labels, seen = [], [], [], [], [], [], []
    moving = moving_joints(seq)
    blank = [np.zeros(c.size[::-1], np.uint8) for c in cams] if exact else None
    it = zip(*images) if images is not None else iter(lambda: None, 0)
    review = Review(tracker)

    def record(ims, rep) -> None:
        k = rep.frame
        if per_frame or overlays is not None:
            tip = float(frame_tip_error_px(m, cams, np.asarray(rep.q_filtered)[None], seq.truth.q[k][None])[0])
            if per_frame:
                print(frame_line(seq, k, rep.q_filtered, rep, tip, moving), flush=True)
            if overlays is not None and not exact and tip > BAD_PX:
                write_overlay(overlays / f"{k:04d}.png", seq, ims[0], k, rep.q_filtered)
        labels.append(rep.hypothesis)
        seen.append(rep.seen)
        filt.append(rep.q_filtered)
        raw.append(rep.q_solved)
        lost_flags.append(rep.lost)
        conf.append(rep.confidence)

    for k in range(n):
        frame = next(it)
        ims = blank if exact else [f.image for f in frame]
        t0 = time.perf_counter()
        state, rep = tracker.step(state, ims, k)
        times.append(time.perf_counter() - t0)
        for held in review.push(state, ims, rep):
            record(*held)
    for held in review.flush():
        record(*held)
    lost = int(sum(lost_flags))
    qt = np.asarray(seq.truth.q[:n])
    out = {"frames": n, "lost": lost, "fps": 1.0 / float(np.median(times[1:])) if n > 1 else float("nan")}
    filt = np.asarray(filt)
    errors = {}
    for label, q in (("filtered", filt), ("raw", raw)):
        e = errors[label] = np.degrees(np.abs(np.asarray(q) - qt))[:, moving]
        out[f"{label}_mean_deg"], out[f"{label}_max_deg"] = float(e.mean()), float(e.max())
        out[f"{label}_tip_mean_px"] = accuracy_summary(m, cams, np.asarray(q), qt)["tip_error_px"]["mean"]
    out["longest_run_over_15deg"] = longest_run(errors["filtered"] > RUN_OFF_DEG)
    out["per_frame_joint_deg"] = np.round(errors["filtered"], 3).tolist()     # (frames, moving joints)
    out["per_frame_joint_raw_deg"] = np.round(errors["raw"], 3).tolist()
    out["per_frame_tip_px"] = frame_tip_error_px(m, cams, filt, qt).tolist()
    out["per_frame_confidence"], out["per_frame_lost"] = [float(c) for c in conf], [bool(x) for x in lost_flags]
    out["per_frame_mean_deg"] = errors["filtered"].mean(1).tolist()
    out["per_frame_start"] = labels
    out["review"] = review.summary()
    out["loss_flag"] = loss_flag_quality(out["per_frame_tip_px"], conf, lost_flags)
    out["seen"] = seen_summary(m, np.asarray(seen), filt, qt)
    return out


#: issue 13's run target: no joint more than RUN_OFF_DEG off for more than 5 frames in a row
#: wherever the exact-feature reference's raw solve holds it within RUN_HELD_DEG
RUN_OFF_DEG, RUN_HELD_DEG = 15.0, 5.0


def longest_run(flags) -> int:
    """The longest stretch of consecutive true values in any column of a (frames, joints) array."""
    best = 0
    for col in np.asarray(flags, bool).reshape(len(flags), -1).T:
        run = 0
        for f in col:
            run = run + 1 if f else 0
            best = max(best, run)
    return best


def run_rows(records) -> list[list[str]]:
    """Per image run with an exact-feature run of the same sequence, setting and seed: the longest
    run of a joint over RUN_OFF_DEG, and the same counting only the frames where the exact
    reference's raw solve holds that joint within RUN_HELD_DEG (issue 13's definition); the image
    record gains it as ``longest_run_over_15deg_where_exact_holds``."""
    exact = {(r["sequence"], r["setting"], r["seed"]): r for r in records if r["features"] == "exact"}
    rows = []
    for r in records:
        ref = exact.get((r["sequence"], r["setting"], r["seed"]))
        if r["features"] != "image" or ref is None:
            continue
        held = np.asarray(ref["per_frame_joint_raw_deg"]) <= RUN_HELD_DEG
        r["longest_run_over_15deg_where_exact_holds"] = longest_run((np.asarray(r["per_frame_joint_deg"]) > RUN_OFF_DEG)
                                                                    & held)
        rows.append([r["sequence"], r["setting"], str(r["seed"]), str(r["longest_run_over_15deg"]),
                     str(r["longest_run_over_15deg_where_exact_holds"])])
    return rows


def _blur_noise(text: str) -> tuple[float, float]:
    try:
        blur, noise = (float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected BLUR,NOISE (two numbers, e.g. 0.6,5), got {text!r}") from None
    if not (blur >= 0 and noise >= 0):
        raise argparse.ArgumentTypeError(f"blur and noise must be >= 0, got {text!r}")
    return blur, noise


def _share(x) -> str:
    return "-" if x is None else f"{100 * x:.0f}%"


def _deg(x) -> str:
    return "-" if x is None else f"{x:.2f}"


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--only", default=",".join(SEQUENCES), help="comma-separated sequences")
    p.add_argument("--root", type=Path, default=DEVSET,
                   help="the folder holding the sequences: the dev set (default) or its held-out twin, "
                        "data/mujoco_heldout (made after the settings were chosen; measure there, do not tune)")
    p.add_argument("--settings", default=",".join(SETTINGS), help="comma-separated settings: " + ", ".join(SETTINGS))
    p.add_argument("--frames", type=int, default=None, help="first N frames only")
    p.add_argument("--no-exact", action="store_true", help="skip the exact-feature reference")
    p.add_argument("--no-json", action="store_true")
    p.add_argument("--json", default="devset.json", help="file name under benchmarks/results/")
    p.add_argument("--extra", type=json.loads, default={},
                   help="a JSON mapping merged over every setting, for a trial change "
                        "(e.g. '{\"support\": {\"judge_power\": 2}}')")
    p.add_argument("--start-deg", type=float, default=0.0,
                   help="start each run this far (Gaussian sigma, deg) off the true first pose in its moving joints")
    p.add_argument("--seeds", type=int, default=1,
                   help="runs per sequence and setting, each from its own seeded start (needs --start-deg); the "
                        "spread of their errors says how much of a difference between settings is chance")
    p.add_argument("--first-seed", type=int, default=0,
                   help="the first seed of --seeds (to split the seeds of one comparison over processes)")
    p.add_argument("--reference", default=None, choices=list(SETTINGS),
                   help="run the exact-feature reference with this setting instead of each setting's own (issue "
                        "13 measures against the default tracker's: `--reference default`); the image-based parts "
                        "of a robust setting (silhouette, support) see blank images there")
    p.add_argument("--reference-noise-px", type=float, default=0.5,
                   help="Gaussian noise (px) on the exact reference's features (issue 13's table: 0)")
    p.add_argument("--per-frame", action="store_true",
                   help="print every frame: error, tip px, confidence, lost, the winning start, the worst joints")
    p.add_argument("--overlays", type=Path, default=None,
                   help=f"a folder: for each image run, the frames over {BAD_PX:g} px drawn (truth green, estimate "
                        "red) under <folder>/<sequence>_<setting>_<seed>/")
    p.add_argument("--degrade", type=_blur_noise, default=None, metavar="BLUR,NOISE",
                   help="track copies of the frames blurred (Gaussian sigma, px) and with Gaussian noise (grey "
                        "levels) as the cluttered copy was, e.g. 0.6,5 on open_close: what noise alone costs; "
                        "the sequence is recorded as <name>+blur<B>+noise<N>")
    p.add_argument("--true-foreground", action="store_true",
                   help="the image runs read the true foreground (the clean sequence's frames over "
                        f"{TRUE_FG_GREY}; for open_close_noise_clutter, open_close's) instead of their own "
                        "foreground model: what a perfect segmentation would give; recorded as <name>+true-fg")
    p.add_argument("--masks", type=Path, default=None, metavar="DIR",
                   help="the image runs read these masks (one image per frame, sorted by name; one camera) instead "
                        "of their own foreground model, as jaxhand track --masks does; recorded as <name>+masks")
    add_runtime_option(p)
    args = p.parse_args(argv)
    if args.seeds < 1 or (args.seeds > 1 and not args.start_deg > 0):
        p.error(f"--seeds {args.seeds}: need 1, or more than 1 with --start-deg > 0 (else the runs are the same)")
    unknown = [s for s in args.settings.split(",") if s not in SETTINGS]
    if unknown:
        p.error(f"--settings: unknown {', '.join(unknown)}; choose from {', '.join(SETTINGS)} "
                "(the preset robust-temporal is robust-limits+temporal+restore)")
    apply_runtime(args)
    rows, records = [], []
    scratch = None if args.degrade is None else tempfile.TemporaryDirectory(prefix="devset_degraded_")
    for name in args.only.split(","):
        seq = load_devset(args.root / name)
        if args.root.resolve() != DEVSET.resolve():
            name = f"{args.root.name}/{name}"
        folders = None
        if scratch is not None:
            folders = degraded_copy(seq, *args.degrade, Path(scratch.name) / name)
            name = f"{name}+blur{args.degrade[0]:g}+noise{args.degrade[1]:g}"
        if args.true_foreground:
            name = f"{name}+true-fg"
        if args.masks is not None:
            name = f"{name}+masks"
        for setting in args.settings.split(","):
            config = TrackConfig().merged(SETTINGS[setting]).merged(args.extra)
            reference = config if args.reference is None else TrackConfig().merged(SETTINGS[args.reference])
            seeds = range(args.first_seed, args.first_seed + args.seeds)
            for exact, seed in itertools.product((False,) if args.no_exact else (False, True), seeds):
                if args.per_frame:
                    print(f"{name} {setting} {'exact' if exact else 'image'} seed {seed}:", flush=True)
                where = None if args.overlays is None else args.overlays / f"{name}_{setting}_{seed}"
                used = reference if exact else config
                r = track(seq, used, exact, args.frames, noise_px=args.reference_noise_px,
                          q0=start_pose(seq, args.start_deg, seed), per_frame=args.per_frame, overlays=where,
                          folders=folders, true_fg=args.true_foreground, masks=args.masks)
                rec = {"sequence": name, "setting": setting, "features": "exact" if exact else "image",
                       "start_deg": args.start_deg, "seed": seed, **r, "config": config_to_dict(used)}
                records.append(rec)
                if not args.no_json:   # as it goes: an interrupted run keeps what it measured
                    write_json({"environment": environment(), "runs": records}, RESULTS / args.json)
                rows.append([name, setting, rec["features"], str(seed), f"{r['filtered_mean_deg']:.2f}",
                             f"{r['filtered_max_deg']:.1f}", f"{r['raw_mean_deg']:.2f}", f"{r['raw_max_deg']:.1f}",
                             str(r["lost"]), f"{r['fps']:.1f}", str(r["longest_run_over_15deg"]),
                             _share(r["loss_flag"]["flagged_bad"]),
                             _share(r["loss_flag"]["flagged_good"]), _share(r["seen"]["unseen_entries_share"]),
                             _deg(r["seen"]["error_deg_seen"]) + " / " + _deg(r["seen"]["error_deg_unseen"])])
                print(" | ".join(rows[-1]), flush=True)
    print(format_table(rows, ["sequence", "setting", "features", "seed", "mean", "max", "raw mean", "raw max", "lost",
                              "fps", "frames >15° in a row", "flagged >8px", "flagged <3px", "unseen",
                              "error seen / unseen"]))
    print(format_table(pooled_flag_rows(records), ["setting", "features", "seed", "sequences",
                                                   "frames >8px flagged", "frames <3px flagged"]))
    runs = run_rows(records)
    if runs:
        print(format_table(runs, ["sequence", "setting", "seed", "frames >15° in a row",
                                  "... where the exact reference is within 5°"]))
        if not args.no_json:
            write_json({"environment": environment(), "runs": records}, RESULTS / args.json)
    if args.seeds > 1:
        print(format_table(spread_rows(records), ["sequence", "setting", "features", "runs", "median of means",
                                                  "min", "max"]))


def pooled_flag_rows(records) -> list[list[str]]:
    """Per setting, features and seed: the loss flag's hit rates pooled over the sequences run
    (issue 13's target: >= 90 % of the frames over 8 px flagged, <= 5 % of those under 3 px)."""
    groups: dict[tuple, list[dict]] = {}
    for r in records:
        groups.setdefault((r["setting"], r["features"], r["seed"]), []).append(r)
    rows = []
    for (setting, features, seed), runs in groups.items():
        q = loss_flag_quality(*(np.concatenate([r[key] for r in runs]) for key in
                                ("per_frame_tip_px", "per_frame_confidence", "per_frame_lost")))
        counts = [f"{round((q[share] or 0.0) * q[frames])} / {q[frames]}"
                  for share, frames in (("flagged_bad", "frames_bad"), ("flagged_good", "frames_good"))]
        rows.append([setting, features, str(seed), str(len(runs)), *counts])
    return rows


def spread_rows(records) -> list[list[str]]:
    """Per sequence, setting and features: the median, min and max over seeds of the mean error."""
    groups: dict[tuple, list[float]] = {}
    for r in records:
        groups.setdefault((r["sequence"], r["setting"], r["features"]), []).append(r["filtered_mean_deg"])
    return [[*key, str(len(v)), f"{np.median(v):.2f}", f"{min(v):.2f}", f"{max(v):.2f}"] for key, v in groups.items()]


if __name__ == "__main__":
    main()
