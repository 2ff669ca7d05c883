"""Helpers shared by the tests."""

import jax
import numpy as np

import jaxhand as jh


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
