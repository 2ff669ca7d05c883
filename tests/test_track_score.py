"""The frame's score and loss rule: one function on the host and in the compiled step."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxhand import InputError
from jaxhand.render import make_preset
from jaxhand.track import (
    ExactFrontEnd,
    LossConfig,
    TrackConfig,
    Tracker,
    confidence_of,
    frame_score,
    reported_confidence,
)


@pytest.mark.parametrize("rms, share", [(0.0, 1.0), (2.0, 0.5), (5.9, 0.2), (6.5, 1.0), (1.0, 0.1), (np.inf, 1.0),
                                        (np.nan, 0.8)])
def test_host_and_jit_agree(rms, share):
    loss = LossConfig()
    host = confidence_of(rms, share, TrackConfig())
    jitted = jax.jit(lambda r, s: frame_score(r, s, loss.rms_scale_px, loss.min_valid_share, loss.max_rms_px))(
        jnp.asarray(rms), jnp.asarray(share))
    assert host == (float(jitted[0]), bool(jitted[1]))
    assert np.isfinite(host[0])


def test_golden_scores():
    # share / (1 + (rms / 2)^2): rms 2 px halves the confidence
    assert confidence_of(2.0, 0.5, LossConfig()) == (0.25, False)
    assert confidence_of(0.0, 0.1, LossConfig()) == (0.1, True)            # too few valid features
    assert confidence_of(8.0, 1.0, LossConfig()) == (1 / 17, True)         # residual RMS above 6 px
    assert confidence_of(np.inf, 1.0, LossConfig()) == (0.0, True)
    assert confidence_of(8.0, 1.0, LossConfig(max_rms_px=9.0, rms_scale_px=4.0)) == (0.2, False)


@pytest.mark.parametrize("rms, share, good", [(0.0, 0.3, 0.5), (2.0, 0.6, 0.5), (1.0, 0.45, 0.9), (0.0, 0.1, 0.5)])
def test_a_share_over_its_good_level_does_not_lower_the_confidence(rms, share, good):
    loss = LossConfig(valid_share_good=good)
    expected = min(1.0, share / good) / (1 + (rms / 2.0) ** 2)
    host = confidence_of(rms, share, loss)
    score = jax.jit(lambda r, s: frame_score(r, s, 2.0, 0.15, 6.0, share_good=good))
    jitted = score(jnp.asarray(rms), jnp.asarray(share))
    assert host[0] == pytest.approx(expected, rel=1e-12) and float(jitted[0]) == pytest.approx(expected, rel=1e-12)
    assert host[1] == bool(jitted[1]) == (share < 0.15)
    assert confidence_of(0.0, 0.3, LossConfig()) == (0.3, False)   # default 1: the share itself


def test_valid_share_good_must_lie_in_0_1():
    with pytest.raises(InputError, match=r"loss.valid_share_good: must lie in \(0, 1\], got 0.0"):
        LossConfig(valid_share_good=0.0)


def test_the_reported_confidence_puts_the_doubt_level_at_one_half():
    assert [reported_confidence(c, 0.8) for c in (0.0, 0.4, 0.8, 0.9, 1.0)] == pytest.approx(
        [0.0, 0.25, 0.5, 0.75, 1.0], abs=1e-12)
    assert [reported_confidence(c) for c in (0.0, 0.2, 0.5, 0.93, 1.0)] == [0.0, 0.2, 0.5, 0.93, 1.0]
    assert reported_confidence(1.2, 0.8) == 1.0 and reported_confidence(-0.1, 0.8) == 0.0
    c = np.linspace(0, 1, 101)
    assert np.all(np.diff([reported_confidence(x, 0.3) for x in c]) > 0)   # monotone: the order is kept
    for bad in (0.0, 1.0):
        with pytest.raises(InputError, match=r"loss.doubt_level: must lie in \(0, 1\)"):
            LossConfig(doubt_level=bad)


def test_the_tracker_reports_the_mapped_confidence_and_keeps_its_own():
    seq = make_preset("two_finger_occlusion", frames=3, size=(160, 120))
    runs = []
    for level in (0.5, 0.8):
        config = TrackConfig(loss=LossConfig(doubt_level=level))
        tracker = Tracker(seq.model, seq.cameras, ExactFrontEnd(seq.model, seq.cameras, seq.q, noise_px=1.5),
                          config, dt_s=1 / 30)
        state = tracker.init(seq.q[0])
        runs.append([])
        for k in range(3):
            state, rep = tracker.step(state, [None], k)
            runs[-1].append((state.confidence, rep.confidence, rep.q_filtered))
    for (own, shown, q), (own8, shown8, q8) in zip(*runs):
        assert own == shown and own8 == own and np.array_equal(q8, q)   # the tracking is the same
        assert shown8 == pytest.approx(reported_confidence(own, 0.8), abs=1e-15) and 0.0 < shown8 < own < 1.0
