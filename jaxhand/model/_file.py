"""Model files: a TOML or JSON description of a kinematic tree, validated on load.

Format (version 1); lengths in mm, angles in degrees::

    format_version = 1
    name = "index"
    description = "..."                      # optional

    [base]
    kind = "fixed"                           # fixed | free | planar
    rotation = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]   # R_world_mount (rows), optional
    translation_mm = [0, 0, 0]               # optional
    # free:   default_quaternion = [1,0,0,0], default_translation_mm, translation_limits_mm = [lo, hi]
    # planar: default = [x_mm, y_mm, yaw_deg], xy_limits_mm = [lo, hi], yaw_limits_deg = [lo, hi]

    [[frames]]
    name = "index_mcp"
    parent = "base"                          # "base" or an earlier/later frame's name
    alpha_deg = 0.0                          # alpha_{i-1}
    a_mm = 0.0                               # a_{i-1}
    d_mm = 0.0                               # d_i (offset for a prismatic joint)
    theta_deg = 0.0                          # theta_i (offset for a revolute joint)
    joint = "revolute"                       # revolute | prismatic | fixed
    limits = [-45.0, 90.0]                   # deg (revolute) or mm (prismatic)
    default = 10.0                           # deg or mm, inside limits
    link = { axis = "x", length_mm = 40.0, radius_mm = 9.0, tip = false }   # optional pill

Version 2 adds (version 1 files load unchanged)::

    handedness = "right"                     # right | left | none (default)

    [[frames]]
    ...
    link = { name = "index_proximal", axis = "x", ... }      # a link name (default: the frame's)
    # A fixed transform before the DH transform: T_parent_frame = T_pre @ DH. The rotation is a
    # 3x3 matrix (rows) or a unit quaternion (w, x, y, z); both default to the identity.
    pre_transform = { rotation = [[1, 0, 0], [0, 1, 0], [0, 0, 1]], translation_mm = [0, 0, 0] }
    # pre_transform = { quaternion = [1, 0, 0, 0], translation_mm = [22, 15, 6] }

    [[occluders]]                            # occluder-only pills: no link or tip features
    name = "palm_middle"
    frame = "palm"                           # the frame it is attached to
    start_mm = [5.5, 12, 0]                  # segment ends in that frame's coordinates
    end_mm = [9.35, 91, 0]
    radius_mm = 12.19

Numbers are written so that loading a saved model gives back the same floats: a length or
matrix entry as is (shortened to 9 decimals only where that is exact), an angle as the degree
value that converts back to the same radians (one exists for all but about one angle in ten; the
others come back within one unit in the last place).

Every validation error names the source, the frame and the field.
"""

from __future__ import annotations

import json
import math
import tomllib
from pathlib import Path
from typing import Any

import numpy as np
from jaxtyping import ArrayLike

from .._errors import ModelFileError
from ._model import AXES, Model
from ._spec import FORMAT_VERSION, model_from_dict

__all__ = ["model_from_dict", "model_to_dict", "load_model", "save_model", "FORMAT_VERSION"]


def _short(x: float) -> float | int:
    r = round(x, 9)
    return int(r) if r == int(r) and abs(r) < 1e15 else r


def _clean(x: ArrayLike) -> float | int:
    """A length or matrix entry for a file: shortened to 9 decimals where that is exact."""
    x = float(x)
    r = _short(x)
    return r if float(r) == x else x


def _deg(x: ArrayLike) -> float | int:
    """Degrees for a file whose ``math.radians`` gives back exactly ``x`` (rad) where such a value
    exists: the 9-decimal rounding, else ``math.degrees(x)`` or one of its 8 float neighbours."""
    x = float(x)
    d = math.degrees(x)
    r = _short(d)
    if math.radians(r) == x:
        return r
    lo = hi = d
    candidates = [d]
    for _ in range(4):
        lo, hi = float(np.nextafter(lo, -math.inf)), float(np.nextafter(hi, math.inf))
        candidates += [lo, hi]
    return next((c for c in candidates if math.radians(c) == x), d)


def model_to_dict(model: Model) -> dict[str, Any]:
    """The file-format dictionary of ``model`` (inverse of :func:`model_from_dict`)."""
    dh = np.asarray(model.dh)
    lo, hi, q0 = (np.asarray(a) for a in (model.q_lower, model.q_upper, model.q_default))
    mount = np.asarray(model.T_world_mount)
    base: dict[str, Any] = {"kind": model.base_kind,
                            "rotation": [[_clean(v) for v in row] for row in mount[:3, :3]],
                            "translation_mm": [_clean(v) for v in mount[:3, 3]]}
    if model.base_kind == "free":
        base["default_quaternion"] = [_clean(v) for v in q0[:4]]
        base["default_translation_mm"] = [_clean(v) for v in q0[4:7]]
        base["translation_limits_mm"] = [_clean(lo[4]), _clean(hi[4])]
    elif model.base_kind == "planar":
        base["default"] = [_clean(q0[0]), _clean(q0[1]), _deg(q0[2])]
        base["xy_limits_mm"] = [_clean(lo[0]), _clean(hi[0])]
        base["yaw_limits_deg"] = [_deg(lo[2]), _deg(hi[2])]
    frames = []
    link_of = {f: k for k, f in enumerate(model.link_frame)}
    pre_of = {f: k for k, f in enumerate(model.pre_transform_frames)}
    pre = np.asarray(model.T_pre_transform)
    for i, name in enumerate(model.frame_names):
        p = model.parents[i]
        fr: dict[str, Any] = {
            "name": name, "parent": "base" if p < 0 else model.frame_names[p],
            "alpha_deg": _deg(dh[i, 0]), "a_mm": _clean(dh[i, 1]),
            "d_mm": _clean(dh[i, 2]), "theta_deg": _deg(dh[i, 3]),
            "joint": model.joint_kinds[i],
        }
        j = model.q_index[i]
        if j >= 0:
            conv = _deg if model.joint_kinds[i] == "revolute" else _clean
            fr["limits"] = [conv(lo[j]), conv(hi[j])]
            fr["default"] = conv(q0[j])
        if i in link_of:
            k = link_of[i]
            link = {"axis": AXES[model.link_axis[k]], "length_mm": _clean(model.link_length_mm[k]),
                    "radius_mm": _clean(model.link_radius_mm[k]), "tip": k in model.tip_links}
            fr["link"] = link if model.link_names[k] == name else {"name": model.link_names[k], **link}
        if i in pre_of:
            T = pre[pre_of[i]]
            fr["pre_transform"] = {"rotation": [[_clean(v) for v in row] for row in T[:3, :3]],
                                   "translation_mm": [_clean(v) for v in T[:3, 3]]}
        frames.append(fr)
    d: dict[str, Any] = {"format_version": FORMAT_VERSION, "name": model.name}
    if model.handedness != "none":
        d["handedness"] = model.handedness
    d["base"], d["frames"] = base, frames
    if model.n_occluders:
        s0, s1, rad = (np.asarray(a) for a in (model.occluder_start_mm, model.occluder_end_mm,
                                                model.occluder_radius_mm))
        d["occluders"] = [{"name": n, "frame": model.frame_names[model.occluder_frame[k]],
                           "start_mm": [_clean(v) for v in s0[k]], "end_mm": [_clean(v) for v in s1[k]],
                           "radius_mm": _clean(rad[k])} for k, n in enumerate(model.occluder_names)]
    return d


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{k} = {_toml_value(x)}" for k, x in v.items()) + " }"
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


def _to_toml(d: dict[str, Any]) -> str:
    lines = [f"{k} = {_toml_value(v)}" for k, v in d.items() if k not in ("base", "frames", "occluders")]
    lines += ["", "[base]"] + [f"{k} = {_toml_value(v)}" for k, v in d["base"].items()]
    for fr in d["frames"]:
        lines += ["", "[[frames]]"] + [f"{k} = {_toml_value(v)}" for k, v in fr.items()]
    for oc in d.get("occluders", []):
        lines += ["", "[[occluders]]"] + [f"{k} = {_toml_value(v)}" for k, v in oc.items()]
    return "\n".join(lines) + "\n"


def load_model(path: str | Path) -> Model:
    """Load a model from a ``.toml`` or ``.json`` model file, or import an MJCF ``.xml`` or a
    ``.urdf`` with the defaults of :func:`load_mjcf` / :func:`load_urdf`.

    Raises:
        ModelFileError: unreadable, unparsable or invalid file; the message names the file.
    """
    path = Path(path)
    if path.suffix == ".xml":
        from ._mjcf import load_mjcf

        return load_mjcf(path)
    if path.suffix == ".urdf":
        from ._urdf import load_urdf

        return load_urdf(path)
    if path.suffix not in (".json", ".toml"):
        raise ModelFileError(f"{path}: unknown model file type {path.suffix!r} (use .toml, .json, MJCF .xml or .urdf)")
    try:
        text = path.read_text()
    except OSError as err:
        raise ModelFileError(f"{path}: cannot read model file ({err.strerror})") from err
    try:
        spec = json.loads(text) if path.suffix == ".json" else tomllib.loads(text)
    except (json.JSONDecodeError, tomllib.TOMLDecodeError) as err:
        raise ModelFileError(f"{path}: cannot parse: {err}") from err
    return model_from_dict(spec, source=str(path))


def save_model(model: Model, path: str | Path) -> Path:
    """Write ``model`` as ``.toml`` or ``.json`` (by suffix); load_model reads it back."""
    path = Path(path)
    d = model_to_dict(model)
    if path.suffix == ".json":
        path.write_text(json.dumps(d, indent=2) + "\n")
    elif path.suffix == ".toml":
        path.write_text(_to_toml(d))
    else:
        raise ModelFileError(f"{path}: unknown model file type {path.suffix!r} (use .toml or .json)")
    return path
