"""Check images of the synthetic presets: a few frames side by side with the ground truth drawn over.

Run ``python -m jaxhand.render.check_images [--out docs/images]``; it writes
``synth_<preset>.png`` per preset: shaded frames (one row per camera) with the projected link axes,
joint centres (rings) and tips (dots) of the ground-truth state drawn in red by
:func:`jaxhand.viz.draw_view`, so a glance shows whether the projections land on the rendered fingers.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np

from ..kinematics import project_pose
from ..viz import draw_view
from ._config import RenderConfig
from ._frame import render_frame
from ._presets import make_preset, preset_names

__all__ = ["check_image", "main"]


def check_image(name: str, *, n_shown: int = 6, size=(240, 180), config: RenderConfig | None = None) -> np.ndarray:
    """BGR mosaic of ``n_shown`` evenly spaced frames of a preset (one row per camera) with overlays."""
    seq = make_preset(name, size=size)
    idx = np.linspace(0, seq.n_frames - 1, n_shown).round().astype(int)
    rows = []
    for c, cam in enumerate(seq.cameras):
        tiles = []
        for i in idx:
            r = render_frame(seq.model, cam, seq.q[i], config, frame_index=int(i))
            tile = cv2.cvtColor(r.image, cv2.COLOR_GRAY2BGR)
            draw_view(tile, project_pose(seq.model, cam, seq.q[i]), (40, 40, 255))
            label = f"{name} f{i}" + (f" cam{c}" if len(seq.cameras) > 1 else "")
            cv2.putText(tile, label, (4, 14), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (80, 255, 80), 1, cv2.LINE_AA)
            tiles.append(tile)
        rows.append(np.hstack(tiles))
    return np.vstack(rows)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="docs/images", help="output folder (default docs/images)")
    parser.add_argument("--frames", type=int, default=6, help="frames shown per preset")
    args = parser.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for name in preset_names():
        path = out / f"synth_{name}.png"
        cv2.imwrite(str(path), check_image(name, n_shown=args.frames))
        print(path)
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
