"""Copy the few MuJoCo dev-set files the score tests use into tests/data/score/.

Run from the repository root: ``python tests/data/score/make_score_data.py [DEV_SET_DIR]``
(default ``../shared/data/mujoco``). It copies four frames of ``open_close`` (rest, fist closing,
fist, opening) and one of ``open_close_noise_clutter``, and writes ``mujoco_truth.json`` with the
camera, the hand's body list (from ``models/hand.json``) and those frames' joint angles and
points, so a fresh clone runs the tests without the shared folder.
"""

import json
import shutil
import sys
from pathlib import Path

FRAMES = (0, 24, 44, 70)
CLUTTER_FRAMES = (24,)


def main(src: Path, out: Path) -> None:
    hand = json.loads((src / "models" / "hand.json").read_text())
    data = {"source": "MuJoCo dev set (make_mujoco_set.py), sequences open_close and open_close_noise_clutter",
            "bodies": hand["bodies"], "frames": {}}
    for seq, frames in (("open_close", FRAMES), ("open_close_noise_clutter", CLUTTER_FRAMES)):
        truth = json.loads((src / seq / "truth.json").read_text())
        data["camera"] = truth["camera"]
        for i in frames:
            f = truth["frames"][i]
            name = f"{seq}_{i:03d}.png"
            shutil.copyfile(src / seq / f["file"], out / name)
            data["frames"][name] = {"joint_angles": f["joint_angles"], "points_px": f["points_px"],
                                    "points_world": f["points_world"]}
    (out / "mujoco_truth.json").write_text(json.dumps(data, indent=1) + "\n")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("../shared/data/mujoco"), Path(__file__).parent)
