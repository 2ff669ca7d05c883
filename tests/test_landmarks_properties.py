"""Property tests of the landmark loaders: any CSV or JSON loads as a finite sequence or raises
LandmarkFileError (one line naming the file), never another exception."""

import json

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from jaxhand.landmarks import LandmarkFileError, load_landmarks

_CELL = st.one_of(st.integers(-3, 30).map(str), st.floats(allow_nan=True, allow_infinity=True).map(repr),
                  st.sampled_from(["wrist", "index_tip", "thumb_cmc", "nope", "", "x"]), st.text(max_size=4))
_SETTINGS = settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


def _loads_or_says_why(path):
    try:
        seq = load_landmarks(path)
    except LandmarkFileError as err:
        assert str(path) in str(err) and "\n" not in str(err)
        return
    # What loads is a usable sequence: 21 points a frame, pixels finite or NaN (missing, with
    # confidence 0), confidences in [0, 1].
    assert seq.px.shape == (len(seq.frames), 21, 2) and seq.confidence.shape == (len(seq.frames), 21)
    assert not np.any(np.isinf(seq.px))
    assert np.all((seq.confidence >= 0) & (seq.confidence <= 1))
    assert np.all(seq.confidence[np.isnan(seq.px).any(-1)] == 0)


@_SETTINGS
@given(header=st.sampled_from(["frame,point,x,y", "frame,point,x,y,confidence", "frame,point,x,y,z",
                               "frame,point,x", "point,frame,x,y", "a,b"]),
       rows=st.lists(st.lists(_CELL, min_size=0, max_size=6), max_size=6))
def test_any_csv_loads_or_raises_landmark_file_error(tmp_path, header, rows):
    rows = [["0", "wrist", "10", "12"]] + rows   # one good row, so that many examples load
    path = tmp_path / "points.csv"
    path.write_text("\n".join([header] + [",".join(r) for r in rows]) + "\n")
    _loads_or_says_why(path)


_JSON = st.recursive(st.none() | st.booleans() | st.floats(allow_nan=False) | st.integers(-5, 50)
                     | st.sampled_from(["wrist", "index_tip", "Left", "Right"]),
                     lambda inner: st.lists(inner, max_size=4) | st.dictionaries(
                         st.sampled_from(["frames", "hands", "landmarks_px", "rows", "frame", "point", "x", "y",
                                          "image_size", "joint_names", "format"]), inner, max_size=4),
                     max_leaves=16)


@_SETTINGS
@given(data=_JSON)
def test_any_json_loads_or_raises_landmark_file_error(tmp_path, data):
    path = tmp_path / "points.json"
    path.write_text(json.dumps(data))
    _loads_or_says_why(path)


_ONE_HAND = [{"frame": 0, "hands": [{"landmarks_px": [[10.0, 20.0]] * 21}]}]


@pytest.mark.parametrize("data, message", [
    ({"frames": [{"frame": None}]}, r"frames\[0\]: frame: expected a whole number, got None"),
    ({"frames": [{"frame": "wrist"}]}, r"frames\[0\]: frame: expected a whole number, got 'wrist'"),
    ({"frames": [{"frame": 0, "hands": 1.0}]}, r"frame 0: 'hands' must be a list of objects"),
    ({"frames": [{"frame": 0, "hands": [{"landmarks_px": [[1, "x"]] * 21}]}]},
     r"frame 0: hand 0: expected 21 landmarks of \(x, y\[, z\]\), NaN where missing, got none"),
    ({"frames": _ONE_HAND, "summary": {"size": [640]}}, r"summary.size: expected \[width, height\], got \[640\]"),
    ({"frames": _ONE_HAND, "summary": {"fps": "30"}}, r"summary.fps: expected a frame rate > 0, got '30'"),
])
def test_malformed_mediapipe_entries_are_one_line_errors(tmp_path, data, message):
    """Entries the property test above once found raising TypeError or ValueError instead."""
    path = tmp_path / "hand.json"
    path.write_text(json.dumps(data))
    with pytest.raises(LandmarkFileError, match=message):
        load_landmarks(path)
