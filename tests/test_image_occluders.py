"""Occluder-only pills (palm, forearm) in the image front end's visibility windows: a link's
profiles behind a nearer occluder are masked like those behind another finger's link."""

import dataclasses
from pathlib import Path

import cv2
import numpy as np
import pytest

from jaxhand.image import ImageConfig, VisibilityConfig
from jaxhand.image.internal import (
    CameraContext,
    Clock,
    OccluderPills,
    as_grey,
    compute_visibility,
    observe,
    same_chain,
)
from jaxhand.io import load_devset

DEVSET = Path(__file__).resolve().parent.parent / "data" / "mujoco"


def _without_occluders(model):
    return dataclasses.replace(model, occluder_names=(), occluder_frame=(), occluder_start_mm=np.zeros((0, 3)),
                               occluder_end_mm=np.zeros((0, 3)), occluder_radius_mm=np.zeros(0))


def _observe(seq, model, k: int):
    img = cv2.imread(str(seq.image_paths[0][k]), cv2.IMREAD_GRAYSCALE)
    cam = seq.cameras[0]
    ctx = CameraContext(grey=as_grey(img, "image", cam.size), model=model, camera=cam,
                        chain=same_chain(model.link_frame, model.ancestors),
                        config=ImageConfig(), clock=Clock())
    return observe(ctx, seq.truth.q[k])


def test_palm_hides_the_thumb_metacarpal_on_a_devset_frame():
    """index_over_middle frame 0 shows the back of the hand: MuJoCo's render has the thumb
    metacarpal entirely behind the palm capsules (truth.json: visible_fraction 0.0, 1,675 of its
    pixels covered by palm_* and forearm). With the MJCF model's occluders every one of its
    profile samples is masked and its visible share matches the truth; without them more than
    half of its samples are in its window."""
    seq = load_devset(DEVSET / "index_over_middle")
    m = seq.model
    assert set(m.occluder_names) == {"forearm", "palm_index", "palm_middle", "palm_ring", "palm_little"}
    tm = m.link_names.index("thumb_metacarpal")
    truth_share = seq.truth.visible_fraction[0, 0, seq.truth.phalanx_names.index("thumb_metacarpal")]
    assert truth_share == 0.0
    with_occ = _observe(seq, m, 0)
    without = _observe(seq, _without_occluders(m), 0)
    assert not with_occ.window[tm].any()
    assert with_occ.visibility.visible_share[tm] == pytest.approx(truth_share, abs=0.02)
    assert without.window[tm].mean() > 0.5
    assert without.visibility.visible_share[tm] == 1.0
    # the thumb's proximal phalanx lies behind the palm too (truth 0.009 visible)
    tp = m.link_names.index("thumb_proximal")
    assert with_occ.visibility.visible_share[tp] == pytest.approx(
        seq.truth.visible_fraction[0, 0, seq.truth.phalanx_names.index("thumb_proximal")], abs=0.02)
    # links no occluder covers keep exactly their windows
    free = np.flatnonzero(~with_occ.visibility.nearer[:, m.n_links:].any(1))
    assert len(free) >= 5
    np.testing.assert_array_equal(with_occ.window[free], without.window[free])


def _one_link(occluder_depth: float):
    """A horizontal link from (20, 50) to (80, 50), radius 6 px, depth 100 mm, and a vertical
    occluder pill across its middle (x = 50, radius 5 px) at ``occluder_depth``."""
    occ = OccluderPills(start_px=np.array([[50.0, 20.0]]), end_px=np.array([[50.0, 80.0]]),
                        depth=np.array([[occluder_depth, occluder_depth]]), radius_start=np.array([5.0]),
                        radius_end=np.array([5.0]))
    vis = compute_visibility(np.array([[20.0, 50.0]]), np.array([[80.0, 50.0]]), np.array([[100.0, 100.0]]),
                             np.array([6.0]), np.array([6.0]), np.zeros((1, 1), bool), (100, 100),
                             VisibilityConfig(), occ)
    pts = np.stack([np.linspace(20, 80, 61), np.full(61, 50.0)], -1)[None]
    return vis, vis.window_mask(pts)[0], pts[0, :, 0]


def test_a_nearer_occluder_cuts_the_window_and_a_farther_one_does_not():
    vis, win, x = _one_link(occluder_depth=90.0)
    # cut where the occluder (radius 5 px) grown by the 1.5 px margin covers the axis: |x - 50| <= 6.5
    np.testing.assert_array_equal(win, np.abs(x - 50) > 6.5 + 1e-9)
    # the visible polygon loses the strip of width 10 px of a 72 x 12 px (plus caps) outline
    full = np.pi * 36 + 60 * 12
    assert vis.visible_share[0] == pytest.approx((full - 10 * 12) / full, abs=0.01)
    vis, win, _ = _one_link(occluder_depth=110.0)
    assert win.all() and vis.visible_share[0] == pytest.approx(1.0)
    assert not vis.nearer.any()
