"""Helpers shared by the tests."""

import cv2
import jax
import numpy as np

import jaxhand as jh
from jaxhand.features import empty_features, features_from_pose
from jaxhand.track import AbstractFrontEnd, FrontEndResult


def fit_camera(model, q=None, size=(320, 240), R=None):
    """An orthographic camera framing ``model`` at ``q`` (default pose)."""
    q = model.q_default if q is None else q
    pose = jh.forward(model, q)
    return jh.Orthographic.fit(np.concatenate([pose.link_start, pose.link_end]), size=size, R=R)


class CompileCounter:
    """Counts XLA compilations while active (jax.monitoring backend-compile events)."""

    _active: list = []
    _installed = False

    def __init__(self):
        self.count = 0
        if not CompileCounter._installed:
            jax.monitoring.register_event_duration_secs_listener(CompileCounter._listener)
            CompileCounter._installed = True

    @staticmethod
    def _listener(name, duration, **kwargs):
        if name.endswith("backend_compile_duration"):
            for c in CompileCounter._active:
                c.count += 1

    def __enter__(self):
        CompileCounter._active.append(self)
        return self

    def __exit__(self, *exc):
        CompileCounter._active.remove(self)


class FunctionFrontEnd(AbstractFrontEnd):
    """A front end from a function ``fn(images, q_start, state, frame) -> features`` (tests only)."""

    def __init__(self, fn, reextracts: bool = True):
        self.fn, self.reextracts = fn, reextracts

    def extract(self, images, q_start, state, frame):
        return FrontEndResult(tuple(self.fn(images, q_start, state, frame)), state)


def fixed_front_end(features, reextracts: bool = True) -> FunctionFrontEnd:
    """A front end that returns ``features`` (one per camera, or one Features) on every frame."""
    feats = (features,) if isinstance(features, jh.Features) else tuple(features)
    return FunctionFrontEnd(lambda images, q, state, frame: feats, reextracts)


def oracle(model, cameras, truth, noise_px=0.3, seed=0, drop_frame=None) -> FunctionFrontEnd:
    """Exact features of ``truth[frame]`` with noise drawn frame after frame (as ExactFrontEnd);
    on ``drop_frame`` every feature is missing, with NaN in the empty slots."""
    rng = np.random.default_rng(seed)
    feats = [features_from_pose(model, cameras, q, noise_px=noise_px, rng=rng) for q in truth]

    def extract(images, q_start, state, frame):
        if frame == drop_frame:
            f = empty_features(model)
            f = type(f)(f.lines * np.nan, f.line_valid, f.line_weight, f.tips * np.nan, f.tip_valid, f.tip_weight)
            return tuple(f for _ in cameras)
        return feats[frame]

    return FunctionFrontEnd(extract, reextracts=False)


def stopping_oracle(seq, at: int, exc=KeyboardInterrupt) -> FunctionFrontEnd:
    """:func:`oracle` of ``seq`` that raises ``exc`` when asked for frame ``at`` (a run stopped there)."""
    inner = oracle(seq.model, seq.cameras, seq.q)

    def extract(images, q, state, frame):
        if frame == at:
            raise exc()
        return inner.fn(images, q, state, frame)

    return FunctionFrontEnd(extract, reextracts=False)


def blank_frames(folder, n: int, size) -> object:
    """``folder`` made and filled with ``n`` black PNG frames of ``size`` (w, h); returns it."""
    folder.mkdir()
    for k in range(n):
        cv2.imwrite(str(folder / f"f{k:03d}.png"), np.zeros(size[::-1], np.uint8))
    return folder
