"""Palm and forearm occluder pills for a hand model that has only its digits.

The built-in hands (and hands calibrated from landmarks) describe the fingers and thumb only, so
a learned foreground, which sees the palm and the forearm, finds pixels that nothing in the model
explains. :func:`add_palm` adds them as occluder-only pills (no features) hung on a fixed frame
of the palm, laid out from the model's own finger bases as the development set's MuJoCo hand
lays out its palm:

- one pill per finger, from near the wrist to just short of the finger's base (MCP), across the
  palm at 0.63 of the MCP's lateral offset, with 1.25 times the proximal phalanx's radius;
- a forearm pill along the palm's proximal direction from the wrist, ``forearm_mm`` long, with a
  radius of 0.4 times the palm's width across the outer MCPs.

The wrist is the root's origin (where the built-in hands and the development set's hand put it).
The forearm is rigid with the palm, as in the development set; a real wrist bends, so keep it
short there.
"""

from __future__ import annotations

import numpy as np

from .._errors import InputError
from ._file import model_from_dict, model_to_dict
from ._model import Model

__all__ = ["add_palm"]

_ACROSS, _FROM, _SHORT, _WIDEN, _FOREARM_RADIUS = 0.63, 0.15, 0.05, 1.25, 0.4


def _base_digit_links(model: Model) -> list[int]:
    """Links with no link on the frames above them (a digit's first bone)."""
    above = model.ancestors & ~np.eye(model.n_frames, dtype=bool)
    carries = np.isin(np.arange(model.n_frames), model.link_frame)
    return [li for li, f in enumerate(model.link_frame) if not (above[f] & carries).any()]


def _root_frame_poses(model: Model) -> np.ndarray:
    """T_root_frame of every frame at the default pose (numpy, no base motion or mount)."""
    from ..kinematics import base_pose, frame_poses

    q = model.q_default
    return np.linalg.inv(np.asarray(base_pose(model, q))) @ np.asarray(frame_poses(model, q))


def add_palm(model: Model, *, forearm_mm: float = 100.0) -> Model:
    """``model`` with occluder pills ``palm_<finger>`` and ``forearm`` (see the module docstring).

    Raises:
        InputError: the model already has occluders, has fewer than two fingers besides a thumb
            (links whose names contain ``thumb``), no fixed frame on its root, or a negative
            ``forearm_mm``.
    """
    if model.n_occluders:
        raise InputError(f"add_palm: model {model.name!r} already has occluders "
                         f"({', '.join(model.occluder_names)}); add a palm to a model with digits only")
    if not forearm_mm >= 0:
        raise InputError(f"add_palm: forearm_mm must be >= 0 (0 for no forearm), got {forearm_mm}")
    fingers = [li for li in _base_digit_links(model) if "thumb" not in model.link_names[li]]
    if len(fingers) < 2:
        raise InputError(f"add_palm: model {model.name!r} has {len(fingers)} finger(s) on its root besides a "
                         "thumb; a palm needs at least two (a hand such as hand21 or hand27)")
    hang = next((f for f in range(model.n_frames) if model.parents[f] < 0 and model.joint_kinds[f] == "fixed"), None)
    if hang is None:
        raise InputError(f"add_palm: model {model.name!r} has no fixed frame on its root to hang the palm on")
    T = _root_frame_poses(model)
    mcp = np.array([T[model.link_frame[li], :3, 3] for li in fingers])
    distal = mcp.mean(0) / np.linalg.norm(mcp.mean(0))
    lateral = mcp - np.outer(mcp @ distal, distal)
    reach = mcp @ distal
    starts = _ACROSS * lateral + np.outer(_FROM * reach, distal)
    ends = mcp - np.outer(_SHORT * reach, distal)
    radii = _WIDEN * np.asarray(model.link_radius_mm)[fingers]
    width = max(np.linalg.norm(a - b) for a in mcp for b in mcp)
    T_hang_root = np.linalg.inv(T[hang])

    def local(p):
        return [float(v) for v in (T_hang_root[:3, :3] @ p + T_hang_root[:3, 3])]

    pills = [{"name": f"palm_{model.link_names[li].split('_')[0]}", "frame": model.frame_names[hang],
              "start_mm": local(s), "end_mm": local(e), "radius_mm": float(r)}
             for li, s, e, r in zip(fingers, starts, ends, radii, strict=True)]
    if forearm_mm > 0:
        pills.append({"name": "forearm", "frame": model.frame_names[hang],
                      "start_mm": local(_SHORT * reach.mean() * distal), "end_mm": local(-forearm_mm * distal),
                      "radius_mm": float(_FOREARM_RADIUS * width)})
    d = model_to_dict(model)
    d["occluders"] = pills
    return model_from_dict(d, source=f"add_palm({model.name})")
