"""The MuJoCo dev set's capsule hand for the score tests: forward kinematics of its body list.

``hand.json``'s bodies compose as ``R_body = R_parent R(quat) Rot(axis_1, q_1) Rot(axis_2, q_2) ...``
and ``p_body = p_parent + R_parent pos`` (the dev set's README); each capsule is ``fromto`` in its
body frame. This stands in for the MJCF importer (issue 13 item 2) until it exists.
"""

import json
from pathlib import Path

import cv2
import numpy as np

import jaxhand as jh
from jaxhand.score import Capsules

DATA = Path(__file__).parent / "data" / "score"


def load_truth() -> dict:
    return json.loads((DATA / "mujoco_truth.json").read_text())


def _quat(w, x, y, z) -> np.ndarray:
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def _axis_angle(axis, angle) -> np.ndarray:
    R, _ = cv2.Rodrigues(np.asarray(axis, float) * angle)
    return R


def capsules(bodies: list, joint_angles: dict) -> tuple[Capsules, tuple[str, ...]]:
    """World-frame capsules of every body at the given joint angles (rad); the palm's are occluders."""
    R, p = {"world": np.eye(3)}, {"world": np.zeros(3)}
    start, end, radius, occ, names = [], [], [], [], []
    for b in bodies:  # parents come first in hand.json
        Rp, pp = R[b["parent"]], p[b["parent"]]
        Rb = Rp @ _quat(*b["quat"])
        for j in b["joints"]:
            Rb = Rb @ _axis_angle(j["axis"], joint_angles[j["name"]])
        R[b["name"]], p[b["name"]] = Rb, pp + Rp @ np.asarray(b["pos"], float)
        for c in b["capsules"]:
            a, e = (np.asarray(v, float) for v in c["fromto"])
            start.append(p[b["name"]] + Rb @ a)
            end.append(p[b["name"]] + Rb @ e)
            radius.append(c["radius"])
            occ.append(b["name"] == "palm")
            names.append(c["name"])
    return Capsules.from_arrays(start, end, radius, occ), tuple(names)


def camera(truth: dict) -> jh.Perspective:
    c = truth["camera"]
    return jh.Perspective(K=np.asarray(c["K"]), R=np.asarray(c["R_world_to_cam"]), t=np.asarray(c["t_world_to_cam"]),
                          size=(320, 240))


def frame(name: str) -> np.ndarray:
    return cv2.imread(str(DATA / name), cv2.IMREAD_GRAYSCALE)
