"""The frame's score and loss rule: one function on the host and in the compiled step."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxhand import InputError
from jaxhand.track import LossConfig, TrackConfig, confidence_of, frame_score


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
