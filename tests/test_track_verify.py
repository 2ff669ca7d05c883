"""A doubtful finger searched again from starts with features of their own (``hypotheses.verify_below``).

- the starts: the bends, the fold reflections of the finger's own hinges, the last trusted pose;
- the judge: the weakest finger must gain the margin, no other finger may lose more;
- config errors;
- the tracker: a front end whose features follow the search start (a wrong fold keeps the
  features of the wrong fold) is left at the wrong pose without it and brought to the truth with it.
"""

import numpy as np
import pytest
from helpers import FunctionFrontEnd, fit_camera

import jaxhand as jh
from jaxhand.features import features_from_pose
from jaxhand.track import (
    FilterConfig,
    HypothesisConfig,
    ImageSupport,
    SupportConfig,
    TrackConfig,
    Tracker,
    config_from_dict,
    config_to_dict,
    config_to_toml,
)
from jaxhand.track._flexion import flexion_hinges
from jaxhand.track._hypotheses import finger_starts, fold_starts
from jaxhand.track._support import finger_of_frame, finger_of_link
from jaxhand.track._verify import beats, fold_rows, verify_starts

INDEX, THUMB = 14, 19   # hand21's index finger and thumb (their first frames)


def _hand():
    m = jh.builtin_model("hand21")
    return m, flexion_hinges(m, finger_of_frame(m))[INDEX]


def test_fold_rows_keep_the_reflections_of_the_fingers_own_hinges():
    q = np.zeros(4)
    folds = np.array([[0.3, 0, 0, 0], [0, 0, -0.2, 0], [0, 0, 0, 0], [0, 0, 0, 0.5]])
    np.testing.assert_array_equal(fold_rows(folds, q, np.array([2, 3])), folds[[1, 3]])
    assert fold_rows(folds, q, np.array([1])).shape == (0, 4)


def test_verify_starts_are_the_bends_the_folds_and_the_trusted_finger():
    m, joints = _hand()
    lower, upper = np.asarray(m.q_lower), np.asarray(m.q_upper)
    q = np.clip(np.asarray(m.q_default, float) + 0.2, lower, upper)
    folds = np.asarray(fold_starts(m, fit_camera(m, q), q, m.n_q))
    trusted = np.clip(q - 0.3, lower, upper)
    starts = verify_starts(q, joints, (20.0, -20.0), lower, upper, folds, trusted)
    own = fold_rows(folds, q, joints)
    assert len(own) >= 1 and starts.shape == (2 + len(own) + 1, m.n_q)
    np.testing.assert_allclose(starts[:2], finger_starts(q, joints, (20.0, -20.0), lower, upper))
    np.testing.assert_allclose(starts[2:-1], np.clip(own, lower, upper))
    others = np.setdiff1d(np.arange(m.n_q), joints)
    np.testing.assert_allclose(starts[-1, joints], trusted[joints])
    np.testing.assert_allclose(starts[-1, others], q[others])
    assert verify_starts(q, joints, (20.0,), lower, upper, folds, None).shape == (1 + len(own), m.n_q)


@pytest.mark.parametrize("candidate, expected", [
    ({0: 0.9, 1: 0.80}, True),     # the weakest (0.5 -> 0.8) gains more than 0.05
    ({0: 0.9, 1: 0.52}, False),    # ... not enough
    ({0: 0.8, 1: 0.90}, False),    # finger 0 loses 0.1
    ({0: 0.9, 1: 0.9, 2: 0.5}, False),   # a finger the estimate did not judge is now the weakest
    ({}, False),
])
def test_a_candidate_beats_the_estimate_by_the_margin_without_taking_from_another_finger(candidate, expected):
    assert beats(candidate, {0: 0.9, 1: 0.5}, 0.05) is expected


def test_verify_config_round_trip_and_errors():
    assert HypothesisConfig(verify_below=0.5).verify_margin == 0.05
    config = TrackConfig(hypotheses=HypothesisConfig(verify_below=0.4, verify_margin=0.1),
                         support=SupportConfig(enabled=True))
    assert config_from_dict(config_to_dict(config)).hypotheses == config.hypotheses
    assert "verify_below = 0.4" in config_to_toml(config)
    with pytest.raises(jh.InputError, match=r"hypotheses\.verify_below: must lie in \[0, 1\]"):
        HypothesisConfig(verify_below=2.0)
    with pytest.raises(jh.InputError, match=r"hypotheses\.verify_margin: must lie in \[0, 1\]"):
        HypothesisConfig(verify_margin=-0.1)
    with pytest.raises(jh.InputError, match="hypotheses.verify_below: needs the image support"):
        TrackConfig(hypotheses=HypothesisConfig(verify_below=0.5))


class _FoldFrontEnd(FunctionFrontEnd):
    """Features of the truth where the search starts with the index finger within 25 deg of it,
    else of ``wrong`` (the features back the fold the search starts in); the index's links score
    0.95 within 5 deg of the truth, else 0.4 (the image does not support the wrong fold); the
    thumb's links ``thumb`` throughout (where it is the weakest, no finger is searched: a thumb
    has no flexion chain to bend, and bending a finger the image supports better only moves it)."""

    def __init__(self, m, rig, truth, wrong, joints, thumb=0.95):
        near = features_from_pose(m, rig, truth)
        far = features_from_pose(m, rig, wrong)
        self.starts = []

        def extract(images, q, state, frame):
            self.starts.append(np.asarray(q))
            return near if self._off(q) < 25.0 else far

        super().__init__(extract, reextracts=False)
        self.m, self.truth, self.joints, self.thumb = m, truth, joints, thumb

    def _off(self, q):
        return float(np.degrees(np.max(np.abs(np.asarray(q)[self.joints] - self.truth[self.joints]))))

    def support(self, images, q, state, margin_px=1):
        finger = finger_of_link(self.m)
        score = np.where(finger == INDEX, 0.95 if self._off(q) < 5.0 else 0.4, 0.95)
        score = np.where(finger == THUMB, self.thumb, score)
        return ImageSupport(link_score=score[None])


@pytest.mark.parametrize("verify_below, thumb", [(0.0, 0.95), (0.5, 0.95), (0.5, 0.3)])
def test_a_wrong_fold_is_searched_again_from_its_own_starts(verify_below, thumb):
    m, joints = _hand()
    truth = np.clip(np.asarray(m.q_default, float), m.q_lower, m.q_upper)
    truth[joints] = np.radians([-50.0, -60.0, -50.0])        # hand21 flexes to negative angles
    wrong = truth.copy()
    wrong[joints] += np.radians(40.0)                        # 40 deg less flexed in every hinge
    rig = (fit_camera(m, truth),)
    config = TrackConfig(hypotheses=HypothesisConfig(verify_below=verify_below, finger_deg=(20.0, 40.0, -20.0)),
                         support=SupportConfig(enabled=True), filter=FilterConfig(report_solve=True))
    frontend = _FoldFrontEnd(m, rig, truth, wrong, joints, thumb)
    tracker = Tracker(m, rig, frontend, config)
    state, report = tracker.step(tracker.init(wrong), [None], 0)
    if not verify_below or thumb < 0.4:   # one search, around the wrong fold: the solve stays there
        np.testing.assert_allclose(report.q_solved, wrong, atol=1e-6)
        assert report.hypothesis == "prediction" and report.confidence == 0.0 and len(frontend.starts) == 1
        assert ("verify" in report.timings_s) == bool(verify_below)
        return
    np.testing.assert_allclose(report.q_solved, truth, atol=1e-6)
    assert report.hypothesis == "verify" and report.confidence == pytest.approx((0.95 - 0.80) / (0.96 - 0.80))
    assert len(frontend.starts) > 3                           # the prediction's search, then one per start
    assert report.timings_s["verify"] > 0.0
    np.testing.assert_allclose(np.asarray(state.ghk.v)[joints], 0.0)   # the jump is not motion


class _SpeckFrontEnd(_FoldFrontEnd):
    """Every finger well supported, but a blob of unexplained foreground (a speck of the
    background model, or a shadow) beside the hand."""

    def support(self, images, q, state, margin_px=1):
        return ImageSupport(link_score=np.full((1, self.m.n_links), 0.95), unexplained_px=100.0)


def test_unexplained_foreground_alone_searches_no_finger_again():
    """The blob takes the frame's confidence to 0, but names no finger: no finger is searched again."""
    m, joints = _hand()
    truth = np.clip(np.asarray(m.q_default, float), m.q_lower, m.q_upper)
    truth[joints] = np.radians([-50.0, -60.0, -50.0])
    rig = (fit_camera(m, truth),)
    config = TrackConfig(hypotheses=HypothesisConfig(verify_below=0.5), support=SupportConfig(enabled=True),
                         filter=FilterConfig(report_solve=True))
    frontend = _SpeckFrontEnd(m, rig, truth, truth, joints)
    tracker = Tracker(m, rig, frontend, config)
    _, report = tracker.step(tracker.init(truth), [None], 0)
    assert report.confidence == 0.0 and report.hypothesis == "prediction"
    assert len(frontend.starts) == 1   # the prediction's search only
    np.testing.assert_allclose(report.q_solved, truth, atol=1e-6)
