"""End to end: rendered frames through :func:`jaxhand.image.extract_features`.

Thresholds: the issue asks for 0.5 degree / 0.5 px on unoccluded links (clean frames, prediction
at the truth or a few degrees off) for every search, and 1 degree / 1 px for the WSSD search on a
link about half occluded. Frames are rendered by :mod:`jaxhand.render` with 5x5 antialiasing and a
light along the viewing direction, so each phalanx is shaded symmetrically (with the default
oblique light the dark limb's soft edge moves derivative peaks inwards on one side only, a bias of
the derivative methods that ``benchmarks/features.py`` reports separately).
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
import shapely
from helpers import fit_camera

import jaxhand as jh
from jaxhand.features import features_from_pose, line_through, validate_features
from jaxhand.image import (
    SEARCH_NAMES,
    ImageConfig,
    ImageState,
    LineConfig,
    SamplerConfig,
    SearchConfig,
    capture_templates,
    extract_features,
)
from jaxhand.image import internal as imi
from jaxhand.render import RenderConfig, fit_perspective, make_preset, render_frame

FRONT_LIGHT = (0.0, 0.0, -1.0)


def _render(model, cam, q, noise=0.0, seed=0):
    return render_frame(model, cam, q, RenderConfig(antialias=5, light_dir=FRONT_LIGHT, noise_sigma=noise,
                                                    seed=seed)).image


def line_errors(model, cam, q_true, feats):
    """(angle error deg, offset error px at the true link midpoint) of every link slot."""
    v = jh.project_pose(model, cam, jnp.asarray(q_true))
    s, e = np.asarray(v.link_start_px), np.asarray(v.link_end_px)
    lines = np.asarray(feats.lines)
    u = (e - s) / np.linalg.norm(e - s, axis=-1, keepdims=True)
    ang = np.degrees(np.arcsin(np.clip(np.abs(np.sum(lines[:, :2] * u, -1)), 0, 1)))
    off = np.abs(np.sum(lines[:, :2] * (s + e) / 2, -1) - lines[:, 2])
    return ang, off


def _alternating(model, deg):
    """Every flexion off by ``deg``, the middle joint of each finger the other way, so no link's image
    angle is off by more than ``deg`` (for fingers flexing in the image plane)."""
    sign = np.array([-1.0 if n.endswith("pip") else 1.0 for n in model.q_names])
    return np.where(model.is_angle, np.radians(deg) * sign, 0.0)


def _spread(model, deg):
    """Every finger turned by ``deg`` in the image (the abduction joints of the upright hand)."""
    turn = np.array(["abd" in n or n == "thumb_cmc_ra" for n in model.q_names], float)
    return np.radians(deg) * turn


@pytest.fixture(scope="module")
def hand():
    m = jh.builtin_model("hand21")
    cam = fit_camera(m)
    q = np.asarray(m.q_default)
    return m, cam, q, _render(m, cam, q)


@pytest.fixture(scope="module")
def finger():
    m = jh.builtin_model("index")
    cam = fit_camera(m)
    q = np.asarray(m.q_default)
    return m, cam, q, _render(m, cam, q)


@pytest.fixture(scope="module")
def occlusion():
    """two_fingers: templates from a pose with the fingers apart; a frame with the index covering
    about half of the middle finger's middle phalanx."""
    m = jh.builtin_model("two_fingers")
    cam = fit_camera(m)
    q_apart = np.radians([-10.0, -15.0, -10.0, 35.0, 0.0, 0.0])
    q = np.radians([0.0, -15.0, -10.0, 5.0, 0.0, -10.0])
    return m, cam, q_apart, _render(m, cam, q_apart), q, _render(m, cam, q)


def _run(model, cam, image, q_pred, method, state=None, q_templates=None, template_image=None, **cfg):
    config = ImageConfig(method=method, **cfg)
    if q_templates is not None:
        state = capture_templates(template_image, model, cam, q_templates, config)
    feats, diag = extract_features(image, model, cam, q_pred, config, state)
    return feats[0], diag


@pytest.mark.parametrize("method", SEARCH_NAMES)
def test_hand_at_truth_every_method(hand, method):
    m, cam, q, img = hand
    f, diag = _run(m, cam, img, q, method, q_templates=q, template_image=img)
    share = diag.cameras[0].visibility.visible_share
    ang, off = line_errors(m, cam, q, f)
    assert np.all(share > 0.98)  # nothing occludes anything in the open hand
    assert np.asarray(f.line_valid).all()
    assert ang.max() < 0.5 and off.max() < 0.5
    assert np.asarray(f.tip_valid).all()
    tips = np.asarray(jh.project_pose(m, cam, jnp.asarray(q)).tips_px)
    assert np.linalg.norm(np.asarray(f.tips) - tips, axis=-1).max() < 1.0  # shading moves the tip edge inwards


@pytest.mark.parametrize("method", [n for n in SEARCH_NAMES if n != "width"])
def test_hand_with_turned_prediction(hand, method):
    # each finger predicted 3 degrees off in the image (its distal phalanx ~0.45 r sideways)
    m, cam, q, img = hand
    f, _ = _run(m, cam, img, q + _spread(m, 3.0), method, q_templates=q, template_image=img)
    ang, off = line_errors(m, cam, q, f)
    assert np.asarray(f.line_valid).all()
    assert ang.max() < 0.5 and off.max() < 0.5


def test_basic_width_restriction_cannot_follow_a_turned_prediction_but_compensated_can(hand):
    # thesis §11.2.2: the basic windows stay where the prediction puts the edges
    m, cam, q, img = hand
    qp = q + _spread(m, 3.0)
    basic, _ = _run(m, cam, img, qp, "width")
    comp, _ = _run(m, cam, img, qp, "width_compensated")
    assert line_errors(m, cam, q, basic)[0].max() > 1.0
    assert line_errors(m, cam, q, comp)[0].max() < 0.5


@pytest.mark.parametrize("method", SEARCH_NAMES)
def test_finger_with_perturbed_prediction(finger, method):
    m, cam, q, img = finger
    for qp in (q, q + _alternating(m, 3.0)):
        f, _ = _run(m, cam, img, qp, method, q_templates=q, template_image=img)
        ang, off = line_errors(m, cam, q, f)
        assert np.asarray(f.line_valid).all()
        assert ang.max() < 0.5 and off.max() < 0.5


@pytest.mark.parametrize("method", ["gaussian", "imwplls", "wssd"])
def test_noisy_hand(hand, method):
    m, cam, q, _ = hand
    img = _render(m, cam, q, noise=4.0, seed=3)
    tmpl = _render(m, cam, q, noise=4.0, seed=4)
    f, _ = _run(m, cam, img, q + _spread(m, 3.0), method, q_templates=q, template_image=tmpl)
    ang, off = line_errors(m, cam, q, f)
    assert np.asarray(f.line_valid).all()
    assert ang.max() < 1.0 and off.max() < 0.5


@pytest.mark.parametrize("perturb_deg", [0.0, 3.0])
def test_wssd_under_occlusion(occlusion, perturb_deg):
    m, cam, q_apart, img_apart, q, img = occlusion
    qp = q + _alternating(m, perturb_deg)
    f, diag = _run(m, cam, img, qp, "wssd", q_templates=q_apart, template_image=img_apart)
    share = diag.cameras[0].visibility.visible_share  # at the prediction
    pip = m.link_lookup("middle_pip")
    true_share = extract_features(img, m, cam, q, ImageConfig(method="gaussian"))[1].cameras[0].visibility
    assert 0.45 < true_share.visible_share[pip] < 0.6  # about half of it hidden behind the index
    ang, off = line_errors(m, cam, q, f)
    valid = np.asarray(f.line_valid)
    assert valid[pip] and ang[pip] < 1.0 and off[pip] < 1.0
    seen = valid & (share >= 0.5)
    assert seen.sum() >= 5 and ang[seen].max() < 1.0 and off[seen].max() < 1.0
    assert np.isclose(np.asarray(f.line_weight)[pip], share[pip])  # weight = visible share
    # the WSSD window keeps the occluding finger out: no sample of the middle phalanx's window
    # lies on the index finger
    windows = diag.cameras[0].visibility.windows
    index_outline = diag.cameras[0].visibility.outlines[m.link_lookup("index_pip")]
    assert shapely.intersection(windows[pip], index_outline).area < 1e-6


def test_derivative_search_is_misled_by_the_occluding_finger(occlusion):
    # the comparison the benchmark makes: the same frame through the derivative search
    m, cam, _, _, q, img = occlusion
    f, _ = _run(m, cam, img, q, "derivative")
    ang, off = line_errors(m, cam, q, f)
    pip = m.link_lookup("middle_pip")
    assert ang[pip] > 2.0 or off[pip] > 2.0 or not bool(f.line_valid[pip])


def test_single_edge_fallback_offsets_by_the_radius(finger):
    # mask one side of every profile: the link comes from one boundary moved by the radius
    m, cam, q, img = finger
    v = jh.project_pose(m, cam, jnp.asarray(q))
    s, e = np.asarray(v.link_start_px), np.asarray(v.link_end_px)
    n = np.stack([(e - s)[:, 1], -(e - s)[:, 0]], -1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    ys, xs = np.mgrid[0:img.shape[0], 0:img.shape[1]]
    link = 0
    side = ((np.stack([xs, ys], -1) - s[link]) @ n[link]) > 0  # the +normal half plane of link 0's axis
    half = np.where(side, np.nan, img.astype(float))
    cfg = ImageConfig(method="gaussian")
    feats, diag = extract_features(half, m, cam, q, cfg)
    f = feats[0]
    assert diag.cameras[0].single_edge[link] and bool(f.line_valid[link])
    assert np.isclose(float(f.line_weight[link]), cfg.lines.single_edge_weight * 1.0, atol=0.02)
    ang, off = line_errors(m, cam, q, f)
    assert ang[link] < 0.5 and off[link] < 0.75  # the shaded edge sits ~0.3 px inside the radius
    off_cfg = cfg.replace(lines=LineConfig(single_edge=False))
    f2, _ = extract_features(half, m, cam, q, off_cfg)
    assert not bool(f2[0].line_valid[link])


# ---- contract, state, diagnostics ----


def test_features_fit_the_contract(hand):
    m, cam, q, img = hand
    feats, diag = extract_features(img, m, cam, q + _spread(m, 2.0))
    assert len(feats) == 1
    f = validate_features(m, (cam,), feats)[0]
    v = jh.project_pose(m, cam, jnp.asarray(q))
    pred = np.asarray(line_through(v.link_start_px, v.link_end_px))
    lines = np.asarray(f.lines)
    assert np.all(np.sum(lines[:, :2] * pred[:, :2], -1) > 0.99)  # normals oriented like line_through
    assert np.allclose(np.linalg.norm(lines[:, :2], axis=-1), 1.0)
    w = np.asarray(f.line_weight)
    assert np.all((w >= 0) & (w <= 1))
    d = diag.cameras[0]
    L, M, N = m.n_links, SamplerConfig().per_link, SamplerConfig().points
    assert d.samplers.points.shape == (L, M, N, 2) and d.samplers.ends.shape == (L, M, 2, 2)
    assert d.edge_px.shape == (L, M, 2, 2) and d.boundary_lines.shape == (L, 2, 3)
    assert np.all(np.isfinite(d.edge_px[d.edges.valid]))
    assert all(isinstance(g, shapely.Polygon | shapely.MultiPolygon) for g in d.visibility.windows)
    assert d.profiles.values.shape == (L, M, N) and d.edges.surface is not None


def test_same_input_same_bits(hand):
    m, cam, q, img = hand
    a, _ = extract_features(img, m, cam, q, ImageConfig(method="imwplls"))
    b, _ = extract_features(img, m, cam, q, ImageConfig(method="imwplls"))
    leaves = zip(jax.tree_util.tree_leaves(a[0]), jax.tree_util.tree_leaves(b[0]))
    assert all(np.array_equal(np.asarray(x), np.asarray(y)) for x, y in leaves)


def test_templates_state(occlusion):
    m, cam, q_apart, img_apart, q, img = occlusion
    cfg = ImageConfig()
    st = capture_templates(img_apart, m, cam, q_apart, cfg)
    seen_apart = extract_features(img_apart, m, cam, q_apart, cfg.replace(method="gaussian"))[1].cameras[0]
    want = seen_apart.visibility.visible_share >= cfg.template_min_visible
    assert np.array_equal(st.template_valid[0], want) and want.sum() >= 5
    assert st.templates[0].shape == (m.n_links, cfg.samplers.per_link, cfg.samplers.points)
    # the mask holds the samples that showed each link: its window
    p = seen_apart.profiles
    assert np.array_equal(st.template_mask[0][want], (p.window & p.usable)[want])
    # extract without a state fills templates of the links seen at q_pred
    _, diag = extract_features(img, m, cam, q, cfg)
    assert isinstance(diag.state, ImageState)
    assert diag.state.template_valid[0].any() and not diag.state.template_valid[0].all()
    # capturing at the occluded pose overwrites only the samples that show each link now
    st2 = capture_templates(img, m, cam, q, cfg, st)
    now = extract_features(img, m, cam, q, cfg.replace(method="gaussian"))[1].cameras[0].profiles
    pip = m.link_lookup("middle_pip")
    seen = (now.window & now.usable)[pip]
    assert seen.any() and not seen.all()
    assert np.array_equal(st2.templates[0][pip][seen], now.values[pip][seen])
    assert np.array_equal(st2.templates[0][pip][~seen], st.templates[0][pip][~seen])
    assert np.array_equal(st2.template_mask[0][pip], st.template_mask[0][pip] | seen)
    # another sampler layout replaces the state instead of mixing shapes
    other = cfg.replace(samplers=SamplerConfig(points=20))
    _, diag = extract_features(img, m, cam, q, other, st)
    assert diag.state.templates[0].shape[-1] == 20


def test_rig_of_two_cameras(hand):
    m, cam, q, img = hand
    cam2 = fit_camera(m, size=(200, 160))
    img2 = _render(m, cam2, q)
    feats, diag = extract_features([img, img2], m, (cam, cam2), q, ImageConfig(method="gaussian"))
    assert len(feats) == 2 and len(diag.cameras) == 2
    for c, f in zip((cam, cam2), feats):
        ang, off = line_errors(m, c, q, f)
        assert np.asarray(f.line_valid).all() and ang.max() < 0.5 and off.max() < 0.5


@pytest.mark.parametrize("method", ["derivative", "imwplls", "wssd"])
def test_perspective_camera(hand, method):
    # Under perspective a cylinder's silhouette lines are not symmetric about its projected axis
    # (one end is nearer), so the axial line between them is off by up to ~1 degree here on the
    # short, tilted distal phalanges (DigitEyes §3.2 accepts the same approximation).
    m, _, q, _ = hand
    pose = jh.forward(m, jnp.asarray(q))
    pts = np.concatenate([np.asarray(pose.link_start), np.asarray(pose.link_end)])
    (cam,) = fit_perspective(m, q[None], (320, 240), [0.5 * (pts.min(0) + pts.max(0)) + [60.0, -80.0, -300.0]])
    img = _render(m, cam, q)
    f, diag = _run(m, cam, img, q, method, q_templates=q, template_image=img)
    ang, off = line_errors(m, cam, q, f)
    assert np.asarray(f.line_valid).all() and ang.max() < 2.0 and off.max() < 0.5
    assert np.all(diag.cameras[0].visibility.visible_share > 0.98)


# ---- degenerate input: invalid slots, never an exception or NaN ----


def _assert_finite(feats):
    for f in feats:
        for leaf in jax.tree_util.tree_leaves(f):
            assert np.all(np.isfinite(np.asarray(leaf, float)))


@pytest.mark.parametrize("method", SEARCH_NAMES)
def test_hand_outside_the_image(hand, method):
    m, cam, q, img = hand
    away = eqx.tree_at(lambda c: c.center, cam, cam.center + jnp.array([2000.0, -900.0]))
    feats, _ = extract_features(img, m, away, q, ImageConfig(method=method))
    _assert_finite(feats)
    assert not np.asarray(feats[0].line_valid).any() and not np.asarray(feats[0].tip_valid).any()


@pytest.mark.parametrize("method", SEARCH_NAMES)
def test_part_of_the_hand_outside_the_image(hand, method):
    m, cam, q, _ = hand
    shifted = eqx.tree_at(lambda c: c.center, cam, cam.center + jnp.array([130.0, 0.0]))  # little, ring out
    img = _render(m, shifted, q)
    f, _ = _run(m, shifted, img, q, method, q_templates=q, template_image=img)
    _assert_finite([f])
    valid = np.asarray(f.line_valid)
    x = np.asarray(jh.project_pose(m, shifted, jnp.asarray(q)).link_end_px)[:, 0]
    assert not valid[x > 330].any() and valid[x < 300].all()


@pytest.mark.parametrize("method", SEARCH_NAMES)
def test_flat_image(hand, method):
    m, cam, q, img = hand
    feats, _ = extract_features(np.full_like(img, 90), m, cam, q, ImageConfig(method=method))
    _assert_finite(feats)
    assert not np.asarray(feats[0].line_valid).any() and not np.asarray(feats[0].tip_valid).any()


def test_zero_length_projection(finger):
    m, _, q, _ = finger
    pose = jh.forward(m, jnp.asarray(q))
    start, end = np.asarray(pose.link_start), np.asarray(pose.link_end)
    R = jh.camera.look_at_rotation(end[2], 2 * end[2] - start[2], up=(1.0, 0.0, 0.0))  # along the distal link
    cam = jh.Orthographic.fit(np.concatenate([start, end]), R=R)
    img = _render(m, cam, q)
    for method in ("gaussian", "wssd"):
        feats, _ = extract_features(img, m, cam, q, ImageConfig(method=method))
        _assert_finite(feats)
        assert not bool(feats[0].line_valid[2])


def test_fully_occluded_link():
    m = jh.builtin_model("two_fingers")
    m = eqx.tree_at(lambda m: m.link_radius_mm, m, m.link_radius_mm.at[3:].multiply(1.6))  # a fat index
    cam = fit_camera(m)
    q = np.radians([0.0, 0.0, -10.0, 0.0, 0.0, -10.0])
    img = _render(m, cam, q)
    for method in SEARCH_NAMES:
        feats, diag = extract_features(img, m, cam, q, ImageConfig(method=method))
        _assert_finite(feats)
        share = diag.cameras[0].visibility.visible_share
        assert share[0] == 0 and share[1] == 0
        assert not np.asarray(feats[0].line_valid)[:2].any()


@pytest.mark.parametrize("method", SEARCH_NAMES)
def test_nan_pixels(hand, method):
    m, cam, q, img = hand
    bad = img.astype(np.float32)
    v = jh.project_pose(m, cam, jnp.asarray(q))
    x = np.asarray(v.link_start_px)[m.link_lookup("index_pip"), 0]
    bad[:, int(x) - 20:int(x) + 20] = np.nan  # the index finger's column
    bad[0, 0] = np.inf
    feats, _ = _run(m, cam, bad, q, method, q_templates=q, template_image=img)
    _assert_finite([feats])
    valid = np.asarray(feats.line_valid)
    index = [m.link_lookup(n) for n in ("index_mcp", "index_pip", "index_dip")]
    assert not valid[index].any()
    assert valid[[m.link_lookup(n) for n in ("little_pip", "ring_pip")]].all()


# ---- bad input: clear errors ----


@pytest.mark.parametrize("image, match", [
    (np.zeros(320, np.uint8), "2-D grey image"),
    (np.zeros((240, 320), np.int64), "dtype int64"),
    (np.zeros((240, 320), bool), "dtype bool"),
    (np.zeros((240, 320, 4), np.uint8), r"shape \(240, 320, 4\)"),
    (np.zeros((240, 320, 3), np.float32), "colour image must be uint8"),
    (np.zeros((0, 320), np.uint8), "empty"),
    (np.zeros((240, 321), np.uint8), "does not match the camera"),
    (None, "dtype object"),
    ("frame.png", "dtype <U9"),
])
def test_bad_images_raise_input_error(hand, image, match):
    m, cam, q, _ = hand
    with pytest.raises(jh.InputError, match=match):
        extract_features([image], m, cam, q)


def test_float_image_in_unit_range_raises_input_error(hand):
    # A [0, 1]-scaled float image would be read as nearly black and give no features at all: it
    # is refused with what to do; the same image on the 0-255 scale gives the uint8 features.
    m, cam, q, img = hand
    unit = img.astype(np.float32) / 255
    for call in (lambda im: extract_features(im, m, cam, q), lambda im: capture_templates(im, m, cam, q)):
        with pytest.raises(jh.InputError, match=r"images\[0\]: a float image with values in \[0, 1\].*\* 255"):
            call(unit)
    f_unit, _ = extract_features(unit * 255, m, cam, q, ImageConfig(method="gaussian"))
    f_u8, _ = extract_features(img, m, cam, q, ImageConfig(method="gaussian"))
    assert np.asarray(f_unit[0].line_valid).sum() > 5
    np.testing.assert_allclose(np.asarray(f_unit[0].lines), np.asarray(f_u8[0].lines), atol=1e-3)
    # an all-black float frame is not mistaken for one (it holds no features either way)
    feats, _ = extract_features(np.zeros_like(unit), m, cam, q)
    assert not np.asarray(feats[0].line_valid).any()


def test_bad_arguments_raise_input_error(hand):
    m, cam, q, img = hand
    with pytest.raises(jh.InputError, match=r"images\[1\]"):
        extract_features([img, np.zeros((10, 10), np.uint8)], m, (cam, fit_camera(m, size=(20, 20))), q)
    with pytest.raises(jh.InputError, match="one image per camera"):
        extract_features([img, img], m, cam, q)
    with pytest.raises(jh.InputError, match="q_pred"):
        extract_features(img, m, cam, q[:-1])
    with pytest.raises(jh.InputError, match="ImageConfig"):
        extract_features(img, m, cam, q, config={"method": "wssd"})
    with pytest.raises(jh.InputError, match="valid: derivative, gaussian"):
        ImageConfig(method="ssd")
    with pytest.raises(jh.InputError, match="SamplerConfig.interpolation"):
        SamplerConfig(interpolation="lanczos")
    with pytest.raises(jh.InputError, match="SearchConfig.polarity"):
        SearchConfig(polarity="auto")
    with pytest.raises(jh.InputError, match="LineConfig.tau_px"):
        LineConfig(tau_px=0.0)


def test_bgr_and_float_images_give_the_same_lines(hand):
    m, cam, q, img = hand
    bgr = np.repeat(img[..., None], 3, -1)
    a, _ = extract_features(img, m, cam, q, ImageConfig(method="gaussian"))
    b, _ = extract_features(bgr, m, cam, q, ImageConfig(method="gaussian"))
    c, _ = extract_features(img.astype(np.float64), m, cam, q, ImageConfig(method="gaussian"))
    assert np.allclose(np.asarray(a[0].lines), np.asarray(b[0].lines))
    assert np.allclose(np.asarray(a[0].lines), np.asarray(c[0].lines))


def test_templates_taken_at_a_misplaced_pose_do_not_carry_the_error(finger):
    # Template drift (thesis §4.3.1 refreshes templates at each solved pose): a template taken
    # where the solve put the finger 3 degrees off shows the finger off-centre; re-centring the
    # template and snapping the boundaries to the image's edges keep the next match on the finger.
    m, cam, q, img = finger
    q_off = q + _alternating(m, 3.0)
    drift = _run(m, cam, img, q, "wssd", q_templates=q_off, template_image=img, template_recentre=False,
                 search=SearchConfig(snap=0.0))[0]
    fixed = _run(m, cam, img, q, "wssd", q_templates=q_off, template_image=img)[0]
    ang_d, off_d = line_errors(m, cam, q, drift)
    ang_f, off_f = line_errors(m, cam, q, fixed)
    assert np.asarray(fixed.line_valid).all()
    assert ang_d.max() > 2.5 and off_d.max() > 4.0  # the thesis's templates keep the misplacement
    assert ang_f.max() < 0.5 and off_f.max() < 0.6  # snapped edges: Gaussian-derivative peaks


def test_tip_over_another_finger_is_invalid():
    # The index tip lies over the middle finger: its outward boundary there is a faint shading
    # edge, and the strongest derivative along the sampler lies elsewhere (was 4-18 px off).
    seq = make_preset("two_finger_occlusion", frames=80)
    m, cam, q = seq.model, seq.cameras[0], seq.q[20]
    img = render_frame(m, cam, q, RenderConfig(antialias=3)).image
    f, diag = extract_features(img, m, cam, q, ImageConfig(method="gaussian"))
    vis = diag.cameras[0].visibility
    v = jh.project_pose(m, cam, jnp.asarray(q))
    tips, tip_links = np.asarray(v.tips_px), list(m.tip_links)
    over = [shapely.contains_xy(vis.outlines[m.link_lookup("middle_dip")], *tips[1])]
    assert tip_links[1] == m.link_lookup("index_dip") and over == [True]
    valid = np.asarray(f[0].tip_valid)
    assert not valid[1]
    assert valid[0] and np.linalg.norm(np.asarray(f[0].tips)[0] - tips[0]) < 1.0


@pytest.mark.parametrize("frame, joint, turn_deg", [(60, "index_dip", -60.0), (96, "thumb_ip", 57.0),
                                                    (20, "index_pip", -45.0)])
def test_reacquire_finds_a_phalanx_the_prediction_turned_away(frame, joint, turn_deg):
    # index + thumb from the side: one joint of the prediction turned so far that the link's
    # profiles miss its phalanx; turning that joint back by up to 45 degrees finds it again
    seq = make_preset("index_thumb_grasp")
    m, cams, q = seq.model, seq.cameras, seq.q[frame]
    image = render_frame(m, cams[0], q, RenderConfig(antialias=3)).image
    j, link = m.q_lookup(joint), m.link_lookup(joint)
    q_pred = q.copy()
    q_pred[j] += np.radians(turn_deg)
    assert m.q_lower[j] <= q_pred[j] <= m.q_upper[j]
    truth = features_from_pose(m, cams, q)[0]
    plain, d0 = extract_features(image, m, cams, q_pred, ImageConfig(method="imwplls"))
    assert not bool(plain[0].line_valid[link]) and not d0.cameras[0].reacquired.any()
    found, d1 = extract_features(image, m, cams, q_pred, ImageConfig(method="imwplls", reacquire_deg=(15, 30, 45)))
    assert bool(found[0].line_valid[link]) and d1.cameras[0].reacquired[link]
    assert d1.cameras[0].reacquired.sum() == 1
    line, true_line = np.asarray(found[0].lines[link]), np.asarray(truth.lines[link])
    assert np.degrees(np.arccos(min(1.0, abs(line[:2] @ true_line[:2])))) < 0.7
    # the other links' features are those of the plain search
    others = np.arange(m.n_links) != link
    np.testing.assert_array_equal(np.asarray(found[0].lines)[others], np.asarray(plain[0].lines)[others])
    with pytest.raises(jh.InputError, match="reacquire_deg"):
        ImageConfig(reacquire_deg=(0.0,))


_TURNED = {}


def _turned_prediction(preset, frame, joint, turn_deg):
    """The model, cameras, true pose, rendered images and a prediction with ``joint`` turned."""
    key = (preset, frame, joint, turn_deg)
    if key in _TURNED:
        return _TURNED[key]
    seq = make_preset(preset)
    m, cams, q = seq.model, seq.cameras, seq.q[frame]
    images = tuple(render_frame(m, c, q, RenderConfig(antialias=3)).image for c in cams)
    q_pred = q.copy()
    q_pred[m.q_lookup(joint)] += np.radians(turn_deg)
    _TURNED[key] = m, cams, q, images, q_pred
    return _TURNED[key]


@pytest.mark.parametrize("preset, frame, joint, turn_deg", [
    ("index_thumb_grasp", 60, "index_dip", -75.0), ("index_thumb_grasp", 80, "thumb_ip", -75.0),
    ("index_thumb_grasp", 20, "index_pip", -45.0),
    # perspective cameras, two of them, and a turn that moves the phalanx below the searched one
    ("two_camera_hand", 50, "little_pip", -50.0), ("two_camera_hand", 50, "little_pip", 50.0)])
@pytest.mark.parametrize("method", ["imwplls", "gaussian", "wssd"])
def test_reacquire_batch_is_the_search_of_every_turned_view(preset, frame, joint, turn_deg, method):
    # all turns searched as one batch (only the searched links sampled, searched and fitted, only
    # the winner's tip) give the features of observing and searching every turned view whole
    m, cams, q, images, q_pred = _turned_prediction(preset, frame, joint, turn_deg)
    config = ImageConfig(method=method, reacquire_deg=(15, 30, 45))
    state = capture_templates(list(images), m, cams, q, config) if method == "wssd" else None
    _, diag = extract_features(list(images), m, cams, q_pred, config, state)
    chain = imi.same_chain(m.link_frame, m.ancestors)
    n_turns, any_reacquired = [], False
    for c, (cam, image) in enumerate(zip(cams, images)):
        ctx = imi.CameraContext(grey=imi.as_grey(image), model=m, camera=cam, chain=chain, config=config,
                                clock=imi.Clock(), search=imi.search_named(method),
                                templates=diag.state.templates[c], template_mask=diag.state.template_mask[c])
        obs = imi.observe(ctx, q_pred)
        view = imi.search_view(ctx, obs)
        n_turns.append(len(imi.turns_to_try(ctx, q_pred, obs, view)))
        fast, r_fast = imi.reacquire(ctx, q_pred, obs, view)
        full, r_full = imi.reacquire_full(ctx, q_pred, obs, view)
        for name in ("lines", "valid", "weight", "single"):
            np.testing.assert_array_equal(getattr(fast.fit, name), getattr(full.fit, name), err_msg=name)
        np.testing.assert_array_equal(fast.tips.tips, full.tips.tips)
        np.testing.assert_array_equal(fast.tips.valid, full.tips.valid)
        np.testing.assert_array_equal(r_fast, r_full)
        np.testing.assert_array_equal(r_fast, diag.cameras[c].reacquired)
        any_reacquired |= bool(r_fast.any()) and c == 0
    assert max(n_turns) > 1  # the batch ran, on several turns
    # index + thumb: a turn wins for every search; the two-camera hand: in some views none does
    assert preset != "index_thumb_grasp" or any_reacquired
