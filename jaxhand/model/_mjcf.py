"""MJCF (MuJoCo XML) import: bodies, hinge and slide joints, capsule geoms -> a Model.

Supported: nested ``<body>`` with ``pos`` and an orientation (``quat`` w x y z, ``axisangle``,
``euler`` with ``<compiler eulerseq>``, ``xyaxes``, ``zaxis``); any number of ``hinge`` or
``slide`` joints per body, composed in the order listed (each about its ``axis`` through its
``pos``, with ``range`` and ``ref``); ``<freejoint/>`` (or ``type="free"``) on a top-level body,
which gives the model a free base; capsule and cylinder geoms by ``fromto`` or by
``size`` + ``pos`` + orientation (both become pills: the tracker's pills are capsules), and
spheres (zero-length occluder pills); ``<default>`` classes with ``class`` and ``childclass``;
``<compiler angle=... eulerseq=... autolimits=...>`` (MuJoCo's defaults: degrees, "xyz",
autolimits on).

Ignored: geoms directly in ``<worldbody>`` (the scene: floors, backgrounds), geom types other
than capsule, cylinder and sphere (planes, boxes, meshes), sites, cameras, lights, assets,
actuators. Rejected with an error: ball joints, ``<include>``, ``<frame>``, ``<replicate>`` and
``<attach>``, and a free joint below the top level.

Mapping (see :mod:`._tree`): every joint is a frame named after the joint (so ``q_names`` are
the MJCF joint names, in document order), every joint-less body a fixed frame named after the
body. By default the geoms of bodies with joints are links named after the geom (a link is a tip
when no body below it has links), and the geoms of joint-less bodies (a static palm and
forearm) are occluder-only pills; ``occluders=`` names the geoms to make occluders instead.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from .._errors import ModelFileError
from ._model import HANDEDNESS, Model
from ._spec import quaternion_to_matrix
from ._tree import Joint, Pill, TreeBuilder, _rot, _trans, _unit

__all__ = ["load_mjcf"]

_UNSUPPORTED = ("include", "frame", "replicate", "attach")


class _Ctx:
    def __init__(self, src: str, root: ET.Element, length_scale: float):
        self.src = src
        self.scale = length_scale
        comp = root.find("compiler")
        attrs = comp.attrib if comp is not None else {}
        self.degrees = attrs.get("angle", "degree") == "degree"
        self.eulerseq = attrs.get("eulerseq", "xyz")
        self.autolimits = attrs.get("autolimits", "true") == "true"
        self.defaults: dict[str, dict[str, dict[str, str]]] = {}
        for d in root.findall("default"):
            self._read_default(d, "main", {})

    def _read_default(self, el: ET.Element, cls: str, inherited: dict[str, dict[str, str]]) -> None:
        own = {tag: dict(attrs) for tag, attrs in inherited.items()}
        for child in el:
            if child.tag != "default":
                own.setdefault(child.tag, {}).update(child.attrib)
        self.defaults[cls] = own
        for child in el.findall("default"):
            self._read_default(child, child.get("class", cls), own)

    def attrs(self, el: ET.Element, childclass: str) -> dict[str, str]:
        cls = el.get("class", childclass)
        if cls not in self.defaults and cls != "main":
            raise self.fail(el, f"unknown default class {cls!r}")
        out = dict(self.defaults.get(cls, {}).get(el.tag, {}))
        out.update(el.attrib)
        return out

    def fail(self, el: ET.Element, msg: str) -> ModelFileError:
        name = el.get("name")
        return ModelFileError(f"{self.src}: <{el.tag}{f' name={name!r}' if name else ''}>: {msg}")

    def vec(self, el: ET.Element, a: dict[str, str], key: str, n: int, default=None) -> np.ndarray | None:
        if key not in a:
            return None if default is None else np.asarray(default, float)
        try:
            v = np.array([float(x) for x in a[key].split()])
        except ValueError as err:
            raise self.fail(el, f"attribute {key!r} must be numbers, got {a[key]!r}") from err
        if v.shape != (n,) or not np.all(np.isfinite(v)):
            raise self.fail(el, f"attribute {key!r} must be {n} finite numbers, got {a[key]!r}")
        return v

    def angle(self, x: float) -> float:
        return math.radians(x) if self.degrees else x

    def orientation(self, el: ET.Element, a: dict[str, str]) -> np.ndarray:
        """R_parent_el from whichever orientation attribute is given (identity if none)."""
        given = [k for k in ("quat", "axisangle", "euler", "xyaxes", "zaxis") if k in a]
        if len(given) > 1:
            raise self.fail(el, f"more than one orientation given: {', '.join(given)}")
        if not given:
            return np.eye(3)
        key = given[0]
        if key == "quat":
            q = self.vec(el, a, "quat", 4)
            if np.linalg.norm(q) < 1e-12:
                raise self.fail(el, "attribute 'quat' must not be zero")
            return quaternion_to_matrix(q / np.linalg.norm(q))
        if key == "axisangle":
            v = self.vec(el, a, "axisangle", 4)
            return _axis_angle(v[:3], self.angle(v[3]))
        if key == "euler":
            v = self.vec(el, a, "euler", 3)
            if len(self.eulerseq) != 3 or any(c not in "xyzXYZ" for c in self.eulerseq):
                raise self.fail(el, f"unsupported compiler eulerseq {self.eulerseq!r}")
            R = np.eye(3)
            for c, ang in zip(self.eulerseq, v):
                Ri = _axis_angle(np.eye(3)["xyz".index(c.lower())], self.angle(ang))
                R = R @ Ri if c.islower() else Ri @ R  # lower case: axes move with the frame
            return R
        if key == "xyaxes":
            v = self.vec(el, a, "xyaxes", 6)
            x = _unit(v[:3])
            y = _unit(v[3:] - (v[3:] @ x) * x)
            return np.stack([x, y, np.cross(x, y)], axis=1)
        z = _unit(self.vec(el, a, "zaxis", 3))
        c = float(z[2])
        axis = np.cross([0.0, 0.0, 1.0], z)
        if np.linalg.norm(axis) < 1e-12:
            return np.eye(3) if c > 0 else _axis_angle([1.0, 0.0, 0.0], math.pi)
        return _axis_angle(axis, math.atan2(np.linalg.norm(axis), c))

    def pose(self, el: ET.Element, a: dict[str, str]) -> np.ndarray:
        return _trans(self.vec(el, a, "pos", 3, [0.0, 0.0, 0.0]) * self.scale) @ _rot(self.orientation(el, a))


def _axis_angle(axis, angle: float) -> np.ndarray:
    k = _unit(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * (K @ K)


def load_mjcf(path: str | Path, *, name: str | None = None, handedness: str = "none",
              occluders: list[str] | tuple[str, ...] | None = None, length_scale_mm: float = 1.0) -> Model:
    """Import an MJCF model (see the module docstring for what is supported and the mapping).

    Args:
        path: the ``.xml`` file.
        name: the model's name (default: ``<mujoco model=...>``, else the file stem).
        handedness: "right", "left" or "none" (MJCF does not say).
        occluders: geom names to import as occluder-only pills; None: the geoms of joint-less bodies.
        length_scale_mm: millimetres per MJCF length unit (1 for files in mm, 1000 for metres).

    Raises:
        ModelFileError: unreadable or unparsable file, or an unsupported element; the message
            names the file and the element.
    """
    path = Path(path)
    src = str(path)
    try:
        root = ET.parse(path).getroot()
    except OSError as err:
        raise ModelFileError(f"{src}: cannot read MJCF file ({err.strerror})") from err
    except ET.ParseError as err:
        raise ModelFileError(f"{src}: cannot parse: {err}") from err
    if root.tag != "mujoco":
        raise ModelFileError(f"{src}: not an MJCF file (root element <{root.tag}>, expected <mujoco>)")
    for tag in _UNSUPPORTED:
        el = root.find(f".//{tag}")
        if el is not None:
            raise ModelFileError(f"{src}: <{tag}> is not supported by jaxhand's MJCF import")
    if handedness not in HANDEDNESS:
        raise ModelFileError(f"{src}: handedness must be one of {', '.join(HANDEDNESS)}, got {handedness!r}")
    ctx = _Ctx(src, root, float(length_scale_mm))
    world = root.find("worldbody")
    if world is None or world.find("body") is None:
        raise ModelFileError(f"{src}: <worldbody> has no <body>")
    builder = TreeBuilder(name=name or root.get("model") or path.stem, handedness=handedness)
    occ = None if occluders is None else set(occluders)
    tops = world.findall("body")
    counter = {"body": 0}
    for top in tops:
        _body(ctx, builder, top, "base", np.eye(4), "main", occ, counter, top_level=len(tops) == 1)
    builder.mark_tips()
    return builder.model(src)


def _body(ctx: _Ctx, b: TreeBuilder, el: ET.Element, parent: str, T_pending: np.ndarray, childclass: str,
          occ: set[str] | None, counter: dict[str, int], top_level: bool = False) -> None:
    a = ctx.attrs(el, childclass)
    counter["body"] += 1
    bname = el.get("name") or f"body{counter['body']}"
    cc = el.get("childclass", childclass)
    T = T_pending @ ctx.pose(el, a)
    joints: list[Joint] = []
    free = el.find("freejoint") is not None
    for k, j in enumerate(el.findall("joint")):
        ja = ctx.attrs(j, cc)
        kind = ja.get("type", "hinge")
        jname = j.get("name") or f"{bname}_joint{k}"
        if kind == "free":
            free = True
            continue
        if kind not in ("hinge", "slide"):
            raise ctx.fail(j, f"joint type {kind!r} is not supported (hinge, slide or free)")
        axis = ctx.vec(j, ja, "axis", 3, [0.0, 0.0, 1.0])
        if np.linalg.norm(axis) < 1e-12:
            raise ctx.fail(j, "attribute 'axis' must not be zero")
        limited = ja.get("limited", "auto")
        rng = ctx.vec(j, ja, "range", 2)
        has_limits = rng is not None and (limited == "true" or (limited == "auto" and ctx.autolimits))
        conv = ctx.angle if kind == "hinge" else (lambda x: x * ctx.scale)
        if has_limits:
            lo, hi = conv(float(rng[0])), conv(float(rng[1]))
            if lo > hi:
                raise ctx.fail(j, f"attribute 'range': min {rng[0]} > max {rng[1]}")
        else:
            lo, hi = (-math.pi, math.pi) if kind == "hinge" else (-1000.0, 1000.0)
        joints.append(Joint(name=jname, kind="revolute" if kind == "hinge" else "prismatic", axis=axis,
                            pos=ctx.vec(j, ja, "pos", 3, [0.0, 0.0, 0.0]) * ctx.scale, limits=(lo, hi),
                            ref=conv(float(ja.get("ref", "0")))))
    if free:
        if not top_level or parent != "base" or joints:
            raise ctx.fail(el, "a free joint is only supported on the only top-level body, without other joints")
        R, t = T[:3, :3], T[:3, 3]
        b.base = {"kind": "free", "default_quaternion": list(_matrix_to_quaternion(R)),
                  "default_translation_mm": [float(v) for v in t], "translation_limits_mm": [-1000.0, 1000.0]}
        T = np.eye(4)
    pills = []
    for k, g in enumerate(el.findall("geom")):
        pill = _geom(ctx, g, cc, bname, k)
        if pill is not None:
            pill.link = bool(joints) if occ is None else pill.name not in occ
            pills.append(pill)
    frame, T_frame_body = b.add_body(bname, parent, T, joints, pills)
    for child in el.findall("body"):
        _body(ctx, b, child, frame, T_frame_body, cc, occ, counter)


def _geom(ctx: _Ctx, g: ET.Element, childclass: str, body: str, k: int) -> Pill | None:
    ga = ctx.attrs(g, childclass)
    kind = ga.get("type", "sphere")
    if kind not in ("capsule", "cylinder", "sphere"):
        return None
    gname = g.get("name") or f"{body}_geom{k}"
    size = [float(x) for x in ga.get("size", "0").split()]
    radius = size[0] * ctx.scale
    fromto = ctx.vec(g, ga, "fromto", 6)
    if kind == "sphere":
        p = ctx.vec(g, ga, "pos", 3, [0.0, 0.0, 0.0]) * ctx.scale
        return Pill(gname, p, p.copy(), radius)
    if fromto is not None:
        return Pill(gname, fromto[:3] * ctx.scale, fromto[3:] * ctx.scale, radius)
    if len(size) < 2:
        raise ctx.fail(g, "a capsule without 'fromto' needs size = \"radius half_length\"")
    T = ctx.pose(g, ga)
    half = size[1] * ctx.scale * T[:3, 2]
    return Pill(gname, T[:3, 3] - half, T[:3, 3] + half, radius)


def _matrix_to_quaternion(R: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of a rotation matrix (Shepperd's method)."""
    tr = np.trace(R)
    i = int(np.argmax([tr, R[0, 0], R[1, 1], R[2, 2]]))
    if i == 0:
        w = math.sqrt(1 + tr) / 2
        q = [w, (R[2, 1] - R[1, 2]) / (4 * w), (R[0, 2] - R[2, 0]) / (4 * w), (R[1, 0] - R[0, 1]) / (4 * w)]
    else:
        a, b, c = {1: (0, 1, 2), 2: (1, 2, 0), 3: (2, 0, 1)}[i]
        s = math.sqrt(1 + R[a, a] - R[b, b] - R[c, c]) * 2
        v = [0.0, 0.0, 0.0]
        v[a] = s / 4
        v[b] = (R[b, a] + R[a, b]) / s
        v[c] = (R[c, a] + R[a, c]) / s
        q = [(R[c, b] - R[b, c]) / s] + v
    return np.asarray(q) / np.linalg.norm(q)
