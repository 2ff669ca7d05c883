"""Foreground models on synthetic frames whose foreground is known exactly."""

import dataclasses
from pathlib import Path

import cv2
import numpy as np
import pytest
from mujoco_hand import frame

from jaxhand.image import ImageConfig
from jaxhand.io import load_devset, open_frames
from jaxhand.score import (
    AbstractForeground,
    BackgroundForeground,
    ColourSequenceBackground,
    MaskForeground,
    ScoreSection,
    SequenceBackground,
    Silhouette,
    SilhouetteTermConfig,
    SkinForeground,
    ThresholdForeground,
    as_grey,
    camera_numbers,
    capsules_from_model,
    fill_holes,
    foreground_for,
    image_evidence,
    rasterize,
    score_silhouette,
    sequence_foreground,
    silhouette_term,
    skin_foreground,
)
from jaxhand.track import ImageFrontEnd, image_front_end

DEVSET = Path(__file__).resolve().parent.parent / "data" / "mujoco"


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


def _skin_scene(q_hand, seed=3, paint_hand=True):
    """A colour frame of the dev set's model at ``q_hand`` painted a light skin tone (unless not
    ``paint_hand``) over a grey background with a band of 'wood' whose colour the generic skin
    model also takes, the model, its camera and the hand's and the wood's masks."""
    seq = load_devset(DEVSET / "open_close")
    m, cam = seq.model, seq.truth.cameras[0]
    hand = rasterize(capsules_from_model(m, np.asarray(q_hand)), cam).mask
    rng = np.random.default_rng(seed)
    bgr = np.empty(hand.shape + (3,), float)
    bgr[:] = (128, 128, 128)
    wood = np.zeros(hand.shape, bool)
    wood[:, :150] = True   # beside and behind the hand
    bgr[wood] = (40, 90, 160)
    bgr[hand & paint_hand] = (120, 150, 210)
    bgr = np.clip(bgr + rng.normal(0, 3, bgr.shape), 0, 255).astype(np.uint8)
    return bgr, m, cam, seq.truth.q[0], hand, wood & ~hand


def test_skin_foreground_fits_the_hands_own_colour_at_the_first_pose():
    """The generic skin model takes the wood too; the model fitted inside the first pose's
    silhouette takes the hand alone. Off the hand, or without ``skin_fit``, it stays generic."""
    seq = load_devset(DEVSET / "open_close")
    bgr, m, cam, q0, hand, wood = _skin_scene(seq.truth.q[0])
    generic = SkinForeground().mask(bgr)
    assert generic[wood].mean() > 0.95
    fitted = skin_foreground(m, cam, q0, bgr, ScoreSection(foreground="skin"))
    mask = fitted.mask(bgr)
    assert (mask & hand).sum() / (mask | hand).sum() > 0.97
    assert mask[wood].mean() < 0.01
    assert fitted.mean != SkinForeground().mean and fitted.fill_px == 100
    empty = _skin_scene(q0, paint_hand=False)[0]   # the first pose's silhouette on no skin
    assert skin_foreground(m, cam, q0, empty, ScoreSection(foreground="skin")).mean == SkinForeground().mean
    plain = skin_foreground(m, cam, q0, bgr, ScoreSection(foreground="skin", skin_fit=False))
    assert plain.mean == SkinForeground().mean and plain.max_distance == 2.5


def test_the_front_end_scores_with_the_fitted_skin():
    """The front end's image score of the true pose on the colour frame: near 1 with the fitted
    skin, lower with the generic one, which takes the wood beside the hand as foreground."""
    seq = load_devset(DEVSET / "open_close")
    q0 = np.asarray(seq.truth.q[0])
    bgr, m, cam, _, hand, wood = _skin_scene(q0)
    scores = {}
    for fit in (True, False):
        fe = ImageFrontEnd(m, cam, ImageConfig(score=ScoreSection(foreground="skin", skin_fit=fit)))
        state = fe.extract([bgr], q0, None, 0).state
        scores[fit] = float(fe.score([bgr], q0[None], state)[0])
    assert scores[True] > 0.9 and scores[False] < scores[True] - 0.05   # 0.92 and 0.85


class _GivenMask(AbstractForeground):
    def __init__(self, mask):
        self.given = mask

    def mask(self, image):
        return self.given


def test_the_front_end_reads_a_callers_foreground():
    """A caller's foreground replaces the config's (here generic skin, which takes the wood too):
    the true pose scores as with the fitted skin on the hand's own mask, and far lower on a shifted one."""
    seq = load_devset(DEVSET / "open_close")
    q0 = np.asarray(seq.truth.q[0])
    bgr, m, cam, _, hand, _ = _skin_scene(q0)
    config = ImageConfig(score=ScoreSection(foreground="skin", skin_fit=False))
    scores = []
    for given in (hand, np.roll(hand, 30, axis=1)):
        fe = ImageFrontEnd(m, cam, config, foregrounds=[_GivenMask(given)])
        scores.append(float(fe.score([bgr], q0[None], fe.extract([bgr], q0, None, 0).state)[0]))
    assert scores[0] > 0.9 and scores[1] < 0.6
    with pytest.raises(ValueError, match=r"foregrounds: expected one jaxhand.score.AbstractForeground per camera"):
        ImageFrontEnd(m, cam, config, foregrounds=[_GivenMask(hand)] * 2)


def test_mask_foreground_matches_masks_to_frames_by_content(tmp_path):
    rng = np.random.default_rng(4)
    frames = [rng.integers(0, 255, (12, 16), np.uint8) for _ in range(3)]
    masks = [rng.random((12, 16)) > 0.5 for _ in range(3)]
    given = MaskForeground(iter(frames), masks)
    for k in (2, 0, 1, 1):   # out of order and again, as a review and the score read them
        np.testing.assert_array_equal(given.mask(frames[k]), masks[k])
    with pytest.raises(ValueError, match=r"this frame \(\(12, 16\)\) is none of the 3 frames"):
        given.mask(frames[0] + 1)
    with pytest.raises(ValueError, match=r"masks: 2 mask\(s\) for 3 frame\(s\)"):
        MaskForeground(frames, masks[:2])
    paths = []
    for k, m in enumerate(masks):   # mask images at twice the frames' size, read when first asked for
        paths.append(tmp_path / f"m{k}.png")
        cv2.imwrite(str(paths[-1]), np.kron(m, np.ones((2, 2))).astype(np.uint8) * 255)
    np.testing.assert_array_equal(MaskForeground(frames, paths).mask(frames[1]), masks[1])
    cv2.imwrite(str(paths[0]), np.zeros((12, 30), np.uint8))
    with pytest.raises(ValueError, match=r"m0.png: a 30x12 mask for a 16x12 frame"):
        MaskForeground(frames, paths).mask(frames[0])


def test_skin_needs_colour_frames():
    with pytest.raises(ValueError, match="'skin' reads colour, but the frames are grey"):
        foreground_for(ScoreSection(foreground="skin"), np.zeros((4, 4), np.uint8))
    with pytest.raises(ValueError, match="score.skin_fit_distance: need > 0, got 0"):
        ScoreSection(foreground="skin", skin_fit_distance=0)
    assert ScoreSection(foreground="skin").reads_colour and ScoreSection(foreground="skin").needs_colour
    assert ScoreSection(foreground="sequence").reads_colour and not ScoreSection(foreground="sequence").needs_colour
    assert not any(ScoreSection(foreground=f).reads_colour for f in ("auto", "none", "threshold"))


def test_bad_inputs():
    with pytest.raises(ValueError, match="expected an"):
        as_grey(np.zeros((4, 4, 2)))
    with pytest.raises(ValueError, match="non-finite"):
        as_grey(np.full((4, 4), np.nan))
    with pytest.raises(ValueError, match="method"):
        ThresholdForeground(method="mean")
    with pytest.raises(ValueError, match="cov"):
        SkinForeground(cov=((1.0, 2.0), (2.0, 1.0)))


def _moving_finger_frames(n=9, seed=2, cover_from=None):
    """A textured background, a still bright "palm" and a bright "finger" moving right; from
    frame ``cover_from`` on, a grey "fist" sits where the finger started."""
    rng = np.random.default_rng(seed)
    bg = cv2.GaussianBlur(rng.uniform(40, 200, (60, 80)), (0, 0), 3)
    palm = np.zeros(bg.shape, bool)
    palm[35:55, 30:60] = True
    fist = np.zeros(bg.shape, bool)
    fist[8:18, 6:11] = True
    frames, hands = [], []
    for k in range(n):
        f = bg + rng.normal(0, 2, bg.shape)
        finger = np.zeros(bg.shape, bool)
        finger[5:20, 5 + 8 * k: 12 + 8 * k] = True
        hand = palm | finger
        f[hand] = 230
        if cover_from is not None and k >= cover_from:
            f[fist] = 120
            hand = hand | fist
        frames.append(np.clip(np.rint(f), 0, 255).astype(np.uint8))
        hands.append(hand)
    return frames, hands, palm, fist


def test_sequence_background_keeps_the_still_hand_and_learns_the_moving_one():
    """A median learns a hand part that never moves as background; anchored at the first frame's
    known silhouette the still palm stays foreground and the moving finger is found."""
    frames, hands, palm, _ = _moving_finger_frames()
    plain = BackgroundForeground.from_frames(frames)
    assert plain.mask(frames[4])[palm].mean() < 0.05   # the median took the palm for background
    model = SequenceBackground(frames, hands[0])
    assert model.noise == 3.0   # 2 grey levels of noise, floored at min_noise
    assert np.count_nonzero(model.mask(frames[4]) != hands[4]) <= 8
    with pytest.raises(ValueError, match="hand_mask: expected shape"):
        SequenceBackground(frames, palm[:10])
    with pytest.raises(ValueError, match="silhouette: expected shape"):
        model.observe(frames[0], palm[:10])


def test_colour_sequence_background_finds_a_hand_of_the_backgrounds_grey():
    """A palm and a moving finger whose colour has the grey of the background behind them: the
    grey background learns nothing of the finger, the colour one finds it as the grey one finds
    a bright finger."""
    _, hands, palm, _ = _moving_finger_frames()
    finger = hands[4] & ~palm
    rng = np.random.default_rng(5)
    bg = cv2.GaussianBlur(rng.uniform(60, 180, (60, 80)), (0, 0), 3)
    colour = []
    for hand in hands:
        f = np.repeat(bg[..., None], 3, axis=2) + rng.normal(0, 2, bg.shape + (3,))
        f[hand] = np.stack([bg + 50, bg - 50 * 0.413 / 0.587, bg + 50], -1)[hand]   # B, G, R of the same grey
        colour.append(np.clip(np.rint(f), 0, 255).astype(np.uint8))
    grey = [cv2.cvtColor(f, cv2.COLOR_BGR2GRAY) for f in colour]
    assert SequenceBackground(grey, hands[0]).mask(grey[4])[finger].mean() < 0.1
    model = ColourSequenceBackground(colour, hands[0])
    assert [c.noise for c in model.channels] == [3.0, 3.0, 3.0]
    assert np.count_nonzero(model.mask(colour[4]) != hands[4]) <= 8
    with pytest.raises(ValueError, match=r"frames\[0\]: expected a BGR frame"):
        ColourSequenceBackground(grey, hands[0])
    with pytest.raises(ValueError, match="image: expected a BGR frame"):
        model.observe(grey[4], hands[4])


def test_sequence_background_drops_a_mode_the_tracked_model_covers():
    """A part that settles where the finger started (a fist) is the commonest grey there, so
    the mode takes it for background; after the tracked silhouette has covered it on two frames
    it is foreground again (but for its outline), and where the tracked model left the image free the background is
    what was seen."""
    frames, hands, _, fist = _moving_finger_frames(cover_from=3)
    model = SequenceBackground(frames, hands[0], margin_px=1)   # the fist is 5 px wide: covered 1 px in
    assert model.mask(frames[5])[fist].mean() < 0.1
    for k in (3, 4):
        model.observe(frames[k], hands[k])
    assert model.mask(frames[5])[fist].mean() >= 0.4   # 20 of its 50 pixels, its outline left to the seen ones
    background, known = model.background()
    assert known[0, 0] and abs(background[0, 0] - (frames[3][0, 0] / 2 + frames[4][0, 0] / 2)) < 1e-4


def test_a_narrow_fist_beside_the_fingers_first_place_is_dropped_too():
    """A curled finger is a few pixels wide and may rest a little beyond where a finger lay at
    the first pose: a pixel 1 px inside the tracked silhouette counts as covered, anywhere within
    the first silhouette's margin; 3 px in, none of an 8-px-wide fist would be."""
    frames, hands, _, _ = _moving_finger_frames(cover_from=3)
    fist = np.zeros_like(hands[0])
    fist[8:18, 6:14] = True   # the finger lay over columns 5-11 at the first frame
    for k in range(3, len(frames)):
        frames[k][fist] = 120
        hands[k] = hands[k] | fist
    shares = []
    for cover_px in (1, 3):
        model = SequenceBackground(frames, hands[0], cover_px=cover_px)
        assert model.mask(frames[5])[fist].mean() == 0.0   # the commonest grey there: taken for background
        for k in (3, 4):
            model.observe(frames[k], hands[k])
        mask = model.mask(frames[5])
        shares.append((mask[fist].mean(), mask[8:18, 12:14].mean(), model.doubtful(frames[5], mask)[fist].mean()))
    assert shares[0] == pytest.approx((0.55, 0.3, 0.55))   # never seen free: doubtful, out of the scores
    assert shares[1] == (0.0, 0.0, 0.0)
    with pytest.raises(ValueError, match=r"cover_px: expected a whole number of pixels >= 0, got -1"):
        SequenceBackground(frames, hands[0], cover_px=-1)
    with pytest.raises(ValueError, match=r"margin_px: expected a whole number of pixels >= 0, got -2"):
        SequenceBackground(frames, hands[0], margin_px=-2)


def test_a_mode_dropped_under_a_lagging_model_is_doubtful_and_left_out_of_the_scores():
    """A tracked model that lags over the finger's first place covers background that matches the
    learned mode, so the mode is dropped as a hand part that stayed put and those pixels turn
    foreground. They match the mode and were never seen free: doubtful. The scores leave them out,
    so they do not support the lagging model, and the silhouette term's outline skips them."""
    frames, hands, _, _ = _moving_finger_frames()
    start = np.zeros(hands[0].shape, bool)
    start[7:18, 6:11] = True   # inside the finger's first place, away from its outline
    model = SequenceBackground(frames, hands[0], margin_px=1)
    for k in (1, 2):
        model.observe(frames[k], hands[0])   # the model stays where the finger started
    mask, doubtful = model.mask(frames[3]), model.doubtful(frames[3])
    assert mask[start].all() and doubtful[start].all()   # foreground, by the dropped mode
    assert not (doubtful & ~mask).any() and not doubtful[hands[3] & ~hands[0]].any()   # the finger is not doubted
    lagging = Silhouette(mask=start, label=np.where(start, 0, -1).astype(np.int16), occluder=np.zeros(1, bool),
                         adjacent=np.zeros((1, 1), bool), box=(5, 6, 12, 19))
    evidence = image_evidence(frames[3], model)
    assert evidence.doubtful is not None and evidence.doubtful[start].all()
    trusted = score_silhouette(lagging, dataclasses.replace(evidence, doubtful=None))
    judged = score_silhouette(lagging, evidence)
    assert trusted.coverage == 1.0 and trusted.link_score[0] == 0.5   # sanity: the false foreground supports it
    assert judged.coverage == 0.0 and not np.isfinite(judged.link_score[0])   # no pixel left to judge it by
    # the term's outline points: none on the doubtful pixels' outline (the same mask, undoubted, has some)
    near = cv2.dilate(doubtful.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0

    def on_doubt(foreground):
        term = silhouette_term(frames[3], foreground, 0, SilhouetteTermConfig(max_share=1.0))
        pts = np.asarray(term.contour)[np.asarray(term.contour_valid)].round().astype(int)
        return int(near[pts[:, 1], pts[:, 0]].sum()), len(pts)

    assert on_doubt(model)[0] == 0 and on_doubt(MaskForeground([frames[3]], [mask]))[0] > 5
    # the colour model doubts where every channel that calls a pixel foreground doubts it
    colour = ColourSequenceBackground([np.repeat(f[..., None], 3, -1) for f in frames], hands[0], margin_px=1)
    for k in (1, 2):
        colour.observe(np.repeat(frames[k][..., None], 3, -1), hands[0])
    np.testing.assert_array_equal(colour.doubtful(np.repeat(frames[3][..., None], 3, -1)), doubtful)
    # a model that cannot doubt doubts nothing
    assert not ThresholdForeground().doubtful(frames[3]).any()


def test_sequence_background_keeps_a_hand_resting_beyond_the_first_silhouette():
    """A finger that moves off the first silhouette and rests there for most frames is the
    commonest grey there, and a tracked model a few pixels short of it leaves it "free"; where
    the first frame showed background, only greys agreeing with it are learned, so the resting
    finger stays foreground. Without the anchor both learn the finger as background."""
    rng = np.random.default_rng(4)
    bg = cv2.GaussianBlur(rng.uniform(40, 200, (60, 80)), (0, 0), 3)
    start, rest = np.zeros(bg.shape, bool), np.zeros(bg.shape, bool)
    start[20:40, 10:18] = True
    rest[20:40, 50:58] = True
    frames = []
    for k in range(12):
        f = bg + rng.normal(0, 2, bg.shape)
        f[start if k == 0 else rest] = 230
        frames.append(np.clip(np.rint(f), 0, 255).astype(np.uint8))
    short = np.zeros(bg.shape, bool)
    short[20:40, 50:52] = True   # the tracked model covers 2 of the finger's 8 columns
    anchored, plain = SequenceBackground(frames, start), SequenceBackground(frames, start, anchor_clear=False)
    for model in (anchored, plain):
        for k in (1, 2, 3):
            model.observe(frames[k], short)
    assert anchored.mask(frames[5])[rest].mean() > 0.95   # all but corners the opening rounds off
    assert plain.mask(frames[5])[rest].mean() < 0.05   # learned as background (measured 0)
    assert anchored.mask(frames[5])[~rest].mean() < 0.01


def test_sequence_background_patch_finds_a_faint_part():
    """An object passing in one frame, 3 noise levels brighter than the background: the
    per-pixel test (4 levels) misses most of it, the 3x3 patch test finds it without growing
    its outline."""
    rng = np.random.default_rng(3)
    bg = cv2.GaussianBlur(rng.uniform(40, 200, (60, 80)), (0, 0), 3)
    obj = np.zeros(bg.shape, bool)
    obj[20:40, 30:50] = True
    frames = [np.clip(np.rint(bg + rng.normal(0, 2, bg.shape) + 6.0 * (obj & (k == 3))), 0, 255).astype(np.uint8)
              for k in range(12)]
    empty = np.zeros(bg.shape, bool)
    pixel = SequenceBackground(frames, empty, patch_level=0.0, min_noise=2.0)
    patch = SequenceBackground(frames, empty, min_noise=2.0)
    assert pixel.mask(frames[3])[obj].mean() < 0.2
    found = patch.mask(frames[3])
    inner = np.zeros(bg.shape, bool)
    inner[21:39, 31:49] = True   # the patch test's mask is shrunk by a pixel
    assert found[inner].mean() > 0.95 and found[~obj].mean() < 0.01   # measured 0.99 and 0


def test_fill_holes_fills_small_holes_only():
    mask = np.ones((30, 40), bool)
    mask[5:8, 5:8] = False      # 9 px: filled
    mask[15:25, 15:25] = False  # 100 px: kept
    mask[0:3, 30:35] = False    # on the border: kept
    out = fill_holes(mask, 50)
    assert out[5:8, 5:8].all() and not out[15:25, 15:25].any() and not out[0:3, 30:35].any()
    assert np.array_equal(fill_holes(mask, 0), mask)


def test_sequence_foreground_finds_the_hand_on_the_cluttered_dev_sequence():
    """The dev set's clutter sequence against the clean one's threshold mask (the same hand on
    black): learned while tracking (here the true poses are observed), the foreground overlaps
    it by an IoU >= 0.9 (measured 0.93-0.96) where the plain median finds only the moving
    fingers (IoU < 0.2)."""
    seq = load_devset(DEVSET / "open_close_noise_clutter")
    (source,) = open_frames(DEVSET / "open_close_noise_clutter" / "frames")
    (clean,) = open_frames(DEVSET / "open_close" / "frames")
    frames = source.spread(60)
    cam = seq.truth.cameras[0]
    fg = sequence_foreground(seq.model, cam, seq.truth.q[0], frames)
    plain = BackgroundForeground.from_frames(frames)
    clean_frames = {f.index: f.image for f in clean}
    numbers = camera_numbers(cam)
    for f in source:
        if f.index in (15, 30, 45, 80):
            truth = clean_frames[f.index] > 20

            def iou(m, truth=truth):
                return (m & truth).sum() / (m | truth).sum()
            assert iou(fg.mask(f.image)) >= 0.9
            assert iou(plain.mask(f.image)) < 0.2
        fg.observe(f.image, rasterize(capsules_from_model(seq.model, np.asarray(seq.truth.q[f.index])), numbers).mask)


def test_the_sequence_foreground_needs_the_sequence():
    section = ScoreSection(foreground="sequence")
    with pytest.raises(ValueError, match="'sequence' learns from the whole sequence: track with jaxhand"):
        foreground_for(section, np.zeros((4, 4), np.uint8))
    with pytest.raises(ValueError, match="score.sequence_frames: need an integer >= 3, got 2"):
        ScoreSection(foreground="sequence", sequence_frames=2)
    seq = load_devset(DEVSET / "open_close_noise_clutter")
    cam = seq.truth.cameras[0]
    with pytest.raises(ValueError, match=r"background_frames: expected one stack per camera \(1\), got 2"):
        ImageFrontEnd(seq.model, cam, background_frames=[np.zeros((3, 240, 320), np.uint8)] * 2)
    config = ImageConfig(score=ScoreSection(foreground="sequence", sequence_frames=5))
    fe = image_front_end(seq.model, cam, config, open_frames(DEVSET / "open_close_noise_clutter" / "frames"), 40)
    (frames,) = fe.background_frames
    assert frames.shape == (5, 240, 320)   # frames 0, 10, 20, 29, 39 of the first 40
    assert image_front_end(seq.model, cam, ImageConfig(), open_frames(DEVSET / "open_close" / "frames")
                           ).background_frames is None
