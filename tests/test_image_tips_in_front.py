"""Tips in front of other fingers (``TipConfig.over_farther``) on MuJoCo-rendered dev-set frames:
a thumb lying across the fingers keeps its tip, a fingertip seen end on does not gain one."""

import dataclasses
from pathlib import Path

import cv2
import numpy as np
import pytest

from jaxhand import InputError
from jaxhand.features import features_from_pose
from jaxhand.image import TipConfig, extract_features
from jaxhand.io import load_devset
from jaxhand.track import TrackConfig

DEVSET = Path(__file__).resolve().parent.parent / "data" / "mujoco"


def _tips(name: str, k: int, over_farther: float):
    """The front end's tips (valid, points) at the true pose of frame k, and the exact tips."""
    seq = load_devset(DEVSET / name)
    image = cv2.imread(str(seq.image_paths[0][k]), cv2.IMREAD_GRAYSCALE)
    config = TrackConfig().preset("robust-limits").image
    config = config.replace(tips=dataclasses.replace(config.tips, over_farther=over_farther))
    q = seq.truth.q[k]
    features, _ = extract_features(image, seq.model, seq.cameras, q, config)
    exact = features_from_pose(seq.model, seq.cameras, q)[0]
    return np.asarray(features[0].tip_valid), np.asarray(features[0].tips), np.asarray(exact.tips)


@pytest.mark.parametrize("k", [20, 45, 60])
def test_thumb_tip_in_front_of_the_fingers_counts(k):
    # thumb_opposition: the thumb lies across the middle and ring fingers, nearer the camera; past
    # its tip lie those fingers, so the thesis's rule drops the tip and the thumb can slide along
    # its line (benchmarks/README.md, "thumb_opposition's thumb")
    valid, _, _ = _tips("thumb_opposition", k, 0.0)
    assert not valid[0]
    valid, tips, exact = _tips("thumb_opposition", k, 0.5)
    assert valid[0]
    assert np.linalg.norm(tips[0] - exact[0]) < 2.5


def test_fingertips_seen_end_on_gain_no_tip():
    # open_close frame 20: the curled ring and little fingertips point at the camera in front of
    # their neighbours; without the foreshortening test they would count (and were 2-30 px off
    # while tracking)
    base, _, _ = _tips("open_close", 20, 0.0)
    any_length, _, _ = _tips("open_close", 20, 1e-9)
    half, _, _ = _tips("open_close", 20, 0.5)
    assert (any_length & ~base).any()
    np.testing.assert_array_equal(half, base)


@pytest.mark.parametrize("bad", [-0.5, float("nan"), float("inf"), True])
def test_over_farther_must_be_a_finite_number(bad):
    with pytest.raises(InputError, match=r"TipConfig.over_farther: need a finite number >= 0 \(0: off\)"):
        TipConfig(over_farther=bad)
