#!/usr/bin/env python3
"""Render a held-out twin of the MuJoCo development set: the same hand, the same kinds of motion,
other views, timings, amplitudes, clutter and noise.

Every sequence of ``../mujoco/`` has a twin of the same name here. The tracker's settings were
chosen on the development set; these sequences were made after them and are measured, not tuned
on (README.md). The renderer, formats and checks are ``../mujoco/make_mujoco_set.py``'s: this
script changes its cameras, trajectories and seeds, then runs it.

    MUJOCO_GL=egl python make_heldout.py            # writes next to this script (about 70 s on 2 cores)
    MUJOCO_GL=egl python make_heldout.py --out DIR

Dependencies: mujoco, numpy, pillow (as make_mujoco_set.py).
"""
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "mujoco"))
import make_mujoco_set as mk  # noqa: E402

X, Y = [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]
PALM, BACK = np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.0, -1.0])
deg = math.radians

# Views: each sequence's camera turned to another roll, tilt and image rotation of the same kind
# (palm or back towards the camera, fingertips towards or away).
VIEWS = {
    # palm towards the camera, rolled 25 deg towards the little finger, tilted 20 deg (fingertips away)
    "open_close": dict(target=(2.0, 90.0, 12.0), direction=mk.rot(X, deg(20)) @ mk.rot(Y, -deg(25)) @ PALM,
                       distance=410.0, up=(0.12, 1.0, 0.0)),
    # back of the hand, rolled 25 deg towards the little finger, tilted 32 deg (fingertips towards the camera)
    "index_over_middle": dict(target=(10.0, 98.0, 6.0), direction=mk.rot(X, deg(32)) @ mk.rot(Y, deg(25)) @ BACK,
                              distance=400.0, up=(-0.1, 1.0, 0.0)),
    # palm towards the camera, rolled 15 deg towards the thumb, tilted 25 deg (fingertips away)
    "thumb_opposition": dict(target=(8.0, 92.0, 20.0), direction=mk.rot(X, deg(25)) @ mk.rot(Y, deg(15)) @ PALM,
                             distance=410.0, up=(-0.1, 1.0, 0.0)),
    # two cameras 60 deg apart: front (tilted 20 deg, fingertips towards it) and the little-finger side
    "wave_front": dict(target=(0.0, 98.0, 5.0), direction=mk.rot(X, -deg(20)) @ mk.rot(Y, deg(8)) @ PALM,
                       distance=430.0, up=(0.05, 1.0, 0.0)),
    "wave_side": dict(target=(0.0, 98.0, 5.0), direction=mk.rot(X, -deg(12)) @ mk.rot(Y, -deg(60)) @ PALM,
                      distance=430.0, up=(0.0, 1.0, 0.0)),
    # palm towards the camera, rolled 18 deg towards the thumb, tilted 10 deg (fingertips towards it)
    "fast_spread": dict(target=(0.0, 100.0, 5.0), direction=mk.rot(X, -deg(10)) @ mk.rot(Y, deg(18)) @ PALM,
                        distance=430.0, up=(-0.15, 1.0, 0.0)),
}


VIEW_TEXT = {
    "open_close": "palm towards the camera, rolled 25 deg towards the little finger, tilted 20 deg (fingertips away)",
    "index_over_middle": ("back of the hand, rolled 25 deg towards the little finger, tilted 32 deg (fingertips "
                          "towards the camera)"),
    "thumb_opposition": "palm towards the camera, rolled 15 deg towards the thumb, tilted 25 deg (fingertips away)",
    "wave_two_cameras": ("cam0 in front of the palm, tilted 20 deg (fingertips towards it); cam1 on the little-finger "
                         "side, 60 deg from cam0"),
    "fast_spread": "palm towards the camera, rolled 18 deg towards the thumb, tilted 10 deg (fingertips towards it)",
}


def scaled(keys: dict, share: float) -> dict:
    """The joint angles of ``keys`` scaled by ``share`` (a motion of another amplitude)."""
    return {n: share * v for n, v in keys.items()}


def seq_open_close():
    """The loose fist a little tighter, closing faster (frames 4-24) and opening slower (54-84)."""
    fist = scaled(mk.LOOSE_FIST, 1.08)
    keys = [(0, {}), (4, {}), (24, dict(fist, **mk.THUMB_PALMAR)), (34, mk.THUMB_ACROSS), (46, {}),
            (54, mk.THUMB_PALMAR), (84, mk.rest_pose()), (89, {})]
    return mk.trajectory(90, keys)


def seq_index_over_middle():
    """The index's slow cycle in 12 frames and the fast one in 6, flexed 10 % less."""
    ext = dict(mk.CURLED, **mk.THUMB_TUCKED,
               **mk.fingers(index=(0.0, 0.04, 0.08, 0.04), middle=(0.0, 0.04, 0.08, 0.04)))
    flexed = mk.fingers(index=(0.05, 0.86, 1.00, 0.56))
    together = mk.fingers(index=(0.34, None, None, None), middle=(-0.15, None, None, None))
    apart = mk.fingers(index=(0.05, None, None, None), middle=(0.0, None, None, None))
    extend = mk.fingers(index=(0.0, 0.04, 0.08, 0.04))
    keys = [(0, ext), (8, {}), (20, flexed), (29, together), (35, {}), (42, apart), (50, extend), (54, {}),
            (60, dict(flexed, index_mcp_flex=1.0, index_pip=1.15)), (64, together), (66, {}), (69, apart),
            (74, extend), (89, {})]
    return mk.trajectory(90, keys)


def seq_thumb_opposition():
    """The four touches in the other order (little first), each reached in 15 frames."""
    release = mk.thumb(0.35, 0.25, 0.0, 0.25, 0.15)
    keys = [(0, {}), (5, {})]
    order = ("little", "ring", "middle", "index")
    for i, (f, t) in enumerate(zip(order, (20, 46, 72, 98))):
        keys += [(t, {n: v for n, v in mk.opposition_pose(f).items() if n.startswith(("thumb", f))}), (t + 5, {})]
        back = {n: v for n, v in mk.rest_pose().items() if n.startswith(f)}
        keys.append((t + 13, dict(release, **back)) if i < 3 else (119, mk.rest_pose()))
    return mk.trajectory(120, keys)


def seq_wave():
    """The travelling wave from the index to the little finger, 8 frames down and 12 up, 5 frames apart."""
    rest = mk.rest_pose()
    flex = dict(mcp_flex=0.85, pip=1.05, dip=0.58)
    tracks = {}
    for k, f in enumerate(["index", "middle", "ring", "little"]):
        for j, amp in flex.items():
            keys = [(0, rest[f"{f}_{j}"])]
            for start in (5, 48):
                s = start + 5 * k
                keys += [(s, rest[f"{f}_{j}"]), (s + 8, amp), (s + 20, rest[f"{f}_{j}"])]
            tracks[f"{f}_{j}"] = keys
    spread = dict(index=-0.24, middle=-0.04, ring=0.14, little=0.32)
    fanned = dict(index=-0.30, middle=-0.10, ring=0.05, little=0.12)
    for f in mk.FOUR:
        tracks[f"{f}_mcp_abd"] = [(0, 0.0), (10, 0.0), (28, spread[f]), (44, 0.0), (64, fanned[f]), (82, 0.0)]
    return mk.track_trajectory(90, tracks)


def seq_fast_spread():
    """Spread and close twice, 6 frames per movement, closing 10 % less far."""
    spread = mk.fingers(index=(-0.36, -0.15, 0.0, 0.0), middle=(-0.06, -0.15, 0.0, 0.0),
                        ring=(0.24, -0.15, 0.0, 0.0), little=(0.42, -0.12, 0.0, 0.0))
    spread.update(mk.thumb(-0.40, -0.30, 0.0, 0.0, -0.10))
    close = mk.fingers(index=(0.0, 1.0, 1.17, 0.63), middle=(0.0, 1.04, 1.22, 0.63),
                       ring=(0.0, 1.06, 1.22, 0.63), little=(0.02, 1.08, 1.17, 0.61))
    close.update(mk.thumb(0.13, -0.11, -0.06, 0.52, 0.57))
    keys = [(0, {}), (5, {}), (11, spread), (13, {}), (19, close), (21, {}), (27, spread), (29, {}), (35, close),
            (44, {})]
    return mk.trajectory(45, keys)


TRAJECTORIES = {"open_close": seq_open_close, "index_over_middle": seq_index_over_middle,
                "thumb_opposition": seq_thumb_opposition, "wave_two_cameras": seq_wave,
                "fast_spread": seq_fast_spread}


def setup() -> None:
    """Point make_mujoco_set at the held-out views, trajectories and seeds."""
    for name, view in VIEWS.items():
        pos, R = mk.look_at(view["target"], view["direction"], view["distance"], view["up"])
        mk.CAMS[name] = dict(pos=pos, R_cv=R, spec=view)
    for name, traj in TRAJECTORIES.items():
        spec = mk.SEQUENCES[name]
        mk.SEQUENCES[name] = dict(spec, traj=traj, description=f"Held-out twin of ../mujoco/{name}: {traj.__doc__} "
                                  f"View: {VIEW_TEXT[name]}.")
    mk.CLUTTER_SEED = 20261207
    mk.NOISE_SEED = 20261208


if __name__ == "__main__":
    setup()
    if "--out" not in sys.argv:
        sys.argv += ["--out", str(Path(__file__).resolve().parent)]
    mk.main()
