"""Multiple hypotheses per frame (:class:`~jaxhand.track.HypothesisConfig`) and recovery after a loss.

- the vmapped solve of k starts equals k single solves of the frame program;
- a start at the truth among bad ones wins, and its solve is the truth;
- the front end's score decides between candidates whose residuals are equal;
- after a forced loss (a gap without features), recovery starts and proposals bring the error
  back, and ``track_sequence`` counts the re-initialisation;
- with nothing to add, the hypotheses' path gives the default path's numbers;
- where the merit alone chooses, the one-call path gives the two-call path's numbers, and its
  coarse-to-fine variant (``coarse_steps``) equals the coarse solves plus the frame program
  started from the best of them, and still finds a start at the truth;
- the config section round-trips and rejects bad values; the host rules (choose, runners-up).
"""

import dataclasses
from pathlib import Path

import cv2
import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import FunctionFrontEnd, fit_camera

import jaxhand as jh
from jaxhand.camera import look_at_rotation
from jaxhand.features import empty_features, features_from_pose
from jaxhand.filter import ghk_init
from jaxhand.io import FrameSource, load_devset
from jaxhand.render import make_preset
from jaxhand.residuals import make_residual_args, residual_jacobian
from jaxhand.track import (
    AbstractFrontEnd,
    FrontEndResult,
    HypothesisConfig,
    TrackConfig,
    Tracker,
    config_from_dict,
    config_to_dict,
    load_track_config,
    save_track_config,
    track_sequence,
)
from jaxhand.track._compiled import FEATURE_FIELDS, SCALARS, FrameProgram
from jaxhand.track._hypotheses import HypothesisProgram, choose, flip_starts, runners_up

DEVSET = Path(__file__).resolve().parent.parent / "data" / "mujoco"

_flips = eqx.filter_jit(flip_starts)


@pytest.fixture(scope="module")
def hand():
    m = jh.builtin_model("hand21")
    rng = np.random.default_rng(7)
    truth = jh.random_q(m, rng, margin=0.25)
    cam = fit_camera(m, truth)
    return m, (cam,), truth


def _arrays(feats):
    return tuple(tuple(jnp.asarray(getattr(f, n)) for n in FEATURE_FIELDS) for f in feats)


def _rad(m, **deg):
    q = np.zeros(m.n_q)
    for name, d in deg.items():
        q[m.q_names.index(name)] = np.radians(d)
    return q


def _two_flip_problem(hand, **hyp):
    """Noisy features of the truth, a prediction 8 deg off, 3 random extra starts, a config with
    2 flips of 20 deg (and ``hyp``) and the filter state at the prediction."""
    m, rig, truth = hand
    rng = np.random.default_rng(1)
    feats = features_from_pose(m, rig, truth, noise_px=0.5, rng=rng)
    q_pred = np.clip(truth + np.radians(8.0) * rng.standard_normal(m.n_q), m.q_lower, m.q_upper)
    extras = jh.random_q(m, rng, 3, margin=0.1)
    config = TrackConfig(hypotheses=HypothesisConfig(flips=2, flip_deg=20.0, **hyp))
    ghk = ghk_init(jnp.asarray(q_pred))
    return m, rig, feats, q_pred, extras, config, (ghk.x, ghk.v, ghk.a)


def _flip_starts(m, rig, feats, q_pred, extras, config) -> tuple[np.ndarray, np.ndarray]:
    """The two flips of ``q_pred`` and every start in the program's order."""
    flips = np.asarray(_flips(m, rig, feats, jnp.asarray(q_pred), 2, np.radians(20.0), config.fit.link_fractions))
    return flips, np.concatenate([q_pred[None], flips, extras])


@pytest.mark.slow
def test_vmapped_starts_equal_single_solves(hand):
    m, rig, feats, q_pred, extras, config, ghk = _two_flip_problem(hand)
    multi = HypothesisProgram(m, rig, config, 0.85, 0.04)
    cands = multi.candidates(_arrays(feats), ghk, jnp.asarray(extras), jnp.ones(3, bool))
    flips, starts = _flip_starts(m, rig, feats, q_pred, extras, config)
    # the flips push the most poorly observed joint (smallest Jacobian column at q_pred) both ways
    J = np.asarray(residual_jacobian(jnp.asarray(q_pred), make_residual_args(m, rig, feats, config.fit.link_fractions)))
    j = int(np.argmin(np.linalg.norm(J, axis=0)))
    for flip, sign in zip(flips, (1.0, -1.0)):
        want = q_pred.copy()
        want[j] = np.clip(want[j] + sign * np.radians(20.0), m.q_lower[j], m.q_upper[j])
        np.testing.assert_allclose(flip, want, rtol=0, atol=1e-12)
    single = FrameProgram(m, rig, config, 0.85, 0.04)
    q_multi = np.asarray(cands.solved.q)
    assert q_multi.shape == (6, m.n_q)
    for k, q0 in enumerate(starts):
        (q_solved, _, _), _ = single(_arrays(feats), ghk, jnp.asarray(q_pred), jnp.asarray(q0))
        np.testing.assert_allclose(q_multi[k], np.asarray(q_solved), rtol=0, atol=1e-10, err_msg=f"start {k}")
    # the starts converge to different poses, so the comparison is not of one pose six times
    assert np.ptp(q_multi, axis=0).max() > 0.1


@pytest.mark.slow
def test_a_start_at_the_truth_wins(hand):
    m, (cam,), truth = hand
    # two views: one orthographic view leaves each finger's flexion towards or away from the
    # camera ambiguous (zero residual both ways), so the residual could not pick the truth
    rig = (cam, fit_camera(m, truth, R=look_at_rotation([1.0, -0.3, -0.4], [0, 0, 0])))
    feats = features_from_pose(m, rig, truth)
    lo, hi = np.asarray(m.q_lower), np.asarray(m.q_upper)
    bad = lo + 0.02 * (hi - lo), hi - 0.02 * (hi - lo)   # starts whose solves stick at 0.5-0.8 px
    frontend = FunctionFrontEnd(lambda images, q, state, frame: feats, reextracts=False)
    tracker = Tracker(m, rig, frontend, TrackConfig(reextract=0))
    alone = tracker.step(tracker.init(bad[0]), [None, None], 0)[1]
    # from the bad start alone the solve ends far from the truth (so this test can fail)
    assert np.degrees(np.abs(alone.q_solved - truth)).max() > 10.0 and alone.rms_px > 0.3
    state, rep = tracker.step(tracker.init(bad[0]), [None, None], 0, proposals=np.stack([bad[1], truth]))
    assert rep.hypothesis == "proposal" and rep.starts == 3
    np.testing.assert_allclose(rep.q_solved, truth, atol=1e-6)
    assert rep.rms_px < 1e-4 and not rep.lost


class _ScoredFrontEnd(AbstractFrontEnd):
    """Fixed features; the image score prefers poses whose ``joint`` is near ``target`` (rad)."""

    reextracts = False

    def __init__(self, feats, joint: int, target: float):
        self.feats, self.joint, self.target = feats, joint, target
        self.calls = []

    def extract(self, images, q_start, state, frame):
        return FrontEndResult(self.feats, state)

    def score(self, images, qs, state):
        self.calls.append(len(qs))
        return np.clip(1.0 - np.abs(qs[:, self.joint] - self.target), 0.0, 1.0)


@pytest.mark.parametrize("target_deg", [20.0, -40.0])
@pytest.mark.slow
def test_the_image_score_decides_between_equal_residuals(hand, target_deg):
    m, rig, truth = hand
    # the index finger carries no features: its joints do not change the residuals at all
    f = features_from_pose(m, rig, truth)[0]
    unseen = np.array(["index" in name for name in m.link_names])
    f = eqx.tree_at(lambda g: (g.line_valid, g.tip_valid), f,
                    (jnp.asarray(~unseen), jnp.asarray(~unseen[np.asarray(m.tip_links)])))
    j = m.q_names.index("index_mcp")
    a, b, c = truth.copy(), truth.copy(), truth.copy()
    a[j], b[j], c[j] = np.radians(20.0), np.radians(-40.0), np.radians(-70.0)
    frontend = _ScoredFrontEnd((f,), j, np.radians(target_deg))
    tracker = Tracker(m, rig, frontend, TrackConfig(reextract=0))
    _, rep = tracker.step(tracker.init(c), [None], 0, proposals=np.stack([a, b]))
    # the three candidates, then the reported pose for the frame's confidence
    assert frontend.calls == [3, 1] and rep.hypothesis == "proposal"
    assert np.degrees(rep.q_solved[j]) == pytest.approx(target_deg, abs=1e-6)
    np.testing.assert_allclose(np.delete(rep.q_solved, j), np.delete(truth, j), atol=1e-6)


@pytest.mark.slow
def test_nothing_to_add_gives_the_default_numbers(hand):
    m, rig, truth = hand
    rng = np.random.default_rng(3)
    feats = features_from_pose(m, rig, truth, noise_px=0.5, rng=rng)
    frontend = FunctionFrontEnd(lambda images, q, state, frame: feats, reextracts=True)
    q0 = np.clip(truth + np.radians(5.0), m.q_lower, m.q_upper)
    plain = Tracker(m, rig, frontend)
    assert plain.config == TrackConfig(hypotheses=HypothesisConfig())
    s1, s2 = plain.init(q0), plain.init(q0)
    for k in range(3):
        s1, r1 = plain.step(s1, [None], k)
        # the prediction proposed again: a second start equal to the first, which the tie gives away
        s2, r2 = plain.step(s2, [None], k, proposals=np.asarray(s2.ghk.x)[None])
        assert r1.starts == 1 and r2.starts == 2 and r2.hypothesis == "prediction"
        for name in ("q_solved", "q_filtered"):
            np.testing.assert_allclose(getattr(r2, name), getattr(r1, name), rtol=0, atol=1e-10)
        assert r2.rms_px == pytest.approx(r1.rms_px, abs=1e-10) and r2.lost == r1.lost
        assert set(r2.timings_s) == set(r1.timings_s) | {"score"}


def _gap_run(seq, gap, config, proposals=None, frames=None):
    """The tracked seq with no features in ``gap`` (the frames are lost): per frame the report."""
    m, cams = seq.model, seq.cameras
    rng = np.random.default_rng(4)
    good = [features_from_pose(m, cams, q, noise_px=0.3, rng=rng) for q in seq.q]
    frontend = FunctionFrontEnd(lambda images, q, state, frame:
                                (empty_features(m),) if frame in gap else good[frame], reextracts=False)
    tracker = Tracker(m, cams, frontend, config, dt_s=1 / 25)
    state, reports = tracker.init(seq.q[0]), []
    for k in range(len(seq.q) if frames is None else frames):
        state, rep = tracker.step(state, [None], k, proposals=None if proposals is None else proposals(k))
        reports.append(rep)
    return reports


@pytest.mark.slow
def test_recovery_after_a_forced_loss():
    seq = make_preset("full_hand_spread_flex", frames=32, size=(240, 180))
    gap = range(10, 24)
    config = TrackConfig(hypotheses=HypothesisConfig(recover=6, recover_deg=10.0))
    reports = _gap_run(seq, gap, config)
    lost = [r.lost for r in reports]
    assert lost == [k in gap for k in range(32)]
    assert [r.starts for r in reports[23:26]] == [7, 7, 1]   # recovery starts until a frame is not lost
    assert [k for k, r in enumerate(reports) if r.reinitialised] == [24] and reports[24].hypothesis == "recover"
    held = [np.degrees(np.abs(r.q_filtered - q)).mean() for r, q in zip(reports, seq.q)]
    solved = [np.degrees(np.abs(r.q_solved - q)).mean() for r, q in zip(reports, seq.q)]
    # the truth moves away during the gap (19 deg mean from the held pose at its end); from the
    # first frame after it the solve is back within 5 deg (one camera leaves some joints
    # ambiguous: 2.4-7.8 deg in the frames before the gap), the filtered estimate 3 frames later
    assert held[23] > 15.0 and max(solved[24:]) < 5.0 and max(held[27:]) < 5.0
    # a proposal at the truth on the first frame after the gap joins the recovery starts and wins
    # (its solve is not the truth: 0.3 px noise moves the joints one camera sees poorly)
    at_truth = _gap_run(seq, gap, config, proposals=lambda k: seq.q[k][None] if k == 24 else None, frames=25)
    assert at_truth[24].hypothesis == "proposal" and at_truth[24].starts == 8 and at_truth[24].reinitialised


@pytest.mark.slow
def test_track_sequence_passes_proposals_and_counts_reinitialisations(tmp_path):
    seq = make_preset("two_finger_occlusion", frames=8, size=(160, 120))
    d = tmp_path / "frames"
    d.mkdir()
    for k in range(8):
        cv2.imwrite(str(d / f"f{k:03d}.png"), np.zeros((120, 160), np.uint8))
    m = seq.model
    good = [features_from_pose(m, seq.cameras, q) for q in seq.q]
    frontend = FunctionFrontEnd(lambda images, q, state, frame: (empty_features(m),) if frame in (3, 4)
                                else good[frame], reextracts=False)
    asked = []

    def proposals(frame):
        asked.append(frame)
        return seq.q[frame][None] if frame == 5 else None

    summary = track_sequence(m, seq.cameras, [FrameSource(d, fps=25)], seq.q[0], tmp_path / "out", frontend,
                             truth=seq.q, video=False, proposals=proposals)
    assert asked == list(range(8))
    assert summary["lost_frames"] == 2 and summary["reinitialisations"] == 1
    # frame 5's proposal (the truth) ties with the prediction's solve (exact features: both fit
    # them exactly), and a tie goes to the prediction
    assert summary["hypothesis_wins"] == {"prediction": 8}


def test_config_round_trip_and_errors(tmp_path):
    hyp = HypothesisConfig(flips=4, flip_deg=30.0, last_solve=True, carry=2, carry_margin=0.8, carry_min_deg=3.0,
                           recover=8, recover_deg=12.5, recover_mm=5.0, seed=3, coarse_steps=3)
    config = TrackConfig(hypotheses=hyp)
    save_track_config(config, tmp_path / "c.toml")
    back = load_track_config(tmp_path / "c.toml")
    assert back == config and back.hypotheses == hyp and back.hypotheses.enabled
    assert "[hypotheses]" in (tmp_path / "c.toml").read_text()
    assert config_from_dict(config_to_dict(TrackConfig())).hypotheses == HypothesisConfig()
    assert not HypothesisConfig().enabled
    with pytest.raises(jh.InputError, match="hypotheses.flips: expected an integer >= 0"):
        HypothesisConfig(flips=-1)
    with pytest.raises(jh.InputError, match="hypotheses.coarse_steps: expected an integer >= 0"):
        HypothesisConfig(coarse_steps=-2)
    with pytest.raises(jh.InputError, match="hypotheses.carry_margin: must lie in"):
        HypothesisConfig(carry_margin=1.5)
    with pytest.raises(jh.InputError, match="hypotheses.flip_deg: expected a finite number"):
        HypothesisConfig(flip_deg=float("nan"))
    with pytest.raises(jh.InputError, match="did you mean 'recover'"):
        TrackConfig().merged({"hypotheses": {"recovr": 2}})


@pytest.mark.slow
def test_bad_proposals_and_scores_raise(hand):
    m, rig, truth = hand
    feats = features_from_pose(m, rig, truth)
    tracker = Tracker(m, rig, FunctionFrontEnd(lambda images, q, state, frame: feats, reextracts=False))
    state = tracker.init(truth)
    with pytest.raises(jh.InputError, match=r"proposals: frame 4: expected \(k, 21\) starting poses"):
        tracker.step(state, [None], 4, proposals=np.zeros((2, 3)))
    with pytest.raises(jh.InputError, match="proposals: frame 0: a starting pose is not finite"):
        tracker.step(state, [None], 0, proposals=np.full(m.n_q, np.nan))

    class Wrong(_ScoredFrontEnd):
        def score(self, images, qs, state):
            return np.full(len(qs), 1.5)

    bad = Tracker(m, rig, Wrong(feats, 0, 0.0))
    with pytest.raises(jh.InputError, match=r"Wrong.score: expected 2 scores in \[0, 1\]"):
        bad.step(bad.init(truth), [None], 0, proposals=truth[None])


def test_choose_and_runners_up():
    merit = np.array([0.5, 0.9, -1.0, 0.88, 0.2])
    assert choose(merit)[0] == 1
    winner, total = choose(merit, np.array([1.0, 0.5, 1.0, 1.0, 1.0]))   # the score turns it round
    assert winner == 3 and total[2] == -1.0 and total[1] == pytest.approx(0.45)
    assert choose(np.array([0.7, 0.7]))[0] == 0   # a tie goes to the earlier start
    qs = np.array([[0.0, 0.0], [0.5, 0.0], [0.0, 0.0], [0.51, 0.0], [1.0, 1.0]])
    angle = np.array([True, True])
    # within 0.9 of the winner's merit and more than 0.1 rad from it (and from each other)
    total = np.array([0.5, 1.0, -1.0, 0.95, 0.91])
    np.testing.assert_array_equal(runners_up(qs, total, 1, 2, 0.9, 0.1, angle), [[1.0, 1.0]])
    np.testing.assert_array_equal(runners_up(qs, total, 1, 2, 0.4, 0.1, angle), [[1.0, 1.0], [0.0, 0.0]])
    assert runners_up(qs, total, 1, 0, 0.4, 0.1, angle).shape == (0, 2)


@pytest.mark.slow
def test_fold_starts_reflect_a_finger_hinge_across_the_image_plane():
    """An orthographic camera looking at the palm, fingers unabducted: every finger hinge turns
    about an axis across the view, so reflecting it across its fold leaves the image of the link
    it moves where it was and reverses the link's depth."""
    from jaxhand.kinematics import pose
    from jaxhand.track._hypotheses import _fold_joints, fold_starts

    model = load_devset(DEVSET / "open_close").model
    q = np.zeros(model.n_q)
    for i, name in enumerate(model.q_names):
        if not name.startswith("thumb") and name.endswith(("_flex", "_pip", "_dip")):
            q[i] = np.radians(25.0)
    cam = jh.Orthographic.fit(np.asarray(pose(model, jnp.asarray(q)).link_end), R=np.diag([1.0, -1.0, -1.0]))
    joints, _, links = _fold_joints(model)
    starts = np.asarray(fold_starts(model, cam, jnp.asarray(q), len(joints)))
    before = pose(model, jnp.asarray(q))
    checked = 0
    for s in starts:
        moved = np.flatnonzero(np.abs(s - q) > 1e-12)
        if len(moved) == 0:
            continue   # a hinge whose link never lies across the view (abduction, seen along its axis)
        (changed,) = moved
        name = model.q_names[changed]
        at_limit = min(abs(s[changed] - float(model.q_lower[changed])), abs(s[changed] - float(model.q_upper[changed])))
        if name.startswith("thumb") or name.endswith("_abd") or at_limit < 1e-9:
            continue   # the thumb's axes are not across the view; a clipped reflection is not exact
        link = links[list(joints).index(changed)]
        after = pose(model, jnp.asarray(s))
        px_before, depth_before = cam.project(before.link_end[link] - before.link_start[link])
        px_after, depth_after = cam.project(after.link_end[link] - after.link_start[link])
        np.testing.assert_allclose(np.asarray(px_after), np.asarray(px_before), atol=1e-6)
        assert float(depth_after - cam.t[2]) == pytest.approx(-float(depth_before - cam.t[2]), abs=1e-6)
        checked += 1
    assert checked == 4   # the four MCPs (25 deg -> -25 deg); the PIP/DIP reflections leave their limits


def _hand_run(tracker, q0, frames):
    state, reports = tracker.init(q0), []
    for k in range(frames):
        state, rep = tracker.step(state, [None], k)
        reports.append(rep)
    return reports


@pytest.mark.slow
def test_one_call_gives_the_two_call_numbers():
    seq = make_preset("full_hand_spread_flex", frames=12, size=(240, 180))
    m, cams = seq.model, seq.cameras
    rng = np.random.default_rng(5)
    good = [features_from_pose(m, cams, q, noise_px=0.5, rng=rng) for q in seq.q]
    frontend = FunctionFrontEnd(lambda images, q, state, frame: good[frame], reextracts=True)
    config = TrackConfig(hypotheses=HypothesisConfig(flips=2, last_solve=True, carry=1))
    runs = []
    for on_device in (True, False):
        tracker = Tracker(m, cams, frontend, config, dt_s=1 / 25)
        assert tracker._choose_on_device   # no score, no support judge
        tracker._choose_on_device = on_device
        runs.append(_hand_run(tracker, seq.q[0], 12))
    one, two = runs
    for a, b in zip(one, two):
        for name in ("q_solved", "q_filtered"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
        assert (a.hypothesis, a.starts, a.rms_px, a.confidence, a.lost) == (b.hypothesis, b.starts, b.rms_px,
                                                                             b.confidence, b.lost)
    # the choice is not the prediction every time (so the winner's index matters)
    assert {r.hypothesis for r in one} - {"prediction"}
    # a front end with an image score, or the support judge, keeps the host's choice
    assert not Tracker(m, cams, _ScoredFrontEnd(good[0], 0, 0.0), config)._choose_on_device
    judged = config.merged({"support": {"judge_power": 1.0}})
    assert not Tracker(m, cams, frontend, judged)._choose_on_device
    assert not jh.ImageFrontEnd(m, cams).scores and _ScoredFrontEnd(good[0], 0, 0.0).scores
    assert jh.ImageFrontEnd(m, cams, TrackConfig().merged({"image": {"score": {"foreground": "auto"}}}).image).scores


@pytest.mark.slow
def test_coarse_to_fine_is_the_coarse_solves_then_the_frame_program(hand):
    m, rig, feats, q_pred, extras, config, ghk = _two_flip_problem(hand, coarse_steps=3)
    valid = np.array([True, True, False])
    packed, (qs, merit, winner) = HypothesisProgram(m, rig, config, 0.85, 0.04).chosen(
        _arrays(feats), ghk, jnp.asarray(extras), jnp.asarray(valid), jnp.asarray(q_pred))
    (q_solved, q_filtered, scalars), ghk_next = packed
    flips, starts = _flip_starts(m, rig, feats, q_pred, extras, config)
    # every start: 3 iterations of the gated pass alone, as the frame program runs them
    coarse = FrameProgram(m, rig, config.merged({"fit": {"max_steps": 3}, "robust": {"passes": 0}}), 0.85, 0.04)
    for k, q0 in enumerate(starts):
        (q_k, _, _), _ = coarse(_arrays(feats), ghk, jnp.asarray(q_pred), jnp.asarray(q0))
        np.testing.assert_allclose(np.asarray(qs[k]), np.asarray(q_k), rtol=0, atol=1e-10, err_msg=f"start {k}")
    merit = np.asarray(merit)
    assert merit[5] == -1.0 and merit[:5].min() > 0 and int(winner) == int(np.argmax(merit))
    # ...then the best one's start solved in full by the frame program, filter and score included
    (q_want, filtered_want, scalars_want), ghk_want = FrameProgram(m, rig, config, 0.85, 0.04)(
        _arrays(feats), ghk, jnp.asarray(q_pred), jnp.asarray(starts[int(winner)]))
    np.testing.assert_allclose(np.asarray(q_solved), np.asarray(q_want), rtol=0, atol=1e-10)
    np.testing.assert_allclose(np.asarray(q_filtered), np.asarray(filtered_want), rtol=0, atol=1e-10)
    np.testing.assert_allclose(np.asarray(scalars), np.asarray(scalars_want), rtol=0, atol=1e-10)
    for a, b in zip(ghk_next, ghk_want):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=0, atol=1e-10)
    # the coarse solves have not converged: the full solve fits the features better
    assert float(np.asarray(scalars)[list(SCALARS).index("rms_px")]) < 1.0
    assert np.abs(np.asarray(q_solved) - np.asarray(qs[int(winner)])).max() > 1e-3


@pytest.mark.slow
def test_coarse_to_fine_finds_a_start_at_the_truth(hand):
    m, (cam,), truth = hand
    rig = (cam, fit_camera(m, truth, R=look_at_rotation([1.0, -0.3, -0.4], [0, 0, 0])))
    feats = features_from_pose(m, rig, truth)
    lo, hi = np.asarray(m.q_lower), np.asarray(m.q_upper)
    bad = lo + 0.02 * (hi - lo), hi - 0.02 * (hi - lo)
    frontend = FunctionFrontEnd(lambda images, q, state, frame: feats, reextracts=False)
    tracker = Tracker(m, rig, frontend, TrackConfig(reextract=0, hypotheses=HypothesisConfig(coarse_steps=2)))
    state, rep = tracker.step(tracker.init(bad[0]), [None, None], 0, proposals=np.stack([bad[1], truth]))
    assert rep.hypothesis == "proposal" and rep.starts == 3
    np.testing.assert_allclose(rep.q_solved, truth, atol=1e-6)
    assert rep.rms_px < 1e-4 and not rep.lost


def test_too_far_never_rules_out_the_prediction():
    from jaxhand.track._hypotheses import too_far

    qs = np.array([[9.0, 0.0, 0.0], [0.0, 0.2, 0.0], [0.0, 0.6, 0.0], [0.0, 0.0, 5.0]])
    joints = np.array([False, True, False])   # the third entry is not a joint angle (a base entry)
    np.testing.assert_array_equal(too_far(qs, np.zeros(3), joints, 0.5), [False, False, True, False])


def test_a_far_candidate_cannot_win_after_a_trusted_frame(hand):
    """The start at the truth, far from the last estimate, wins without the step limit and not
    with it, whether the merit alone chooses (on the device) or an image score does (on the host)."""
    m, (cam,), truth = hand
    rig = (cam, fit_camera(m, truth, R=look_at_rotation([1.0, -0.3, -0.4], [0, 0, 0])))
    feats = features_from_pose(m, rig, truth)
    lo, hi = np.asarray(m.q_lower), np.asarray(m.q_upper)
    bad = lo + 0.02 * (hi - lo)
    frontend = FunctionFrontEnd(lambda images, q, state, frame: feats, reextracts=False)
    for step, expected in ((0.0, "proposal"), (20.0, "prediction")):
        tracker = Tracker(m, rig, frontend, TrackConfig(reextract=0, hypotheses=HypothesisConfig(max_step_deg=step)))
        rep = tracker.step(tracker.init(bad), [None, None], 0, proposals=truth[None])[1]
        assert rep.hypothesis == expected
    for step, expected in ((0.0, "proposal"), (20.0, "prediction")):
        scored = _ScoredFrontEnd(feats, 0, float(truth[0]))
        tracker = Tracker(m, rig, scored, TrackConfig(reextract=0, hypotheses=HypothesisConfig(max_step_deg=step)))
        assert tracker.step(tracker.init(bad), [None, None], 0, proposals=truth[None])[1].hypothesis == expected
    with pytest.raises(jh.InputError, match=r"hypotheses\.step_trust: must lie in \[0, 1\]"):
        HypothesisConfig(step_trust=2.0)


def test_favour_prediction_scales_the_first_merit_that_solved():
    from jaxhand.track._hypotheses import choose, favour_prediction

    np.testing.assert_allclose(favour_prediction(np.array([0.5, 0.52, -1.0]), 0.1), [0.55, 0.52, -1.0])
    np.testing.assert_allclose(favour_prediction(np.array([-1.0, 0.52]), 0.1), [-1.0, 0.52])   # failed: stays out
    np.testing.assert_allclose(favour_prediction(jnp.array([0.5, 0.52]), 0.1, xp=jnp), [0.55, 0.52])
    assert choose(np.array([0.5, 0.52]))[0] == 1
    assert choose(np.array([0.5, 0.52]), margin=0.1)[0] == 0
    assert choose(np.array([0.5, 0.52]), np.array([1.0, 0.5]), margin=0.1)[0] == 0   # 0.55 against 0.26


def test_a_candidate_must_beat_the_prediction_by_the_margin(hand):
    """The start at the truth beats the prediction's solve from near the limits; with a margin the
    prediction's merit cannot be beaten by, the prediction wins, on the device and on the host."""
    m, (cam,), truth = hand
    rig = (cam, fit_camera(m, truth, R=look_at_rotation([1.0, -0.3, -0.4], [0, 0, 0])))
    feats = features_from_pose(m, rig, truth)
    bad = np.asarray(m.q_lower) + 0.02 * (np.asarray(m.q_upper) - np.asarray(m.q_lower))
    frontend = FunctionFrontEnd(lambda images, q, state, frame: feats, reextracts=False)
    for front in (frontend, _ScoredFrontEnd(feats, 0, float(truth[0]))):
        for margin, expected in ((0.0, "proposal"), (1e6, "prediction")):
            config = TrackConfig(reextract=0, hypotheses=HypothesisConfig(prediction_margin=margin))
            tracker = Tracker(m, rig, front, config)
            assert tracker.step(tracker.init(bad), [None, None], 0, proposals=truth[None])[1].hypothesis == expected
        doubtful = dataclasses.replace(tracker.init(bad), confidence=0.2)   # under step_trust: no margin
        assert tracker.step(doubtful, [None, None], 0, proposals=truth[None])[1].hypothesis == "proposal"
    with pytest.raises(jh.InputError, match=r"hypotheses\.prediction_margin: expected a finite number >= 0"):
        HypothesisConfig(prediction_margin=-0.1)


def test_the_rest_start_without_the_fingers_rests_the_thumb_alone(hand):
    m, rig, truth = hand
    frontend = FunctionFrontEnd(lambda images, q, state, frame: features_from_pose(m, rig, truth), reextracts=False)
    tracker = Tracker(m, rig, frontend, TrackConfig(hypotheses=HypothesisConfig(rest=True, rest_fingers=False)))
    rested = [n for n, keep in zip(m.q_names, tracker._rest_keep) if not keep]
    assert rested == [n for n in m.q_names if n.startswith("thumb")] and len(rested) == 5
