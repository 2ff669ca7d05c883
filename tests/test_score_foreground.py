"""Foreground models on synthetic frames whose foreground is known exactly."""

import cv2
import numpy as np
import pytest
from mujoco_hand import frame

from jaxhand.score import BackgroundForeground, SkinForeground, ThresholdForeground, as_grey


def _disc_image(background, value=150, noise=0.0, seed=0):
    img = np.full((60, 80), float(background))
    yy, xx = np.mgrid[0:60, 0:80]
    disc = (xx - 40) ** 2 + (yy - 30) ** 2 < 15**2
    img[disc] = value
    img += np.random.default_rng(seed).normal(0, noise, img.shape)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8), disc


@pytest.mark.parametrize("method", ["triangle", "otsu", "fixed"])
def test_threshold_finds_a_disc_on_black(method):
    img, disc = _disc_image(0, noise=3.0)
    fg = ThresholdForeground(method=method, threshold=40.0)
    assert np.count_nonzero(fg.mask(img) != disc) <= 4


def test_triangle_keeps_the_dark_contours_otsu_drops():
    img = frame("open_close_000.png")  # MuJoCo: background exactly 0, hand 18..222
    tri, otsu = ThresholdForeground(), ThresholdForeground(method="otsu")
    assert tri.level(img) == 8.0  # the floor: the histogram's foot is at 2
    assert 80 <= otsu.level(img) <= 100  # measured 92
    n_tri, n_otsu = tri.mask(img).sum(), otsu.mask(img).sum()
    assert n_otsu < 0.96 * n_tri


def test_background_from_frames_ignores_a_moving_object():
    rng = np.random.default_rng(1)
    bg = cv2.GaussianBlur(rng.uniform(40, 200, (60, 80)), (0, 0), 3)
    frames = []
    for k in range(7):  # a bright square crossing the image: the median never sees it
        f = bg + rng.normal(0, 2, bg.shape)
        f[10:25, 5 + 10 * k: 15 + 10 * k] = 255
        frames.append(np.clip(np.rint(f), 0, 255).astype(np.uint8))
    model = BackgroundForeground.from_frames(frames)
    np.testing.assert_allclose(model.background, bg, atol=4.0)
    img = np.clip(np.rint(bg + rng.normal(0, 2, bg.shape)), 0, 255).astype(np.uint8)
    img[30:50, 30:50] = np.clip(bg[30:50, 30:50] + 60, 0, 255).astype(np.uint8)
    m = model.mask(img)
    truth = np.zeros_like(m)
    truth[30:50, 30:50] = True
    assert np.count_nonzero(m != truth) <= 8
    with pytest.raises(ValueError, match="shape"):
        model.mask(img[:10])


def test_background_from_a_given_image():
    img, disc = _disc_image(90, value=140, noise=2.0)
    model = BackgroundForeground.from_image(np.full((60, 80), 90, np.uint8))
    assert np.count_nonzero(model.mask(img) != disc) <= 4


def test_skin_model_fitted_and_default():
    rng = np.random.default_rng(2)
    bgr = np.zeros((60, 80, 3), np.uint8)
    bgr[:] = (200, 120, 40)  # blue-ish background
    yy, xx = np.mgrid[0:60, 0:80]
    hand = (xx - 40) ** 2 + (yy - 30) ** 2 < 15**2
    skin = np.array([120, 150, 210])  # BGR of a light skin tone
    bgr[hand] = np.clip(skin + rng.normal(0, 4, (hand.sum(), 3)), 0, 255).astype(np.uint8)
    fitted = SkinForeground.fit(bgr, hand)  # 3 sigma in 2-D keeps 98.9 %: about 8 of 700 pixels miss
    assert np.count_nonzero(fitted.mask(bgr) != hand) <= 12
    assert np.count_nonzero(SkinForeground().mask(bgr) != hand) <= 6
    with pytest.raises(ValueError, match="BGR"):
        SkinForeground().mask(bgr[..., 0])


def test_bad_inputs():
    with pytest.raises(ValueError, match="expected an"):
        as_grey(np.zeros((4, 4, 2)))
    with pytest.raises(ValueError, match="non-finite"):
        as_grey(np.full((4, 4), np.nan))
    with pytest.raises(ValueError, match="method"):
        ThresholdForeground(method="mean")
    with pytest.raises(ValueError, match="cov"):
        SkinForeground(cov=((1.0, 2.0), (2.0, 1.0)))
