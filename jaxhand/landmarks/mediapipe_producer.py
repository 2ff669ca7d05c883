"""Run MediaPipe Hands on a video and write jaxhand's MediaPipe landmark JSON.

This file imports neither jax nor jaxhand, so it runs in MediaPipe's own environment (MediaPipe
0.10.21 pins numpy<2 and its own opencv and jax)::

    .venv-mediapipe/bin/python jaxhand/landmarks/mediapipe_producer.py VIDEO OUT.json

``jaxhand landmarks VIDEO -o OUT.json --python .venv-mediapipe/bin/python`` runs it for you.
The output has the layout of ``data/real/human_hand_video.mediapipe.json``: per frame, per hand,
21 landmarks ``[x, y, z]`` (normalised coordinates times the image width and height, so (0, 0)
is the image's top-left corner; z is MediaPipe's relative depth in the same scale), the world
landmarks in metres, the handedness label (for a mirrored image) and the unmirrored one.
"""

from __future__ import annotations

import json
import sys
import time

NAMES = ["wrist", "thumb_cmc", "thumb_mcp", "thumb_ip", "thumb_tip"] + [
    f"{f}_{j}" for f in ("index", "middle", "ring", "little") for j in ("mcp", "pip", "dip", "tip")]


def produce(video: str, out: str) -> int:
    import cv2
    import mediapipe as mp

    cap = cv2.VideoCapture(video)
    if not cap.isOpened():
        print(f"{video}: cannot open video", file=sys.stderr)
        return 2
    fps = cap.get(cv2.CAP_PROP_FPS) or 30.0
    settings = {"api": "mediapipe.solutions.hands.Hands", "static_image_mode": False, "max_num_hands": 2,
                "model_complexity": 1, "min_detection_confidence": 0.5, "min_tracking_confidence": 0.5}
    frames, size = [], None
    with mp.solutions.hands.Hands(**{k: v for k, v in settings.items() if k != "api"}) as hands:
        i = 0
        while True:
            ok, bgr = cap.read()
            if not ok:
                break
            h, w = bgr.shape[:2]
            size = [w, h]
            t = time.perf_counter()
            res = hands.process(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB))
            ms = 1000 * (time.perf_counter() - t)
            found = []
            for k, lm in enumerate(res.multi_hand_landmarks or []):
                label = res.multi_handedness[k].classification[0]
                world = res.multi_hand_world_landmarks[k].landmark if res.multi_hand_world_landmarks else []
                found.append({"handedness_mediapipe": label.label, "score": float(label.score),
                              "handedness_unmirrored": "Right" if label.label == "Left" else "Left",
                              "landmarks_px": [[p.x * w, p.y * h, p.z * w] for p in lm.landmark],
                              "world_m": [[p.x, p.y, p.z] for p in world]})
            frames.append({"frame": i, "ms": ms, "hands": found})
            i += 1
    data = {"source": video, "mediapipe_version": getattr(mp, "__version__", "?"), "settings": settings,
            "joint_names": NAMES, "summary": {"frames": len(frames), "fps": fps, "size": size,
                                              "frames_with_hand": sum(1 for f in frames if f["hands"])},
            "frames": frames}
    with open(out, "w") as f:
        json.dump(data, f)
    return 0


if __name__ == "__main__":  # pragma: no cover (needs MediaPipe)
    if len(sys.argv) != 3:
        print("usage: mediapipe_producer.py VIDEO OUT.json", file=sys.stderr)
        sys.exit(2)
    sys.exit(produce(sys.argv[1], sys.argv[2]))
