"""Property tests of the public kinematics entry points: any q gives finite numbers or InputError."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

import jaxhand as jh

MODEL = jh.builtin_model("index_thumb")
CAMERA = jh.Orthographic.fit(np.asarray(jh.forward(MODEL, MODEL.q_default).link_end))


@settings(max_examples=80, deadline=None)
@given(q=st.lists(st.floats(allow_nan=True, allow_infinity=True, width=64), min_size=0, max_size=MODEL.n_q + 2))
def test_forward_and_project_pose_return_finite_numbers_or_raise(q):
    q = np.asarray(q, float)
    good = q.shape == (MODEL.n_q,) and bool(np.all(np.isfinite(q)))
    for call in (lambda: jh.forward(MODEL, q).tips, lambda: jh.project_pose(MODEL, CAMERA, q).tips_px):
        try:
            out = np.asarray(call())
        except jh.InputError as err:
            assert not good and "q: " in str(err)
            continue
        assert good and np.all(np.isfinite(out)) or not np.all(np.abs(q) < 1e150)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_random_q_is_inside_the_limits_and_finite(seed):
    q = jh.random_q(MODEL, np.random.default_rng(seed), 3)
    assert q.shape == (3, MODEL.n_q) and np.all(np.isfinite(q))
    assert np.all(q >= np.asarray(MODEL.q_lower)) and np.all(q <= np.asarray(MODEL.q_upper))
