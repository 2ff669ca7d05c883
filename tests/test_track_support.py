"""The per-finger image support in the confidence (jaxhand.track._support, issue 13): a finger the
image does not back lowers the frame's confidence even when the model stays inside the foreground."""

import dataclasses
from pathlib import Path

import cv2
import equinox as eqx
import numpy as np
import pytest

from jaxhand import InputError
from jaxhand.io import load_devset
from jaxhand.render import make_preset
from jaxhand.score import ScoreConfig, ScoreSection, foreground_for, score_frame, side_edge_share
from jaxhand.track import (
    AbstractFrontEnd,
    ExactFrontEnd,
    ImageFrontEnd,
    ImageSupport,
    SupportConfig,
    TrackConfig,
    Tracker,
    config_from_dict,
)
from jaxhand.track._support import (
    finger_of_link,
    judge_weights,
    largest_unexplained_px,
    support_confidence,
    tip_link_scores,
    unexplained_confidence,
    weakest_finger,
    whole_finger_confidence,
)

DEVSET = Path(__file__).resolve().parent.parent / "data" / "mujoco"


@pytest.fixture(scope="module")
def opposition():
    return load_devset(DEVSET / "thumb_opposition")


def test_support_config_checks_its_levels():
    with pytest.raises(InputError, match="support.lost"):
        SupportConfig(lost=0.9, good=0.9)
    with pytest.raises(InputError, match="support.unexplained_px"):
        SupportConfig(unexplained_px=-1.0)
    for key, value in (("enabled", 1), ("margin_px", -1), ("tip_links", "yes")):
        with pytest.raises(InputError, match=f"support.{key}"):
            config_from_dict({"support": {key: value}})
    assert not TrackConfig().support.enabled
    assert TrackConfig().preset("robust").support.enabled


def test_the_hands_links_group_into_its_five_fingers(opposition):
    finger = finger_of_link(opposition.model)
    names = opposition.model.link_names
    assert len(np.unique(finger)) == 5
    for i, a in enumerate(names):
        for j, b in enumerate(names):
            assert (finger[i] == finger[j]) == (a.split("_")[0] == b.split("_")[0]), (a, b)


def test_weakest_finger_averages_cameras_and_leaves_hidden_links_out():
    finger = np.array([0, 0, 1, 1])
    # finger 0: link 0 judged by one camera (0.9), link 1 by both (0.7, 0.9 -> 0.8): 0.85
    # finger 1: link 2 hidden in both cameras, link 3 at 0.6 and 0.8: 0.7
    scores = np.array([[0.9, 0.7, np.nan, 0.6], [np.nan, 0.9, np.nan, 0.8]])
    assert weakest_finger(scores, finger) == pytest.approx(0.7)
    assert weakest_finger(scores[:1], finger) == pytest.approx(0.6)
    assert np.isnan(weakest_finger(np.full((1, 4), np.nan), finger))


def test_tip_link_scores_judge_each_finger_by_its_tip_link():
    finger = np.array([0, 0, 1, 1])
    scores = np.array([[0.5, 0.9, 0.95, 0.7], [np.nan, 0.8, 0.6, np.nan]])
    kept = tip_link_scores(scores, (1, 3))
    np.testing.assert_array_equal(np.isnan(kept), [[True, False, True, False], [True, False, True, True]])
    assert weakest_finger(kept, finger) == pytest.approx(0.7)      # finger 1's tip link, one camera
    assert weakest_finger(scores, finger) == pytest.approx(0.675)  # all links: finger 0's (0.5 + 0.85) / 2
    assert weakest_finger(tip_link_scores(scores[:, :2], (1,)), finger[:2]) == pytest.approx(0.85)


def test_support_confidence_is_a_clipped_ramp():
    config = SupportConfig(lost=0.8, good=0.96)
    assert support_confidence(0.88, config) == pytest.approx(0.5)
    assert support_confidence(0.7, config) == 0.0
    assert support_confidence(0.99, config) == 1.0
    assert support_confidence(float("nan"), config) == 1.0
    config = SupportConfig(unexplained_px=8.0)
    assert [unexplained_confidence(a, config) for a in (0, 8, 12, 20)] == pytest.approx([1.0, 0.5, 0.25, 0.0])
    assert unexplained_confidence(100, SupportConfig(unexplained_px=0.0)) == 1.0


def test_whole_finger_confidence_ramps_the_weakest_finger_and_is_off_by_default():
    config = SupportConfig(whole_lost=0.5, whole_good=0.8)
    assert whole_finger_confidence({0: 0.9, 1: 0.65}, config) == pytest.approx(0.5)
    assert whole_finger_confidence({0: 0.9, 1: 0.56}, config) == pytest.approx(0.2)
    assert whole_finger_confidence({0: 0.45}, config) == 0.0
    assert whole_finger_confidence({}, config) == 1.0
    assert whole_finger_confidence({0: 0.1}, SupportConfig()) == 1.0
    for lost, good in ((0.8, 0.5), (0.5, 0.0), (-0.1, 0.5), (0.5, 1.2)):
        with pytest.raises(InputError, match="support.whole_lost"):
            SupportConfig(whole_lost=lost, whole_good=good)
    with pytest.raises(InputError, match="support.whole_good"):
        SupportConfig(whole_good=float("nan"))


def test_unexplained_foreground_is_the_largest_blob_beyond_the_margin():
    silhouette = np.zeros((40, 40), bool)
    silhouette[10:30, 10:20] = True
    foreground = silhouette.copy()
    foreground[10:30, 20] = True            # a one-pixel rim along the outline: within the margin
    assert largest_unexplained_px(foreground, silhouette, 1) == 0
    foreground[0:3, 30:34] = True           # a 3x4 blob away from the model: thinner than the opening
    foreground[33:36, 0:30] = True          # a three-pixel band (a model 2-3 px off a finger's side): too
    assert largest_unexplained_px(foreground, silhouette, 1) == 0
    foreground[4:9, 30:36] = True           # a 5x6 blob away from the model
    assert largest_unexplained_px(foreground, silhouette, 1) == 30
    foreground[10:16, 20:27] = True         # a 6x7 blob on the outline: its first column lies in the margin
    assert largest_unexplained_px(foreground, silhouette, 1) == 36


def test_a_finger_bent_inside_the_foreground_loses_the_confidence(opposition):
    """thumb_opposition frame 20: at the true pose the weakest finger keeps the confidence above
    0.5; with the index bent 30 deg at its knuckle the model still lies wholly inside the
    foreground (coverage 1), which the global score barely sees, but the index's own links lose
    their support and the frame its confidence."""
    seq, m = opposition, opposition.model
    image = cv2.imread(str(seq.image_paths[0][20]), cv2.IMREAD_GRAYSCALE)
    config = TrackConfig().preset("robust")
    frontend = ImageFrontEnd(m, seq.truth.cameras, config.image)
    q = np.array(seq.truth.q[20])
    bent = q.copy()
    bent[m.q_names.index("index_mcp_flex")] += np.radians(30)
    finger = finger_of_link(m)
    at_true, at_bent = (frontend.support([image], x, None) for x in (q, bent))
    assert at_true.unexplained_px == 0
    assert support_confidence(weakest_finger(at_true.link_score, finger), config.support) >= 0.5
    assert support_confidence(weakest_finger(at_bent.link_score, finger), config.support) < 0.5
    scores = at_bent.link_score
    assert np.nanargmin(scores[0]) in np.flatnonzero(finger == finger[m.link_names.index("index_proximal")])
    foreground = foreground_for(ScoreSection(foreground="auto"), image)
    assert score_frame(m, seq.truth.cameras[0], bent, image, foreground).coverage > 0.99


def test_a_link_off_its_own_edges_loses_its_side_share_and_with_it_its_support(opposition):
    """thumb_opposition frame 20: at the true pose every link finds an edge across nearly all its
    visible side points; with the index bent 15 deg at its knuckle its middle and distal phalanges,
    lying over the hand, find few (the hand's edges near them run the wrong way). With
    ``side_edge_px`` the front end's link support is capped by that share."""
    seq, m = opposition, opposition.model
    image = cv2.imread(str(seq.image_paths[0][20]), cv2.IMREAD_GRAYSCALE)
    q = np.array(seq.truth.q[20])
    bent = q.copy()
    bent[m.q_names.index("index_mcp_flex")] += np.radians(15)
    sides = ScoreConfig(side_edge_px=2.0)
    at_true, at_bent = (side_edge_share(image, m, seq.truth.cameras[0], x, sides) for x in (q, bent))
    assert np.nanmin(at_true) >= 0.9
    index = [m.link_names.index(n) for n in ("index_middle", "index_distal")]
    assert np.all(at_bent[index] <= 0.45)
    config = TrackConfig().preset("robust")
    off = ImageFrontEnd(m, seq.truth.cameras, config.image).support([image], bent, None).link_score[0]
    with_sides = config.merged({"image": {"score": {"silhouette": {"side_edge_px": 2.0}}}}).image
    on = ImageFrontEnd(m, seq.truth.cameras, with_sides).support([image], bent, None).link_score[0]
    np.testing.assert_allclose(on, np.where(np.isfinite(at_bent), np.minimum(off, at_bent), off))
    assert np.all(off[index] > 0.6)   # sanity: the silhouette score alone keeps them
    with pytest.raises(InputError, match="ScoreConfig.side_edge_px, side_edge_gradient: need >= 0 and > 0"):
        ScoreConfig(side_edge_px=-1.0)
    with pytest.raises(InputError, match="ScoreConfig.side_fractions: need at least one fraction in"):
        ScoreConfig(side_fractions=(0.5, 1.5))


def test_side_edges_are_found_in_colour_where_the_grey_has_none(opposition):
    """thumb_opposition frame 20 repainted with its shading in colour alone (blue and red up where
    green goes down, the grey flat at 120): the grey image has no edge across any side, the colour
    one finds the hand's edges across nearly all of every link's sides, as the grey original does."""
    seq, m = opposition, opposition.model
    original = cv2.imread(str(seq.image_paths[0][20]), cv2.IMREAD_GRAYSCALE).astype(float)
    d = 0.8 * (original - 120.0)
    colour = np.rint(np.stack([120 + d, 120 - d * 0.299 / 0.587 - d * 0.114 / 0.587, 120 + d], -1)).astype(np.uint8)
    grey = cv2.cvtColor(colour, cv2.COLOR_BGR2GRAY)
    assert np.ptp(grey) <= 2
    q, sides = np.array(seq.truth.q[20]), ScoreConfig(side_edge_px=2.0)
    assert np.nanmax(side_edge_share(grey, m, seq.truth.cameras[0], q, sides)) == 0.0
    assert np.nanmin(side_edge_share(colour, m, seq.truth.cameras[0], q, sides)) >= 0.85   # 0.875 at 0.8 the contrast


class _Supported(AbstractFrontEnd):
    """Exact features, and a fixed link support (None: the front end measures none)."""

    reextracts = False

    def __init__(self, exact, support):
        self.exact, self.measured = exact, support

    def extract(self, images, q_start, state, frame):
        return self.exact.extract(images, q_start, state, frame)

    def support(self, images, q, state, margin_px=1):
        return self.measured


@pytest.mark.parametrize("support, unexplained, enabled, low", [
    (0.5, 0, True, True), (0.95, 0, True, False), (0.95, 20, True, True), (0.5, 20, False, False),
    (None, 0, True, False)])
def test_the_tracker_takes_the_lower_confidence(support, unexplained, enabled, low):
    """A clean exact-feature frame is confident; a front end reporting weak support for one finger,
    or a blob of unexplained foreground, lowers it below 0.5 when the rule is on, without losing
    the frame or moving the estimate."""
    seq = make_preset("two_finger_occlusion", frames=3, size=(160, 120))
    exact = ExactFrontEnd(seq.model, seq.cameras, seq.q, noise_px=0.0)
    measured = None
    if support is not None:
        scores = np.full((1, seq.model.n_links), 0.99)
        scores[0, 0] = support
        measured = ImageSupport(link_score=scores, unexplained_px=float(unexplained))
    config = TrackConfig(support=SupportConfig(enabled=enabled))
    runs = []
    for frontend in (exact, _Supported(exact, measured)):
        tracker = Tracker(seq.model, seq.cameras, frontend, config)
        _, rep = tracker.step(tracker.init(seq.q[0]), [None] * len(seq.cameras), 0)
        runs.append(rep)
    plain, judged = runs
    assert plain.confidence >= 0.5 and not plain.lost
    assert (judged.confidence < 0.5) == low
    assert not judged.lost
    np.testing.assert_array_equal(judged.q_filtered, plain.q_filtered)


@pytest.mark.parametrize("weak_link, tip_links, whole, low", [
    (0, False, False, True), (0, True, False, False), ("tip", True, False, True), (0, True, True, True)])
def test_tip_links_leave_a_stray_proximal_phalanx_out(weak_link, tip_links, whole, low):
    """With ``support.tip_links`` a weak link that carries no tip does not lower the confidence;
    a weak fingertip link still does, and so does a weak whole finger with ``whole_lost``."""
    seq = make_preset("two_finger_occlusion", frames=3, size=(160, 120))
    m = seq.model
    link = m.tip_links[0] if weak_link == "tip" else weak_link
    assert (link in m.tip_links) == (weak_link == "tip")
    scores = np.full((1, m.n_links), 0.99)
    scores[0, link] = 0.3
    exact = ExactFrontEnd(m, seq.cameras, seq.q, noise_px=0.0)
    whole_levels = {"whole_lost": 0.8, "whole_good": 0.95} if whole else {}
    config = TrackConfig(support=SupportConfig(enabled=True, tip_links=tip_links, **whole_levels))
    tracker = Tracker(m, seq.cameras, _Supported(exact, ImageSupport(link_score=scores)), config)
    _, rep = tracker.step(tracker.init(seq.q[0]), [None] * len(seq.cameras), 0)
    assert (rep.confidence < 0.5) == low


def test_judge_weights_are_the_weakest_finger_to_a_power():
    finger = np.array([0, 0, 1, 1])
    scores = [np.array([[0.9, 0.7, 0.8, 0.8]]), np.array([[np.nan, np.nan, np.nan, np.nan]])]
    np.testing.assert_allclose(judge_weights(scores, finger, 4.0), [0.8**4, 1.0])
    with pytest.raises(InputError, match="support.judge_power: expected a finite number >= 0, got -1"):
        SupportConfig(judge_power=-1)


class _Unseen(AbstractFrontEnd):
    """Exact features with the index's distal link and tip hidden (its joint is unobservable), and
    a link support that backs only a distal joint bent past ``backed_rad``."""

    reextracts = False

    def __init__(self, exact, backed_rad):
        self.exact, self.backed_rad = exact, backed_rad

    def extract(self, images, q_start, state, frame):
        out = self.exact.extract(images, q_start, state, frame)
        hide = [eqx.tree_at(lambda f: (f.line_valid, f.tip_valid), f,
                            (f.line_valid.at[5].set(False), f.tip_valid.at[1].set(False))) for f in out.features]
        return dataclasses.replace(out, features=tuple(hide))

    def support(self, images, q, state, margin_px=1):
        return ImageSupport(link_score=np.full((1, 6), 0.99 if q[5] < self.backed_rad else 0.6))


@pytest.mark.parametrize("power", [0.0, 4.0])
def test_the_support_judges_starts_the_edges_cannot_tell_apart(power):
    """The index's distal joint (limits -80..0 deg, 0 at frame 0) sees nothing, so the prediction
    (0) and its flip (-40; +40 is clipped to 0) fit the edges alike and the prediction wins the
    tie; judged by the finger support (power > 0), a flip the image backs (< -20 deg) wins."""
    seq = make_preset("two_finger_occlusion", frames=3, size=(160, 120))
    exact = ExactFrontEnd(seq.model, seq.cameras, seq.q, noise_px=0.0)
    config = TrackConfig(support=SupportConfig(judge_power=power)).merged(
        {"hypotheses": {"flips": 2, "flip_deg": 40.0}})
    tracker = Tracker(seq.model, seq.cameras, _Unseen(exact, np.radians(-20)), config)
    state, _ = tracker.step(tracker.init(seq.q[0]), [None] * len(seq.cameras), 0)
    _, rep = tracker.step(state, [None] * len(seq.cameras), 1)
    dip = np.degrees(rep.q_solved[5])
    if power:
        assert dip < -20.0   # a flip won at frame 0 already, and the flips of its prediction at frame 1
    else:
        assert dip == pytest.approx(0.0, abs=1e-6) and rep.hypothesis == "prediction"
