"""Smooth joint trajectories through key poses: minimum-jerk segments.

Between two key poses ``q_i`` and ``q_{i+1}`` held at times ``t_i < t_{i+1}``, every entry moves along
the minimum-jerk profile (the path that minimises the integral of the squared third derivative with
zero velocity and acceleration at both ends)::

    s(tau) = 10 tau^3 - 15 tau^4 + 6 tau^5,   tau = (t - t_i) / (t_{i+1} - t_i)
    q(t)   = q_i + s(tau) (q_{i+1} - q_i)

Since ``0 <= s <= 1``, every entry stays between its values at the two keys, so keys inside the
joint limits give a trajectory inside them. A free base's quaternion is interpolated by spherical
linear interpolation with the same ``s`` (the rotation turns about a fixed axis at a
minimum-jerk rate), keeping it a unit quaternion.
"""

from __future__ import annotations

import numpy as np

from .._errors import InputError
from ..kinematics import validate_q
from ..model import Model

__all__ = ["minimum_jerk", "joint_trajectory", "min_jerk_profile", "slerp"]


def min_jerk_profile(tau):
    """The normalised minimum-jerk position profile s(tau) on [0, 1] (clipped outside)."""
    tau = np.clip(np.asarray(tau, float), 0.0, 1.0)
    return tau**3 * (10.0 - 15.0 * tau + 6.0 * tau**2)


def _segments(key_times, times) -> tuple[np.ndarray, np.ndarray]:
    """Segment index and normalised time within it for every time."""
    kt = np.asarray(key_times, float)
    if kt.ndim != 1 or len(kt) < 1 or not np.all(np.isfinite(kt)):
        raise InputError(f"key_times: expected a finite 1-D array, got {key_times!r}")
    if np.any(np.diff(kt) <= 0):
        raise InputError("key_times: must be strictly increasing")
    t = np.asarray(times, float)
    if len(kt) == 1:
        return np.zeros(t.shape, int), np.zeros(t.shape)
    seg = np.clip(np.searchsorted(kt, t, side="right") - 1, 0, len(kt) - 2)
    tau = (t - kt[seg]) / (kt[seg + 1] - kt[seg])
    return seg, min_jerk_profile(tau)


def minimum_jerk(keys, key_times, times) -> np.ndarray:
    """Interpolate key vectors with minimum-jerk segments (rest at every key).

    Args:
        keys: (n_keys, n) key values.
        key_times: (n_keys,) strictly increasing times (s).
        times: (frames,) sample times (s); times before the first or after the last key hold it.

    Returns:
        (frames, n) values.
    """
    k = np.asarray(keys, float)
    if k.ndim != 2 or len(k) != len(np.asarray(key_times)):
        raise InputError(f"keys: expected shape (len(key_times), n), got {k.shape}")
    seg, s = _segments(key_times, times)
    if len(k) == 1:
        return np.repeat(k, len(seg), axis=0)
    return k[seg] + s[:, None] * (k[seg + 1] - k[seg])


def slerp(q0, q1, s) -> np.ndarray:
    """Spherical linear interpolation of unit quaternions (rows), short way round, at fractions s."""
    q0 = np.asarray(q0, float)
    q1 = np.asarray(q1, float)
    s = np.asarray(s, float)[..., None]
    dot = np.sum(q0 * q1, axis=-1, keepdims=True)
    q1 = np.where(dot < 0, -q1, q1)  # q and -q are the same rotation: take the shorter arc
    dot = np.abs(dot)
    omega = np.arccos(np.clip(dot, -1.0, 1.0))
    sin_o = np.sin(omega)
    # Guard: nearly equal quaternions (sin_o ~ 0) fall back to normalised linear interpolation.
    close = sin_o < 1e-9
    safe = np.where(close, 1.0, sin_o)
    w0 = np.where(close, 1.0 - s, np.sin((1.0 - s) * omega) / safe)
    w1 = np.where(close, s, np.sin(s * omega) / safe)
    out = w0 * q0 + w1 * q1
    return out / np.linalg.norm(out, axis=-1, keepdims=True)


def joint_trajectory(model: Model, keys, key_times, times) -> np.ndarray:
    """Minimum-jerk trajectory of a model's state through key poses inside its joint limits.

    Args:
        model: the model whose q layout the keys follow.
        keys: (n_keys, n_q) key states (radians, mm; a free base's quaternion is normalised).
        key_times: (n_keys,) strictly increasing key times (s).
        times: (frames,) sample times (s).

    Returns:
        (frames, n_q) states, every one inside the joint limits.

    Raises:
        InputError: a key outside the joint limits (naming the joint), or malformed times.
    """
    k = np.array(keys, float)
    if k.ndim != 2 or k.shape[1] != model.n_q:
        raise InputError(f"keys: expected shape (n_keys, {model.n_q}) for model {model.name!r}, got {k.shape}")
    if model.base_kind == "free":
        n = np.linalg.norm(k[:, :4], axis=1, keepdims=True)
        if np.any(n == 0):
            raise InputError("keys: a free base's quaternion must not be zero")
        k[:, :4] /= n
    for i, key in enumerate(k):
        validate_q(model, key, name=f"keys[{i}]", within_limits=True)
    q = minimum_jerk(k, key_times, times)
    if model.base_kind == "free" and len(k) > 1:
        seg, s = _segments(key_times, times)
        q[:, :4] = slerp(k[seg, :4], k[seg + 1, :4], s)
    return q
