"""Property tests of the camera loader: any JSON either loads as a valid camera or raises CameraError."""

import json

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import jaxhand as jh

_JSON = st.recursive(st.none() | st.booleans() | st.floats(allow_nan=True, allow_infinity=True) | st.integers()
                     | st.text(max_size=5), lambda inner: st.lists(inner, max_size=4), max_leaves=12)
_VALID = {"kind": "perspective", "K": [[400.0, 0.0, 159.5], [0.0, 400.0, 119.5], [0.0, 0.0, 1.0]],
          "R": np.eye(3).tolist(), "t": [0.0, 0.0, 400.0], "size": [320, 240]}


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(field=st.sampled_from(["kind", "K", "R", "t", "size", "scale", "center", "extra"]), value=_JSON)
def test_any_field_value_loads_or_raises_camera_error(tmp_path, field, value):
    d = dict(_VALID, **{field: value})
    path = tmp_path / "cam.json"
    path.write_text(json.dumps(d))
    try:
        (cam,) = jh.load_camera(path)
    except jh.CameraError as err:
        assert str(path) in str(err) and "\n" not in str(err)
        return
    # Whatever loaded is a usable camera: finite pixels for a point 100 mm in front of it (its depth
    # exact up to the rounding of subtracting a translation as large as 3.6e16 mm and adding it back).
    p_world = (np.array([0.0, 0.0, 100.0]) - np.asarray(cam.t)) @ np.asarray(cam.R)
    px, depth = cam.project(p_world)
    rounding = 1e-15 * float(np.abs(np.asarray(cam.t)).max())
    assert np.all(np.isfinite(np.asarray(px))) and float(depth) == pytest.approx(100.0, abs=1e-9 + rounding)


def test_json_booleans_are_not_numbers(tmp_path):
    path = tmp_path / "cam.json"
    path.write_text(json.dumps(dict(_VALID, t=[False, False, True])))
    with pytest.raises(jh.CameraError, match="field 't' must be finite numbers"):
        jh.load_camera(path)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(text=st.text(max_size=40))
def test_any_text_loads_or_raises_camera_error(tmp_path, text):
    path = tmp_path / "cam.json"
    path.write_text(text)
    try:
        jh.load_camera(path)
    except jh.CameraError:
        return
