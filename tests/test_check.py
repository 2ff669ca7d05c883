"""Jacobians: jacfwd vs central differences (1e-6 relative) vs the geometric Jacobian (1e-9)."""

import jax.numpy as jnp
import numpy as np
import pytest
from _params import model_params
from helpers import fit_camera

import jaxhand as jh
from jaxhand.camera import look_at_rotation
from jaxhand.check import jacobian_errors


@pytest.mark.parametrize("name", model_params(jh.builtin_names()))
def test_autodiff_matches_finite_differences_and_geometric(name):
    m = jh.builtin_model(name)
    rng = np.random.default_rng(42)
    ortho = fit_camera(m, R=look_at_rotation([1.0, -0.5, -2.0], [0, 0, 0]))
    persp = jh.Perspective.look_at([80.0, -60.0, -500.0], [0.0, 0.0, 0.0])
    worst = {"finite_difference": 0.0, "geometric": 0.0}
    poses = jh.random_q(m, rng, 100)
    poses[0] = np.clip(0.0, m.q_lower, m.q_upper)  # zero angles (or nearest)
    poses[1] = np.asarray(m.q_upper)               # at the limits
    if m.base_kind == "free":
        poses[:2, :4] = [0.0, 0.0, 0.0, 1.0]
        poses[2, :4] = [np.cos(1.55), np.sin(1.55), 0.0, 0.0]  # base rotated near pi
    for k, q in enumerate(poses):
        for cam in (ortho, persp) if k % 4 == 0 else (ortho,):
            e = jacobian_errors(m, cam, jnp.asarray(q))
            worst = {key: max(worst[key], e[key]) for key in worst}
    assert worst["finite_difference"] < 1e-6, worst
    assert worst["geometric"] < 1e-9, worst
