"""Pose priors as optional residuals (issue 13 item 6): DIP-PIP coupling and soft joint limits.

Each prior is an :class:`equinox.Module` built once at the boundary from a model (entries looked up
by name, never by literal index) and called as a pure, jit-compatible function
``prior(q) -> residual vector``. Its squared norm is the prior's cost, so its residuals can be
stacked under the image residuals of a solve (``jnp.concatenate([image_r, prior(q)])``); a weight
of 0 turns a prior off without changing any shape.

- :class:`DipPipCoupling`: ``r_f = w (q_dip - ratio * q_pip)`` per finger (the DIP joint flexes
  about 2/3 as much as the PIP in natural motion; the ratio is a common anatomical approximation,
  not a constraint of the model).
- :class:`AbstractTerm`: a frame's extra solve term (landmarks, the silhouette), unbound: arrays
  only, bound to a model and rig inside the compiled frame program.
- :class:`SoftLimits`: zero while an entry lies inside its limits widened by ``margin``, growing
  linearly beyond (so its cost grows quadratically): ``r_i = w (relu(q_i - hi_i - m) - relu(lo_i - m - q_i))``.
"""

from __future__ import annotations

import abc
from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from ._errors import InputError
from .model import Model

__all__ = ["AbstractTerm",
           "DipPipCoupling", "SoftLimits", "TemporalPrior", "dip_pip_coupling", "soft_limits", "temporal_prior",
           "stack_priors", "temporal_weight", "information_weight"]

#: Default DIP/PIP flexion ratio (DIP about 2/3 of PIP).
DIP_PIP_RATIO = 2.0 / 3.0


class AbstractTerm(eqx.Module):
    """One frame's extra solve term, unbound: its numbers only (traced, fixed shapes), so every
    frame reuses one compiled program. :meth:`bind` gives a prior ``prior(q) -> residuals``
    stacked under the image residuals. A ``judged`` term is a measurement of the image: the
    hypotheses' merit includes its :meth:`merit`; a term that is not judged (e.g. a detector's
    landmarks) only pulls the solve."""

    judged: ClassVar[bool] = False

    @abc.abstractmethod
    def bind(self, model: Model, rig: tuple):
        """The prior of this term on ``model`` seen by the cameras of ``rig`` (traceable)."""

    def merit(self, model: Model, rig: tuple, q) -> Float[Array, ""]:
        """How well the pose ``q`` agrees with this term's measurement, in (0, 1] (1 when not judged)."""
        return jnp.ones((), jnp.asarray(q).dtype)


class DipPipCoupling(eqx.Module):
    """DIP-PIP coupling residuals, one per finger that has both joints.

    Static: ``fingers`` (finger names), ``pip_index``, ``dip_index`` (entries of q).
    Traced: ``ratio`` (unitless, DIP over PIP) and ``weight`` (1/rad: a residual of 1 is one
    prior "sigma"; ``weight = 1 / sigma_rad``), each one value per finger.
    """

    fingers: tuple[str, ...] = eqx.field(static=True)
    pip_index: tuple[int, ...] = eqx.field(static=True)
    dip_index: tuple[int, ...] = eqx.field(static=True)
    ratio: Float[Array, " fingers"] = eqx.field(converter=jnp.asarray)
    weight: Float[Array, " fingers"] = eqx.field(converter=jnp.asarray)

    def __check_init__(self):
        n = len(self.fingers)
        if len(self.pip_index) != n or len(self.dip_index) != n:
            raise ValueError("DipPipCoupling: one pip and one dip index per finger")
        if self.ratio.shape != (n,) or self.weight.shape != (n,):
            raise ValueError(f"DipPipCoupling: ratio and weight need shape ({n},)")

    def __call__(self, q: Float[ArrayLike, " nq"]) -> Float[Array, " fingers"]:
        """Residuals ``weight * (q_dip - ratio * q_pip)`` (unitless when weight is 1/sigma)."""
        pip = q[np.array(self.pip_index, dtype=int)]
        dip = q[np.array(self.dip_index, dtype=int)]
        return self.weight * (dip - self.ratio * pip)


def dip_pip_coupling(model: Model, *, weight: float = 1.0 / np.radians(10.0), ratio: float = DIP_PIP_RATIO,
                     fingers: tuple[str, ...] | None = None) -> DipPipCoupling:
    """The DIP-PIP prior of ``model``: every finger ``f`` with q entries ``f_pip`` and ``f_dip``.

    Args:
        model: any model; the fingers are found by the q names (``index_pip``/``index_dip`` in the
            built-in hands and the MuJoCo dev set's hand).
        weight: 1 / sigma (1/rad); the default, sigma = 10 deg, lets a DIP leave the coupling by
            10 deg at the cost of one residual unit.
        ratio: DIP flexion over PIP flexion.
        fingers: finger names to couple (default: every finger found).

    Returns:
        The prior (possibly with no fingers: it then returns an empty residual vector).

    Raises:
        InputError: a requested finger lacks a pip or dip entry, or weight/ratio are not finite.
    """
    if not (np.isfinite(weight) and weight >= 0 and np.isfinite(ratio)):
        raise InputError(f"dip_pip_coupling: weight must be finite and >= 0 and ratio finite, got {weight!r}, "
                         f"{ratio!r}")
    found = [n[: -len("_pip")] for n in model.q_names if n.endswith("_pip") and n[:-4] + "_dip" in model.q_names]
    if fingers is None:
        fingers = tuple(found)
    missing = [f for f in fingers if f not in found]
    if missing:
        raise InputError(f"dip_pip_coupling: model {model.name!r} has no '<finger>_pip'/'<finger>_dip' q entries "
                         f"for {missing}; fingers with both: {found}")
    dtype = model.q_lower.dtype
    n = len(fingers)
    return DipPipCoupling(fingers=tuple(fingers), pip_index=tuple(model.q_lookup(f + "_pip") for f in fingers),
                          dip_index=tuple(model.q_lookup(f + "_dip") for f in fingers),
                          ratio=jnp.full((n,), ratio, dtype), weight=jnp.full((n,), weight, dtype))


class SoftLimits(eqx.Module):
    """Soft joint limits: zero inside ``[lower - margin, upper + margin]``, linear beyond (a
    negative margin lies inside the limits).

    Static: ``index`` (the q entries it acts on). Traced: ``lower``, ``upper``, ``margin`` (rad or
    mm, as the entries) and ``weight`` (1/rad or 1/mm), one value per entry.
    """

    index: tuple[int, ...] = eqx.field(static=True)
    lower: Float[Array, " k"] = eqx.field(converter=jnp.asarray)
    upper: Float[Array, " k"] = eqx.field(converter=jnp.asarray)
    margin: Float[Array, " k"] = eqx.field(converter=jnp.asarray)
    weight: Float[Array, " k"] = eqx.field(converter=jnp.asarray)

    def __check_init__(self):
        k = len(self.index)
        for name in ("lower", "upper", "margin", "weight"):
            if getattr(self, name).shape != (k,):
                raise ValueError(f"SoftLimits.{name}: expected shape ({k},), got {getattr(self, name).shape}")

    def __call__(self, q: Float[ArrayLike, " nq"]) -> Float[Array, " k"]:
        """Residuals ``weight * (relu(q - upper - margin) - relu(lower - margin - q))``.

        Positive above the upper limit, negative below the lower one, exactly 0 in between; the
        residual is continuous and its square (the cost) has a continuous gradient.
        """
        x = q[np.array(self.index, dtype=int)]
        above = jnp.maximum(x - self.upper - self.margin, 0.0)
        below = jnp.maximum(self.lower - self.margin - x, 0.0)
        return self.weight * (above - below)


def soft_limits(model: Model, *, weight: float = 1.0 / np.radians(2.0), margin: float = 0.0,
                names: tuple[str, ...] | None = None) -> SoftLimits:
    """Soft limits on ``model``'s joint angles (default: every revolute q entry, base excluded).

    Args:
        model: the model whose ``q_lower``/``q_upper`` are the limits.
        weight: 1 / sigma (1/rad); the default, 2 deg, costs one residual unit 2 deg past a limit.
        margin: dead zone beyond each limit before the residual starts (rad); negative: the
            residual starts that far inside the range (a pose at its limits is unlikely), but
            never past the model's default pose or the zero angle (a straight finger near its
            extension limit is not).
        names: q names to limit (default: every entry of kind 'angle' that is not a base entry).

    Raises:
        InputError: an unknown name, a negative weight, a margin that is not finite.
    """
    if not (np.isfinite(weight) and weight >= 0 and np.isfinite(margin)):
        raise InputError(f"soft_limits: weight must be finite and >= 0 and margin finite, got {weight!r}, {margin!r}")
    if names is None:
        kinds = model.q_kinds
        idx = tuple(i for i in range(model.n_base_q, model.n_q) if kinds[i] == "angle")
    else:
        bad = [n for n in names if n not in model.q_names]
        if bad:
            raise InputError(f"soft_limits: model {model.name!r} has no q entries {bad}; valid: "
                             f"{', '.join(model.q_names)}")
        idx = tuple(model.q_lookup(n) for n in names)
    sel = np.array(idx, dtype=int)
    dtype = model.q_lower.dtype
    k = len(idx)
    lower, upper = model.q_lower[sel], model.q_upper[sel]
    if margin < 0:   # the band inside the range stops at the default pose and at zero
        rest, zero = jnp.clip(model.q_default[sel], lower, upper), jnp.clip(0.0, lower, upper)
        lower = jnp.minimum(lower - margin, jnp.minimum(rest, zero))
        upper, margin = jnp.maximum(upper + margin, jnp.maximum(rest, zero)), 0.0
    return SoftLimits(index=idx, lower=lower, upper=upper, margin=jnp.full((k,), margin, dtype),
                      weight=jnp.full((k,), weight, dtype))


def stack_priors(priors, q: Float[ArrayLike, " nq"]) -> Float[Array, " r"]:
    """The residuals of several priors, concatenated in order (an empty tuple gives shape (0,))."""
    parts = [p(q) for p in priors]
    return jnp.concatenate(parts) if parts else jnp.zeros((0,), q.dtype)


class TemporalPrior(eqx.Module):
    """A Gaussian prior around a predicted state: ``r = weight * (q - q_pred)`` per q entry, or
    ``r = weight @ (q - q_pred)`` with a square weight matrix (a full information square root).

    Traced: ``q_pred`` (q units) and ``weight`` ((nq,): 1 / sigma per entry, 0 where there is no
    prior; or (nq, nq), e.g. :func:`information_weight`), so a tracker builds one per frame
    without recompiling (whether the weight is a vector or a matrix is static). Weighted by how
    poorly each direction was seen it keeps unobserved joints at the prediction and leaves
    observed ones to the images (thesis ch. 7: a compromise between the solve and the prediction).
    """

    q_pred: Float[Array, " nq"] = eqx.field(converter=jnp.asarray)
    weight: Float[Array, " nq"] | Float[Array, "nq nq"] = eqx.field(converter=jnp.asarray)

    def __check_init__(self):
        n = self.q_pred.shape[0] if self.q_pred.ndim == 1 else -1
        if n < 0 or self.weight.shape not in ((n,), (n, n)):
            raise ValueError("TemporalPrior: q_pred needs shape (nq,) and weight (nq,) or (nq, nq)")

    def __call__(self, q: Float[ArrayLike, " nq"]) -> Float[Array, " nq"]:
        d = q - self.q_pred
        return self.weight @ d if self.weight.ndim == 2 else self.weight * d


def information_weight(weight: Float[Array, "*k nq"], information: Float[Array, "nq nq"], ratio
                       ) -> Float[Array, "*k nq nq"]:
    """The weight matrix of an information-weighted :class:`TemporalPrior` (issue 13 item 5).

    With ``D = diag(weight)`` (1 / sigma per entry, 0 for none) and the image information
    ``Lambda = J^T J`` of the solve (px^2 per unit of q squared; the prior's residual unit is one
    px), ``L = S Lambda S`` is that information in units of the prior's (``S = D^-1`` where the
    weight is not 0, else 0). The prior's information becomes ``D f(L) D`` with
    ``f(L) = ratio (ratio I + L)^-1``: full (``1/sigma^2``) along directions the images do not
    see, falling as ``ratio / l`` along those they see with information ``l`` (so the solve there
    follows the images and a well-seen joint is not held back). Returns the symmetric square root
    ``f(L)^(1/2) D`` (so ``|W d|^2 = d^T D f(L) D d``). ``ratio`` > 0, unitless.

    Several priors' ``weight`` rows (shape ``(k, nq)``) give ``k`` matrices from one
    eigen-decomposition call: under ``vmap`` jaxlib's CPU kernel splits a batch over the thread
    pool and waits for it, so two independent batched calls can starve a two-thread pool.
    """
    weight = jnp.asarray(weight)
    s = jnp.where(weight > 0, 1.0 / jnp.where(weight > 0, weight, 1.0), 0.0)
    lam = 0.5 * (information + information.T) * s[..., :, None] * s[..., None, :]
    eig, vec = jnp.linalg.eigh(lam)
    root = (vec * jnp.sqrt(ratio / (ratio + jnp.maximum(eig, 0.0)))[..., None, :]) @ jnp.swapaxes(vec, -1, -2)
    return root * weight[..., None, :]


def temporal_prior(model: Model, q_pred, *, sigma_deg: float = 10.0, sigma_mm: float = 20.0) -> TemporalPrior:
    """A :class:`TemporalPrior` at ``q_pred`` with one sigma for angles (deg) and one for lengths
    (mm); the entries of a free base's quaternion get none.

    Raises:
        InputError: a sigma is not a positive number.
    """
    if not (sigma_deg > 0 and sigma_mm > 0):
        raise InputError(f"temporal prior: sigmas must be > 0, got {sigma_deg} deg, {sigma_mm} mm")
    q_pred = jnp.asarray(q_pred)
    return TemporalPrior(q_pred=q_pred, weight=jnp.asarray(temporal_weight(model, sigma_deg, sigma_mm), q_pred.dtype))


def temporal_weight(model: Model, sigma_deg: float, sigma_mm: float) -> np.ndarray:
    """Per q entry ``1 / sigma``: ``1 / radians(sigma_deg)`` for angles, ``1 / sigma_mm`` for
    lengths, 0 for a free base's quaternion; a sigma of 0 (or None) gives that kind no prior."""
    kinds = np.asarray(model.q_kinds)
    w_angle = 1.0 / np.radians(sigma_deg) if sigma_deg else 0.0
    w_length = 1.0 / sigma_mm if sigma_mm else 0.0
    return np.where(kinds == "angle", w_angle, np.where(kinds == "length", w_length, 0.0))
