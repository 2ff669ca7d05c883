"""The front end's compiled steps give the NumPy steps' answers to rounding: the line fit
(:func:`fit_rows`) against the frozen reference copy's RANSAC + PCA and axial line
(``tests/reference_image/_lines.py``, the NumPy implementation before it was compiled), the iMWPLLS
crest fit against :func:`imwplls`; and re-acquisition's other row counts compile a bounded number
of times."""

import numpy as np
import pytest
from reference_image._lines import axial_line, line_params, offset_towards, ransac_pca

from jaxhand.image import ImageConfig, extract_features
from jaxhand.image._linefit import _fit
from jaxhand.image._regression import _imwplls_crest
from jaxhand.image.internal import fit_rows, imwplls, imwplls_crest_fit, padded_rows
from jaxhand.image.searches._rectilinear import crest_weights
from jaxhand.render import RenderConfig, make_preset, render_frame

LC = ImageConfig().lines


def _numpy_fit(edge_px, edge_ok, mid, radius, direction, s_ok, share):
    """The NumPy line fit the compiled one replaced (the reference copy's steps)."""
    pts = np.swapaxes(np.where(edge_ok[..., None], edge_px, 0.0), 1, 2)
    p, v, ok, inliers = ransac_pca(pts, np.swapaxes(edge_ok, 1, 2), LC.tau_px, LC.min_inliers)
    p_ax, v_ax = axial_line(p[:, 0], v[:, 0], p[:, 1], v[:, 1], LC.det_eps)
    single = LC.single_edge & (ok[:, 0] ^ ok[:, 1])
    k = np.where(ok[:, 0], 0, 1)
    rows = np.arange(len(k))
    p_one = offset_towards(p[rows, k], v[rows, k], mid, radius)
    p_ax = np.where(single[:, None], p_one, p_ax)
    v_ax = np.where(single[:, None], v[rows, k], v_ax)
    lines = line_params(p_ax, v_ax, direction)
    valid = s_ok & ((ok[:, 0] & ok[:, 1]) | single) & (share >= LC.min_visible)
    return lines, valid, ok, inliers, single & valid


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_compiled_line_fit_equals_numpy(seed):
    rng = np.random.default_rng(seed)
    L, S = 13, 8
    t = np.linspace(0, 40, S)[None, :, None]
    a = rng.uniform(0, np.pi, (L, 1, 1))
    centre = rng.uniform(50, 250, (L, 1, 2))
    along = np.concatenate([np.cos(a), np.sin(a)], -1)
    normal = along[..., ::-1] * [-1, 1]
    edge_px = np.stack([centre + t * along + s * 6 * normal + rng.normal(0, 0.3, (L, S, 2)) for s in (-1, 1)], 2)
    edge_px[rng.random((L, S, 2)) < 0.1] += rng.normal(0, 8, 2)  # outliers
    edge_ok = rng.random((L, S, 2)) > 0.15
    edge_ok[0, :, 1] = False  # one boundary only: offset by the radius
    edge_ok[1] = False        # no boundary
    edge_px = np.where(edge_ok[..., None], edge_px, np.nan)
    mid, radius = centre[:, 0] + 20 * along[:, 0], rng.uniform(4, 8, L)
    direction, s_ok, share = along[:, 0], rng.random(L) > 0.1, rng.uniform(0, 1, L)
    got = fit_rows(edge_px, edge_ok, mid, radius, direction, s_ok, share, LC)
    lines, valid, ok, inliers, single = _numpy_fit(edge_px, edge_ok, mid, radius, direction, s_ok, share)
    np.testing.assert_array_equal(got["valid"], valid)
    np.testing.assert_array_equal(got["bvalid"], ok)
    np.testing.assert_array_equal(got["inliers"], inliers)
    np.testing.assert_array_equal(got["single"], single)
    np.testing.assert_allclose(got["lines"][valid], lines[valid], rtol=0, atol=1e-9)
    assert not got["valid"][1]


def test_compiled_imwplls_equals_numpy():
    rng = np.random.default_rng(5)
    shifts = np.arange(-14, 15)
    x = np.arange(8.0)
    crest = 1.5 + 0.4 * x[None, :, None] + rng.normal(0, 2, (11, 1, 1))
    C = np.exp(-0.5 * ((shifts - crest) / 2.0) ** 2) + 0.3 * rng.random((11, 8, 29))
    ok = rng.random((11, 8)) > 0.1
    ok[0] = False  # singular
    for floor, hw, it in ((0.5, 3.4, 20), (0.0, 2.0, 1)):
        want_c, want_ok, _ = imwplls(x, shifts.astype(float), crest_weights(C, floor), ok, hw, it)
        c, fit_ok = imwplls_crest_fit(C, shifts, ok, floor, hw, it)
        np.testing.assert_array_equal(fit_ok, want_ok)
        np.testing.assert_allclose(c, want_c, rtol=0, atol=1e-9)


def test_row_padding_bounds_the_compilations():
    assert [padded_rows(n) for n in (1, 15, 16, 17, 40)] == [16, 16, 16, 32, 64]
    seq = make_preset("two_camera_hand", frames=40)
    config = ImageConfig(method="imwplls", reacquire_deg=(8.0, 16.0))
    rng = np.random.default_rng(1)
    counts = []
    for k in range(0, 40, 4):
        images = [render_frame(seq.model, cam, seq.q[k], RenderConfig(antialias=1)).image for cam in seq.cameras]
        q = seq.q[k] + np.where(seq.model.is_angle, np.radians(6.0) * rng.standard_normal(seq.model.n_q), 0.0)
        extract_features(images, seq.model, seq.cameras, q, config)
        counts.append((_fit._cache_size(), _imwplls_crest._cache_size()))
    assert max(max(c) for c in counts) <= 4  # a few padded sizes, not one per batch
