"""The silhouette term (jaxhand.score._term): its residuals on dev-set frames at the truth and
away from it, its Jacobian against finite differences, an inactive frame, its configuration,
and the tracker carrying it (ImageConfig.silhouette_term)."""

import dataclasses
from pathlib import Path

import cv2
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxhand as jh
from jaxhand.image import ImageConfig
from jaxhand.io import load_devset
from jaxhand.kinematics import project_pose
from jaxhand.score import (
    MaskForeground,
    SilhouetteTerm,
    SilhouetteTermConfig,
    ThresholdForeground,
    pill_images,
    silhouette_term,
)
from jaxhand.track import ImageFrontEnd, TrackConfig, Tracker

DEVSET = Path(__file__).resolve().parent.parent / "data" / "mujoco"
ON = SilhouetteTermConfig(weight=0.5)
EDGES = SilhouetteTermConfig(weight=0.5, edge_weight=0.5)


@pytest.fixture(scope="module")
def open_close():
    return load_devset(DEVSET / "open_close")


def _frame(seq, k):
    return cv2.imread(str(seq.image_paths[0][k]), cv2.IMREAD_GRAYSCALE)


def _bound(seq, k, config=ON):
    term = silhouette_term(_frame(seq, k), ThresholdForeground(), 0, config)
    return term, term.bind(seq.model, tuple(seq.truth.cameras))


def _q(seq, k, **deg):
    q = np.array(seq.truth.q[k], float)
    for name, d in deg.items():
        q[seq.model.q_names.index(name)] += np.radians(d)
    return jnp.asarray(q)


def test_truth_fits_the_foreground_and_a_flexed_finger_does_not(open_close):
    term, prior = _bound(open_close, 20)
    assert bool(term.active) and int(term.contour_valid.sum()) == ON.contour_points
    at_truth = float(prior.rms_px(_q(open_close, 20)))
    off = float(prior.rms_px(_q(open_close, 20, index_mcp_flex=-30.0)))
    assert at_truth < 0.8, at_truth          # the MuJoCo hand at its true pose: sub-pixel
    assert off > 3 * at_truth and off > 1.5, (at_truth, off)
    assert float(term.merit(open_close.model, tuple(open_close.truth.cameras), _q(open_close, 20))) > 0.85
    r = prior(_q(open_close, 20))
    n_outline = open_close.model.n_links + len(open_close.model.occluder_radius_mm)
    assert r.shape == (ON.contour_points + n_outline * (2 * len(ON.outline_fractions) + 2),)


def test_edges_fit_the_truth_and_hide_the_covered_sides(open_close):
    term, prior = _bound(open_close, 30, EDGES)
    blocks = prior.distances(_q(open_close, 30))
    assert len(blocks) == 3
    d, visible, _ = blocks[2]
    n_points = 2 * open_close.model.n_links * len(EDGES.edge_fractions) + len(open_close.model.tip_links)
    assert d.shape == (n_points,)
    # in the fist (frame 30) the curled phalanges hide each other; on the open hand (frame 0) few are hidden
    open_visible = int(np.sum(_bound(open_close, 0, EDGES)[1].distances(_q(open_close, 0))[2][1]))
    assert int(np.sum(visible)) < open_visible - 10, (int(np.sum(visible)), open_visible)
    at_truth = float(np.median(np.asarray(d)[np.asarray(visible)]))
    assert at_truth < 1.5, at_truth
    off = prior.distances(_q(open_close, 30, thumb_cmc_flex=20.0))[2]
    assert float(np.median(np.asarray(off[0])[np.asarray(off[1])])) >= at_truth
    assert float(prior.rms_px(_q(open_close, 30, thumb_cmc_flex=20.0))) > float(prior.rms_px(_q(open_close, 30)))


@pytest.mark.parametrize("config", [ON, EDGES], ids=["silhouette", "with-edges"])
@pytest.mark.slow
def test_jacobian_matches_central_differences(open_close, config):
    _, prior = _bound(open_close, 30, config)
    q = _q(open_close, 30, little_pip=-7.0, index_mcp_abd=3.0)
    J = np.asarray(eqx.filter_jit(lambda p, q: jax.jacfwd(p)(q))(prior, q))
    f = eqx.filter_jit(lambda q: prior(q))
    h = 1e-6
    fd = np.stack([(np.asarray(f(q.at[i].add(h))) - np.asarray(f(q.at[i].add(-h)))) / (2 * h)
                   for i in range(len(q))], 1)
    assert np.all(np.isfinite(J))
    np.testing.assert_allclose(J, fd, atol=2e-3 * np.abs(fd).max())


def test_pill_radii_agree_with_the_views_mid_depth_radius(open_close):
    m, cam = open_close.model, open_close.truth.cameras[0]
    q = _q(open_close, 0)
    a, b, ra, rb = (np.asarray(x) for x in pill_images(m, cam, q))
    view = project_pose(m, cam, np.asarray(q))
    np.testing.assert_allclose(a[: m.n_links], np.asarray(view.link_start_px), atol=1e-9)
    np.testing.assert_allclose(0.5 * (ra + rb)[: m.n_links], np.asarray(view.link_radius_px), rtol=0.02)


def test_an_empty_frame_gives_an_inactive_term(open_close):
    blank = np.zeros_like(_frame(open_close, 0))
    term = silhouette_term(blank, ThresholdForeground(), 0, ON)
    assert not bool(term.active) and not bool(term.contour_valid.any())
    prior = term.bind(open_close.model, tuple(open_close.truth.cameras))
    q = _q(open_close, 0)
    np.testing.assert_array_equal(np.asarray(prior(q)), 0.0)
    assert float(prior.rms_px(q)) == 0.0
    assert float(term.merit(open_close.model, tuple(open_close.truth.cameras), q)) == 1.0


@pytest.mark.parametrize("field, value, message", [
    ("weight", -1.0, "silhouette_term.weight: need >= 0"),
    ("scale_px", 0.0, "silhouette_term.scale_px: need > 0 px"),
    ("contour_points", 4, "silhouette_term.contour_points: need an int >= 8"),
    ("outline_fractions", (0.5, 1.5), "silhouette_term.outline_fractions"),
    ("max_share", 0.0, "silhouette_term.min_share/max_share"),
    ("rim_px", "wide", "silhouette_term.rim_px: need a number of px"),
])
def test_bad_settings_are_named(field, value, message):
    with pytest.raises(jh.InputError, match=message.replace(".", r"\.")):
        SilhouetteTermConfig(**{field: value})


def test_the_front_end_returns_one_term_per_camera_only_when_on(open_close):
    m, cams = open_close.model, open_close.truth.cameras
    images = [_frame(open_close, 0)]
    off = ImageFrontEnd(m, cams).extract(images, np.asarray(open_close.truth.q[0]), None, 0)
    assert off.terms == ()
    on = ImageFrontEnd(m, cams, ImageConfig(silhouette_term=ON)).extract(images, np.asarray(open_close.truth.q[0]),
                                                                          None, 0)
    assert len(on.terms) == 1 and isinstance(on.terms[0], SilhouetteTerm) and on.terms[0].camera == 0


@pytest.mark.slow
def test_the_terms_keep_the_closing_hand(open_close):
    """Frames 1-30 of open_close: the fingers curl towards the camera, where the default front
    end lets fingers settle at their hyper-extension limits (benchmarks/README.md); the
    robust preset (the silhouette term judging several starts) stays far closer to the truth."""
    m, cams = open_close.model, open_close.truth.cameras
    moving = np.ptp(np.asarray(open_close.truth.q), axis=0) > 1e-6
    errors = {}
    for label, config in (("default", TrackConfig()), ("robust", TrackConfig().preset("robust"))):
        tracker = Tracker(m, cams, ImageFrontEnd(m, cams, config.image), config, dt_s=1 / 30)
        state, err = tracker.init(np.asarray(open_close.truth.q[0])), []
        for k in range(1, 31):
            state, rep = tracker.step(state, [_frame(open_close, k)], k)
            err.append(np.degrees(np.abs(rep.q_filtered - np.asarray(open_close.truth.q[k])))[moving])
        errors[label] = float(np.mean(err))
    print(errors)
    assert errors["robust"] < 0.5 * errors["default"], errors


def test_the_foreground_outline_is_compared_near_the_model_only():
    from jaxhand.score import roi_box

    image = np.zeros((120, 200), np.uint8)
    image[40:60, 30:40] = 200     # the hand
    image[90:110, 150:190] = 200  # something else, far away
    hand = image[:, :] > 0
    hand[:, 100:] = False
    assert roi_box(hand, 0.25, 20.0) == (10, 20, 59, 79)   # 20 px margin: more than 0.25 x 20 px
    assert roi_box(hand, None, 20.0) is None
    whole = silhouette_term(image, ThresholdForeground(method="fixed", threshold=100), 0, ON)
    near = silhouette_term(image, ThresholdForeground(method="fixed", threshold=100), 0, ON,
                           box=roi_box(hand, 0.25, 20.0))
    pts_whole = np.asarray(whole.contour)[np.asarray(whole.contour_valid)]
    pts_near = np.asarray(near.contour)[np.asarray(near.contour_valid)]
    assert (pts_whole[:, 0] > 140).sum() > 40   # the far object's outline is most of the whole image's
    assert len(pts_near) > 40 and pts_near[:, 0].max() < 41 and pts_near[:, 0].min() > 28
    with pytest.raises(jh.InputError, match=r"silhouette_term\.roi_margin: need a fraction >= 0 or None"):
        SilhouetteTermConfig(roi_margin=-1.0)


def test_a_gated_outline_point_far_outside_the_model_hardly_pulls(open_close):
    """open_close frame 20 with a bright bar beside the hand (a second object inside the region of
    interest): its outline points lie 15 px and more outside every pill. Ungated they pull on the
    pose as hard as any; with ``cover_gate_px`` 5 their Jacobian rows shrink to a small fraction,
    while the points on the hand's own outline keep theirs."""
    image = _frame(open_close, 20).copy()
    ys, xs = np.nonzero(image > 20)
    image[ys.min():ys.max(), xs.max() + 15: xs.max() + 25] = 200
    q = _q(open_close, 20)
    configs = {gate: SilhouetteTermConfig(weight=0.5, cover_gate_px=gate) for gate in (None, 5.0)}
    terms = {gate: silhouette_term(image, ThresholdForeground(), 0, c) for gate, c in configs.items()}
    priors = {gate: t.bind(open_close.model, tuple(open_close.truth.cameras)) for gate, t in terms.items()}
    n = ON.contour_points
    d = np.asarray(priors[None].distances(q)[0][0])
    valid = np.asarray(terms[None].contour_valid)
    far, near = valid & (d > 15), valid & (np.abs(d) < 1)
    assert far.sum() >= 10 and near.sum() >= 30
    rows = {gate: np.linalg.norm(np.asarray(jax.jacfwd(p)(q))[:n], axis=1) for gate, p in priors.items()}
    assert rows[5.0][far].mean() < 0.05 * rows[None][far].mean()   # 0.016
    np.testing.assert_allclose(rows[5.0][near], rows[None][near], rtol=0.05)
    with pytest.raises(jh.InputError, match=r"silhouette_term\.cover_gate_px: need > 0 px or None"):
        SilhouetteTermConfig(cover_gate_px=0.0)


def _shifted_outline(image, grow: int) -> np.ndarray:
    """The threshold mask of ``image`` grown (> 0) or shrunk (< 0) by ``|grow|`` px (3x3 cross)."""
    mask = ThresholdForeground().mask(image).astype(np.uint8)
    cross = cv2.getStructuringElement(cv2.MORPH_CROSS, (3, 3))
    return (cv2.dilate(mask, cross, iterations=grow) if grow > 0 else cv2.erode(mask, cross, iterations=-grow)) > 0


@pytest.mark.parametrize("grow", [-1, 1], ids=["shrunk", "grown"])
def test_a_mask_a_pixel_off_the_outline_is_measured_and_taken_out(open_close, grow):
    """A mask shrunk (grown) by a pixel, as a segmentation network's may be: at the true pose its
    outline lies about a pixel inside (outside) the model's, which ``outline_bias_px`` measures;
    with ``rim_px`` at minus that the pills are compared as if that much thinner (fatter), and the
    true pose fits it about as well as the exact mask fits the pills as they are."""
    image, q = _frame(open_close, 20), _q(open_close, 20)
    cams = tuple(open_close.truth.cameras)
    given = MaskForeground([image], [_shifted_outline(image, grow)])
    plain = silhouette_term(image, given, 0, ON).bind(open_close.model, cams)
    bias = plain.outline_bias_px(q)
    exact = silhouette_term(image, ThresholdForeground(), 0, ON).bind(open_close.model, cams)
    base = exact.outline_bias_px(q)   # 0.28: the threshold keeps the anti-aliased rim
    assert abs(base) < 0.4 and abs(bias - base - grow) < 0.25, (bias, base)
    rimmed = silhouette_term(image, given, 0, ON, rim_px=-bias).bind(open_close.model, cams)
    assert float(rimmed.term.rim_px) == pytest.approx(-bias)
    assert abs(rimmed.outline_bias_px(q) - bias) < 1e-9   # measured on the pills as they are
    covered = np.asarray(rimmed.distances(q)[0][0])[np.asarray(rimmed.term.contour_valid)]
    assert abs(float(np.median(covered))) < 0.3
    assert float(rimmed.rms_px(q)) < 0.6 * float(plain.rms_px(q)), (float(rimmed.rms_px(q)), float(plain.rms_px(q)))
    assert float(rimmed.rms_px(q)) < 1.5 * float(exact.rms_px(q)) + 0.1


def test_the_front_end_measures_the_rim_at_the_first_pose_and_keeps_it(open_close):
    """``rim_px = "auto"``: the first frame's terms are measured at the caller's pose and every
    later frame's carry that rim; a number is used as it is and nothing is measured."""
    m, cams = open_close.model, open_close.truth.cameras
    frames = [_frame(open_close, k) for k in (0, 1)]
    given = MaskForeground(frames, [_shifted_outline(f, -1) for f in frames])
    auto = dataclasses.replace(ON, rim_px="auto")
    fe = ImageFrontEnd(m, cams, ImageConfig(silhouette_term=auto), foregrounds=[given])
    assert fe.rims_px is None
    first = fe.extract([frames[0]], np.asarray(open_close.truth.q[0]), None, 0)
    (rim,) = fe.rims_px
    assert 0.7 < rim < 1.3 and float(first.terms[0].rim_px) == pytest.approx(rim)
    later = fe.extract([frames[1]], np.asarray(open_close.truth.q[0]) + 0.05, None, 1)
    assert fe.rims_px == (rim,) and float(later.terms[0].rim_px) == pytest.approx(rim)
    half = ImageConfig(silhouette_term=dataclasses.replace(ON, rim_px=0.5))
    fixed = ImageFrontEnd(m, cams, half, foregrounds=[given])
    assert float(fixed.extract([frames[0]], np.asarray(open_close.truth.q[0]), None, 0).terms[0].rim_px) == 0.5
    assert fixed.rims_px is None
