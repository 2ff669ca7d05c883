"""Initial poses from the command line or a file, in user units (degrees, mm)."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np

from .._errors import InputError, JaxhandWarning
from ..kinematics import validate_q
from ..model import Model

__all__ = ["parse_pose", "pose_to_dict"]


def _from_user(model: Model, values, src: str = "pose") -> np.ndarray:
    try:
        v = np.asarray(values, float)
    except (TypeError, ValueError) as err:
        raise InputError(f"{src}: cannot read {values!r} as numbers") from err
    if v.shape != (model.n_q,):
        raise InputError(f"{src}: expected {model.n_q} values for {model.name!r} ({', '.join(model.q_names)}), "
                         f"got {v.size}")
    angles = v[model.is_angle]
    if angles.size >= 2 and np.abs(angles).max() > 0.05 and np.all(np.abs(angles) <= np.pi + 1e-6) \
            and not np.allclose(angles, np.round(angles)):
        warnings.warn(f"{src}: every angle lies within +-pi and few are whole degrees: these look like radians, "
                      f"but poses are read in degrees (0.6 rad is 34.4 deg)", JaxhandWarning, stacklevel=3)
    return np.where(model.is_angle, np.radians(v), v)


def pose_to_dict(model: Model, q) -> dict[str, float]:
    """q as {name: value} in degrees (angles) or mm (lengths); quaternion entries unitless."""
    q = np.asarray(q, float)
    return {n: float(np.degrees(v) if a else v) for n, v, a in zip(model.q_names, q, model.is_angle)}


def _overrides(model: Model, items: dict, src: str) -> np.ndarray:
    q = pose_to_dict(model, model.q_default)
    for name, value in items.items():
        if name not in q:
            raise InputError(f"{src}: unknown joint {name!r}; valid: {', '.join(model.q_names)}")
        try:
            q[name] = float(value)
        except (TypeError, ValueError):
            raise InputError(f"{src}: joint {name!r}: {value!r} is not a number") from None
    return _from_user(model, [q[n] for n in model.q_names], src)


def parse_pose(model: Model, spec: str | None) -> np.ndarray:
    """An initial state from ``spec``, validated against the joint limits.

    ``spec`` may be ``None`` or ``"default"`` (the model's default pose); ``"name=value,..."``
    (the default pose with some joints set, degrees or mm); a comma list of all ``n_q`` values
    in q order (degrees or mm); or a ``.json`` file holding ``{"q": {name: value}}`` (or the
    ground-truth JSON of ``jaxhand synth``, whose first frame is used) or a list of values.

    Raises:
        InputError: unknown joint names, wrong counts, non-numbers, poses outside the limits.
    """
    if spec is None or spec == "default":
        return np.asarray(model.q_default, float)
    path = Path(spec)
    if path.suffix == ".json":
        try:
            data = json.loads(path.read_text())
        except (OSError, json.JSONDecodeError) as err:
            raise InputError(f"{path}: cannot read pose file ({err})") from err
        if isinstance(data, dict) and "frames" in data:  # a synth ground-truth file
            data = data["frames"][0]
        if isinstance(data, dict):
            data = data.get("q", data)
        q = _overrides(model, data, str(path)) if isinstance(data, dict) else _from_user(model, data, str(path))
        src = str(path)
    elif "=" in spec:
        items = {}
        for part in spec.split(","):
            name, _, value = part.partition("=")
            items[name.strip()] = value.strip()
        q, src = _overrides(model, items, "--init"), "--init"
    else:
        try:
            values = [float(v) for v in spec.split(",")]
        except ValueError:
            raise InputError(f"--init: {spec!r} is neither 'default', name=value pairs, numbers nor a .json file"
                             ) from None
        q, src = _from_user(model, values, "--init"), "--init"
    if model.base_kind == "free":
        n = np.linalg.norm(q[:4])
        if n < 1e-9:
            raise InputError(f"{src}: the palm quaternion must not be zero")
        q[:4] /= n
    return validate_q(model, q, name=src, within_limits=True)
