"""Bad input on the command line: one line naming the input and what to do, exit status 2."""

import numpy as np
import pytest

import jaxhand as jh
from jaxhand.cli import _join_negative_values, main
from jaxhand.io import parse_pose


def _one_line_error(capsys, command: str) -> str:
    err = capsys.readouterr().err
    assert err.startswith(f"jaxhand {command}: error: ") and err.count("\n") == 1, err
    return err


def test_export_to_an_unwritable_path(tmp_path, capsys):
    (tmp_path / "file").write_text("x")
    assert main(["models", "hand21", "--export", str(tmp_path / "file" / "hand.toml")]) == 2
    assert "--export" in _one_line_error(capsys, "models")


def test_sketch_negative_pose_count_and_out_on_a_file(tmp_path, capsys):
    assert main(["sketch", "--poses", "-5", "--out", str(tmp_path)]) == 2
    assert "--poses: expected a count >= 0, got -5" in _one_line_error(capsys, "sketch")
    (tmp_path / "f").write_text("x")
    assert main(["sketch", "--poses", "0", "--out", str(tmp_path / "f")]) == 2
    assert f"--out {tmp_path / 'f'}: exists and is a file" in _one_line_error(capsys, "sketch")
    assert main(["sketch", "--poses", "0", "--out", str(tmp_path / "f" / "sub")]) == 2
    assert "lies under a file" in _one_line_error(capsys, "sketch")


def test_negative_values_after_a_flag_are_joined():
    assert _join_negative_values(["track", "x", "--init", "-35,-40,-30,10,-5,0", "--out", "o"]) == \
        ["track", "x", "--init=-35,-40,-30,10,-5,0", "--out", "o"]
    assert _join_negative_values(["--init", "-1.5e-3"]) == ["--init=-1.5e-3"]
    assert _join_negative_values(["--init=-35", "--no-video"]) == ["--init=-35", "--no-video"]


def test_pose_in_radians_is_taken_but_warned_about():
    model = jh.builtin_model("two_fingers")
    with pytest.warns(jh.JaxhandWarning, match="look like radians"):
        q = parse_pose(model, ",".join(["-0.6"] * model.n_q))
    assert np.allclose(q, np.radians(-0.6))
    q = parse_pose(model, ",".join(["-35"] * model.n_q))   # whole degrees: no warning (warnings are errors here)
    assert np.allclose(q, np.radians(-35.0))
    with pytest.raises(jh.InputError, match=r"--init: expected 6 values for 'two_fingers' \(.*\), got 2"):
        parse_pose(model, "1,2")


def test_unknown_model_suffix_names_the_readable_ones(tmp_path, capsys):
    (tmp_path / "hand.yaml").write_text("name: x")
    assert main(["models", str(tmp_path / "hand.yaml")]) == 2
    err = _one_line_error(capsys, "models")
    assert "not a model file jaxhand reads (model files are .toml, .json, MJCF .xml or .urdf)" in err


@pytest.mark.parametrize("limits", ["[-inf, inf]", "[-90.0, nan]"])
def test_infinite_or_nan_limits_are_refused_on_load(tmp_path, limits):
    text = jh.model_to_dict(jh.builtin_model("planar_rr"))
    path = tmp_path / "m.toml"
    jh.save_model(jh.model_from_dict(text), path)
    lines = path.read_text().splitlines()
    lines = [f"limits = {limits}" if ln.startswith("limits = ") else ln for ln in lines]
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(jh.ModelFileError, match=r"field 'limits' must be finite.*\[-180, 180\] deg"):
        jh.load_model(path)


def test_fit_given_a_plain_array_as_features_says_what_to_pass():
    model = jh.builtin_model("index")
    cam = jh.Orthographic.fit(np.asarray(jh.forward(model, model.q_default).link_end))
    with pytest.raises(jh.InputError, match="features: expected a jaxhand.Features .* got ndarray"):
        jh.fit(model, cam, np.zeros((3, 3)), model.q_default)
