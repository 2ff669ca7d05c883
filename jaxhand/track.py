"""The tracker: predict, extract features, solve, filter, once per frame (thesis chs. 4-6).

Per frame k (thesis fig. 1.2 / DESIGN.md data flow):

1. **predict** the state q̂_k with the g-h-k filter (thesis eqs. 5.4-5.6), clipped to the
   joint limits;
2. **extract features** from every camera around the prediction (image front end; visibility
   windows come from the predicted pose, templates from earlier unoccluded views);
3. **solve** for the pose q̃_k from those features starting at q̂_k (configurable solver and
   iterations, including the thesis's fast mode of one update per frame);
4. **filter**: refine q̃_k with the g-h-k update (eqs. 5.1-5.3) into the reported estimate;
5. score the frame: residual RMS (px) and the share of valid features give a confidence in
   [0, 1] and a loss-of-track flag. A failed or non-finite solve keeps the prediction.

The sequence loop is host Python (frames come from disk and the image front end is NumPy);
the solve and the filter step are jitted once per model structure, so a sequence never
recompiles. Results are written frame by frame.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Sequence
from typing import Any

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ._errors import InputError
from .camera import as_rig
from .features import Features
from .filter import GHKState, ghk_init, ghk_predict, ghk_update
from .kinematics import _pose, clip_q, link_points, validate_q
from .model import Model

__all__ = ["TrackConfig", "TrackState", "StepReport", "Tracker", "confidence_of", "exact_extractor",
           "feature_errors", "reweight"]


@dataclasses.dataclass(frozen=True)
class TrackConfig:
    """Tracker settings (host-side; numbers that enter jitted code are passed as arrays).

    Attributes:
        solver: solver name for :func:`jaxhand.fit` (e.g. "gn", "lm", "bounded").
        max_steps: solver iterations per frame (1 = the thesis's fast mode).
        theta: g-h-k discount factor in [0, 1] (thesis §6 uses 0.85).
        filter: apply the g-h-k filter (False: report and predict the raw solve).
        rms_scale_px: residual RMS (px) at which the confidence halves.
        min_valid_share: below this share of valid features the frame counts as lost.
        max_rms_px: above this residual RMS (px) the frame counts as lost.
        robust_passes: re-solves after reweighting every feature by its residual at the last
            solution (iteratively reweighted least squares with Cauchy weights
            ``w / (1 + (e / robust_scale_px)^2)``), so a few wrong image features cannot pull the
            pose away. 0 solves once, as the thesis does.
        robust_scale_px: the Cauchy scale (px): a feature this far from the model halves its weight.
        refresh_templates: after a frame that is not lost, let the front end store the profiles
            seen at the solved pose as templates (when it keeps templates).
        hold_on_loss: on a lost frame, report the last good estimate and predict it standing
            still, rather than filtering the lost frame's solve into the state.
    """

    solver: str = "lm"
    max_steps: int = 20
    theta: float = 0.85
    filter: bool = True
    rms_scale_px: float = 2.0
    min_valid_share: float = 0.3
    max_rms_px: float = 6.0
    robust_passes: int = 2
    robust_scale_px: float = 2.0
    refresh_templates: bool = True
    hold_on_loss: bool = True

    def __post_init__(self):
        if not 0.0 <= self.theta <= 1.0:
            raise InputError(f"theta must lie in [0, 1], got {self.theta}")
        if self.max_steps < 1:
            raise InputError(f"max_steps must be >= 1, got {self.max_steps}")
        if self.robust_passes < 0 or self.robust_scale_px <= 0:
            raise InputError(f"robust_passes must be >= 0 and robust_scale_px > 0, got {self.robust_passes}, "
                             f"{self.robust_scale_px}")


@dataclasses.dataclass(frozen=True)
class TrackState:
    """What the tracker carries between frames: the filter state (whose x is the prediction for
    the next frame) and the image front end's state (templates, widths)."""

    ghk: GHKState
    image_state: Any
    frames_done: int = 0
    q_last: np.ndarray | None = None


@dataclasses.dataclass(frozen=True)
class StepReport:
    """Exactly what gets written for one frame."""

    frame: int
    time_s: float
    q_pred: np.ndarray
    q_solved: np.ndarray
    q_filtered: np.ndarray
    cost: float
    rms_px: float
    iterations: int
    status: str
    valid_share: float
    confidence: float
    lost: bool
    timings_s: dict[str, float]
    diagnostics: Any = None


def confidence_of(rms_px: float, valid_share: float, config: TrackConfig) -> tuple[float, bool]:
    """Confidence in [0, 1] (valid share times 1 / (1 + (rms / scale)^2)) and the loss flag."""
    conf = valid_share / (1.0 + (rms_px / config.rms_scale_px) ** 2)
    lost = valid_share < config.min_valid_share or rms_px > config.max_rms_px or not np.isfinite(rms_px)
    return float(conf if np.isfinite(conf) else 0.0), bool(lost)


@eqx.filter_jit
def _filter_step(model: Model, ghk: GHKState, q_meas, theta, dt_s, use_filter: bool):
    """g-h-k update with the measured q, then the prediction for the next frame (both clipped)."""
    if model.base_kind == "free":  # keep the measured quaternion in the prediction's hemisphere
        flip = jnp.sign(jnp.dot(q_meas[:4], ghk.x[:4]))
        q_meas = q_meas.at[:4].multiply(jnp.where(flip == 0, 1.0, flip))
    if use_filter:
        updated = ghk_update(ghk, q_meas, theta, dt_s)
    else:
        updated = GHKState(x=q_meas, v=jnp.zeros_like(q_meas), a=jnp.zeros_like(q_meas))
    filtered = clip_q(model, updated.x)
    updated = GHKState(x=filtered, v=updated.v, a=updated.a)
    nxt = ghk_predict(updated, dt_s)
    return filtered, GHKState(x=clip_q(model, nxt.x), v=nxt.v, a=nxt.a)


@eqx.filter_jit
def feature_errors(model: Model, cameras: tuple, features: tuple, q, fractions) -> tuple:
    """Per camera, each link line's largest distance (px) to the model's link points and each tip's
    distance (px) to the model's tip at state q (0 where a feature is invalid)."""
    pose = _pose(model, q)
    out = []
    for cam, f in zip(cameras, features):
        tips_px, _ = cam.project(pose.tips)
        e_tip = jnp.linalg.norm(jnp.where(f.tip_valid[:, None], tips_px - jnp.where(f.tip_valid[:, None], f.tips, 0.0),
                                          0.0), axis=-1)
        pts, _ = cam.project(link_points(pose, fractions))
        lines = jnp.where(f.line_valid[:, None], f.lines, 0.0)
        e_link = jnp.max(jnp.abs(jnp.sum(lines[:, None, :2] * pts, -1) - lines[:, None, 2]), axis=-1)
        out.append((e_link, e_tip))
    return tuple(out)


def reweight(features: tuple, errors: tuple, scale_px: float) -> tuple:
    """Features with Cauchy weights ``w / (1 + (e / scale)^2)`` from their residual errors."""
    out = []
    for f, (e_link, e_tip) in zip(features, errors):
        out.append(eqx.tree_at(lambda g: (g.line_weight, g.tip_weight), f,
                               (f.line_weight / (1.0 + (e_link / scale_px) ** 2),
                                f.tip_weight / (1.0 + (e_tip / scale_px) ** 2))))
    return tuple(out)


def _valid_share(features: Sequence[Features]) -> float:
    valid = sum(int(np.sum(f.line_valid)) + int(np.sum(f.tip_valid)) for f in features)
    total = sum(f.line_valid.shape[-1] + f.tip_valid.shape[-1] for f in features)
    return valid / max(total, 1)


class Tracker:
    """Tracks one model through frames from one or more cameras.

    Args:
        model: the kinematic model.
        cameras: a camera or a rig (tuple of cameras), in the order images are passed.
        extract: the image front end, ``extract(images, q_pred, image_state) -> (features,
            image_state, diagnostics)``, optionally with ``extract.refresh(images, q, image_state)
            -> image_state`` to update templates at the solved pose;
            :class:`jaxhand.cli_track.image_extractor` wraps :func:`jaxhand.image.extract_features`.
        config: tracker settings.
        dt_s: frame interval (s).
    """

    def __init__(self, model: Model, cameras, extract: Callable, config: TrackConfig | None = None,
                 dt_s: float = 1 / 25):
        from .solve import FitConfig, fit

        self.model, self.cameras, self.extract = model, as_rig(cameras), extract
        self.config = config = TrackConfig() if config is None else config
        if dt_s <= 0:
            raise InputError(f"dt_s must be > 0, got {dt_s}")
        self.dt_s = float(dt_s)
        self._fit = fit
        self._fit_config = FitConfig(max_steps=config.max_steps)

    def init(self, q0, image_state=None) -> TrackState:
        """The state before the first frame: the filter sits at q0 with zero velocity."""
        q0 = validate_q(self.model, q0, name="initial pose", within_limits=True)
        return TrackState(ghk=ghk_init(jnp.asarray(q0)), image_state=image_state, q_last=q0)

    def step(self, state: TrackState, images: Sequence[np.ndarray], frame: int = 0, time_s: float = 0.0
             ) -> tuple[TrackState, StepReport]:
        """Process one frame (one image per camera)."""
        if len(images) != len(self.cameras):
            raise InputError(f"expected one image per camera ({len(self.cameras)}), got {len(images)}")
        t0 = time.perf_counter()
        q_pred = state.ghk.x
        features, image_state, diag = self.extract(images, q_pred, state.image_state)
        t1 = time.perf_counter()
        result = self._fit(self.model, self.cameras, features, q_pred, solver=self.config.solver,
                           config=self._fit_config)
        weighted = features
        for _ in range(self.config.robust_passes):
            errors = feature_errors(self.model, self.cameras, tuple(features), result.q,
                                    self._fit_config.link_fractions)
            weighted = reweight(tuple(features), errors, self.config.robust_scale_px)
            result = self._fit(self.model, self.cameras, weighted, result.q, solver=self.config.solver,
                               config=self._fit_config)
        q_solved = np.asarray(result.q)
        cost = float(result.cost)
        t2 = time.perf_counter()
        ok = bool(np.all(np.isfinite(q_solved))) and np.isfinite(cost)
        q_meas = q_solved if ok else np.asarray(q_pred)
        n_res = max(1, 2 * sum(int(np.sum(f.tip_valid)) for f in features)
                    + 2 * sum(int(np.sum(f.line_valid)) for f in features))
        rms = float(np.sqrt(2.0 * cost / n_res)) if ok else float("inf")
        share = _valid_share(features)
        conf, lost = confidence_of(rms, share, self.config)
        if lost and self.config.hold_on_loss and state.q_last is not None:
            # A lost frame's solve fits stray features: hold the last good estimate still
            # (zero velocity and acceleration) instead of letting the filter extrapolate it.
            filtered = np.asarray(state.q_last)
            ghk_next = GHKState(x=jnp.asarray(filtered), v=jnp.zeros_like(state.ghk.v), a=jnp.zeros_like(state.ghk.a))
        else:
            filtered, ghk_next = _filter_step(self.model, state.ghk, jnp.asarray(q_meas),
                                              jnp.asarray(self.config.theta), jnp.asarray(self.dt_s),
                                              self.config.filter)
            filtered = np.asarray(filtered)
        t3 = time.perf_counter()
        timings = {"features": t1 - t0, "solve": t2 - t1, "filter": t3 - t2}
        refresh = getattr(self.extract, "refresh", None)
        if refresh is not None and not lost and self.config.refresh_templates:
            t4 = time.perf_counter()
            image_state = refresh(images, q_meas, image_state)
            timings["templates"] = time.perf_counter() - t4
        if isinstance(diag, dict) and "timings_s" in diag:  # the front end's own split (e.g. visibility)
            timings.update({f"features.{k}": v for k, v in diag["timings_s"].items()})
        report = StepReport(frame=frame, time_s=time_s, q_pred=np.asarray(q_pred), q_solved=q_meas,
                            q_filtered=filtered, cost=cost if ok else float("nan"), rms_px=rms,
                            iterations=int(result.iterations), status=str(result.status_name()), valid_share=share,
                            confidence=conf, lost=lost, timings_s=timings, diagnostics=diag)
        return TrackState(ghk=ghk_next, image_state=image_state, frames_done=state.frames_done + 1,
                          q_last=filtered), report



def exact_extractor(model: Model, cameras, truth, *, noise_px: float = 0.5, seed: int = 0) -> Callable:
    """An oracle front end for experiments: call k returns the exact features of ``truth[k]``
    (every camera) with Gaussian pixel noise of ``noise_px``, ignoring the images. Tracking with
    it measures what the solver and the filter can do with perfect image analysis."""
    from .features import features_from_pose

    rng = np.random.default_rng(seed)
    calls = [0]

    def extract(images, q_pred, state):
        k = calls[0]
        calls[0] += 1
        return features_from_pose(model, cameras, truth[k], noise_px=noise_px, rng=rng), state, {}

    return extract
