"""Which joints a frame saw (StepReport.seen, summary.json's "seen"): a finger whose features are
all missing is reported unseen (share 0) and the others seen (share 1); the run's summary counts
the frames each joint was seen on and the error of the seen and unseen entries apart."""

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import FunctionFrontEnd

from jaxhand import InputError
from jaxhand.features import features_from_pose
from jaxhand.kinematics import View
from jaxhand.render import make_preset
from jaxhand.track import TrackConfig, Tracker, seen_summary
from jaxhand.track._seen import unseen_links
from jaxhand.track._support import moved_links
from jaxhand.viz import draw_view, plot_joint_angles
from jaxhand.viz._draw import DIM


@pytest.fixture(scope="module")
def fingers():
    return make_preset("two_finger_occlusion", frames=4, size=(160, 120))


def _hide_index(model, feats):
    """The features with every link the index MCP moves, and their tips, missing."""
    links = np.asarray(moved_links(model))[model.q_names.index("index_mcp")]
    tips = np.isin(np.asarray(model.tip_links), np.flatnonzero(links))
    return tuple(eqx.tree_at(lambda f: (f.line_valid, f.tip_valid), f,
                             (f.line_valid & ~links, f.tip_valid & ~tips)) for f in feats)


def test_a_finger_without_features_is_reported_unseen_and_the_other_seen(fingers):
    seq, m = fingers, fingers.model
    rng = np.random.default_rng(0)
    feats = [features_from_pose(m, seq.cameras, q, noise_px=0.2, rng=rng) for q in seq.q]

    def extract(images, q_start, state, frame):
        return feats[frame] if frame == 0 else _hide_index(m, feats[frame])

    tracker = Tracker(m, seq.cameras, FunctionFrontEnd(extract), TrackConfig(), dt_s=1 / 30)
    state = tracker.init(seq.q[0])
    state, first = tracker.step(state, [None], 0)
    np.testing.assert_allclose(first.seen, 1.0, atol=1e-9)
    index = [m.q_names.index(n) for n in ("index_mcp", "index_pip", "index_dip")]
    middle = [m.q_names.index(n) for n in ("middle_mcp", "middle_pip", "middle_dip")]
    for k in (1, 2):
        state, rep = tracker.step(state, [None], k)
        np.testing.assert_allclose(rep.seen[index], 0.0, atol=1e-6)
        np.testing.assert_allclose(rep.seen[middle], 1.0, atol=1e-6)
        assert rep.timings_s["seen"] > 0.0


def test_seen_summary_counts_frames_and_splits_the_error(fingers):
    m = fingers.model
    seen = np.ones((4, m.n_q))
    seen[1:, m.q_names.index("index_pip")] = 0.2    # unseen on 3 of 4 frames
    seen[3, m.q_names.index("middle_dip")] = 0.5     # at the level: seen
    truth = np.zeros((4, m.n_q))
    est = truth + np.radians(1.0)
    est[1:, m.q_names.index("index_pip")] = np.radians(10.0)
    out = seen_summary(m, seen, est, truth)
    assert out["share_of_frames"]["index_pip"] == 0.25 and out["share_of_frames"]["middle_dip"] == 1.0
    assert out["mostly_unseen"] == ["index_pip"]
    assert out["unseen_entries_share"] == pytest.approx(3 / 24)
    assert out["error_deg_seen"] == pytest.approx(1.0) and out["error_deg_unseen"] == pytest.approx(10.0)
    assert "error_deg_seen" not in seen_summary(m, seen)


def test_the_angle_plot_takes_the_shares_and_refuses_another_shape(fingers, tmp_path):
    m = fingers.model
    seen = np.ones((4, m.n_q))
    seen[1:3, 0] = 0.0
    t = np.arange(4) / 30
    path = plot_joint_angles(m, t, np.asarray(fingers.q), tmp_path / "a.png", seen=seen)
    assert path.stat().st_size > 0
    with pytest.raises(InputError, match=r"seen: expected \(4, 6\)"):
        plot_joint_angles(m, t, np.asarray(fingers.q), tmp_path / "b.png", seen=seen[:2])


def test_the_links_of_unseen_joints_are_found_and_drawn_grey(fingers):
    m = fingers.model
    seen = np.ones(m.n_q)
    seen[[m.q_names.index(n) for n in ("index_mcp", "index_pip", "index_dip")]] = 0.1
    dim = unseen_links(m, seen)
    assert [m.link_names[k] for k in np.flatnonzero(dim)] == ["index_mcp", "index_pip", "index_dip"]
    two = jnp.zeros(2)
    view = View(joints_px=jnp.zeros((2, 2)), joints_depth=two, link_start_px=jnp.array([[10.0, 10.0], [10.0, 30.0]]),
                link_end_px=jnp.array([[50.0, 10.0], [50.0, 30.0]]), link_depth=jnp.ones((2, 2)),
                tips_px=jnp.zeros((0, 2)), tips_depth=jnp.zeros(0), link_radius_px=jnp.array([3.0, 3.0]))
    image = draw_view(np.zeros((40, 60, 3), np.uint8), view, (0, 0, 255), thickness=3, joints=False,
                      dim=[False, True])
    assert tuple(image[10, 30]) == (0, 0, 255) and tuple(image[30, 30]) == DIM


def test_the_cli_summary_names_the_unseen_joints(tmp_path):
    import io

    from jaxhand.cli_track import print_summary

    summary = {"frames": 4, "model": "two_fingers", "lost_frames": 0,
               "seen": {"level": 0.5, "share_of_frames": {}, "mostly_unseen": ["index_pip"],
                        "unseen_entries_share": 0.125, "error_deg_seen": 1.0, "error_deg_unseen": 10.0}}
    text = io.StringIO()
    print_summary(summary, tmp_path, file=text)
    assert ("joints not seen: 12% of joint-frames, the priors alone placed them; unseen on most frames: index_pip; "
            "error seen 1.00 deg, unseen 10.00 deg") in text.getvalue()
    summary["seen"].update(mostly_unseen=[], error_deg_unseen=None)
    text = io.StringIO()
    print_summary(summary, tmp_path, file=text)
    assert "unseen on most frames: none\n" in text.getvalue()
