"""Turning a tree of rigid bodies (MJCF, URDF) into a modified-DH model.

Both importers describe each body by its offset from its parent (a 4x4 transform), a list of
one-axis joints at given points of the body, and pills (capsule segments) in body coordinates.
:class:`TreeBuilder` writes that as model-file frames:

- each joint becomes a frame whose z axis is the joint axis and whose origin is the joint
  point: ``pre_transform = T_pending @ Trans(c) @ R_a``, then ``RotZ(q - ref)`` (hinge) or
  ``TransZ(q - ref)`` (slide) as the DH part, and ``T_pending = R_a^T Trans(-c)`` carries the
  rest of the body's transform to the next joint, its pills and its children. ``R_a`` has the
  joint axis as z and, where possible, the body's first link pill as x, so that a link starts at
  the frame origin along x as in the built-in hands (thesis Table 6.2);
- a body without joints becomes a fixed frame named after the body (``pre_transform`` = its
  offset);
- a link pill that starts at its frame's origin along a frame axis sits on that frame;
  any other becomes a fixed frame of its own (``<pill>_pill``, x along the pill);
- occluder pills keep their segment in frame coordinates.

The result goes through :func:`model_from_dict`, so imported models are validated like files.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ._file import FORMAT_VERSION, _clean, _deg, model_from_dict
from ._model import Model

__all__ = ["TreeBuilder", "Joint", "Pill", "occluders_as_links"]

_TOL = 1e-9


@dataclass
class Joint:
    """One joint of a body: kind "revolute" (rad) or "prismatic" (mm), axis and point in body
    coordinates, limits and the reference value (the joint value of the body's own pose)."""

    name: str
    kind: str
    axis: np.ndarray
    pos: np.ndarray
    limits: tuple[float, float]
    ref: float = 0.0


@dataclass
class Pill:
    """A capsule segment in body coordinates (mm), a link (features) or an occluder (none)."""

    name: str
    start: np.ndarray
    end: np.ndarray
    radius: float
    link: bool = True
    tip: bool = False


@dataclass
class TreeBuilder:
    """Collects frames, links and occluders; :meth:`model` validates and builds the model."""

    name: str
    handedness: str = "none"
    base: dict[str, Any] = field(default_factory=lambda: {"kind": "fixed"})
    frames: list[dict[str, Any]] = field(default_factory=list)
    occluders: list[dict[str, Any]] = field(default_factory=list)
    #: Frames made only to carry a pill (``<pill>_pill``), mapped to the body frame they hang off.
    pill_frames: dict[str, str] = field(default_factory=dict)

    def _frame(self, name: str, parent: str, pre: np.ndarray | None, **kw) -> str:
        fr: dict[str, Any] = {"name": name, "parent": parent, "alpha_deg": 0, "a_mm": 0, "d_mm": 0, "theta_deg": 0,
                              "joint": "fixed"}
        fr.update(kw)
        if pre is not None:
            fr["pre_transform"] = {"rotation": [[_clean(v) for v in row] for row in pre[:3, :3]],
                                   "translation_mm": [_clean(v) for v in pre[:3, 3]]}
        self.frames.append(fr)
        return name

    def add_body(self, name: str, parent: str, T_parent_body: np.ndarray, joints: list[Joint],
                 pills: list[Pill]) -> tuple[str, np.ndarray]:
        """Add one body hanging off frame ``parent`` ("base" for the root) at ``T_parent_body``.

        Returns the frame that carries the body and ``T_frame_body`` (for its children).
        """
        T = np.asarray(T_parent_body, dtype=float)
        frame = parent
        main = next((p.end - p.start for p in pills if p.link and np.linalg.norm(p.end - p.start) > _TOL), None)
        for j in joints:
            R_a = _axis_frame(j.axis, main)
            F = T @ _trans(j.pos) @ _rot(R_a)
            lo, hi = j.limits
            default = min(max(j.ref, lo), hi)
            if j.kind == "revolute":
                kw = {"theta_deg": _deg(-j.ref), "limits": [_deg(lo), _deg(hi)], "default": _deg(default)}
            else:
                kw = {"d_mm": _clean(-j.ref), "limits": [_clean(lo), _clean(hi)], "default": _clean(default)}
            frame = self._frame(j.name, frame, F, joint=j.kind, **kw)
            T = _rot(R_a.T) @ _trans(-np.asarray(j.pos, float))
        if not joints:
            frame = self._frame(name, parent, None if np.array_equal(T, np.eye(4)) else T)
            T = np.eye(4)
        self._add_pills(frame, T, pills)
        return frame, T

    def _add_pills(self, frame: str, T: np.ndarray, pills: list[Pill]) -> None:
        carrier = next(fr for fr in self.frames if fr["name"] == frame)
        for p in pills:
            s = T[:3, :3] @ p.start + T[:3, 3]
            e = T[:3, :3] @ p.end + T[:3, 3]
            length = float(np.linalg.norm(e - s))
            if not p.link or length <= _TOL:  # a sphere has no axis: always an occluder
                self.occluders.append({"name": p.name, "frame": frame, "start_mm": [_clean(v) for v in s],
                                       "end_mm": [_clean(v) for v in e], "radius_mm": _clean(p.radius)})
                continue
            d = (e - s) / length
            axis = int(np.argmax(np.abs(d)))
            direct = (np.all(np.abs(s) <= _TOL) and d[axis] > 0 and np.all(np.abs(np.delete(d, axis)) <= _TOL)
                      and "link" not in carrier)
            if direct:
                length = float(e[axis] - s[axis])
                on = carrier
            else:
                R = _axis_frame_x(d)
                on = {"name": f"{p.name}_pill"}
                self._frame(on["name"], frame, _trans(s) @ _rot(R))
                self.pill_frames[on["name"]] = frame
                on = self.frames[-1]
                axis = 0
            on["link"] = {"name": p.name, "axis": "xyz"[axis], "length_mm": _clean(length),
                          "radius_mm": _clean(p.radius), "tip": p.tip}

    def mark_tips(self) -> None:
        """A link is a tip when no body below its own carries a link."""
        parent = {fr["name"]: fr["parent"] for fr in self.frames}
        body = lambda n: self.pill_frames.get(n, n)  # noqa: E731
        above: set[str] = set()
        for fr in self.frames:
            if "link" in fr:
                p = parent[body(fr["name"])]
                while p != "base":
                    above.add(p)
                    p = parent[p]
        for fr in self.frames:
            if "link" in fr:
                fr["link"]["tip"] = body(fr["name"]) not in above

    def model(self, source: str) -> Model:
        spec: dict[str, Any] = {"format_version": FORMAT_VERSION, "name": self.name, "handedness": self.handedness,
                                "base": self.base, "frames": self.frames}
        if self.occluders:
            spec["occluders"] = self.occluders
        return model_from_dict(spec, source=source)


def _trans(p) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = np.asarray(p, dtype=float)
    return T


def _rot(R) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = R
    return T


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


def _axis_frame(axis, prefer_x) -> np.ndarray:
    """R with z = ``axis`` and x = ``prefer_x`` made perpendicular to it (or a coordinate axis)."""
    z = _unit(axis)
    candidates = [np.asarray(prefer_x, float)] if prefer_x is not None else []
    candidates += list(np.eye(3)[np.argsort(np.abs(z))])  # the coordinate axis least along z first
    for c in candidates:
        x = c - (c @ z) * z
        n = np.linalg.norm(x)
        if n > 1e-6 * max(np.linalg.norm(c), 1.0):
            x = x / n
            break
    return np.stack([x, np.cross(z, x), z], axis=1)


def _axis_frame_x(d) -> np.ndarray:
    """R with x = ``d`` (a unit vector)."""
    R = _axis_frame(d, None)  # z = d
    return np.stack([R[:, 2], R[:, 0], R[:, 1]], axis=1)


def occluders_as_links(model: Model, names: list[str] | tuple[str, ...] | None = None, *,
                       tips: bool = False) -> Model:
    """The model with occluder pills turned into links (which carry link features).

    Each named occluder (default: all) becomes a link on a new fixed frame ``<name>_pill`` hung
    off its frame, with its origin at the occluder's start and its x axis along the occluder;
    the link keeps the occluder's name and radius and is a tip if ``tips``. Existing frames, q
    entries and links keep their indices (the new links come last); the structure changes, so
    the result compiles its own programs. Zero-length occluders (spheres) cannot become links.

    Raises:
        InputError: an unknown occluder name, or a zero-length occluder.
    """
    from .._errors import InputError
    from ._file import model_to_dict

    names = list(model.occluder_names if names is None else names)
    for n in names:
        if n not in model.occluder_names:
            raise InputError(f"model {model.name!r} has no occluder {n!r}; valid: "
                             f"{', '.join(model.occluder_names) or '(none)'}")
    d = model_to_dict(model)
    keep = []
    for oc in d.get("occluders", []):
        if oc["name"] not in names:
            keep.append(oc)
            continue
        s, e = np.asarray(oc["start_mm"], float), np.asarray(oc["end_mm"], float)
        length = float(np.linalg.norm(e - s))
        if length <= _TOL:
            raise InputError(f"occluder {oc['name']!r} has zero length (a sphere) and cannot become a link")
        b = TreeBuilder(name=model.name)
        b._frame(f"{oc['name']}_pill", oc["frame"], _trans(s) @ _rot(_axis_frame_x((e - s) / length)))
        b.frames[-1]["link"] = {"name": oc["name"], "axis": "x", "length_mm": _clean(length),
                                "radius_mm": oc["radius_mm"], "tip": tips}
        d["frames"] += b.frames
    d["occluders"] = keep
    if not keep:
        del d["occluders"]
    return model_from_dict(d, source=f"occluders_as_links({model.name})")
