"""Phalanx width estimation in the tracker's front end (thesis appendix E).

The hands are rendered with every phalanx radius scaled (thicker or thinner than the model says)
and measured or tracked with the model's own radii, as with a real hand whose widths the model
only guesses. Frames use the renderer's default oblique light, whose shading moves the Gaussian-
derivative boundaries inwards by about 2% of the width: hence the 4% tolerances.
"""

import dataclasses

import equinox as eqx
import numpy as np
import pytest

import jaxhand as jh
from jaxhand.image import ImageConfig, ImageState, measure_widths, update_widths
from jaxhand.render import RenderConfig, make_preset, render_frame
from jaxhand.track import ImageFrontEnd, TrackConfig, Tracker, accuracy_summary


def _scaled(model, scale):
    return eqx.tree_at(lambda m: m.link_radius_mm, model, model.link_radius_mm * scale)


def _images(model, cameras, q):
    return [render_frame(model, c, q, RenderConfig(antialias=3)).image for c in cameras]


@pytest.fixture(scope="module")
def hand():
    return make_preset("full_hand_spread_flex", frames=100)


@pytest.mark.parametrize("scale", [0.8, 1.0, 1.3])
def test_measures_give_each_radius_of_the_rendered_hand(scale):
    seq = make_preset("two_finger_occlusion")
    m, q = seq.model, seq.q[0]   # the fingers apart: most phalanges seen against the background
    measures, valid = measure_widths(_images(_scaled(m, scale), seq.cameras, q), m, seq.cameras, q)
    assert measures.shape == valid.shape == (m.n_links, 8)
    measured = valid.any(-1)
    assert measured.sum() >= 4 and np.all(valid.sum(-1)[measured] >= 4), valid.sum(-1)
    assert np.all(np.isnan(measures[~valid]))
    ratio = np.nanmedian(measures[measured], axis=-1) / np.asarray(m.link_radius_mm)[measured]
    np.testing.assert_allclose(ratio, scale, rtol=0.04)


def test_a_hidden_phalanx_gives_no_measure():
    seq = make_preset("two_finger_occlusion")
    m, q = seq.model, seq.q[40]   # the index across the middle finger: no middle-finger boundary is clear
    measures, valid = measure_widths(_images(m, seq.cameras, q), m, seq.cameras, q)
    middle = [m.link_lookup(f"middle_{j}") for j in ("mcp", "pip", "dip")]
    assert not valid[middle].any()


def test_first_estimate_fills_unmeasured_phalanges_with_the_hand_scale(hand):
    m, q = hand.model, hand.q[0]   # straight fingers: three phalanges touch a neighbour and cannot be measured
    images = _images(_scaled(m, 0.8), hand.cameras, q)
    _, valid = measure_widths(images, m, hand.cameras, q)
    unmeasured = ~valid.any(-1)
    assert 1 <= unmeasured.sum() <= 5, unmeasured
    state = update_widths(images, m, hand.cameras, q, ImageConfig(), None, gain=1.0, fill_unmeasured=True)
    np.testing.assert_allclose(state.radius_mm / np.asarray(m.link_radius_mm), 0.8, rtol=0.04)
    # without filling, those keep the model's radius
    plain = update_widths(images, m, hand.cameras, q, ImageConfig(), None, gain=1.0)
    np.testing.assert_allclose(plain.radius_mm[unmeasured], np.asarray(m.link_radius_mm)[unmeasured])
    # a gain of 0.25 moves each measured radius a quarter of the way (appendix E)
    quarter = update_widths(images, m, hand.cameras, q, ImageConfig(), None, gain=0.25)
    r0 = np.asarray(m.link_radius_mm)
    np.testing.assert_allclose(quarter.radius_mm - r0, 0.25 * (plain.radius_mm - r0), atol=1e-12)
    with pytest.raises(jh.InputError, match=r"gain must lie in \[0, 1\], got 1.5"):
        update_widths(images, m, hand.cameras, q, ImageConfig(), None, gain=1.5)


def test_front_end_uses_the_estimated_radii(hand):
    m, q = hand.model, hand.q[0]
    state = dataclasses.replace(ImageState.empty(1, m.n_links, (8, 48, 1.75)), radius_mm=np.asarray(m.link_radius_mm)
                                * 1.25)
    _, diag = jh.extract_features(_images(m, hand.cameras, q), m, hand.cameras, q, ImageConfig(), state)
    np.testing.assert_allclose(diag.state.radius_mm, state.radius_mm)   # carried along
    plain = jh.extract_features(_images(m, hand.cameras, q), m, hand.cameras, q, ImageConfig())[1]
    # profile spacing follows the radius: 1.25 times as far apart
    ok = plain.cameras[0].samplers.ok
    np.testing.assert_allclose(diag.cameras[0].samplers.spacing_px[ok] / plain.cameras[0].samplers.spacing_px[ok],
                               1.25, rtol=1e-9)
    with pytest.raises(jh.InputError, match=r"radius_mm: expected shape \(15,\)"):
        dataclasses.replace(state, radius_mm=np.ones(3)).model_radii(m)
    with pytest.raises(jh.InputError, match="width_gain"):
        ImageConfig(width_gain=1.5)


@pytest.mark.slow
def test_tracking_a_thinner_hand_recovers_its_widths_and_the_pose(hand):
    # hand21 with every phalanx 20% thinner than the model: with the model's radii the front end's
    # profiles and windows are too wide and the estimate goes far off; estimating the widths
    # (first frame at gain 1, then 0.05 per frame) keeps it near the truth
    m, n = hand.model, 30
    thin = _scaled(m, 0.8)
    images = [_images(thin, hand.cameras, q) for q in hand.q[:n]]
    errors, radii = {}, None
    for gain in (0.0, 0.05):
        extract = ImageFrontEnd(m, hand.cameras, ImageConfig(method="imwplls", width_gain=gain))
        tracker = Tracker(m, hand.cameras, extract, TrackConfig(reextract=0), dt_s=float(hand.times_s[1]))
        state, qs = tracker.init(hand.q[0]), []
        for k in range(n):
            state, rep = tracker.step(state, images[k], k)
            qs.append(rep.q_filtered)
        errors[gain] = accuracy_summary(m, hand.cameras, np.stack(qs), hand.q[:n])["joint_error_deg"]["mean"]
        radii = None if state.frontend_state is None else state.frontend_state.radius_mm
    np.testing.assert_allclose(radii / np.asarray(m.link_radius_mm), 0.8, rtol=0.04)
    # measured: 2.1 deg against 25.3 deg
    assert errors[0.05] < 3.0 and errors[0.0] > 4 * errors[0.05], errors
