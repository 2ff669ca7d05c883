import copy

import numpy as np
import pytest

import jaxhand as jh
from jaxhand.model import builtin_spec, model_from_dict, model_to_dict

EXPECTED = {"index": (3, 3, 1), "index_thumb": (6, 6, 2), "two_fingers": (6, 6, 2), "hand21": (21, 15, 5),
            "hand27": (27, 15, 5), "mouse3d": (8, 9, 3), "planar_r": (1, 1, 1), "planar_p": (1, 1, 1),
            "planar_pr": (2, 1, 1), "planar_rr": (2, 2, 1)}


@pytest.mark.parametrize("name", list(EXPECTED))
def test_builtin_sizes(name):
    m = jh.builtin_model(name)
    assert (m.dof, m.n_links, m.n_tips) == EXPECTED[name]
    assert np.all(np.asarray(m.q_lower) <= np.asarray(m.q_default))
    assert np.all(np.asarray(m.q_default) <= np.asarray(m.q_upper))


def test_hand27_is_hand21_on_a_free_palm():
    h21, h27 = jh.builtin_model("hand21"), jh.builtin_model("hand27")
    assert h27.n_q == 28 and h27.q_names[:7] == ("palm_qw", "palm_qx", "palm_qy", "palm_qz", "palm_tx",
                                                 "palm_ty", "palm_tz")
    assert h27.q_names[7:] == h21.q_names
    # Same world geometry at the default pose: the palm quaternion (0,0,0,1) equals hand21's mount.
    p21, p27 = jh.forward(h21, h21.q_default), jh.forward(h27, h27.q_default)
    np.testing.assert_allclose(p21.tips, p27.tips, atol=1e-12)


def test_joint_limits_follow_table_2_1():
    m = jh.builtin_model("hand21")
    deg = lambda name: np.degrees([m.q_lower[m.q_lookup(name)], m.q_upper[m.q_lookup(name)]])  # noqa: E731
    np.testing.assert_allclose(deg("index_mcp"), [-90, 45])
    np.testing.assert_allclose(deg("index_pip"), [-100, 0])
    np.testing.assert_allclose(deg("index_dip"), [-80, 0])
    np.testing.assert_allclose(deg("thumb_ip"), [-80, 15])
    np.testing.assert_allclose(deg("thumb_mcp"), [-55, 10])


@pytest.mark.parametrize("name", list(EXPECTED))
@pytest.mark.parametrize("suffix", [".toml", ".json"])
def test_model_file_round_trip(tmp_path, name, suffix):
    m = jh.builtin_model(name)
    path = jh.save_model(m, tmp_path / f"{name}{suffix}")
    m2 = jh.load_model(path)
    assert m2.structure() == m.structure()
    for field in ("dh", "T_world_mount", "q_lower", "q_upper", "q_default", "link_length_mm", "link_radius_mm"):
        np.testing.assert_allclose(getattr(m2, field), getattr(m, field), rtol=0, atol=1e-12, err_msg=field)
    assert model_to_dict(m2) == model_to_dict(m)


def _spec():
    return copy.deepcopy(builtin_spec("index"))


def _frame(spec, name):
    return next(f for f in spec["frames"] if f["name"] == name)


@pytest.mark.parametrize("mutate, match", [
    (lambda s: _frame(s, "index_pip").update(parent="index_9"), r"frame 'index_pip'.*parent 'index_9' is not defined"),
    (lambda s: _frame(s, "index_mcp").update(parent="index_dip"), r"frame 'index_mcp'.*cyclic"),
    (lambda s: _frame(s, "index_pip").update(name="index_mcp"), r"frame 'index_mcp'.*duplicate"),
    (lambda s: _frame(s, "index_pip").pop("a_mm"), r"frame 'index_pip'.*missing field 'a_mm'"),
    (lambda s: _frame(s, "index_pip").update(limits=[10, -10]), r"frame 'index_pip'.*limit min 10.0 > max -10.0"),
    (lambda s: _frame(s, "index_dip")["link"].update(radius_mm=-1), r"frame 'index_dip' link.*negative radius"),
    (lambda s: _frame(s, "index_dip").update(joint="spherical"), r"frame 'index_dip'.*unknown joint kind"),
    (lambda s: _frame(s, "index_dip").update(alpah_deg=0), r"unknown field 'alpah_deg' \(did you mean 'alpha_deg'"),
    (lambda s: _frame(s, "index_dip").update(default=45.0), r"frame 'index_dip'.*outside limits"),
    (lambda s: _frame(s, "index_dip").update(a_mm="long"), r"frame 'index_dip'.*'a_mm' must be a finite number"),
    (lambda s: _frame(s, "index_dip")["link"].update(axis="w"), r"unknown axis 'w'"),
    (lambda s: s.update(format_version=7), r"format_version"),
    (lambda s: s["base"].update(kind="floating"), r"unknown base kind 'floating'"),
    (lambda s: s["base"].update(rotation=[[1, 0, 0], [0, 1, 0], [0, 0, 2]]), r"not a proper rotation"),
    (lambda s: s.update(frames=[]), r"'frames' must be a non-empty list"),
])
def test_validation_errors_name_frame_and_field(mutate, match):
    spec = _spec()
    mutate(spec)
    with pytest.raises(jh.ModelFileError, match=match) as info:
        model_from_dict(spec, source="hand.toml")
    assert str(info.value).startswith("hand.toml: ")


def test_load_errors_name_the_file(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("name = [unclosed\n")
    with pytest.raises(jh.ModelFileError, match=r"bad.toml: cannot parse"):
        jh.load_model(bad)
    with pytest.raises(jh.ModelFileError, match=r"missing.toml: cannot read"):
        jh.load_model(tmp_path / "missing.toml")
    with pytest.raises(jh.ModelFileError, match=r"unknown model file type '.yaml'"):
        jh.load_model(tmp_path / "m.yaml")


def test_get_model_by_name_or_path(tmp_path):
    path = jh.save_model(jh.builtin_model("index"), tmp_path / "mine.json")
    assert jh.get_model(path).structure() == jh.builtin_model("index").structure()
    with pytest.raises(jh.InputError, match="unknown model 'hand99'; built-in models: index"):
        jh.get_model("hand99")


def test_q_lookup_lists_valid_names():
    m = jh.builtin_model("index")
    assert m.q_lookup("index_pip") == 1
    with pytest.raises(KeyError, match="valid: index_mcp, index_pip, index_dip"):
        m.q_lookup("index_tip")
