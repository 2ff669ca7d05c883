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

import types

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Bool, Float

from ._errors import InputError
from .camera import Camera, as_rig
from .kinematics import project_pose
from .model import Model

__all__ = ["Features", "empty_features", "features_from_pose", "features_from_points", "line_through",
           "validate_features", "feature_value_checks", "raise_on_values", "FEATURE_CHECKS"]

#: The value checks of :func:`feature_value_checks`, in its order, with the message each failure
#: raises from :func:`validate_features` (after ``features[c]``).
FEATURE_CHECKS = (
    ("finite", ": a valid line or tip holds NaN or inf"),
    ("unit_normal", ".lines: (a, b) must be unit normals where valid"),
    ("line_weight", ".line_weight: weights must be finite and >= 0"),
    ("tip_weight", ".tip_weight: weights must be finite and >= 0"),
)
#: Tolerance on the unit length of a valid line normal (``|norm - 1| <= 1e-6 + 1e-5``, the
#: tolerance of ``np.allclose(norm, 1, atol=1e-6)``).
_NORMAL_TOL = 1e-6 + 1e-5


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


def line_through(p0: Float[ArrayLike, "*n 2"], p1: Float[ArrayLike, "*n 2"]) -> Float[Array, "*n 3"]:
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


def features_from_points(start_px, end_px, tips_px, *, noise_px: float = 0.0,
                         rng: np.random.Generator | None = None) -> Features:
    """Exact features of one camera from the projected link axes and tips (the one rule behind
    :func:`features_from_pose` and :func:`jaxhand.solve.features_from_poses`).

    Every link line passes through its projected axis (``start_px`` -> ``end_px``, (*b, links, 2))
    and every tip sits on its projected centre (``tips_px``, (*b, tips, 2)); with ``noise_px`` > 0
    the two axis end points and the tip get independent Gaussian noise of that standard
    deviation (pixels, drawn from ``rng`` in that order) before the lines are formed. A link
    whose projection is shorter than 1e-6 px is marked invalid; every weight is 1.
    """
    s, e, t = (np.asarray(x) for x in (start_px, end_px, tips_px))
    if noise_px > 0:
        rng = rng if rng is not None else np.random.default_rng(0)
        s = s + rng.normal(0, noise_px, s.shape)
        e = e + rng.normal(0, noise_px, e.shape)
        t = t + rng.normal(0, noise_px, t.shape)
    valid = np.linalg.norm(e - s, axis=-1) > 1e-6
    return Features(lines=line_through(jnp.asarray(s), jnp.asarray(e)), line_valid=jnp.asarray(valid),
                    line_weight=jnp.ones(valid.shape), tips=jnp.asarray(t),
                    tip_valid=jnp.ones(t.shape[:-1], bool), tip_weight=jnp.ones(t.shape[:-1]))


def features_from_pose(model: Model, cameras, q, *, noise_px: float = 0.0,
                       rng: np.random.Generator | None = None) -> tuple[Features, ...]:
    """Exact features of the model at state q in every camera (optionally with pixel noise):
    :func:`features_from_points` of each camera's projection, sharing ``rng``."""
    rng = rng if rng is not None else np.random.default_rng(0)
    out = []
    for cam in as_rig(cameras):
        v = project_pose(model, cam, jnp.asarray(q))
        out.append(features_from_points(v.link_start_px, v.link_end_px, v.tips_px, noise_px=noise_px, rng=rng))
    return tuple(out)


def feature_value_checks(f, xp=jnp):
    """The value checks of one camera's features, one flag per entry of :data:`FEATURE_CHECKS`
    (True: passed), over any leading batch axes: valid lines and tips finite, valid line normals
    of unit length, weights finite and >= 0.

    The one home of the rule: :func:`validate_features` runs it on the host (``xp=numpy``), the
    tracker's compiled step inside jit (``xp=jax.numpy``). Masked slots may hold anything.
    ``f`` is a :class:`Features` or any object with its fields as ``xp`` arrays.
    """
    lv, tv = f.line_valid[..., None], f.tip_valid[..., None]
    norm = xp.linalg.norm(xp.where(lv, f.lines[..., :2], 0.0), axis=-1)
    return (xp.all(xp.isfinite(f.lines) | ~lv) & xp.all(xp.isfinite(f.tips) | ~tv),
            xp.all((xp.abs(norm - 1.0) <= _NORMAL_TOL) | ~f.line_valid),
            xp.all(xp.isfinite(f.line_weight) & (f.line_weight >= 0)),
            xp.all(xp.isfinite(f.tip_weight) & (f.tip_weight >= 0)))


def raise_on_values(features: tuple[Features, ...], xp=np) -> None:
    """Raise the :class:`~jaxhand.InputError` of the first failed value check
    (:func:`feature_value_checks`), naming the camera and the field."""
    for c, f in enumerate(features):
        if xp is np:
            f = types.SimpleNamespace(**{name: np.asarray(getattr(f, name)) for name in _FIELDS})
        for ok, (_, message) in zip(feature_value_checks(f, xp), FEATURE_CHECKS):
            if not bool(ok):
                raise InputError(f"features[{c}]{message}")


_FIELDS = ("lines", "line_valid", "line_weight", "tips", "tip_valid", "tip_weight")


def validate_features(model: Model, cameras: Camera | tuple[Camera, ...], features) -> tuple[Features, ...]:
    """Check a user's features against the model and rig: one per camera, right shapes, finite
    where valid, unit line normals. Returns them as a tuple.

    Raises:
        InputError: naming the camera, the field and the problem.
    """
    rig = as_rig(cameras)
    if not isinstance(features, Features) and not (isinstance(features, (tuple, list))
                                                   and all(isinstance(f, Features) for f in features)):
        raise InputError(f"features: expected a jaxhand.Features (or a tuple of one per camera), got "
                         f"{type(features).__name__}: build them with jaxhand.features_from_pose, "
                         "jaxhand.extract_features or Features(lines=..., line_valid=..., ...)")
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
    raise_on_values(feats)
    return feats
