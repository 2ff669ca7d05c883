"""The template refresh at a solved pose (:func:`jaxhand.image.refresh_templates`): a link keeps
its template until it has moved ``refresh.min_move`` radii since its last refresh, and with the
gate off the refresh is :func:`jaxhand.image.capture_templates` itself."""

import numpy as np
import pytest

from jaxhand.image import ImageConfig, RefreshConfig, capture_templates, refresh_templates
from jaxhand.render import RenderConfig, make_preset, render_frame


@pytest.fixture(scope="module")
def scene():
    seq = make_preset("two_finger_occlusion", frames=80, size=(320, 240))
    image = render_frame(seq.model, seq.cameras[0], seq.q[10], RenderConfig(antialias=1)).image
    return seq, image


def _same(a, b):
    return all(np.array_equal(x, y) for x, y in zip(a.templates, b.templates)) and all(
        np.array_equal(x, y) for x, y in zip(a.template_mask, b.template_mask))


def test_refresh_without_gate_is_capture(scene):
    seq, image = scene
    config = ImageConfig(refresh=RefreshConfig(min_move=0.0))
    start = capture_templates(image, seq.model, seq.cameras, seq.q[10], config)
    q = seq.q[10] + np.radians(2.0) * seq.model.is_angle
    assert _same(refresh_templates(image, seq.model, seq.cameras, q, config, start),
                 capture_templates(image, seq.model, seq.cameras, q, config, start))


def test_a_link_seen_at_a_slightly_wrong_pose_keeps_its_template(scene):
    seq, image = scene
    m = seq.model
    config = ImageConfig(refresh=RefreshConfig(min_move=0.5))
    first = refresh_templates(image, m, seq.cameras, seq.q[10], config,
                              capture_templates(image, m, seq.cameras, seq.q[10], config))
    assert np.isfinite(first.refreshed_px[0]).all()   # the first refresh takes every link and records where
    # the index's distal joint solved 1 deg off: its phalanx moves by far less than half a radius
    dip = m.q_lookup("index_dip")
    off = seq.q[10].copy()
    off[dip] += np.radians(1.0)
    kept = refresh_templates(image, m, seq.cameras, off, config, first)
    assert _same(kept, first)
    np.testing.assert_array_equal(kept.refreshed_px[0], first.refreshed_px[0])
    # ... where a capture (the thesis's refresh) stores the profiles of the wrong pose
    assert not _same(capture_templates(image, m, seq.cameras, off, config, first), first)
    # turned by 25 deg the distal phalanx has moved: its template (and only the moved links') is re-taken
    off[dip] += np.radians(24.0)
    moved = refresh_templates(image, m, seq.cameras, off, config, first)
    link = m.link_lookup("index_dip")
    assert not np.array_equal(moved.templates[0][link], first.templates[0][link])
    assert not np.array_equal(moved.refreshed_px[0][link], first.refreshed_px[0][link])
    others = np.arange(m.n_links) != link
    np.testing.assert_array_equal(moved.templates[0][others], first.templates[0][others])
