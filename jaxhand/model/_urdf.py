"""URDF import: links, revolute/continuous/prismatic/fixed joints, collision geometry -> a Model.

Supported: ``<joint type="revolute|continuous|prismatic|fixed">`` with ``<parent link>``,
``<child link>``, ``<origin xyz rpy>`` (``T_parent_child = Trans(xyz) Rz(yaw) Ry(pitch)
Rx(roll)``), ``<axis xyz>`` (default 1 0 0) and ``<limit lower upper>``; ``<collision>``
geometry of each link with its ``<origin>``: ``<cylinder radius length>`` and ``<capsule radius
length>`` (along the origin's z, centred on it; both become pills, whose ends are capsule caps)
and ``<sphere radius>`` (a zero-length occluder pill). Without any ``<collision>``, a link's
``<visual>`` geometry is used. Other geometry (box, mesh) is ignored.

Rejected with an error: ``floating`` and ``planar`` joints, ``<mimic>``, a link with two
parents, and more than one root link. A continuous joint gets limits [-180, 180] deg.

Mapping (see :mod:`._tree`): the root link becomes a fixed frame named after it; every joint a
frame named after the joint (a moving joint's q entry has the joint's name); pills are named
after their link (``<link>``, ``<link>_1``, ...). By default the pills of links that move with a
joint are links (a tip where no link further down has pills) and the pills of the root link and
of links fixed to it are occluder-only pills; ``occluders=`` names the pills to make occluders
instead. URDF lengths are in metres: ``length_scale_mm`` (default 1000) converts them.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from .._errors import ModelFileError
from ._model import HANDEDNESS, Model
from ._tree import Joint, Pill, TreeBuilder, _rot, _trans

__all__ = ["load_urdf"]


def _rpy(r: float, p: float, y: float) -> np.ndarray:
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    Rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    Ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    Rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


def load_urdf(path: str | Path, *, name: str | None = None, handedness: str = "none",
              occluders: list[str] | tuple[str, ...] | None = None, length_scale_mm: float = 1000.0) -> Model:
    """Import a URDF robot description (see the module docstring for what is supported).

    Args:
        path: the ``.urdf`` file.
        name: the model's name (default: ``<robot name=...>``, else the file stem).
        handedness: "right", "left" or "none".
        occluders: pill names to import as occluder-only pills; None: the root link's pills.
        length_scale_mm: millimetres per URDF length unit (1000: URDF is in metres).

    Raises:
        ModelFileError: unreadable or unparsable file, or an unsupported joint; the message names
            the file and the element.
    """
    path = Path(path)
    src = str(path)
    try:
        root = ET.parse(path).getroot()
    except OSError as err:
        raise ModelFileError(f"{src}: cannot read URDF file ({err.strerror})") from err
    except ET.ParseError as err:
        raise ModelFileError(f"{src}: cannot parse: {err}") from err
    if root.tag != "robot":
        raise ModelFileError(f"{src}: not a URDF file (root element <{root.tag}>, expected <robot>)")
    if handedness not in HANDEDNESS:
        raise ModelFileError(f"{src}: handedness must be one of {', '.join(HANDEDNESS)}, got {handedness!r}")
    scale = float(length_scale_mm)

    def fail(el: ET.Element, msg: str) -> ModelFileError:
        n = el.get("name")
        return ModelFileError(f"{src}: <{el.tag}{f' name={n!r}' if n else ''}>: {msg}")

    def numbers(el: ET.Element | None, key: str, n: int, default: list[float]) -> np.ndarray:
        if el is None or key not in el.attrib:
            return np.asarray(default, float)
        try:
            v = np.array([float(x) for x in el.get(key).split()])
        except ValueError as err:
            raise fail(el, f"attribute {key!r} must be numbers, got {el.get(key)!r}") from err
        if v.shape != (n,) or not np.all(np.isfinite(v)):
            raise fail(el, f"attribute {key!r} must be {n} finite numbers, got {el.get(key)!r}")
        return v

    def origin(el: ET.Element) -> np.ndarray:
        o = el.find("origin")
        return _trans(numbers(o, "xyz", 3, [0, 0, 0]) * scale) @ _rot(_rpy(*numbers(o, "rpy", 3, [0, 0, 0])))

    def scalar(el: ET.Element, key: str) -> float:
        v = numbers(el, key, 1, [math.nan])[0]
        if not math.isfinite(v):
            raise fail(el, f"missing attribute {key!r}")
        return float(v)

    links = {el.get("name"): el for el in root.findall("link")}
    joints = root.findall("joint")
    child_of: dict[str, ET.Element] = {}
    children: dict[str, list[ET.Element]] = {n: [] for n in links}
    for j in joints:
        if j.find("mimic") is not None:
            raise fail(j, "<mimic> joints are not supported")
        p, c = j.find("parent"), j.find("child")
        if p is None or c is None or p.get("link") not in links or c.get("link") not in links:
            raise fail(j, "needs <parent link=...> and <child link=...> naming defined links")
        if c.get("link") in child_of:
            raise fail(j, f"link {c.get('link')!r} has two parent joints")
        child_of[c.get("link")] = j
        children[p.get("link")].append(j)
    roots = [n for n in links if n not in child_of]
    if len(roots) != 1:
        raise ModelFileError(f"{src}: expected one root link, found {len(roots)}: {', '.join(roots) or '(none)'}")
    occ = None if occluders is None else set(occluders)

    def pills(link: ET.Element, moving: bool) -> list[Pill]:
        lname = link.get("name")
        shapes = link.findall("collision") or link.findall("visual")
        out: list[Pill] = []
        for s in shapes:
            g = s.find("geometry")
            shape = next(iter(g), None) if g is not None else None
            if shape is None or shape.tag not in ("cylinder", "capsule", "sphere"):
                continue
            T = origin(s)
            pname = lname if not out else f"{lname}_{len(out)}"
            radius = scalar(shape, "radius") * scale
            if shape.tag == "sphere":
                start = end = T[:3, 3]
            else:
                half = 0.5 * scalar(shape, "length") * scale * T[:3, 2]
                start, end = T[:3, 3] - half, T[:3, 3] + half
            out.append(Pill(pname, start, end, radius, link=moving if occ is None else pname not in occ))
        return out

    builder = TreeBuilder(name=name or root.get("name") or path.stem, handedness=handedness)
    builder.add_body(roots[0], "base", np.eye(4), [], pills(links[roots[0]], False))

    def walk(link_name: str, frame: str, T_frame_link: np.ndarray, moving: bool) -> None:
        for j in children[link_name]:
            kind = j.get("type")
            jname = j.get("name")
            child = links[j.find("child").get("link")]
            T = T_frame_link @ origin(j)
            if kind == "fixed":
                jl: list[Joint] = []
            elif kind in ("revolute", "continuous", "prismatic"):
                axis = numbers(j.find("axis"), "xyz", 3, [1, 0, 0])
                if np.linalg.norm(axis) < 1e-12:
                    raise fail(j, "<axis xyz> must not be zero")
                lim = j.find("limit")
                if kind == "continuous":
                    lo, hi = -math.pi, math.pi
                elif lim is None:
                    raise fail(j, f"a {kind} joint needs <limit lower=... upper=...>")
                else:
                    lo, hi = (scalar(lim, "lower"), scalar(lim, "upper"))
                    if kind == "prismatic":
                        lo, hi = lo * scale, hi * scale
                    if lo > hi:
                        raise fail(j, f"<limit>: lower {lo} > upper {hi}")
                jl = [Joint(name=jname, kind="prismatic" if kind == "prismatic" else "revolute", axis=axis,
                            pos=np.zeros(3), limits=(lo, hi))]
            else:
                raise fail(j, f"joint type {kind!r} is not supported (revolute, continuous, prismatic, fixed)")
            # A fixed joint is a frame named after the joint (the body builder names joint-less bodies).
            child_moving = moving or bool(jl)
            f, T_child = builder.add_body(jname, frame, T, jl, pills(child, child_moving))
            walk(child.get("name"), f, T_child, child_moving)

    walk(roots[0], roots[0], np.eye(4), False)
    builder.mark_tips()
    return builder.model(src)
