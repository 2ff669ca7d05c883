"""Features: the contract between the image front end and the residuals.

One :class:`Features` per camera, with one slot per link and one per tip of the model, each with
a validity flag and a weight, so a link that goes missing flips a flag and never changes a shape
(and never triggers a recompilation). A rig's features are a tuple, one entry per camera, in the
rig's order.

- link slot: the observed axial line of the link, ``a x + b y = rho`` in pixels, with
  ``a^2 + b^2 = 1`` (thesis eq. 3.2, DigitEyes eq. 3);
- tip slot: the observed tip centre ``(x, y)`` in pixels (thesis eq. 3.1).
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float

from ._errors import InputError
from .camera import Camera, as_rig
from .kinematics import project_pose
from .model import Model

__all__ = ["Features", "empty_features", "features_from_pose", "line_through", "validate_features"]


class Features(eqx.Module):
    """Observed link lines and tip points of one camera (all fields traced arrays).

    Attributes:
        lines: (links, 3) line parameters (a, b, rho), unit normal (a, b), pixels.
        line_valid: (links,) True where the line was observed.
        line_weight: (links,) weight of the link's residuals (0 ignores it).
        tips: (tips, 2) observed tip centres, pixels.
        tip_valid: (tips,) True where the tip was observed.
        tip_weight: (tips,) weight of the tip's residuals.
    """

    lines: Float[Array, "*b links 3"]
    line_valid: Bool[Array, "*b links"]
    line_weight: Float[Array, "*b links"]
    tips: Float[Array, "*b tips 2"]
    tip_valid: Bool[Array, "*b tips"]
    tip_weight: Float[Array, "*b tips"]


def empty_features(model: Model) -> Features:
    """All slots invalid (weight 1 once they become valid)."""
    return Features(lines=jnp.tile(jnp.array([1.0, 0.0, 0.0]), (model.n_links, 1)),
                    line_valid=jnp.zeros(model.n_links, bool), line_weight=jnp.ones(model.n_links),
                    tips=jnp.zeros((model.n_tips, 2)), tip_valid=jnp.zeros(model.n_tips, bool),
                    tip_weight=jnp.ones(model.n_tips))


def line_through(p0: Float[Array, "*n 2"], p1: Float[Array, "*n 2"]) -> Float[Array, "*n 3"]:
    """(a, b, rho) of the line through p0 and p1, unit normal rotated +90 deg from p1 - p0.

    A zero-length segment gives the (finite) line (1, 0, p0.x); callers mark it invalid.
    """
    d = p1 - p0
    n = jnp.linalg.norm(d, axis=-1, keepdims=True)
    # Guard: a degenerate segment has no direction; fall back to x-axis to stay finite.
    u = jnp.where(n > 1e-12, d / jnp.where(n > 1e-12, n, 1.0), jnp.array([0.0, 1.0]))
    normal = jnp.stack([u[..., 1], -u[..., 0]], axis=-1)
    rho = jnp.sum(normal * p0, axis=-1, keepdims=True)
    return jnp.concatenate([normal, rho], axis=-1)


def features_from_pose(model: Model, cameras, q, *, noise_px: float = 0.0,
                       rng: np.random.Generator | None = None) -> tuple[Features, ...]:
    """Exact features of the model at state q in every camera (optionally with pixel noise).

    Every link line passes through the projected link axis and every tip sits on the projected
    tip centre; with ``noise_px`` > 0 the two axis end points and the tip get independent
    Gaussian noise of that standard deviation (pixels) before the lines are formed.
    """
    out = []
    rng = rng if rng is not None else np.random.default_rng(0)
    for cam in as_rig(cameras):
        v = project_pose(model, cam, jnp.asarray(q))
        s, e, t = (np.asarray(x) for x in (v.link_start_px, v.link_end_px, v.tips_px))
        if noise_px > 0:
            s = s + rng.normal(0, noise_px, s.shape)
            e = e + rng.normal(0, noise_px, e.shape)
            t = t + rng.normal(0, noise_px, t.shape)
        valid = np.linalg.norm(e - s, axis=-1) > 1e-6
        out.append(Features(lines=line_through(jnp.asarray(s), jnp.asarray(e)), line_valid=jnp.asarray(valid),
                            line_weight=jnp.ones(model.n_links), tips=jnp.asarray(t),
                            tip_valid=jnp.ones(model.n_tips, bool), tip_weight=jnp.ones(model.n_tips)))
    return tuple(out)


def validate_features(model: Model, cameras: Camera | tuple[Camera, ...], features) -> tuple[Features, ...]:
    """Check a user's features against the model and rig: one per camera, right shapes, finite
    where valid, unit line normals. Returns them as a tuple.

    Raises:
        InputError: naming the camera, the field and the problem.
    """
    rig = as_rig(cameras)
    feats = (features,) if isinstance(features, Features) else tuple(features)
    if len(feats) != len(rig):
        raise InputError(f"features: expected one Features per camera ({len(rig)}), got {len(feats)}")
    shapes = {"lines": (model.n_links, 3), "line_valid": (model.n_links,), "line_weight": (model.n_links,),
              "tips": (model.n_tips, 2), "tip_valid": (model.n_tips,), "tip_weight": (model.n_tips,)}
    for c, f in enumerate(feats):
        for name, shape in shapes.items():
            a = np.asarray(getattr(f, name))
            if a.shape != shape:
                raise InputError(f"features[{c}].{name}: expected shape {shape} for {model.name!r}, got {a.shape}")
        lines, tips = np.asarray(f.lines), np.asarray(f.tips)
        lv, tv = np.asarray(f.line_valid), np.asarray(f.tip_valid)
        if not np.all(np.isfinite(lines[lv])) or not np.all(np.isfinite(tips[tv])):
            raise InputError(f"features[{c}]: a valid line or tip holds NaN or inf")
        if lv.any() and not np.allclose(np.linalg.norm(lines[lv, :2], axis=-1), 1.0, atol=1e-6):
            raise InputError(f"features[{c}].lines: (a, b) must be unit normals where valid")
        for name in ("line_weight", "tip_weight"):
            w = np.asarray(getattr(f, name))
            if not np.all(np.isfinite(w)) or np.any(w < 0):
                raise InputError(f"features[{c}].{name}: weights must be finite and >= 0")
    return feats
