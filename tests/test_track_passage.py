"""A hinge that turns back at its fold is tried through it (``hypotheses.fold_passage_deg``).

- the window rule: a fast approach to within the distance, then two frames away, on one side;
- the crossing test;
- config errors;
- the tracker: a front end whose features are the truth's where the search starts on the truth's
  side of the fold, else its mirror image's (one view cannot tell them apart), follows the mirror
  back out without the rule and the truth through the fold with it.
"""

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import FunctionFrontEnd, fit_camera

import jaxhand as jh
from jaxhand.features import features_from_pose
from jaxhand.track import FilterConfig, HypothesisConfig, ImageSupport, SupportConfig, TrackConfig, Tracker
from jaxhand.track._hypotheses import fold_turns
from jaxhand.track._passage import WINDOW, crossed, push, turned_back

MCP = 13   # hand21's index MCP flexion (q entry)
BOUNCE = [22.0, 17.0, 12.0, 7.0, 2.0, 3.0, 8.0]   # deg from the fold: in fast, turned back at 2


@pytest.mark.parametrize("offsets, expected", [
    (BOUNCE[-WINDOW:], True),
    ([-d for d in BOUNCE[-WINDOW:]], True),              # the other side alike
    ([17.0, 12.0, 7.0, 2.0, -3.0, -8.0], False),         # passed through
    ([17.0, 16.0, 15.0, 14.0, 15.0, 16.0], False),       # too slow (1 deg/frame)
    ([40.0, 32.0, 24.0, 16.0, 17.0, 22.0], False),       # never within 12 deg
    ([17.0, 12.0, 7.0, 2.0, 3.0, 2.5], False),           # not away on both frames after
    ([17.0, 12.0, np.nan, 2.0, 3.0, 8.0], False),        # the link was not across the ray
])
def test_a_hinge_turned_back_at_its_fold_is_found(offsets, expected):
    history = None
    for d in offsets:
        history = push(history, np.array([d, 30.0]))
    assert history.shape == (WINDOW, 2)
    assert turned_back(history, 12.0, 1.5).tolist() == [expected, False]
    assert turned_back(history[1:], 12.0, 1.5).tolist() == [False, False]   # too few frames yet


def test_crossed_is_the_other_side_of_the_fold():
    assert crossed(0.3, -0.1, 0.1) and crossed(-0.3, 0.1, -0.1)
    assert not crossed(0.3, -0.1, 0.25) and not crossed(0.3, 0.0, -1.0)


def test_fold_passage_config_errors():
    assert HypothesisConfig().fold_passage_deg == 0.0
    with pytest.raises(jh.InputError, match=r"hypotheses\.fold_passage_deg: expected a finite number >= 0"):
        HypothesisConfig(fold_passage_deg=-1.0)
    with pytest.raises(jh.InputError, match="hypotheses.fold_passage_deg: needs the image support"):
        TrackConfig(hypotheses=HypothesisConfig(fold_passage_deg=12.0))


class _MirrorFrontEnd(FunctionFrontEnd):
    """The truth's features where the search starts on the truth's side of the hinge's fold, else
    those of its mirror image; every link supported alike (the image cannot tell the two)."""

    def __init__(self, m, rig, truth, mirror, joint, fold):
        self.sides = []

        def extract(images, q, state, frame):
            side = np.sign(np.asarray(q)[joint] - fold) == np.sign(truth[frame][joint] - fold)
            self.sides.append(bool(side))
            return features_from_pose(m, rig, (truth if side else mirror)[frame])

        super().__init__(extract, reextracts=False)
        self.m = m

    def support(self, images, q, state, margin_px=1):
        return ImageSupport(link_score=np.full((1, self.m.n_links), 0.95))


def _index_mcp_alone():
    """hand21 with every q entry but the index's MCP flexion pinned by its limits (so the solve
    cannot trade the MCP against the PIP), and an orthographic camera turned 45 deg about x, where
    that hinge folds at -45 deg: (model, pose, rig, fold in rad)."""
    m = jh.builtin_model("hand21")
    base = np.clip(np.asarray(m.q_default, float), m.q_lower, m.q_upper)
    pinned = np.arange(m.n_q) != MCP
    lower, upper = np.where(pinned, base - 1e-4, m.q_lower), np.where(pinned, base + 1e-4, m.q_upper)
    m = eqx.tree_at(lambda mm: (mm.q_lower, mm.q_upper), m, (jnp.asarray(lower), jnp.asarray(upper)))
    tilt = np.radians(-45.0)
    rig = (fit_camera(m, base, R=np.array([[1, 0, 0], [0, np.cos(tilt), -np.sin(tilt)],
                                            [0, np.sin(tilt), np.cos(tilt)]])),)
    joints, turn, ok = fold_turns(m, rig[0], base)
    i = list(joints).index(MCP)
    assert bool(ok[i])
    return m, base, rig, base[MCP] + float(turn[i])   # the hinge alone moves, so its fold stays put


@pytest.mark.parametrize("passage", [0.0, 12.0])
def test_a_finger_that_turned_back_at_its_fold_is_passed_through(passage):
    m, base, rig, fold = _index_mcp_alone()
    assert np.degrees(fold) == pytest.approx(-45.0)
    d = np.radians(24.0 - 7.0 * np.arange(10))   # in through the fold at 7 deg per frame
    truth, mirror = np.tile(base, (10, 1)), np.tile(base, (10, 1))
    truth[:, MCP], mirror[:, MCP] = fold + d, fold + np.abs(d)
    config = TrackConfig(hypotheses=HypothesisConfig(fold_passage_deg=passage), support=SupportConfig(enabled=True),
                         filter=FilterConfig(report_solve=True))
    frontend = _MirrorFrontEnd(m, rig, truth, mirror, MCP, fold)
    tracker = Tracker(m, rig, frontend, config)
    state, labels, estimate = tracker.init(truth[0]), [], []
    for k in range(10):
        state, report = tracker.step(state, [None], k)
        labels.append(report.hypothesis)
        estimate.append(report.q_filtered[MCP])
    offset = np.degrees(np.asarray(estimate) - fold)
    np.testing.assert_allclose(offset[:2], [24.0, 17.0], atol=0.01)   # on the truth, away from the fold
    if not passage:   # at frame 5 the estimate sits on the mirror's side, 11 deg beyond the fold, not 11 short
        assert "passage" not in labels and offset[5] > 5.0
        return
    # the nearest (3 deg) at frame 3, away on frames 4 and 5: tried through, and the truth from then on
    assert labels.index("passage") == 5 and labels.count("passage") == 1
    np.testing.assert_allclose(offset[5:], np.degrees(d[5:]), atol=0.01)
