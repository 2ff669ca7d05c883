"""Built-in models, each usable by name (``builtin_model("hand21")``).

Every built-in is written as a file-format dictionary (:mod:`._file`), so the model file format
expresses each of them exactly. Lengths are an adult hand's (mm); joint limits follow thesis
Table 2.1 under the sign convention of thesis §6.2.2: opening or spreading the hand is positive,
so flexion is negative (MCP [-90, 45], PIP [-100, 0], DIP [-80, 0]).

Each fixed mount is chosen so that an orthographic camera with identity rotation (camera x right,
y down, z forward) sees the model the way the thesis draws it: the fingers point up the image and
move in (or, for the 21-DOF hand, spread in) the image plane. Tilts such as the 45-degree plane
of thesis §6 belong to the camera, not the model.

Handedness: the thesis hands (``hand21``, ``hand27``, ``mouse3d``) are *left* hands. With
radial (towards the index), distal and palmar (the direction of flexion) axes, a right hand has
``det[radial, distal, palmar] = +1`` (the MuJoCo development set's hand); these have -1, as
``tests/test_model.py`` checks. ``hand21_right`` and ``hand27_right`` are their mirror images
(:func:`mirror_model`), with the same joint names, limits and sign conventions.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from .._errors import InputError
from ._file import FORMAT_VERSION, model_from_dict
from ._model import Model

__all__ = ["builtin_model", "builtin_names", "builtin_spec", "BUILTIN_DESCRIPTIONS"]

# Phalanx lengths (proximal, middle, distal-to-tip) and radii, mm.
_FINGERS = {
    "index": ((40.0, 24.0, 20.0), (9.0, 8.0, 7.5)),
    "middle": ((44.0, 28.0, 22.0), (9.5, 8.5, 8.0)),
    "ring": ((41.0, 27.0, 21.0), (9.0, 8.0, 7.5)),
    "little": ((33.0, 20.0, 18.0), (7.5, 7.0, 6.5)),
}
# Finger base on the palm: x offset (|a_0|, the side sets the sign) and palm length a_1, mm.
_ANCHORS = {"little": (-33.0, 68.0), "ring": (-12.0, 80.0), "middle": (10.0, 85.0), "index": (31.0, 80.0)}
_FLEX_LIMITS = ((-90.0, 45.0), (-100.0, 0.0), (-80.0, 0.0))
_FLEX_DEFAULT = (-10.0, -15.0, -10.0)
_ABD_LIMITS = (-15.0, 30.0)


def _frame(name, parent, alpha=0.0, a=0.0, d=0.0, theta=0.0, joint="fixed", limits=None, default=None,
           link=None) -> dict[str, Any]:
    fr: dict[str, Any] = {"name": name, "parent": parent, "alpha_deg": alpha, "a_mm": a, "d_mm": d,
                          "theta_deg": theta, "joint": joint}
    if joint != "fixed":
        fr["limits"] = list(limits)
        fr["default"] = default
    if link is not None:
        fr["link"] = link
    return fr


def _pill(length, radius, tip=False) -> dict[str, Any]:
    return {"axis": "x", "length_mm": length, "radius_mm": radius, "tip": tip}


def _finger(finger: str, *, abduct: bool = True, flex: tuple[bool, bool, bool] = (True, True, True),
            prefix: str | None = None) -> list[dict[str, Any]]:
    """A planar finger on the palm, rows as in thesis Table 6.2.

    Fingers on the little-finger side (x < 0) use the little-finger rows (alpha 0 aux frame, MCP
    alpha +90); the others the middle-finger rows (alpha 180 aux frame, MCP alpha -90), which
    flip the joint axes so that spreading and extension stay positive on both sides.
    """
    p = prefix or finger
    (l1, l2, l3), (r1, r2, r3) = _FINGERS[finger]
    x, palm = _ANCHORS[finger]
    left = x < 0
    aux = _frame(f"{p}_aux", "base", alpha=0.0 if left else 180.0, a=-abs(x) if left else abs(x),
                 theta=90.0 if left else -90.0)
    abd_kw = dict(joint="revolute", limits=_ABD_LIMITS, default=0.0) if abduct else {}
    rows = [aux, _frame(f"{p}_abd", f"{p}_aux", a=palm, **abd_kw)]
    parent = f"{p}_abd"
    for k, (jn, alpha, a, length, radius) in enumerate(
            (("mcp", 90.0 if left else -90.0, 0.0, l1, r1), ("pip", 0.0, l1, l2, r2), ("dip", 0.0, l2, l3, r3))):
        kw = dict(joint="revolute", limits=_FLEX_LIMITS[k], default=_FLEX_DEFAULT[k]) if flex[k] else {}
        rows.append(_frame(f"{p}_{jn}", parent, alpha=alpha, a=a, link=_pill(length, radius, tip=k == 2), **kw))
        parent = f"{p}_{jn}"
    return rows


def _thumb5() -> list[dict[str, Any]]:
    """Five-DOF thumb of thesis Table 6.2 (frames 21-26): CMC 2 DOF, MCP 2 DOF, IP 1 DOF."""
    return [
        _frame("thumb_aux", "base", a=25.0),
        _frame("thumb_cmc_pa", "thumb_aux", alpha=90.0, joint="revolute", limits=(-10.0, 60.0), default=20.0),
        _frame("thumb_cmc_ra", "thumb_cmc_pa", alpha=90.0, joint="revolute", limits=(-60.0, 60.0), default=-40.0,
               link=_pill(42.0, 10.0)),
        _frame("thumb_mcp_ab", "thumb_cmc_ra", alpha=-90.0, a=42.0, joint="revolute", limits=(-20.0, 20.0),
               default=0.0),
        _frame("thumb_mcp", "thumb_mcp_ab", alpha=90.0, joint="revolute", limits=(-55.0, 10.0), default=-10.0,
               link=_pill(32.0, 9.0)),
        _frame("thumb_ip", "thumb_mcp", a=32.0, joint="revolute", limits=(-80.0, 15.0), default=-10.0,
               link=_pill(26.0, 8.5, tip=True)),
    ]


def _spec(name, description, frames, base=None, handedness="none") -> dict[str, Any]:
    spec = {"format_version": FORMAT_VERSION, "name": name, "description": description,
            "base": base or {"kind": "fixed"}, "frames": frames}
    if handedness != "none":
        spec["handedness"] = handedness
    return spec


_UPRIGHT_HAND = [[-1, 0, 0], [0, -1, 0], [0, 0, 1]]  # RotZ(180): fingers (+y0) up the image, palm to camera


def _index() -> dict[str, Any]:
    (l1, l2, l3), (r1, r2, r3) = _FINGERS["index"]
    frames = [
        _frame("index_mcp", "base", joint="revolute", limits=_FLEX_LIMITS[0], default=_FLEX_DEFAULT[0],
               link=_pill(l1, r1)),
        _frame("index_pip", "index_mcp", a=l1, joint="revolute", limits=_FLEX_LIMITS[1], default=_FLEX_DEFAULT[1],
               link=_pill(l2, r2)),
        _frame("index_dip", "index_pip", a=l2, joint="revolute", limits=_FLEX_LIMITS[2], default=_FLEX_DEFAULT[2],
               link=_pill(l3, r3, tip=True)),
    ]
    return _spec("index", "Index finger, 3 flexion DOF (thesis Table 2.2)", frames,
                 {"kind": "fixed", "rotation": [[0, 1, 0], [-1, 0, 0], [0, 0, 1]]})


def _index_thumb() -> dict[str, Any]:
    (l1, l2, l3), (r1, r2, r3) = _FINGERS["index"]
    frames = [
        _frame("index_aux", "base", d=20.0),
        _frame("index_mcp", "index_aux", alpha=90.0, a=10.0, joint="revolute", limits=_FLEX_LIMITS[0],
               default=10.0, link=_pill(l1, r1)),
        _frame("index_pip", "index_mcp", a=l1, joint="revolute", limits=_FLEX_LIMITS[1], default=-10.0,
               link=_pill(l2, r2)),
        _frame("index_dip", "index_pip", a=l2, joint="revolute", limits=_FLEX_LIMITS[2], default=-5.0,
               link=_pill(l3, r3, tip=True)),
        _frame("thumb_aux", "base", d=-30.0),
        _frame("thumb_cmc", "thumb_aux", alpha=-90.0, a=10.0, joint="revolute", limits=(-45.0, 20.0), default=5.0,
               link=_pill(42.0, 10.0)),
        _frame("thumb_mcp", "thumb_cmc", a=42.0, joint="revolute", limits=(-55.0, 10.0), default=-5.0,
               link=_pill(32.0, 9.0)),
        _frame("thumb_ip", "thumb_mcp", a=32.0, joint="revolute", limits=(-80.0, 15.0), default=-5.0,
               link=_pill(26.0, 8.5, tip=True)),
    ]
    return _spec("index_thumb", "Index finger and thumb, 3 DOF each, side view (thesis Table 2.3)", frames,
                 {"kind": "fixed", "rotation": [[1, 0, 0], [0, 0, -1], [0, 1, 0]]})


def _two_fingers() -> dict[str, Any]:
    frames = _finger("middle", abduct=False) + _finger("index", abduct=False)
    return _spec("two_fingers", "Middle and index fingers, 3 flexion DOF each, seen from the index side so "
                 "that the index occludes the middle finger (thesis Table 6.1)", frames,
                 {"kind": "fixed", "rotation": [[0, 0, -1], [0, -1, 0], [-1, 0, 0]]})


def _hand_frames() -> list[dict[str, Any]]:
    return _finger("little") + _finger("ring") + _finger("middle") + _finger("index") + _thumb5()


def _hand21() -> dict[str, Any]:
    return _spec("hand21", "Full hand, static wrist: 4 DOF per finger, 5 DOF thumb (thesis Table 6.2)",
                 _hand_frames(), {"kind": "fixed", "rotation": _UPRIGHT_HAND}, handedness="left")


def _hand27() -> dict[str, Any]:
    return _spec("hand27", "DigitEyes hand: the 21-DOF hand on a free palm (quaternion + translation, "
                 "27 DOF in 28 parameters)", _hand_frames(),
                 {"kind": "free", "default_quaternion": [0, 0, 0, 1], "default_translation_mm": [0, 0, 0],
                  "translation_limits_mm": [-500, 500]}, handedness="left")


def _mouse3d() -> dict[str, Any]:
    """DigitEyes §6.1: palm in the table plane (x, y, yaw), index 3 flexion DOF, ring and thumb abduct."""
    ring = _finger("ring", abduct=True, flex=(False, False, False))
    index = _finger("index", abduct=False)
    thumb = [
        _frame("thumb_aux", "base", a=25.0, theta=30.0),
        _frame("thumb_abd", "thumb_aux", joint="revolute", limits=(-30.0, 30.0), default=0.0, link=_pill(42.0, 10.0)),
        _frame("thumb_mcp", "thumb_abd", a=42.0, link=_pill(32.0, 9.0)),
        _frame("thumb_ip", "thumb_mcp", a=32.0, link=_pill(26.0, 8.5, tip=True)),
    ]
    return _spec("mouse3d", "DigitEyes 3D-mouse hand: planar palm (3 DOF), index (3 DOF), ring and thumb "
                 "abduction (1 DOF each); the table is the mount's x-y plane, z up", index + ring + thumb,
                 {"kind": "planar", "default": [0, 0, 0], "xy_limits_mm": [-300, 300], "yaw_limits_deg": [-180, 180]},
                 handedness="left")


def _planar(kind: str) -> Callable[[], dict[str, Any]]:
    """The planar chains of thesis §3.2 (lengths L1 = L2 = 5, image units)."""
    R = {"r": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "p": [[0, 0, 1], [0, 1, 0], [-1, 0, 0]],
         "pr": [[0, 0, 1], [1, 0, 0], [0, 1, 0]], "rr": [[0, -1, 0], [1, 0, 0], [0, 0, 1]]}[kind]
    rev = dict(joint="revolute", limits=(-720.0, 720.0), default=0.0)
    pri = dict(joint="prismatic", limits=(-100.0, 100.0), default=0.0)
    frames = {
        "r": [_frame("j1", "base", link=_pill(5.0, 0.5, tip=True), **rev)],
        "p": [_frame("j1", "base", link={"axis": "y", "length_mm": 5.0, "radius_mm": 0.5, "tip": True}, **pri)],
        "pr": [_frame("j1", "base", **pri), _frame("j2", "j1", alpha=-90.0, link=_pill(5.0, 0.5, tip=True), **rev)],
        "rr": [_frame("j1", "base", link=_pill(5.0, 0.5), **rev),
               _frame("j2", "j1", a=5.0, link=_pill(5.0, 0.5, tip=True), **rev)],
    }[kind]
    desc = f"Planar {kind.upper()} chain of thesis §3.2 (L = 5), mount = the rotation of its camera matrix"
    return lambda: _spec(f"planar_{kind}", desc, frames, {"kind": "fixed", "rotation": R})


class _Mirrored:
    """The file dictionary of the mirror image of a built-in (see :mod:`._mirror`), built when
    called; its description is known without building it."""

    def __init__(self, make: Callable[[], dict[str, Any]], description: str):
        self.make, self.description = make, description

    def __call__(self) -> dict[str, Any]:
        from ._file import model_to_dict
        from ._mirror import mirror_model

        d = model_to_dict(mirror_model(model_from_dict(self.make())))
        return {"format_version": d.pop("format_version"), "name": d.pop("name"), "description": self.description,
                **d}


_BUILTINS: dict[str, Callable[[], dict[str, Any]]] = {
    "index": _index, "index_thumb": _index_thumb, "two_fingers": _two_fingers, "hand21": _hand21,
    "hand21_right": _Mirrored(_hand21, "Right hand: the mirror image of hand21 (same joints, limits and signs)"),
    "hand27": _hand27,
    "hand27_right": _Mirrored(_hand27, "Right hand on a free palm: the mirror image of hand27 (palm quaternion "
                              "x, y and translation z change sign, see mirror_q)"),
    "mouse3d": _mouse3d,
    "planar_r": _planar("r"), "planar_p": _planar("p"), "planar_pr": _planar("pr"), "planar_rr": _planar("rr"),
}
BUILTIN_DESCRIPTIONS = {name: f.description if isinstance(f, _Mirrored) else f()["description"]
                        for name, f in _BUILTINS.items()}


def builtin_names() -> tuple[str, ...]:
    """Names accepted by :func:`builtin_model`."""
    return tuple(_BUILTINS)


def builtin_spec(name: str) -> dict[str, Any]:
    """The file-format dictionary of a built-in model (save it to start a model file of your own)."""
    if name not in _BUILTINS:
        raise InputError(f"unknown model {name!r}; built-in models: {', '.join(_BUILTINS)}")
    return _BUILTINS[name]()


def builtin_model(name: str) -> Model:
    """A built-in model by name; see :func:`builtin_names`."""
    return model_from_dict(builtin_spec(name), source=f"builtin:{name}")
