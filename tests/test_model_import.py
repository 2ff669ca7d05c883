"""MJCF and URDF import: the dev set's hand reproduces its truth; small files against reference FK."""

import json
import math
from pathlib import Path

import jax
import numpy as np
import pytest

import jaxhand as jh
from jaxhand.kinematics import occluder_pills, pose
from jaxhand.model import load_mjcf, load_urdf

DEVSET = Path(__file__).resolve().parents[1] / "data" / "mujoco"
HAND_XML = DEVSET / "models" / "hand.xml"
SEQUENCES = sorted(p.parent.name for p in DEVSET.glob("*/truth.json"))


def test_devset_is_in_the_repository():
    assert SEQUENCES == ["fast_spread", "index_over_middle", "open_close", "open_close_noise_clutter",
                         "thumb_opposition", "wave_two_cameras"]


def test_hand_xml_structure():
    m = load_mjcf(HAND_XML)
    hand = json.loads((DEVSET / "models" / "hand.json").read_text())
    assert m.q_names == tuple(j["name"] for j in hand["joints"])  # document order, MJCF names
    assert m.n_links == 15 and m.tip_names == ("thumb_distal", "index_distal", "middle_distal", "ring_distal",
                                               "little_distal")
    assert m.occluder_names == ("forearm", "palm_index", "palm_middle", "palm_ring", "palm_little")
    np.testing.assert_array_equal(m.q_lower, [j["range"][0] for j in hand["joints"]])  # radians, exactly
    np.testing.assert_array_equal(m.q_upper, [j["range"][1] for j in hand["joints"]])
    # Every link starts at its joint and runs along its frame's x axis, as the built-in hands do.
    assert set(m.link_axis) == {0} and len(m.frame_names) == 22


def _points(model, poses, hand):
    """Truth points from the model: joint centres are link starts, tips link ends, the wrist the palm."""
    out = []
    for p in hand["points"].values():
        if p["body"] == "palm":
            out.append(poses.frames[:, model.frame_lookup("palm"), :3, 3])
        else:
            k = model.link_lookup(p["body"])  # the dev set names each link's capsule after its body
            out.append(poses.link_start[:, k] if not any(p["pos_in_body"]) else poses.link_end[:, k])
    return list(hand["points"]), np.stack(out, 1)


@pytest.mark.parametrize("sequence", SEQUENCES)
def test_hand_xml_reproduces_the_truth(sequence):
    """Forward kinematics of the imported MJCF against truth.json's points, every frame and camera.

    Tolerance 1e-3 px: the truth's pixels are rounded to 1e-3 px (max error 5e-4) and its 3-D
    points to 1e-4 mm.
    """
    m = load_mjcf(HAND_XML)
    hand = json.loads((DEVSET / "models" / "hand.json").read_text())
    truth = json.loads((DEVSET / sequence / "truth.json").read_text())
    q = np.array([[f["joint_angles"][n] for n in m.q_names] for f in truth["frames"]])
    names, P = _points(m, jax.vmap(lambda x: pose(m, x))(q), hand)
    W = np.array([[f["points_world"][n] for n in names] for f in truth["frames"]])
    np.testing.assert_allclose(P, W, rtol=0, atol=1e-4)
    for c, cam_spec in enumerate(truth["cameras"]):
        cam = jh.Perspective(K=cam_spec["K"], R=cam_spec["R_world_to_cam"], t=cam_spec["t_world_to_cam"],
                             size=(truth["image_size"]["width"], truth["image_size"]["height"]))
        key = f"points_px_cam{c}" if truth["num_cameras"] > 1 else "points_px"
        px = np.array([[f[key][n] for n in names] for f in truth["frames"]])
        np.testing.assert_allclose(np.asarray(cam.project(P)[0]), px, rtol=0, atol=1e-3)


def test_hand_xml_occluders_are_the_palm_capsules():
    m = load_mjcf(HAND_XML)
    occ = occluder_pills(m, jh.forward(m, m.q_default))
    k = m.occluder_lookup("palm_middle")
    np.testing.assert_allclose(occ.start[k], [5.5, 12, 0], atol=1e-12)
    np.testing.assert_allclose(occ.end[k], [9.35, 91, 0], atol=1e-12)
    assert float(occ.radius_mm[k]) == 12.19
    # A choice of occluders: the thumb metacarpal as an occluder, the forearm as a link.
    m2 = load_mjcf(HAND_XML, occluders=["thumb_metacarpal", "palm_index", "palm_middle", "palm_ring", "palm_little"])
    assert "forearm" in m2.link_names and "thumb_metacarpal" in m2.occluder_names and m2.n_links == 15


def test_hand_xml_through_load_model_and_get_model():
    assert jh.load_model(HAND_XML).structure() == load_mjcf(HAND_XML).structure()
    assert jh.get_model(str(HAND_XML)).q_names == load_mjcf(HAND_XML).q_names


# ---- a small MJCF exercising the other features, against a reference implementation ----

_MJCF = """<mujoco model="bits">
  <compiler angle="degree" eulerseq="zyx"/>
  <default>
    <geom type="capsule" size="4"/>
    <default class="slim"><geom size="2.5"/><joint range="-30 60"/></default>
  </default>
  <worldbody>
    <geom type="plane" size="100 100 1"/>
    <body name="root" pos="1 2 3" euler="10 20 30">
      <geom name="palm" fromto="0 0 0 0 40 0"/>
      <body name="a" pos="5 40 2" axisangle="0 0 1 30" childclass="slim">
        <joint name="a1" axis="0 0 1"/>
        <joint name="a2" axis="1 0 0" pos="0 2 0" ref="10"/>
        <geom name="a_link" fromto="0 0 0 0 30 0"/>
        <geom name="a_side" type="capsule" size="3 6" pos="4 10 0" xyaxes="0 1 0 -1 0 0"/>
        <body name="b" pos="0 30 0" zaxis="0 1 1">
          <joint name="b1" class="main" axis="0 1 0" range="-45 45"/>
          <joint name="b_slide" type="slide" axis="0 0 1" range="-5 8"/>
          <geom name="b_link" type="cylinder" size="3 10" pos="0 0 10"/>
          <geom name="b_ball" type="sphere" size="5" pos="0 0 20"/>
          <body name="c" pos="0 0 20" quat="0.9 0.1 -0.3 0.2">
            <joint name="c1" class="main" axis="1 1 0"/>
            <geom name="c_link" fromto="1 0 0 15 3 -2"/>
          </body>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


def _axis_angle(axis, angle):
    k = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def _T(R=None, p=(0, 0, 0)):
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = np.eye(3) if R is None else R, p
    return T


def _quat(w, x, y, z):
    n = math.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / n, x / n, y / n, z / n
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def _reference_bits(q):
    """MuJoCo's composition written out for _MJCF: T_body = T_parent Trans(pos) R(orient) joints..."""
    d = np.radians
    a1, a2, b1, bs, c1 = q
    # zyx euler, lower case: intrinsic, R = Rz(10) Ry(20) Rx(30)
    R_root = _axis_angle([0, 0, 1], d(10)) @ _axis_angle([0, 1, 0], d(20)) @ _axis_angle([1, 0, 0], d(30))
    T_root = _T(R_root, [1, 2, 3])
    hinge = lambda axis, ang, c=(0, 0, 0): _T(p=c) @ _T(_axis_angle(axis, ang)) @ _T(p=-np.asarray(c, float))  # noqa: E731
    T_a = T_root @ _T(_axis_angle([0, 0, 1], d(30)), [5, 40, 2]) @ hinge([0, 0, 1], a1) @ hinge([1, 0, 0], a2 - d(10),
                                                                                                 (0, 2, 0))
    z = np.array([0, 1, 1]) / np.sqrt(2)
    R_b = _axis_angle(np.cross([0, 0, 1], z), np.arccos(z[2]))
    T_b = T_a @ _T(R_b, [0, 30, 0]) @ hinge([0, 1, 0], b1) @ _T(p=[0, 0, bs])
    T_c = T_b @ _T(_quat(0.9, 0.1, -0.3, 0.2), [0, 0, 20]) @ hinge([1, 1, 0], c1)
    at = lambda T, p: (T @ np.append(p, 1.0))[:3]  # noqa: E731
    R_side = np.stack([[0, 1, 0], [-1, 0, 0], [0, 0, 1]], axis=1)
    links = {"a_link": (at(T_a, [0, 0, 0]), at(T_a, [0, 30, 0])),
             "a_side": (at(T_a, [4, 10, 0] - 6 * R_side[:, 2]), at(T_a, [4, 10, 0] + 6 * R_side[:, 2])),
             "b_link": (at(T_b, [0, 0, 0]), at(T_b, [0, 0, 20])),
             "c_link": (at(T_c, [1, 0, 0]), at(T_c, [15, 3, -2]))}
    occluders = {"palm": (at(T_root, [0, 0, 0]), at(T_root, [0, 40, 0])),
                 "b_ball": (at(T_b, [0, 0, 20]), at(T_b, [0, 0, 20]))}
    return links, occluders


def test_mjcf_features_against_reference(tmp_path):
    path = tmp_path / "bits.xml"
    path.write_text(_MJCF)
    m = load_mjcf(path)
    assert m.q_names == ("a1", "a2", "b1", "b_slide", "c1")
    assert m.link_names == ("a_link", "a_side", "b_link", "c_link") and m.tip_names == ("c_link",)
    assert m.occluder_names == ("palm", "b_ball")
    np.testing.assert_allclose(np.degrees([m.q_lower[0], m.q_upper[0]]), [-30, 60])  # class "slim"
    np.testing.assert_allclose(np.degrees([m.q_lower[2], m.q_upper[2]]), [-45, 45])
    np.testing.assert_allclose([m.q_lower[3], m.q_upper[3]], [-5, 8])
    np.testing.assert_allclose(np.degrees([m.q_lower[4], m.q_upper[4]]), [-180, 180])  # no range: a full turn
    np.testing.assert_allclose(m.link_radius_mm, [2.5, 3, 3, 2.5])
    np.testing.assert_allclose(m.q_default[1], np.radians(10))  # ref: the body's own pose
    rng = np.random.default_rng(3)
    for q in [np.asarray(m.q_default)] + list(jh.random_q(m, rng, 4)):
        p = jh.forward(m, q)
        occ = occluder_pills(m, p)
        links, occluders = _reference_bits(q)
        for name, (s, e) in links.items():
            k = m.link_lookup(name)
            np.testing.assert_allclose(p.link_start[k], s, atol=1e-10, err_msg=name)
            np.testing.assert_allclose(p.link_end[k], e, atol=1e-10, err_msg=name)
        for name, (s, e) in occluders.items():
            k = m.occluder_lookup(name)
            np.testing.assert_allclose(occ.start[k], s, atol=1e-10, err_msg=name)
            np.testing.assert_allclose(occ.end[k], e, atol=1e-10, err_msg=name)


def test_mjcf_free_joint_gives_a_free_base(tmp_path):
    path = tmp_path / "free.xml"
    path.write_text('<mujoco><compiler angle="radian"/><worldbody><body name="palm" pos="1 2 3" '
                    'quat="0 0 0 1"><freejoint/><geom type="capsule" fromto="0 0 0 0 50 0" size="10"/>'
                    '<body name="f" pos="0 50 0"><joint name="f1" axis="1 0 0" range="-1 1"/>'
                    '<geom type="capsule" fromto="0 0 0 0 30 0" size="8"/></body></body></worldbody></mujoco>')
    m = load_mjcf(path)
    assert m.base_kind == "free" and m.q_names[7:] == ("f1",) and m.occluder_names == ("palm_geom0",)
    p = jh.forward(m, m.q_default)
    np.testing.assert_allclose(p.link_start[0], [1, 2 - 50, 3], atol=1e-12)  # RotZ(180) turns +y into -y
    np.testing.assert_allclose(p.tips[0], [1, 2 - 80, 3], atol=1e-12)


@pytest.mark.parametrize("xml, match", [
    ("<robot/>", r"not an MJCF file"),
    ("<mujoco><worldbody><body><joint type='ball'/></body></worldbody></mujoco>", r"joint type 'ball'"),
    ("<mujoco><worldbody><body><geom class='nope'/></body></worldbody></mujoco>", r"unknown default class 'nope'"),
    ("<mujoco><worldbody><body pos='1 2'/></worldbody></mujoco>", r"<body>: attribute 'pos' must be 3"),
    ("<mujoco><include file='x.xml'/><worldbody><body/></worldbody></mujoco>", r"<include> is not supported"),
    ("<mujoco><worldbody><body><body><freejoint/></body></body></worldbody></mujoco>", r"free joint"),
    ("<mujoco><worldbody><body", r"cannot parse"),
])
def test_mjcf_errors_name_file_and_element(tmp_path, xml, match):
    path = tmp_path / "bad.xml"
    path.write_text(xml)
    with pytest.raises(jh.ModelFileError, match=match) as info:
        load_mjcf(path)
    assert str(info.value).startswith(str(path))


# ---- URDF ----

ARM_URDF = Path(__file__).with_name("data") / "arm.urdf"  # a planar RR arm, a prismatic tool, a fixed camera


def _rpy(r, p, y):
    return _axis_angle([0, 0, 1], y) @ _axis_angle([0, 1, 0], p) @ _axis_angle([1, 0, 0], r)


def test_urdf_closed_form_and_reference():
    path = ARM_URDF
    m = load_urdf(path)
    assert m.q_names == ("shoulder", "elbow", "slide") and m.q_kinds == ("angle", "angle", "length")
    assert m.link_names == ("upper", "fore", "tool_1") and m.tip_names == ("tool_1",)
    assert m.occluder_names == ("base_link", "tool", "camera_link")
    np.testing.assert_allclose([m.q_lower[0], m.q_upper[0]], [-1.5, 1.5])
    np.testing.assert_allclose([m.q_lower[1], m.q_upper[1]], [-np.pi, np.pi])
    np.testing.assert_allclose([m.q_lower[2], m.q_upper[2]], [-10, 20])  # metres -> mm
    np.testing.assert_allclose(m.link_radius_mm, [10, 8, 4])
    rng = np.random.default_rng(5)
    for q in [np.zeros(3)] + list(jh.random_q(m, rng, 4)):
        t1, t2, s = q
        p = jh.forward(m, q)
        # Closed form: a planar RR arm 20 mm up, links 100 and 80 mm.
        elbow = np.array([100 * np.cos(t1), 100 * np.sin(t1), 20])
        wrist = elbow + 80 * np.array([np.cos(t1 + t2), np.sin(t1 + t2), 0])
        np.testing.assert_allclose(p.link_start[0], [0, 0, 20], atol=1e-9)
        np.testing.assert_allclose(p.link_end[0], elbow, atol=1e-9)
        np.testing.assert_allclose(p.link_start[1], elbow, atol=1e-9)
        np.testing.assert_allclose(p.link_end[1], wrist, atol=1e-9)
        # Reference for the prismatic joint and the tool's cylinder (URDF: Trans(xyz) RPY, then the motion).
        T_fore = _T(_axis_angle([0, 0, 1], t1 + t2), elbow)
        axis = np.array([0, 1, 1]) / np.sqrt(2)
        T_tool = T_fore @ _T(_rpy(0.3, -0.2, 0.5), [80, 0, 0]) @ _T(p=s * axis)
        T_cyl = T_tool @ _T(_rpy(0.1, 0.2, 0.3), [0, 10, 10])
        np.testing.assert_allclose(p.link_start[2], (T_cyl @ [0, 0, -10, 1])[:3], atol=1e-9)
        np.testing.assert_allclose(p.tips[0], (T_cyl @ [0, 0, 10, 1])[:3], atol=1e-9)
        occ = occluder_pills(m, p)
        np.testing.assert_allclose(occ.start[1], T_tool[:3, 3], atol=1e-9)
        np.testing.assert_allclose(occ.start[2], [0, 50, 0], atol=1e-12)
        np.testing.assert_allclose(occ.start[0], [0, 0, 0], atol=1e-12)
        np.testing.assert_allclose(occ.end[0], [0, 0, 20], atol=1e-12)
    assert jh.load_model(path).structure() == m.structure()


@pytest.mark.parametrize("body, match", [
    ('<link name="a"/><link name="b"/><joint name="j" type="floating"><parent link="a"/><child link="b"/></joint>',
     r"joint type 'floating'"),
    ('<link name="a"/><link name="b"/><joint name="j" type="revolute"><parent link="a"/><child link="b"/></joint>',
     r"needs <limit"),
    ('<link name="a"/><link name="b"/>', r"expected one root link, found 2"),
    ('<link name="a"/><joint name="j" type="fixed"><parent link="a"/><child link="zz"/></joint>', r"defined links"),
])
def test_urdf_errors_name_file_and_element(tmp_path, body, match):
    path = tmp_path / "bad.urdf"
    path.write_text(f"<robot name='r'>{body}</robot>")
    with pytest.raises(jh.ModelFileError, match=match):
        load_urdf(path)
