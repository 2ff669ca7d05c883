"""Reading model files: the file-format dictionary (degrees, mm) validated into a :class:`Model`.

The format is described in :mod:`jaxhand.model._file`; every error names the source, the frame
and the field.
"""


from __future__ import annotations

import difflib
import math
from typing import Any

import numpy as np

from .._errors import ModelFileError
from ._model import AXES, BASE_KINDS, BASE_Q_NAMES, HANDEDNESS, JOINT_KINDS, Model

__all__ = ["model_from_dict", "quaternion_to_matrix", "FORMAT_VERSION"]

FORMAT_VERSION = 2
_VERSIONS = (1, 2)
_TOP_KEYS = {"format_version", "name", "description", "base", "frames", "handedness", "occluders"}
_FRAME_KEYS = {"name", "parent", "alpha_deg", "a_mm", "d_mm", "theta_deg", "joint", "limits", "default", "link",
               "pre_transform"}
_LINK_KEYS = {"name", "axis", "length_mm", "radius_mm", "tip"}
_PRE_KEYS = {"rotation", "quaternion", "translation_mm"}
_OCCLUDER_KEYS = {"name", "frame", "start_mm", "end_mm", "radius_mm"}
#: Keys that need format version 2, by place.
_V2_KEYS = {"top level": {"handedness", "occluders"}, "frame": {"pre_transform"}, "link": {"name"}}
_BASE_KEYS = {
    "fixed": {"kind", "rotation", "translation_mm"},
    "free": {"kind", "rotation", "translation_mm", "default_quaternion", "default_translation_mm",
             "translation_limits_mm"},
    "planar": {"kind", "rotation", "translation_mm", "default", "xy_limits_mm", "yaw_limits_deg"},
}


def _fail(src: str, where: str, msg: str) -> ModelFileError:
    return ModelFileError(f"{src}: {where}: {msg}")


def _check_keys(src: str, where: str, got: dict, allowed: set[str]) -> None:
    for key in got:
        if key not in allowed:
            hint = difflib.get_close_matches(key, sorted(allowed), n=1)
            extra = f" (did you mean {hint[0]!r}?)" if hint else f" (valid: {', '.join(sorted(allowed))})"
            raise _fail(src, where, f"unknown field {key!r}{extra}")


def _number(src: str, where: str, d: dict, key: str, default: float | None = None) -> float:
    if key not in d:
        if default is None:
            raise _fail(src, where, f"missing field {key!r}")
        return default
    v = d[key]
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise _fail(src, where, f"field {key!r} must be a finite number, got {v!r}")
    return float(v)


def _pair(src: str, where: str, d: dict, key: str, default: tuple[float, float]) -> tuple[float, float]:
    v = d.get(key, list(default))
    if (not isinstance(v, (list, tuple)) or len(v) != 2
            or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v)):
        raise _fail(src, where, f"field {key!r} must be [min, max], got {v!r}")
    lo, hi = float(v[0]), float(v[1])
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise _fail(src, where, f"field {key!r} must be finite, got {v!r} (a joint that turns freely: give "
                                "[-180, 180] deg)")
    if lo > hi:
        raise _fail(src, where, f"field {key!r}: limit min {lo} > max {hi}")
    return lo, hi


def _vector(src: str, where: str, d: dict, key: str, default: list[float]) -> np.ndarray:
    v = np.asarray(d.get(key, default), dtype=float)
    if v.shape != (len(default),) or not np.all(np.isfinite(v)):
        raise _fail(src, where, f"field {key!r} must be {len(default)} finite numbers, got {d.get(key)!r}")
    return v


def _rotation(src: str, base: dict, where: str = "base") -> np.ndarray:
    try:
        R = np.asarray(base.get("rotation", np.eye(3).tolist()), dtype=float)
    except (TypeError, ValueError):
        R = np.zeros(0)
    if R.shape != (3, 3) or not np.all(np.isfinite(R)):
        raise _fail(src, where, f"field 'rotation' must be a 3x3 matrix, got {base.get('rotation')!r}")
    if not np.allclose(R @ R.T, np.eye(3), atol=1e-9) or np.linalg.det(R) < 0:
        raise _fail(src, where, "field 'rotation' is not a proper rotation matrix (R R^T = I, det R = +1)")
    return R


def quaternion_to_matrix(quat) -> np.ndarray:
    """Rotation matrix of a unit quaternion (w, x, y, z), NumPy (MJCF's convention)."""
    w, x, y, z = (float(v) for v in quat)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def _pre_transform(src: str, where: str, pre: Any) -> np.ndarray:
    pw = f"{where} pre_transform"
    if not isinstance(pre, dict):
        raise _fail(src, pw, "expected a table/object")
    _check_keys(src, pw, pre, _PRE_KEYS)
    if "rotation" in pre and "quaternion" in pre:
        raise _fail(src, pw, "give either 'rotation' or 'quaternion', not both")
    T = np.eye(4)
    if "quaternion" in pre:
        quat = _vector(src, pw, pre, "quaternion", [1.0, 0.0, 0.0, 0.0])
        n = np.linalg.norm(quat)
        if abs(n - 1.0) > 1e-3:  # allows written-out values such as 0.7071068; normalised below
            raise _fail(src, pw, f"field 'quaternion' must have unit length (w, x, y, z), got norm {n:.9g}")
        T[:3, :3] = quaternion_to_matrix(quat / n)
    else:
        T[:3, :3] = _rotation(src, pre, pw)
    T[:3, 3] = _vector(src, pw, pre, "translation_mm", [0.0, 0.0, 0.0])
    return T


def _check_version(src: str, version: int, where: str, place: str, d: dict) -> None:
    if version < 2:
        for key in _V2_KEYS[place]:
            if key in d:
                raise _fail(src, where, f"field {key!r} needs format_version 2")


def model_from_dict(spec: dict[str, Any], source: str = "<dict>") -> Model:
    """Build and validate a :class:`Model` from a file-format dictionary (degrees, mm).

    Raises:
        ModelFileError: naming ``source``, the frame and the field for every malformed entry.
    """
    src = source
    if not isinstance(spec, dict):
        raise _fail(src, "top level", "expected a table/object")
    _check_keys(src, "top level", spec, _TOP_KEYS)
    version = spec.get("format_version")
    if isinstance(version, bool) or version not in _VERSIONS:
        raise _fail(src, "top level", f"field 'format_version' must be one of {_VERSIONS}, got {version!r}")
    _check_version(src, version, "top level", "top level", spec)
    name = spec.get("name")
    if not isinstance(name, str) or not name:
        raise _fail(src, "top level", f"field 'name' must be a non-empty string, got {name!r}")
    handedness = spec.get("handedness", "none")
    if handedness not in HANDEDNESS:
        raise _fail(src, "top level", f"field 'handedness' must be one of {', '.join(HANDEDNESS)}, got {handedness!r}")

    base = spec.get("base", {"kind": "fixed"})
    if not isinstance(base, dict):
        raise _fail(src, "base", "expected a table/object")
    kind = base.get("kind", "fixed")
    if kind not in BASE_KINDS:
        raise _fail(src, "base", f"field 'kind': unknown base kind {kind!r} (valid: {', '.join(BASE_KINDS)})")
    _check_keys(src, "base", base, _BASE_KEYS[kind])
    mount = np.eye(4)
    mount[:3, :3] = _rotation(src, base)
    mount[:3, 3] = _vector(src, "base", base, "translation_mm", [0.0, 0.0, 0.0])

    lower, upper, default = [], [], []
    if kind == "free":
        quat = _vector(src, "base", base, "default_quaternion", [1.0, 0.0, 0.0, 0.0])
        if np.linalg.norm(quat) < 1e-9:
            raise _fail(src, "base", "field 'default_quaternion' must not be zero")
        quat = quat / np.linalg.norm(quat)
        lo, hi = _pair(src, "base", base, "translation_limits_mm", (-1000.0, 1000.0))
        trans = _vector(src, "base", base, "default_translation_mm", [0.0, 0.0, 0.0])
        lower += [-1.0] * 4 + [lo] * 3
        upper += [1.0] * 4 + [hi] * 3
        default += list(quat) + list(trans)
    elif kind == "planar":
        lo, hi = _pair(src, "base", base, "xy_limits_mm", (-1000.0, 1000.0))
        ylo, yhi = _pair(src, "base", base, "yaw_limits_deg", (-180.0, 180.0))
        x, y, yaw = _vector(src, "base", base, "default", [0.0, 0.0, 0.0])
        lower += [lo, lo, math.radians(ylo)]
        upper += [hi, hi, math.radians(yhi)]
        default += [x, y, math.radians(yaw)]

    frames = spec.get("frames")
    if not isinstance(frames, list) or not frames:
        raise _fail(src, "top level", "field 'frames' must be a non-empty list of frame tables")
    names: list[str] = []
    for i, fr in enumerate(frames):
        if not isinstance(fr, dict):
            raise _fail(src, f"frame #{i}", "expected a table/object")
        fname = fr.get("name")
        if not isinstance(fname, str) or not fname:
            raise _fail(src, f"frame #{i}", f"field 'name' must be a non-empty string, got {fname!r}")
        if fname in names or fname == "base":
            raise _fail(src, f"frame {fname!r}", "duplicate frame name" if fname != "base" else "'base' is reserved")
        names.append(fname)

    parents, kinds, q_index, dh = [], [], [], []
    q_names = list(BASE_Q_NAMES[kind])
    link_names, link_frame, link_axis, link_len, link_rad, tips = [], [], [], [], [], []
    pre_frames, pre = [], []
    for i, fr in enumerate(frames):
        where = f"frame {names[i]!r}"
        _check_keys(src, where, fr, _FRAME_KEYS)
        _check_version(src, version, where, "frame", fr)
        if "pre_transform" in fr:
            pre_frames.append(i)
            pre.append(_pre_transform(src, where, fr["pre_transform"]))
        parent = fr.get("parent", "base")
        if parent == "base":
            parents.append(-1)
        elif parent in names:
            parents.append(names.index(parent))
        else:
            raise _fail(src, where, f"field 'parent': parent {parent!r} is not defined")
        jk = fr.get("joint", "fixed")
        if jk not in JOINT_KINDS:
            raise _fail(src, where, f"field 'joint': unknown joint kind {jk!r} (valid: {', '.join(JOINT_KINDS)})")
        kinds.append(jk)
        row = [math.radians(_number(src, where, fr, "alpha_deg")), _number(src, where, fr, "a_mm"),
               _number(src, where, fr, "d_mm"), math.radians(_number(src, where, fr, "theta_deg"))]
        dh.append(row)
        if jk == "fixed":
            for key in ("limits", "default"):
                if key in fr:
                    raise _fail(src, where, f"field {key!r} is only allowed on a moving joint")
            q_index.append(-1)
        else:
            unit = math.radians if jk == "revolute" else float
            lo, hi = _pair(src, where, fr, "limits", (-180.0, 180.0) if jk == "revolute" else (-1000.0, 1000.0))
            dflt = _number(src, where, fr, "default", min(max(0.0, lo), hi))
            if not lo <= dflt <= hi:
                raise _fail(src, where, f"field 'default': {dflt} lies outside limits [{lo}, {hi}]")
            q_index.append(len(q_names))
            q_names.append(names[i])
            lower.append(unit(lo))
            upper.append(unit(hi))
            default.append(unit(dflt))
        link = fr.get("link")
        if link is not None:
            lw = f"{where} link"
            if not isinstance(link, dict):
                raise _fail(src, lw, "expected a table/object")
            _check_keys(src, lw, link, _LINK_KEYS)
            _check_version(src, version, lw, "link", link)
            lname = link.get("name", names[i])
            if not isinstance(lname, str) or not lname:
                raise _fail(src, lw, f"field 'name' must be a non-empty string, got {lname!r}")
            if lname in link_names:
                raise _fail(src, lw, f"field 'name': duplicate link name {lname!r}")
            axis = link.get("axis", "x")
            if axis not in AXES:
                raise _fail(src, lw, f"field 'axis': unknown axis {axis!r} (valid: x, y, z)")
            length = _number(src, lw, link, "length_mm")
            radius = _number(src, lw, link, "radius_mm")
            if length < 0:
                raise _fail(src, lw, f"field 'length_mm' must be >= 0, got {length}")
            if radius < 0:
                raise _fail(src, lw, f"field 'radius_mm': negative radius {radius}")
            tip = link.get("tip", False)
            if not isinstance(tip, bool):
                raise _fail(src, lw, f"field 'tip' must be true or false, got {tip!r}")
            if tip:
                tips.append(len(link_names))
            link_names.append(lname)
            link_frame.append(i)
            link_axis.append(AXES.index(axis))
            link_len.append(length)
            link_rad.append(radius)

    _check_acyclic(src, names, parents)
    occ = _occluders(src, spec.get("occluders", []), names, link_names)
    return Model(
        name=name, frame_names=tuple(names), parents=tuple(parents), joint_kinds=tuple(kinds),
        q_index=tuple(q_index), base_kind=kind, q_names=tuple(q_names), link_names=tuple(link_names),
        link_frame=tuple(link_frame), link_axis=tuple(link_axis), tip_links=tuple(tips),
        dh=np.array(dh, dtype=float), T_world_mount=mount, q_lower=np.array(lower, dtype=float),
        q_upper=np.array(upper, dtype=float), q_default=np.array(default, dtype=float),
        link_length_mm=np.array(link_len, dtype=float).reshape(-1),
        link_radius_mm=np.array(link_rad, dtype=float).reshape(-1),
        pre_transform_frames=tuple(pre_frames), T_pre_transform=np.array(pre, dtype=float).reshape(-1, 4, 4),
        occluder_names=tuple(o[0] for o in occ), occluder_frame=tuple(o[1] for o in occ),
        occluder_start_mm=np.array([o[2] for o in occ], dtype=float).reshape(-1, 3),
        occluder_end_mm=np.array([o[3] for o in occ], dtype=float).reshape(-1, 3),
        occluder_radius_mm=np.array([o[4] for o in occ], dtype=float).reshape(-1), handedness=handedness,
    )


def _occluders(src: str, items: Any, names: list[str], link_names: list[str]) -> list[tuple]:
    if not isinstance(items, list):
        raise _fail(src, "top level", "field 'occluders' must be a list of occluder tables")
    out: list[tuple] = []
    for k, oc in enumerate(items):
        if not isinstance(oc, dict):
            raise _fail(src, f"occluder #{k}", "expected a table/object")
        oname = oc.get("name")
        if not isinstance(oname, str) or not oname:
            raise _fail(src, f"occluder #{k}", f"field 'name' must be a non-empty string, got {oname!r}")
        where = f"occluder {oname!r}"
        _check_keys(src, where, oc, _OCCLUDER_KEYS)
        if oname in link_names or any(o[0] == oname for o in out):
            raise _fail(src, where, f"field 'name': duplicate pill name {oname!r} (links and occluders share names)")
        frame = oc.get("frame")
        if frame not in names:
            hint = difflib.get_close_matches(str(frame), names, n=1)
            extra = f" (did you mean {hint[0]!r}?)" if hint else ""
            raise _fail(src, where, f"field 'frame': frame {frame!r} is not defined{extra}")
        radius = _number(src, where, oc, "radius_mm")
        if radius < 0:
            raise _fail(src, where, f"field 'radius_mm': negative radius {radius}")
        for key in ("start_mm", "end_mm"):
            if key not in oc:
                raise _fail(src, where, f"missing field {key!r}")
        out.append((oname, names.index(frame), _vector(src, where, oc, "start_mm", [0.0] * 3),
                    _vector(src, where, oc, "end_mm", [0.0] * 3), radius))
    return out


def _check_acyclic(src: str, names: list[str], parents: list[int]) -> None:
    for i in range(len(names)):
        seen, j = set(), i
        while j >= 0:
            if j in seen:
                raise _fail(src, f"frame {names[i]!r}", "field 'parent': the parent chain is cyclic")
            seen.add(j)
            j = parents[j]
    # Kinematics composes parents before children: require a topological frame order.
    for i, p in enumerate(parents):
        if p > i:
            raise _fail(src, f"frame {names[i]!r}",
                        f"field 'parent': parent {names[p]!r} must be listed before its child")
