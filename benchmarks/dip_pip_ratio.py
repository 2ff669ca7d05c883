"""The DIP-PIP coupling's ratio measured on a real hand (``prior.dip_pip_ratio``).

The coupling prior holds each finger's DIP flexion near ``r`` times its PIP flexion. The common
anatomical approximation is r = 2/3. Here r is measured on the real video (data/real/): from
MediaPipe's world landmarks (metres, one right hand) each finger's PIP and DIP flexion is the
angle between its successive bones, and r is the least-squares slope through the origin of DIP
on PIP over the frames where the PIP is flexed past ``--min-pip`` (straighter fingers say little
about the slope and MediaPipe's noise dominates there). The per-frame median ratio is given beside
it. The MuJoCo dev set's truth (data/mujoco/) is measured the same way, from its joint angles, for
comparison. Writes ``benchmarks/results/dip_pip_ratio.json``.

    .venv/bin/python benchmarks/dip_pip_ratio.py [--min-pip 40]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import REPO, RESULTS, environment, format_table, write_json  # noqa: E402

FINGERS = ("index", "middle", "ring", "little")
VIDEO_LANDMARKS = REPO / "data" / "real" / "human_hand_video.mediapipe.json"
DEVSET = REPO / "data" / "mujoco"


def bend_deg(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """The flexion at joint b (deg): the angle between the bones a->b and b->c, per row."""
    u, v = b - a, c - b
    cos = np.sum(u * v, -1) / (np.linalg.norm(u, axis=-1) * np.linalg.norm(v, axis=-1))
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def ratio_fit(pip: np.ndarray, dip: np.ndarray, min_pip: float) -> dict:
    """The slope of DIP on PIP through the origin and the median per-frame ratio, over the frames
    whose PIP flexion exceeds ``min_pip`` (deg)."""
    sel = np.abs(pip) > min_pip
    if not sel.any():
        return {"frames": 0, "slope": None, "median": None}
    return {"frames": int(sel.sum()), "slope": float(np.sum(pip[sel] * dip[sel]) / np.sum(pip[sel] ** 2)),
            "median": float(np.median(dip[sel] / pip[sel]))}


def video_angles(path: Path) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per finger, the PIP and DIP flexion (deg) of every frame's first hand in MediaPipe's JSON."""
    data = json.loads(path.read_text())
    names = data["joint_names"]
    world = np.array([fr["hands"][0]["world_m"] for fr in data["frames"] if fr.get("hands")])
    out = {}
    for f in FINGERS:
        mcp, pip, dip, tip = (world[:, names.index(f"{f}_{p}")] for p in ("mcp", "pip", "dip", "tip"))
        out[f] = bend_deg(mcp, pip, dip), bend_deg(pip, dip, tip)
    return out


def devset_angles(folder: Path) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per finger, the true PIP and DIP angles (deg) of a dev-set sequence (its ``truth.json``)."""
    from jaxhand.io import load_devset

    seq = load_devset(folder)
    q, names = np.degrees(np.asarray(seq.truth.q)), seq.model.q_names
    return {f: (q[:, names.index(f"{f}_pip")], q[:, names.index(f"{f}_dip")]) for f in FINGERS}


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--min-pip", type=float, default=40.0, help="only frames whose PIP flexes past this (deg)")
    args = p.parse_args(argv)
    import jaxhand

    jaxhand.enable_x64()
    sources = {"real video (MediaPipe world landmarks)": video_angles(VIDEO_LANDMARKS)}
    for folder in sorted(d for d in DEVSET.iterdir() if (d / "truth.json").exists()):
        sources[f"dev set {folder.name} (truth)"] = devset_angles(folder)
    rows, record = [], {}
    for source, angles in sources.items():
        record[source] = {f: ratio_fit(*angles[f], args.min_pip) for f in FINGERS}
        rows.append([source] + [f"{r['slope']:.2f} / {r['median']:.2f} ({r['frames']})" if r["frames"] else "-"
                                for r in record[source].values()])
    print(f"DIP over PIP flexion, frames with PIP > {args.min_pip:g} deg: slope / median ratio (frames)")
    print(format_table(rows, ["source", *FINGERS]))
    write_json({"environment": environment(), "min_pip_deg": args.min_pip, "ratios": record},
               RESULTS / "dip_pip_ratio.json")


if __name__ == "__main__":
    main()
