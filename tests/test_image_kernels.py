"""The image front end's vectorised kernels against slow, obvious references, and the shared search
signature."""

import dataclasses

import numpy as np
import pytest
import shapely

from jaxhand import InputError
from jaxhand.image import SEARCH_NAMES, SearchConfig
from jaxhand.image import SamplerConfig as SC
from jaxhand.image.internal import (
    Edges,
    Profiles,
    as_grey,
    correlate_last,
    correlate_shifts,
    derivative_kernel,
    gaussian_derivative,
    parabola_vertex,
    pill_outlines,
    place_link_samplers,
    sample_profiles,
    search_named,
    simple_derivative,
    width_template,
    window_masks,
    wssd_surface,
)
from jaxhand.track import config_from_dict


def _image(seed=0, h=30, w=40):
    return np.random.default_rng(seed).uniform(0, 255, (h, w)).astype(np.float32)


def _positions(rng, n, h, w, margin=0.0):
    # on OpenCV's 1/32-pixel grid, so its fixed-point positions are exact
    x = np.round(rng.uniform(margin, w - 1 - margin, n) * 32) / 32
    y = np.round(rng.uniform(margin, h - 1 - margin, n) * 32) / 32
    return np.stack([x, y], -1)


def _ref_pixel(img, x, y):
    h, w = img.shape
    return float(img[min(max(y, 0), h - 1), min(max(x, 0), w - 1)])  # border replicated


def _keys(t, a=-0.75):
    t = abs(t)
    if t <= 1:
        return (a + 2) * t**3 - (a + 3) * t**2 + 1
    if t < 2:
        return a * t**3 - 5 * a * t**2 + 8 * a * t - 4 * a
    return 0.0


def _ref_sample(img, x, y, kind):
    if kind == "nearest":
        return _ref_pixel(img, int(np.floor(x + 0.5)), int(np.floor(y + 0.5)))
    x0, y0 = int(np.floor(x)), int(np.floor(y))
    fx, fy = x - x0, y - y0
    if kind == "bilinear":
        return sum(wx * wy * _ref_pixel(img, x0 + i, y0 + j)
                   for i, wx in ((0, 1 - fx), (1, fx)) for j, wy in ((0, 1 - fy), (1, fy)))
    return sum(_keys(i - fx) * _keys(j - fy) * _ref_pixel(img, x0 + i, y0 + j)
               for i in range(-1, 3) for j in range(-1, 3))


@pytest.mark.parametrize("kind", ["nearest", "bilinear", "bicubic"])
def test_sample_profiles_matches_reference(kind):
    img = _image()
    rng = np.random.default_rng(1)
    pts = _positions(rng, 300, *img.shape).reshape(10, 6, 5, 2)
    if kind == "nearest":  # keep clear of exact half-pixel ties
        pts = np.where(np.abs(pts % 1 - 0.5) < 0.05, pts + 0.125, pts).clip(0, [img.shape[1] - 1, img.shape[0] - 1])
    vals, usable = sample_profiles(img, pts, kind)
    assert vals.shape == (10, 6, 5) and usable.all()
    ref = np.array([_ref_sample(img, x, y, kind) for x, y in pts.reshape(-1, 2)]).reshape(10, 6, 5)
    assert np.allclose(vals, ref, atol=1e-3)


def test_sample_profiles_masks_outside_and_nonfinite():
    img = _image()
    img[5, 5] = np.nan
    pts = np.array([[-0.5, 3.0], [39.0, 29.0], [39.01, 3.0], [5.0, 5.0], [np.nan, 2.0], [1e12, -1e12], [10.0, 10.0]])
    vals, usable = sample_profiles(img, pts, "bilinear")
    assert usable.tolist() == [False, True, False, False, False, False, True]
    assert np.all(np.isfinite(vals)) and np.all(vals[~usable] == 0)


def test_sample_profiles_many_rows():
    img = _image()
    pts = _positions(np.random.default_rng(2), 5000, *img.shape)
    vals, usable = sample_profiles(img, pts, "bilinear")
    ref = np.array([_ref_sample(img, x, y, "bilinear") for x, y in pts[::97]])
    assert usable.all() and np.allclose(vals[::97], ref, atol=1e-3)


def test_gaussian_derivative_matches_reference():
    rng = np.random.default_rng(3)
    v = rng.uniform(0, 200, (4, 3, 20))
    usable = rng.random(v.shape) > 0.05
    d, ok, pos = gaussian_derivative(v, usable, 1.3)
    c = derivative_kernel(1.3)
    h = (len(c) - 1) // 2
    n = v.shape[-1]
    for idx in np.ndindex(v.shape[:-1]):
        for k in range(n):
            taps = [min(max(k + i, 0), n - 1) for i in range(-h, h + 1)]  # ends extended with end values
            want_ok = all(usable[idx][t] for t in taps)
            assert ok[idx][k] == want_ok
            if want_ok:
                assert np.isclose(d[idx][k], sum(c[i + h] * v[idx][t] for i, t in zip(range(-h, h + 1), taps)))
    assert np.array_equal(pos, np.arange(n))
    ramp = 3.0 * np.arange(20.0)
    dr, _, _ = gaussian_derivative(ramp, np.ones(20, bool), 1.3)
    assert np.allclose(dr[h:-h], 3.0)  # a unit-slope kernel


def test_simple_derivative():
    v = np.array([[0.0, 1.0, 4.0, 4.0]])
    d, ok, pos = simple_derivative(v, np.array([[True, True, False, True]]))
    assert np.allclose(d, [[1.0, 0.0, 0.0]]) and ok.tolist() == [[True, False, False]]
    assert np.allclose(pos, [0.5, 1.5, 2.5])


@pytest.mark.parametrize("taps", [2, 3, 7, 13, 31, 48, 49, 50, 61])
def test_correlate_last_is_the_window_matmul_bit_for_bit(taps):
    # The searches' derivatives and correlation surfaces must keep the bits of the sliding-window
    # matmul they replaced (masks and edge positions downstream are compared bit for bit).
    from numpy.lib.stride_tricks import sliding_window_view

    rng = np.random.default_rng(taps)
    kernel = rng.normal(size=taps)
    kernel[rng.random(taps) < 0.2] = 0.0  # zero taps (a Gaussian's underflowed tails)
    for shape in [(15, 8, taps + 47), (5, taps + 31), (3, 2, taps + 1), (2, taps), (taps + 5,)]:
        a = rng.normal(size=shape) * 100.0
        a[..., 3:9] = 77.0  # a flat stretch, where the products cancel
        want = sliding_window_view(a, taps, axis=-1) @ kernel
        got = correlate_last(a, kernel)
        assert got.shape == want.shape and np.array_equal(got, want)


def test_correlate_shifts_matches_reference():
    rng = np.random.default_rng(4)
    d = rng.normal(size=(3, 2, 15))
    ok = rng.random(d.shape) > 0.1
    t = rng.normal(size=15)
    C, shifts = correlate_shifts(d, ok, t, 4)
    assert np.array_equal(shifts, np.arange(-4, 5))
    for idx in np.ndindex(d.shape[:-1]):
        for si, s in enumerate(shifts):
            want = sum(d[idx][j + s] * t[j] for j in range(15) if 0 <= j + s < 15 and ok[idx][j + s])
            assert np.isclose(C[idx][si], want)


def _wssd_case(seed):
    """Random profiles, usable samples, templates and windows, (3, 2, 12)."""
    rng = np.random.default_rng(seed)
    vals = rng.uniform(0, 255, (3, 2, 12))
    usable = rng.random(vals.shape) > 0.1
    tmpl = rng.uniform(0, 255, vals.shape)
    win = rng.random(vals.shape) > 0.3
    return vals, usable, tmpl, win


def _wssd_differences(vals, usable, tmpl, win, idx, s):
    """The differences I(j + s) - t(j) that profile ``idx`` counts at shift ``s``, by a plain loop."""
    n = vals.shape[-1]
    return [vals[idx][j + s] - tmpl[idx][j] for j in range(n) if win[idx][j] and 0 <= j + s < n and usable[idx][j + s]]


def test_wssd_surface_matches_reference():
    case = _wssd_case(5)
    W, counts, shifts = wssd_surface(*case, 3)
    for idx in np.ndindex(case[0].shape[:-1]):
        for si, s in enumerate(shifts):
            terms = np.square(_wssd_differences(*case, idx, s))
            assert counts[idx][si] == len(terms)
            assert (np.isinf(W[idx][si]) and not len(terms)) or np.isclose(W[idx][si], np.mean(terms))


def test_zero_mean_wssd_surface_is_the_variance_of_the_difference():
    case = _wssd_case(6)
    W, counts, shifts = wssd_surface(*case, 3, zero_mean=True)
    plain, plain_counts, _ = wssd_surface(*case, 3)
    np.testing.assert_array_equal(counts, plain_counts)
    for idx in np.ndindex(case[0].shape[:-1]):
        for si, s in enumerate(shifts):
            d = _wssd_differences(*case, idx, s)
            assert (np.isinf(W[idx][si]) and not d) or np.isclose(W[idx][si], np.var(d))
            assert not d or W[idx][si] <= plain[idx][si] + 1e-9


def test_zero_mean_wssd_matches_a_bar_that_shades_lighter():
    """Bars 60 grey levels brighter than their templates (phalanges turned in the light) are no
    match for the plain WSSD (the RMS difference exceeds half the template's spread) but are
    found, in their place, by the zero-mean one, where most links fail at once; one link alone
    that fails (an occluder's doing) stays unmatched."""
    prof = _synthetic_profiles(shift=1.5)
    lighter = dataclasses.replace(prof, values=prof.values + 60.0)
    assert not search_named("wssd")(lighter, SearchConfig()).valid.any()
    edges = search_named("wssd")(lighter, SearchConfig(zero_mean=True))
    want = 19.5 + 1.5 + 0.1 * np.arange(6)[None, :] * np.arange(3)[:, None]
    assert edges.valid.all() and np.allclose(edges.pos.mean(-1), want, atol=0.3)
    one = dataclasses.replace(prof, values=prof.values + np.array([60.0, 0.0, 0.0])[:, None, None])
    edges = search_named("wssd")(one, SearchConfig(zero_mean=True))
    assert not edges.valid[0].any() and edges.valid[1:].all()
    with pytest.raises(InputError, match="zero_mean"):
        config_from_dict({"image": {"search": {"zero_mean": 1}}})


@pytest.mark.parametrize("n", [12, 16, 48, 248, 256])
def test_wssd_surface_counts_on_word_sized_rows(n):
    # 16, 48 and 248 samples take the 64-bit word count, 12 and 256 the plain sum
    rng = np.random.default_rng(n)
    vals = rng.uniform(0, 255, (4, 3, n))
    usable = rng.random(vals.shape) > 0.1
    usable[0, 0] = True  # a full row: every count reaches its largest value
    win = rng.random(vals.shape) > 0.3
    win[0, 0] = True
    _, counts, shifts = wssd_surface(vals, usable, rng.uniform(0, 255, vals.shape), win, 5)
    for idx in np.ndindex(vals.shape[:-1]):
        for si, s in enumerate(shifts):
            lo, hi = max(0, -s), min(n, n - s)
            assert counts[idx][si] == np.count_nonzero(win[idx][lo:hi] & usable[idx][lo + s:hi + s])


def test_window_masks_match_pointwise_shapely():
    polys = pill_outlines(np.array([[10.0, 10.0], [30.0, 5.0]]), np.array([[25.0, 20.0], [30.0, 25.0]]),
                          np.array([4.0, 3.0]), np.array([4.0, 3.0]), 8, 0.1)
    polys = np.array([shapely.difference(polys[0], polys[1]), polys[1]], dtype=object)
    pts = np.random.default_rng(6).uniform(0, 40, (2, 5, 30, 2))
    pts[0, 0, 0] = np.nan
    m = window_masks(polys, pts)
    for idx in np.ndindex(m.shape):
        p = pts[idx]
        want = bool(np.all(np.isfinite(p)) and polys[idx[0]].contains(shapely.Point(p)))
        assert m[idx] == want


def test_pill_outline_is_a_stadium():
    poly = pill_outlines(np.array([[0.0, 0.0]]), np.array([[10.0, 0.0]]), np.array([2.0]), np.array([2.0]), 64,
                         0.0)[0]
    assert np.isclose(poly.area, 10 * 4 + np.pi * 4, rtol=2e-3)
    assert np.allclose(poly.bounds, [-2, -2, 12, 2], atol=1e-9)
    bad = pill_outlines(np.array([[np.nan, 0.0]]), np.array([[1.0, 0.0]]), np.array([2.0]), np.array([2.0]), 8, 0.1)
    assert bad[0].is_empty


def test_link_samplers_geometry():
    cfg = SC(per_link=3, along=(0.25, 0.75), points=9, scope=2.0)
    s = place_link_samplers(np.array([[0.0, 0.0], [5.0, 5.0]]), np.array([[0.0, 8.0], [5.0, 5.0]]),
                            np.array([2.0, 2.0]), cfg)
    assert s.ok.tolist() == [True, False]  # the second link has zero length
    assert np.allclose(s.direction[0], [0, 1]) and np.allclose(s.normal[0], [1, 0])
    assert np.allclose(s.centres[0], [[0, 2], [0, 4], [0, 6]])
    assert np.isclose(s.spacing_px[0], 2 * 2.0 * 2.0 / 8)
    assert np.allclose(s.points[0, 1, [0, 4, 8]], [[-4, 4], [0, 4], [4, 4]])  # ±scope·r about the axis
    assert np.all(np.isnan(s.points[1])) and np.all(np.isfinite(s.direction))


def test_parabola_vertex():
    # through (-1, 1), (0, 4), (1, 3): y = 4 + x - 2 x^2, vertex at x = 1/4
    assert np.isclose(parabola_vertex(np.array(1.0), np.array(4.0), np.array(3.0)), 0.25)
    assert parabola_vertex(np.array(1.0), np.array(1.0), np.array(1.0)) == 0.0


def test_width_template():
    t = width_template(21, 10.0, 8.0, 0.5, 1.0)
    assert np.isclose(t[t > 0].sum(), 1.0) and np.isclose(t[t < 0].sum(), -1.0)
    assert np.argmax(t) == 6 and np.argmin(t) == 14
    assert np.allclose(width_template(21, 10.0, 8.0, 0.5, -1.0), -t)


def _synthetic_profiles(shift=0.0, with_templates=True):
    """Bright bars on a dark background: 3 links x 6 samplers x 40 samples, bar half-width = radius."""
    n, centre, radius = 40, 19.5, 8.0
    k = np.arange(n)
    bar = lambda c: 40 + 150 * np.clip(radius + 0.5 - np.abs(k - c), 0, 1)  # noqa: E731
    vals = np.stack([np.stack([bar(centre + shift + 0.1 * i * link) for i in range(6)]) for link in range(3)])
    tmpl = np.stack([np.stack([bar(centre)] * 6)] * 3)
    return Profiles(values=vals, usable=np.ones(vals.shape, bool), window=np.ones(vals.shape, bool), centre=centre,
                    radius=radius, spacing_px=np.ones(3), templates=tmpl if with_templates else None,
                    template_valid=np.ones(3, bool) if with_templates else None)


@pytest.mark.parametrize("name", SEARCH_NAMES)
def test_every_search_shares_the_signature_and_finds_bars(name):
    prof = _synthetic_profiles(shift=1.5)
    edges = search_named(name)(prof, SearchConfig())
    assert isinstance(edges, Edges)
    assert edges.pos.shape == edges.strength.shape == edges.valid.shape == (3, 6, 2)
    assert edges.valid.all()
    i = np.arange(6)
    want = 19.5 + 1.5 + 0.1 * i[None, :] * np.arange(3)[:, None]
    assert np.allclose(edges.pos.mean(-1), want, atol=0.3)  # centre between the two boundaries
    assert np.all(edges.pos[..., 1] - edges.pos[..., 0] > 12)


@pytest.mark.parametrize("name", SEARCH_NAMES)
def test_every_search_masks_flat_and_unusable_profiles(name):
    prof = _synthetic_profiles()
    flat = Profiles(values=np.full(prof.values.shape, 77.0), usable=prof.usable, window=prof.window,
                    centre=prof.centre, radius=prof.radius, spacing_px=prof.spacing_px,
                    templates=np.full(prof.values.shape, 77.0), template_valid=prof.template_valid)
    edges = search_named(name)(flat, SearchConfig())
    assert not edges.valid.any() and np.all(np.isfinite(edges.pos))
    dead = Profiles(values=np.zeros(prof.values.shape), usable=np.zeros(prof.values.shape, bool),
                    window=np.zeros(prof.values.shape, bool), centre=prof.centre, radius=prof.radius,
                    spacing_px=prof.spacing_px, templates=prof.templates, template_valid=prof.template_valid)
    edges = search_named(name)(dead, SearchConfig())
    assert not edges.valid.any() and np.all(np.isfinite(edges.pos))


def test_wssd_without_templates_finds_nothing():
    edges = search_named("wssd")(_synthetic_profiles(with_templates=False), SearchConfig())
    assert not edges.valid.any()


def test_as_grey_converts_once():
    bgr = np.zeros((4, 5, 3), np.uint8)
    bgr[..., 2] = 255  # pure red
    g = as_grey(bgr)
    assert g.dtype == np.float32 and g.shape == (4, 5) and np.allclose(g, round(0.299 * 255))
    assert as_grey(np.full((4, 5, 1), 7.0)).shape == (4, 5)  # (all ones would read as a [0, 1] image)


def test_wssd_with_a_partial_template():
    # a template that saw only the first boundary and half the bar still places the bar
    prof = _synthetic_profiles(shift=1.5)
    mask = np.zeros(prof.values.shape, bool)
    mask[..., :20] = True
    partial = Profiles(values=prof.values, usable=prof.usable, window=prof.window, centre=prof.centre,
                       radius=prof.radius, spacing_px=prof.spacing_px, templates=np.where(mask, prof.templates, 0.0),
                       template_valid=prof.template_valid, template_mask=mask)
    edges = search_named("wssd")(partial, SearchConfig())
    i = np.arange(6)
    want = 19.5 + 1.5 + 0.1 * i[None, :] * np.arange(3)[:, None]
    assert edges.valid.all() and np.allclose(edges.pos.mean(-1), want, atol=0.3)
