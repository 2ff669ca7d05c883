"""Two boundary lines too far from parallel (``LineConfig.max_splay_deg``): the axial line comes
from the one nearer the predicted direction, offset by the radius, on synthetic boundary points
and on a MuJoCo-rendered dev-set frame (the thumb metacarpal beside the palm)."""

import dataclasses
from pathlib import Path

import cv2
import numpy as np
import pytest

from jaxhand import InputError
from jaxhand.features import features_from_pose
from jaxhand.image import LineConfig, extract_features
from jaxhand.image.internal import fit_rows
from jaxhand.io import load_devset
from jaxhand.track import TrackConfig

DEVSET = Path(__file__).resolve().parent.parent / "data" / "mujoco"


def _angle_deg(line, along) -> float:
    """Angle between a line (a, b, rho) and a direction."""
    return float(np.degrees(np.arcsin(min(1.0, abs(line[0] * along[0] + line[1] * along[1])))))


def _fit_one(splay_deg: float, bad_side: int, max_splay_deg: float):
    """One link along x from (0, 0) to (40, 0), radius 6: its good side at y = -/+6 exactly, the
    other side's points turned by ``splay_deg`` about the link's start."""
    t = np.linspace(0, 40, 8)
    sides = [np.stack([t, np.full_like(t, y)], -1) for y in (-6.0, 6.0)]
    c, s = np.cos(np.radians(splay_deg)), np.sin(np.radians(splay_deg))
    sides[bad_side] = sides[bad_side] @ np.array([[c, s], [-s, c]])
    edge_px = np.stack(sides, 1)[None]                       # (1 link, 8 samplers, 2 sides, 2)
    ok = np.ones((1, 8, 2), bool)
    return fit_rows(edge_px, ok, np.array([[20.0, 0.0]]), np.array([6.0]), np.array([[1.0, 0.0]]),
                    np.array([True]), np.array([1.0]), LineConfig(max_splay_deg=max_splay_deg))


@pytest.mark.parametrize("bad_side", [0, 1])
def test_a_splayed_boundary_is_left_out(bad_side):
    off = _fit_one(8.0, bad_side, 0.0)   # the thesis: the bisector, half the splay off
    assert not off["single"][0] and abs(_angle_deg(off["lines"][0], (1.0, 0.0)) - 4.0) < 0.05
    on = _fit_one(8.0, bad_side, 4.0)    # the parallel side alone, moved by the radius onto the axis
    assert on["single"][0] and on["valid"][0]
    assert _angle_deg(on["lines"][0], (1.0, 0.0)) < 1e-6
    assert abs(on["lines"][0][2]) < 1e-6                      # rho: the axis y = 0 itself
    assert on["weight"][0] == pytest.approx(LineConfig().single_edge_weight)


def test_boundaries_within_the_splay_keep_both():
    both = _fit_one(3.0, 1, 4.0)
    assert not both["single"][0] and abs(_angle_deg(both["lines"][0], (1.0, 0.0)) - 1.5) < 0.05


def test_thumb_metacarpal_beside_the_palm():
    # open_close frame 0 at the true pose: the metacarpal's inner boundary runs along the palm and
    # the index's base, 6-9 deg from its outer one; the bisector is 5.9 deg off the true axis
    seq = load_devset(DEVSET / "open_close")
    image = cv2.imread(str(seq.image_paths[0][0]), cv2.IMREAD_GRAYSCALE)
    q = seq.truth.q[0]
    exact = np.asarray(features_from_pose(seq.model, seq.cameras, q)[0].lines[0])
    along = (-exact[1], exact[0])
    errors = {}
    for splay in (0.0, 4.0):
        config = TrackConfig().preset("robust-limits").image
        config = config.replace(lines=dataclasses.replace(config.lines, max_splay_deg=splay))
        features, _ = extract_features(image, seq.model, seq.cameras, q, config)
        errors[splay] = _angle_deg(np.asarray(features[0].lines[0]), along)
    assert errors[0.0] > 5.0
    assert errors[4.0] < 3.0


@pytest.mark.parametrize("bad", [-1.0, 90.0, float("nan")])
def test_max_splay_must_lie_below_a_right_angle(bad):
    with pytest.raises(InputError, match=r"LineConfig.max_splay_deg: must lie in \[0, 90\)"):
        LineConfig(max_splay_deg=bad)
