"""Model file version 2: fixed transforms, occluder pills, link names, handedness and mirroring."""

import copy
import math
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import CompileCounter

import jaxhand as jh
from jaxhand.cli import main
from jaxhand.io import load_devset
from jaxhand.kinematics import all_pills, dh_transform, frame_poses, occluder_pills
from jaxhand.model import (
    builtin_spec,
    load_mjcf,
    load_urdf,
    mirror_model,
    mirror_q,
    model_from_dict,
    model_to_dict,
    occluders_as_links,
)

HAND_XML = Path(__file__).resolve().parents[1] / "data" / "mujoco" / "models" / "hand.xml"


def _rot_z(deg):
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]


def _index_spec():
    return copy.deepcopy(builtin_spec("index"))


def _frame(spec, name):
    return next(f for f in spec["frames"] if f["name"] == name)


# ---- fixed transform before the DH transform ----

def test_builtins_have_no_fixed_transform_and_plain_dh_kinematics():
    """No pre_transform: frame_poses is the plain DH composition, bit for bit."""
    for name in jh.builtin_names():
        m = jh.builtin_model(name)
        assert m.pre_transform_frames == () and m.T_pre_transform.shape == (0, 4, 4)
    m = jh.builtin_model("index")
    q = jnp.asarray(jh.random_q(m, np.random.default_rng(2)))
    dh = np.asarray(m.dh)
    T = np.asarray(m.T_world_mount)
    for i in range(3):  # a serial chain
        T = T @ np.asarray(dh_transform(dh[i, 0], dh[i, 1], dh[i, 2], dh[i, 3] + q[i]))
    np.testing.assert_allclose(frame_poses(m, q)[2], T, rtol=0, atol=1e-12)


@pytest.mark.parametrize("rotation", ["matrix", "quaternion"])
def test_pre_transform_is_applied_before_the_dh_transform(rotation):
    spec = _index_spec()
    spec["base"] = {"kind": "fixed"}
    pre = {"translation_mm": [1.0, 2.0, 3.0]}
    if rotation == "matrix":
        pre["rotation"] = _rot_z(90)
    else:
        pre["quaternion"] = [math.cos(math.pi / 4), 0.0, 0.0, math.sin(math.pi / 4)]
    _frame(spec, "index_mcp")["pre_transform"] = pre
    m = model_from_dict(spec)
    plain = model_from_dict(_index_spec() | {"base": {"kind": "fixed"}})
    assert m.pre_transform_frames == (0,)
    q = jh.random_q(m, np.random.default_rng(0))
    T_pre = np.eye(4)
    T_pre[:3, :3], T_pre[:3, 3] = _rot_z(90), [1, 2, 3]
    # index_mcp hangs off the base, so every frame of the finger moves by T_pre.
    np.testing.assert_allclose(frame_poses(m, q), T_pre @ np.asarray(frame_poses(plain, q)), atol=1e-12)
    # Golden: at q = 0 the tip (40 + 24 + 20 mm along x of index_mcp) is at T_pre (84, 0, 0).
    np.testing.assert_allclose(jh.forward(m, jnp.zeros(3)).tips[0], [1.0, 2.0 + 84.0, 3.0], atol=1e-12)


def test_imported_models_compile_once_per_structure():
    """Fixed transforms, occluders and mirroring are traced numbers: same structure, same program."""
    m = load_mjcf(HAND_XML)
    others = [m.with_lengths(1.1), mirror_model(m, name=m.name)]  # handedness "none" stays "none"
    assert all(o.structure() == m.structure() for o in others)
    q = jnp.asarray(m.q_default)
    occluder_pills(m, jh.forward(m, q))
    with CompileCounter() as counter:
        for other in others:
            for x in jh.random_q(m, np.random.default_rng(1), 3):
                jh.forward(other, jnp.asarray(x))
    assert counter.count == 0


def test_pre_transform_jacobian_matches_finite_differences():
    m = load_mjcf(HAND_XML)
    q = jnp.asarray(jh.random_q(m, np.random.default_rng(4), margin=0.1))
    J = jax.jacfwd(lambda x: jh.forward(m, x).tips.ravel())(q)
    h = 1e-6
    tips = lambda x: np.asarray(jh.forward(m, x).tips).ravel()  # noqa: E731
    Jfd = np.stack([(tips(q + h * e) - tips(q - h * e)) / (2 * h) for e in np.eye(m.n_q)], 1)
    np.testing.assert_allclose(J, Jfd, atol=1e-6)


# ---- occluders and link names ----

def _with_occluders():
    spec = _index_spec()
    _frame(spec, "index_mcp")["link"]["name"] = "proximal"
    spec["occluders"] = [{"name": "palm", "frame": "index_mcp", "start_mm": [0, -10, 0], "end_mm": [-60, -10, 0],
                          "radius_mm": 20},
                         {"name": "knuckle", "frame": "index_pip", "start_mm": [0, 0, 0], "end_mm": [0, 0, 0],
                          "radius_mm": 5}]
    return spec


def test_occluders_move_with_their_frame_and_carry_no_features():
    m = model_from_dict(_with_occluders())
    assert m.link_names == ("proximal", "index_pip", "index_dip") and m.link_lookup("proximal") == 0
    assert m.occluder_names == ("palm", "knuckle") and m.n_links == 3 and m.n_tips == 1
    for q in jh.random_q(m, np.random.default_rng(1), 3):
        p = jh.forward(m, q)
        occ = occluder_pills(m, p)
        T = np.asarray(p.frames)
        np.testing.assert_allclose(occ.start[0], T[0, :3, :3] @ [0, -10, 0] + T[0, :3, 3], atol=1e-12)
        np.testing.assert_allclose(occ.end[0], T[0, :3, :3] @ [-60, -10, 0] + T[0, :3, 3], atol=1e-12)
        np.testing.assert_allclose(occ.start[1], p.link_start[1], atol=1e-12)  # the PIP centre
        np.testing.assert_allclose(occ.radius_mm, [20, 5])
        pills = all_pills(m, p)
        assert pills.start.shape == (5, 3)
        np.testing.assert_allclose(pills.end[:3], p.link_end)
        np.testing.assert_allclose(pills.radius_mm, [9, 8, 7.5, 20, 5])
    # Batched poses give batched occluders.
    Q = jh.random_q(m, np.random.default_rng(2), 4)
    P = jax.vmap(lambda x: jh.kinematics.pose(m, x))(jnp.asarray(Q))
    assert occluder_pills(m, P).start.shape == (4, 2, 3)
    assert occluder_pills(jh.builtin_model("hand21"), jh.forward(jh.builtin_model("hand21"),
                                                                  jh.builtin_model("hand21").q_default)).start.shape \
        == (0, 3)


def test_occluders_as_links_keeps_the_geometry():
    m = load_mjcf(HAND_XML)
    m2 = occluders_as_links(m, ["forearm", "palm_middle"], tips=False)
    assert m2.link_names == m.link_names + ("forearm", "palm_middle") and m2.tip_names == m.tip_names
    assert m2.occluder_names == ("palm_index", "palm_ring", "palm_little") and m2.q_names == m.q_names
    q = jh.random_q(m, np.random.default_rng(8))
    p, p2 = jh.forward(m, q), jh.forward(m2, q)
    occ = occluder_pills(m, p)
    np.testing.assert_allclose(p2.link_start[-2:], np.asarray(occ.start)[[0, 2]], atol=1e-12)
    np.testing.assert_allclose(p2.link_end[-2:], np.asarray(occ.end)[[0, 2]], atol=1e-12)
    np.testing.assert_allclose(m2.link_radius_mm[-2:], [23.32, 12.19])
    np.testing.assert_allclose(p2.tips, p.tips, rtol=0, atol=1e-12)   # 1 ulp apart on some machines
    assert occluders_as_links(m).n_occluders == 0
    with pytest.raises(jh.InputError, match="no occluder 'palm'; valid: forearm"):
        occluders_as_links(m, ["palm"])


def test_hand_clutter_xml_skips_the_background_plane():
    clutter = load_mjcf(HAND_XML.with_name("hand_clutter.xml"))
    assert clutter.structure() == load_mjcf(HAND_XML).structure()


def test_with_lengths_scales_fixed_transforms_and_occluders():
    m = load_mjcf(HAND_XML)
    m2 = m.with_lengths(2.0)
    q = jh.random_q(m, np.random.default_rng(0))
    np.testing.assert_allclose(jh.forward(m2, q).tips, 2 * np.asarray(jh.forward(m, q).tips), atol=1e-10)
    np.testing.assert_allclose(occluder_pills(m2, jh.forward(m2, q)).end,
                               2 * np.asarray(occluder_pills(m, jh.forward(m, q)).end), atol=1e-10)


# ---- handedness and mirroring ----

def _handedness_sign(m, radial, finger, flex):
    """sign det[radial, distal, palmar]: +1 for a right hand (the dev set's convention)."""
    q = np.zeros(m.n_q) if m.base_kind == "fixed" else np.asarray(m.q_default).copy()
    p = jh.forward(m, q)
    a, b = (np.asarray(p.link_start[m.link_lookup(n)]) for n in radial)
    k = next(i for i, n in enumerate(m.tip_names) if n.startswith(finger))
    tip = np.asarray(p.tips[k])
    q2 = q.copy()
    for n, dq in flex.items():
        q2[m.q_lookup(n)] += dq
    palmar = np.asarray(jh.forward(m, q2).tips[k]) - tip
    distal = tip - np.asarray(p.link_start[m.link_lookup(radial[0])])
    return np.sign(np.linalg.det(np.stack([b - a, distal, palmar])))


@pytest.mark.parametrize("name", ["hand21", "hand21_right", "hand27", "hand27_right"])
def test_builtin_handedness_follows_the_geometry(name):
    m = jh.builtin_model(name)
    sign = _handedness_sign(m, ("little_mcp", "index_mcp"), "middle", {"middle_pip": -0.5, "middle_dip": -0.5})
    assert m.handedness == {1.0: "right", -1.0: "left"}[sign]


def test_devset_hand_is_a_right_hand():
    m = load_devset(HAND_XML.parents[1] / "open_close").model
    assert m.handedness == "right"
    assert _handedness_sign(m, ("little_proximal", "index_proximal"), "middle", {"middle_pip": 0.5}) == 1.0


@pytest.mark.parametrize("name", [*jh.builtin_names(), "devset_hand"])
def test_mirror_is_the_mirror_image(name):
    m = load_mjcf(HAND_XML) if name == "devset_hand" else jh.builtin_model(name)
    mm = mirror_model(m)
    S = np.array([-1.0, 1.0, 1.0])
    for q in jh.random_q(m, np.random.default_rng(11), 3):
        p, pm = jh.forward(m, q), jh.forward(mm, mirror_q(m, q))
        np.testing.assert_allclose(pm.tips, np.asarray(p.tips) * S, atol=1e-12)
        np.testing.assert_allclose(pm.link_start, np.asarray(p.link_start) * S, atol=1e-12)
        np.testing.assert_allclose(pm.link_end, np.asarray(p.link_end) * S, atol=1e-12)
        np.testing.assert_allclose(occluder_pills(mm, pm).end, np.asarray(occluder_pills(m, p).end) * S, atol=1e-12)
        R = np.asarray(pm.frames[:, :3, :3])
        np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-12)  # frames stay right-handed
    # Mirroring twice gives the model back (exactly: only signs change).
    back = mirror_model(mm, name=m.name)
    assert back.structure() == m.structure()
    for a, b in zip(jax.tree_util.tree_leaves(back), jax.tree_util.tree_leaves(m)):
        np.testing.assert_array_equal(a, b)


def test_mirror_names_and_handedness():
    assert mirror_model(jh.builtin_model("hand21")).name == "hand21_right"
    assert mirror_model(jh.builtin_model("hand21_right")).name == "hand21_left"
    assert mirror_model(jh.builtin_model("index")).handedness == "none"
    assert mirror_model(load_mjcf(HAND_XML, handedness="right")).name == "hand_left"
    assert mirror_model(jh.builtin_model("hand21"), name="mine").name == "mine"


def test_mirror_rejects_links_along_z():
    spec = _index_spec()
    _frame(spec, "index_dip")["link"]["axis"] = "z"
    with pytest.raises(jh.InputError, match="along their frame's z axis cannot be mirrored: index_dip"):
        mirror_model(model_from_dict(spec))


def test_cli_models_mirror(tmp_path, capsys):
    path = tmp_path / "left.toml"
    assert main(["models", "hand21_right", "--mirror", "--export", str(path)]) == 0
    assert "hand21_left: 21 DOF" in capsys.readouterr().out
    m = jh.load_model(path)
    assert m.handedness == "left"
    np.testing.assert_allclose(jh.forward(m, m.q_default).tips,
                               jh.forward(jh.builtin_model("hand21"), m.q_default).tips, atol=1e-12)


# ---- files: exact round trip, version 1 and 2, validation ----

@pytest.mark.parametrize("suffix", [".toml", ".json"])
def test_save_load_is_exact(tmp_path, suffix):
    urdf = Path(__file__).with_name("data") / "arm.urdf"
    models = [jh.builtin_model(n) for n in jh.builtin_names()]
    models += [load_mjcf(HAND_XML, handedness="right"), load_urdf(urdf), model_from_dict(_with_occluders())]
    models.append(mirror_model(models[-3]))
    for m in models:
        m2 = jh.load_model(jh.save_model(m, tmp_path / f"{m.name}{suffix}"))
        assert m2.structure() == m.structure(), m.name
        for a, b in zip(jax.tree_util.tree_leaves(m2), jax.tree_util.tree_leaves(m)):
            np.testing.assert_array_equal(a, b, err_msg=m.name)
        assert model_to_dict(m2) == model_to_dict(m)


def test_version_1_files_still_load_and_cannot_use_version_2_fields():
    spec = _index_spec()
    spec["format_version"] = 1
    assert model_from_dict(spec).structure() == jh.builtin_model("index").structure()
    spec["handedness"] = "left"
    with pytest.raises(jh.ModelFileError, match="field 'handedness' needs format_version 2"):
        model_from_dict(spec)
    spec = _index_spec()
    spec["format_version"] = 1
    _frame(spec, "index_pip")["pre_transform"] = {}
    with pytest.raises(jh.ModelFileError, match="frame 'index_pip'.*'pre_transform' needs format_version 2"):
        model_from_dict(spec)


@pytest.mark.parametrize("mutate, match", [
    (lambda s: _frame(s, "index_pip").update(pre_transform={"rotaton": _rot_z(5)}),
     r"frame 'index_pip' pre_transform: unknown field 'rotaton' \(did you mean 'rotation'"),
    (lambda s: _frame(s, "index_pip").update(pre_transform={"quaternion": [1, 1, 0, 0]}),
     r"frame 'index_pip' pre_transform: field 'quaternion' must have unit length"),
    (lambda s: _frame(s, "index_pip").update(pre_transform={"quaternion": [1, 0, 0, 0], "rotation": _rot_z(0)}),
     r"either 'rotation' or 'quaternion'"),
    (lambda s: _frame(s, "index_pip").update(pre_transform={"rotation": [[1, 0, 0], [0, 1, 0], [0, 0, -1]]}),
     r"frame 'index_pip' pre_transform: field 'rotation' is not a proper rotation"),
    (lambda s: _frame(s, "index_pip").update(pre_transform={"translation_mm": [1, 2]}),
     r"field 'translation_mm' must be 3 finite numbers"),
    (lambda s: s["occluders"][0].update(frame="index_mpc"),
     r"occluder 'palm': field 'frame': frame 'index_mpc' is not defined \(did you mean 'index_mcp'"),
    (lambda s: s["occluders"][1].update(name="palm"), r"occluder 'palm'.*duplicate pill name"),
    (lambda s: s["occluders"][1].update(name="proximal"), r"duplicate pill name 'proximal'"),
    (lambda s: s["occluders"][0].update(radius_mm=-2), r"occluder 'palm': field 'radius_mm': negative radius"),
    (lambda s: s["occluders"][0].pop("end_mm"), r"occluder 'palm': missing field 'end_mm'"),
    (lambda s: s["occluders"][0].update(strat_mm=[0, 0, 0]), r"unknown field 'strat_mm' \(did you mean 'start_mm'"),
    (lambda s: _frame(s, "index_pip")["link"].update(name="proximal"), r"duplicate link name 'proximal'"),
    (lambda s: s.update(handedness="both"), r"field 'handedness' must be one of right, left, none"),
    (lambda s: s.update(handednes="left"), r"unknown field 'handednes' \(did you mean 'handedness'"),
])
def test_version_2_validation_errors(mutate, match):
    spec = _with_occluders()
    mutate(spec)
    with pytest.raises(jh.ModelFileError, match=match) as info:
        model_from_dict(spec, source="hand.toml")
    assert str(info.value).startswith("hand.toml: ")
