"""Pose priors in the tracker's solve (issue 13 items 5, 6): TrackConfig.prior.

- a temporal prior of huge weight pins the solve to its prediction; weight 0 gives the solve
  without priors (to the solver's tolerance), and priors off (the default) is the program without priors;
- the information weight is the fixed one where the images see nothing and fades where they do;
- the frame's RMS counts the image residuals only;
- no recompilation across frames or for new prior numbers;
- on exact features the information-weighted prior's reported estimate is no worse than the raw
  solve without priors;
- ``prior.temporal_merit``: a start's merit counts its temporal residuals beside the features';
- ``prior.temporal_min_confidence``: after a doubtful frame the solve is the one without the
  temporal prior, from the same compiled program;
- ``prior.restore_hidden_below``: after a doubtful frame the joints that move only links the
  support did not judge are predicted at the last trusted pose, still; the others as before.
"""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import CompileCounter, FunctionFrontEnd

import jaxhand as jh
from jaxhand.features import features_from_pose
from jaxhand.priors import TemporalPrior, information_weight, temporal_weight
from jaxhand.render import make_preset
from jaxhand.residuals import ResidualArgs, residuals_and_jacobian
from jaxhand.solve.internal import fit_traced, solver_program
from jaxhand.track import ExactFrontEnd, FilterConfig, PriorConfig, RobustConfig, TrackConfig, Tracker
from jaxhand.track._compiled import _Priors
from jaxhand.track._hypotheses import image_merit
from jaxhand.track._support import ImageSupport, moved_links


@pytest.fixture(scope="module")
def problem():
    seq = make_preset("two_finger_occlusion", frames=8, size=(160, 120))
    feats = [features_from_pose(seq.model, seq.cameras, q, noise_px=0.5, rng=np.random.default_rng(k))
             for k, q in enumerate(seq.q)]
    return seq, feats


def _solve(seq, feats, q0, priors):
    build, config = solver_program("lm", jh.FitConfig(max_steps=30, jacobian="geometric"))
    return jax.jit(lambda f, q, p: fit_traced(seq.model, seq.cameras, f, q, build, config, priors=p))(
        tuple(feats), jnp.asarray(q0), priors)


def test_huge_weight_pins_q_to_the_prediction_and_zero_weight_changes_nothing(problem):
    seq, feats = problem
    m = seq.model
    q_pred = np.clip(seq.q[3] + 0.2, m.q_lower, m.q_upper)
    plain = _solve(seq, feats[3], q_pred, ())
    w = jnp.asarray(temporal_weight(m, 5.0, 5.0))
    pinned = _solve(seq, feats[3], q_pred, (TemporalPrior(q_pred=q_pred, weight=w * 1e6),))
    zero = _solve(seq, feats[3], q_pred, (TemporalPrior(q_pred=q_pred, weight=w * 0.0),))
    np.testing.assert_allclose(np.asarray(pinned.q), q_pred, atol=1e-6)
    # zero rows change the rounding of the linear solves only (bit for bit: PriorConfig off)
    np.testing.assert_allclose(np.asarray(zero.q), np.asarray(plain.q), rtol=0, atol=1e-7)
    assert float(zero.cost) == pytest.approx(float(plain.cost), rel=1e-6)
    # sanity: without a prior the solve leaves q_pred for the truth
    assert np.abs(np.asarray(plain.q) - seq.q[3]).max() < np.abs(q_pred - seq.q[3]).max() / 2


def test_information_weight_is_full_where_unseen_and_fades_where_seen():
    w = jnp.asarray([2.0, 3.0, 0.0])
    np.testing.assert_allclose(information_weight(w, jnp.zeros((3, 3)), 1.0), np.diag(w), atol=1e-14)
    lam = jnp.diag(jnp.asarray([4.0 * 99.0, 0.0, 5.0]))   # entry 0 seen with 99x the prior's information
    W = np.asarray(information_weight(w, lam, 1.0))
    np.testing.assert_allclose(W, np.diag([2.0 * 0.1, 3.0, 0.0]), atol=1e-12)
    # a rotated information: the prior's information is D f(L) D, whatever the basis
    rng = np.random.default_rng(0)
    A = rng.normal(size=(3, 3))
    lam = jnp.asarray(A @ A.T)
    W = np.asarray(information_weight(w, lam, 0.5))
    D = np.diag(np.asarray(w))
    S = np.diag([0.5, 1 / 3, 0.0])
    L = S @ np.asarray(lam) @ S
    np.testing.assert_allclose(W.T @ W, D @ (0.5 * np.linalg.inv(0.5 * np.eye(3) + L)) @ D, atol=1e-12)


def test_stacked_information_weights_match_one_by_one_and_take_one_eigh_under_vmap():
    rng = np.random.default_rng(1)
    A = rng.normal(size=(2, 4, 4))
    infos = jnp.asarray(A @ np.swapaxes(A, 1, 2))   # two starts' information
    ws = jnp.asarray([[2.0, 3.0, 0.0, 1.0], [0.0, 0.0, 4.0, 0.5]])   # two priors' weights
    stacked = np.asarray(information_weight(ws, infos[0], 0.5))
    for k in range(2):
        np.testing.assert_allclose(stacked[k], np.asarray(information_weight(ws[k], infos[0], 0.5)), atol=1e-12)
    # jaxlib's CPU kernel splits a batched eigh over the thread pool and blocks on it: two
    # independent batched calls can starve a two-thread pool, so the priors of a frame share one
    hlo = jax.jit(jax.vmap(lambda lam: information_weight(ws, lam, 0.5))).lower(infos).compile().as_text()
    assert hlo.count("lapack_dsyevd") == 1


def test_a_frames_priors_share_one_eigh_over_the_starts():
    seq = make_preset("full_hand_spread_flex", frames=2, size=(160, 120))
    m = seq.model
    q = jnp.asarray(seq.q[0])
    feats = tuple(features_from_pose(m, seq.cameras, q))
    fractions = jh.FitConfig().link_fractions
    priors = _Priors.of(m, PriorConfig(temporal_sigma_deg=10.0, information_ratio=1.0, thumb_rest_sigma_deg=20.0))
    assert priors.rest_weight is not None   # sanity: two information-weighted priors
    starts = jnp.stack([q, q + 0.05])
    at = jax.vmap(lambda q0: tuple(p.weight for p in priors.at(m, seq.cameras, feats, q, q0, fractions)))
    assert jax.jit(at).lower(starts).compile().as_text().count("lapack_dsyevd") == 1
    temporal, rest = (np.asarray(w) for w in at(starts))
    _, J = residuals_and_jacobian(starts[1], ResidualArgs(model=m, cameras=seq.cameras, features=feats,
                                                          fractions=fractions))
    for got, weight in ((temporal, priors.temporal_weight), (rest, priors.rest_weight)):
        np.testing.assert_allclose(got[1], np.asarray(information_weight(weight, J.T @ J, 1.0)), rtol=1e-9,
                                   atol=1e-12)


def test_information_weight_counts_the_measured_terms_beside_the_features(problem):
    seq, _ = problem
    m, q = seq.model, jnp.asarray(seq.q[3])
    feats = tuple(features_from_pose(m, seq.cameras, q))
    fractions = jh.FitConfig().link_fractions
    priors = _Priors.of(m, PriorConfig(temporal_sigma_deg=10.0, information_ratio=1.0))
    pip = m.q_lookup("index_pip")

    def term(x):   # a measurement of index_pip alone (px), slope 100 x
        return 50.0 * x[pip:pip + 1] ** 2

    with_term, = priors.at(m, seq.cameras, feats, q, q, fractions, (term,))
    without, = priors.at(m, seq.cameras, feats, q, q, fractions)
    _, J = residuals_and_jacobian(q, ResidualArgs(model=m, cameras=seq.cameras, features=feats,
                                                      fractions=fractions))
    J_term = np.zeros((1, m.n_q))
    J_term[0, pip] = 100.0 * float(q[pip])
    expected = information_weight(priors.temporal_weight, J.T @ J + J_term.T @ J_term, 1.0)
    np.testing.assert_allclose(np.asarray(with_term.weight), np.asarray(expected), rtol=1e-9, atol=1e-12)
    # sanity: the term's information lowers the prior's weight along index_pip
    assert np.linalg.norm(np.asarray(with_term.weight) @ np.eye(m.n_q)[pip]) < 0.9 * np.linalg.norm(
        np.asarray(without.weight) @ np.eye(m.n_q)[pip])


def test_information_terms_scales_the_measured_terms_share(problem):
    seq, _ = problem
    m, q = seq.model, jnp.asarray(seq.q[3])
    feats = tuple(features_from_pose(m, seq.cameras, q))
    fractions = jh.FitConfig().link_fractions
    pip = m.q_lookup("index_pip")

    def term(x):   # slope 100 x along index_pip, as above
        return 50.0 * x[pip:pip + 1] ** 2

    def weight(share):
        priors = _Priors.of(m, PriorConfig(temporal_sigma_deg=10.0, information_ratio=1.0, information_terms=share))
        return np.asarray(priors.at(m, seq.cameras, feats, q, q, fractions, (term,))[0].weight)

    features_only = np.asarray(_Priors.of(m, PriorConfig(temporal_sigma_deg=10.0, information_ratio=1.0))
                               .at(m, seq.cameras, feats, q, q, fractions)[0].weight)
    np.testing.assert_allclose(weight(0.0), features_only, rtol=1e-12, atol=1e-12)
    _, J = residuals_and_jacobian(q, ResidualArgs(model=m, cameras=seq.cameras, features=feats,
                                                      fractions=fractions))
    J_term = np.zeros((1, m.n_q))
    J_term[0, pip] = 100.0 * float(q[pip])
    base = _Priors.of(m, PriorConfig(temporal_sigma_deg=10.0, information_ratio=1.0))
    expected = information_weight(base.temporal_weight, J.T @ J + 0.25 * J_term.T @ J_term, 1.0)
    np.testing.assert_allclose(weight(0.25), np.asarray(expected), rtol=1e-9, atol=1e-12)


def test_temporal_merit_counts_the_prior_residuals_beside_the_features(problem):
    seq, feats = problem
    m, q = seq.model, jnp.asarray(seq.q[3])
    exact = tuple(features_from_pose(m, seq.cameras, q))
    weight = sum(float(jnp.sum(jnp.where(f.line_valid, f.line_weight, 0.0)) + jnp.sum(jnp.where(f.tip_valid,
                 f.tip_weight, 0.0))) for f in exact)
    fractions = jh.FitConfig().link_fractions
    assert float(image_merit(m, seq.cameras, exact, q, fractions, 2.0, 2.0)) == pytest.approx(1.0, abs=1e-12)
    # 8 px^2 over the feature weights: e_r^2 = 8 / weight, merit 1 / (1 + e_r^2 / 4)
    merit = float(image_merit(m, seq.cameras, exact, q, fractions, 2.0, 2.0, 8.0))
    assert merit == pytest.approx(1.0 / (1.0 + 8.0 / weight / 4.0), rel=1e-12)
    priors = _Priors.of(m, PriorConfig(temporal_sigma_deg=10.0, temporal_sigma_mm=5.0, temporal_merit=0.5))
    q_pred = q + jnp.where(jnp.asarray(m.is_angle), np.radians(20.0), 0.0)   # every angle 2 sigmas off
    n_angles = int(np.sum(np.asarray(m.q_kinds) == "angle"))
    assert float(priors.merit_sq(q, q_pred)) == pytest.approx(0.5 * 4.0 * n_angles, rel=1e-9)
    assert float(_Priors.of(m, PriorConfig(temporal_sigma_deg=10.0)).merit_sq(q, q_pred)) == 0.0


def _track(seq, feats, config, frames=None):
    n = len(seq.q) if frames is None else frames
    dt = float(seq.times_s[1] - seq.times_s[0])
    tracker = Tracker(seq.model, seq.cameras, FunctionFrontEnd(lambda images, q, s, frame: feats[frame]), config,
                      dt_s=dt)
    state = tracker.init(seq.q[0])
    reports = []
    for k in range(n):
        state, rep = tracker.step(state, [None] * len(seq.cameras), k)
        reports.append(rep)
    return reports


@pytest.mark.slow
def test_priors_off_is_the_program_without_priors_and_rms_counts_image_residuals_only(problem):
    seq, feats = problem
    base = _track(seq, feats, TrackConfig(reextract=0), 4)
    off = _track(seq, feats, TrackConfig(reextract=0, prior=PriorConfig(temporal_sigma_deg=0.0)), 4)
    for a, b in zip(base, off):
        np.testing.assert_array_equal(a.q_filtered, b.q_filtered)
        assert a.rms_px == b.rms_px
    strong = _track(seq, feats, TrackConfig(reextract=0, robust=RobustConfig(passes=0, gate_scale_px=0.0),
                                            prior=PriorConfig(temporal_sigma_deg=1e-3, temporal_sigma_mm=1e-3)), 4)
    n_res = 2 * (seq.model.n_tips + seq.model.n_links) * len(seq.cameras)
    for rep in strong:   # pinned to the prediction, the RMS is that of the image residuals there
        args = jh.residuals.make_residual_args(seq.model, seq.cameras, feats[rep.frame])
        r = np.asarray(jh.residuals.residuals(jnp.asarray(rep.q_solved), args))
        assert rep.rms_px == pytest.approx(np.sqrt(np.sum(r * r) / n_res), rel=1e-6)
        assert rep.cost == pytest.approx(0.5 * np.sum(r * r), rel=1e-6)
        np.testing.assert_allclose(rep.q_solved, rep.q_pred, atol=1e-5)


@pytest.mark.slow
def test_no_recompile_across_frames_nor_for_new_prior_numbers(problem):
    seq, feats = problem
    dt = float(seq.times_s[1] - seq.times_s[0])
    images = [np.zeros((120, 160), np.uint8)]
    config = TrackConfig(prior=PriorConfig(temporal_sigma_deg=5.0, temporal_sigma_mm=5.0, information_ratio=1.0,
                                           dip_pip_weight=10.0), filter=FilterConfig(report_solve=True))
    tracker = Tracker(seq.model, seq.cameras, ExactFrontEnd(seq.model, seq.cameras, seq.q), config, dt_s=dt)
    state = tracker.init(seq.q[0])
    state, _ = tracker.step(state, images)
    with CompileCounter() as counter:
        for k in range(1, 5):
            state, rep = tracker.step(state, images, k)
        other = config.merged({"prior": {"temporal_sigma_deg": 2.0, "information_ratio": 3.0, "dip_pip_weight": 1.0}})
        t2 = Tracker(seq.model, seq.cameras, ExactFrontEnd(seq.model, seq.cameras, seq.q), other, dt_s=dt)
        s2 = t2.init(seq.q[0])
        for k in range(3):
            s2, _ = t2.step(s2, images, k)
    assert counter.count == 0
    assert np.degrees(np.abs(rep.q_solved - seq.q[4])).mean() < 4.0   # sanity


@pytest.mark.slow
def test_information_weighted_estimate_on_exact_features_is_no_worse_than_the_raw_solve(problem):
    seq, feats = problem
    truth = np.asarray(seq.q)
    moving = (np.ptp(truth, axis=0) > 1e-9) & np.asarray(seq.model.is_angle)
    raw = _track(seq, feats, TrackConfig(reextract=0, filter=FilterConfig(enabled=False)))
    info = _track(seq, feats, TrackConfig(reextract=0, filter=FilterConfig(report_solve=True),
                                          prior=PriorConfig(temporal_sigma_deg=5.0, temporal_sigma_mm=5.0,
                                                            information_ratio=1.0)))
    ghk = _track(seq, feats, TrackConfig(reextract=0))

    def err(reps, field):
        return np.degrees(np.abs(np.array([getattr(r, field) for r in reps]) - truth))[:, moving].mean()

    e_raw, e_info, e_ghk = err(raw, "q_solved"), err(info, "q_filtered"), err(ghk, "q_filtered")
    assert e_info <= e_raw * 1.02 + 0.05, (e_info, e_raw, e_ghk)


def test_coupled_preset_carries_a_hidden_distal_joint_with_its_pip():
    # issue 13: a DIP whose phalanx and tip are hidden gets no innovation, so without the coupling
    # the filter extrapolates it; with the "coupled" preset it follows its (seen) PIP at 2/3
    seq = make_preset("two_finger_occlusion", frames=40, size=(160, 120))
    m = seq.model
    link, tip = m.link_lookup("middle_dip"), m.tip_names.index("middle_dip")
    dip, pip = m.q_lookup("middle_dip"), m.q_lookup("middle_pip")

    def hidden(k):   # exact features, the middle finger's distal phalanx and tip hidden from frame 4 on
        (f,) = features_from_pose(m, seq.cameras, seq.q[k])
        if k >= 4:
            f = f.__class__(lines=f.lines, line_valid=f.line_valid.at[link].set(False), line_weight=f.line_weight,
                            tips=f.tips, tip_valid=f.tip_valid.at[tip].set(False), tip_weight=f.tip_weight)
        return (f,)

    feats = [hidden(k) for k in range(len(seq.q))]
    assert TrackConfig().preset("coupled").prior.dip_pip_weight == 4.0
    errors = {}
    for label, config in (("default", TrackConfig(reextract=0)),
                          ("coupled", TrackConfig(reextract=0).preset("coupled"))):
        q = np.array([r.q_filtered for r in _track(seq, feats, config)])
        errors[label] = np.degrees(np.abs(q[:, dip] - seq.q[:, dip]))[4:]
        if label == "coupled":   # at the end the hidden DIP sits at 2/3 of its PIP (measured: 0.04 deg off)
            np.testing.assert_allclose(q[-1, dip], 2 / 3 * q[-1, pip], atol=np.radians(0.5))
    # measured (exact features, deterministic): coupled max 5.58 / mean 2.32 deg over the hidden
    # frames (the path's own ratio moves between 0.67 and 0.75), default 9.99 / 3.49
    assert errors["coupled"].max() < 6.0 and errors["coupled"].mean() < 2.6
    assert errors["default"].max() > 9.0 and errors["default"].mean() > errors["coupled"].mean() + 1.0


@pytest.mark.slow
def test_a_frame_after_a_doubtful_one_is_solved_without_the_temporal_prior(problem):
    seq, feats = problem
    dt = float(seq.times_s[1] - seq.times_s[0])
    front = FunctionFrontEnd(lambda images, q, s, frame: feats[frame])
    prior = {"temporal_sigma_deg": 2.0, "temporal_sigma_mm": 2.0, "temporal_merit": 0.1}
    base = TrackConfig(reextract=0, filter=FilterConfig(report_solve=True)).merged(
        {"hypotheses": {"flips": 2, "last_solve": True}})
    gated = Tracker(seq.model, seq.cameras, front, base.merged({"prior": {**prior, "temporal_min_confidence": 0.5}}),
                    dt_s=dt)
    held = Tracker(seq.model, seq.cameras, front, base.merged({"prior": prior}), dt_s=dt)
    free = Tracker(seq.model, seq.cameras, front, base, dt_s=dt)
    state = gated.init(seq.q[0])
    for k in range(3):
        state, _ = gated.step(state, [None], k)
    assert state.confidence > 0.5
    doubtful = dataclasses.replace(state, confidence=0.4)
    with CompileCounter() as counter:   # the untrusted frame reuses the compiled program
        after_doubt = gated.step(doubtful, [None], 3)[1]
    assert counter.count == 0
    np.testing.assert_allclose(after_doubt.q_solved, free.step(doubtful, [None], 3)[1].q_solved, rtol=0, atol=1e-9)
    after_good = gated.step(state, [None], 3)[1]
    np.testing.assert_allclose(after_good.q_solved, held.step(state, [None], 3)[1].q_solved, rtol=0, atol=1e-9)
    # sanity: the prior (sigma 2 deg) holds the solve measurably
    assert np.abs(after_good.q_solved - after_doubt.q_solved).max() > np.radians(0.05)


def test_moved_links_are_the_links_at_and_below_each_joint(problem):
    seq, _ = problem
    m = seq.model   # middle_mcp, _pip, _dip, index_mcp, _pip, _dip: one link per joint, two chains
    chain = np.triu(np.ones((3, 3), bool))
    np.testing.assert_array_equal(moved_links(m), np.block([[chain, np.zeros((3, 3), bool)],
                                                            [np.zeros((3, 3), bool), chain]]))
    hand = jh.builtin_model("hand21")   # a free base moves every link
    moves = moved_links(hand)
    assert moves[: hand.n_base_q].all() and moves.shape == (hand.n_q, hand.n_links)
    pip = hand.q_lookup("index_pip")
    assert {hand.link_names[i] for i in np.flatnonzero(moves[pip])} == {"index_pip", "index_dip"}


class _Hiding(FunctionFrontEnd):
    """Features from ``fn``; the support judges every link but ``hidden_links`` (at ``score``)."""

    def __init__(self, fn, n_links, hidden_links, score=1.0):
        super().__init__(fn)
        self.link_score = np.full((1, n_links), score)
        self.link_score[0, list(hidden_links)] = np.nan

    def support(self, images, q, state, margin_px=1):
        return ImageSupport(link_score=self.link_score)


def test_after_a_doubtful_frame_hidden_joints_restart_from_the_trusted_pose(problem):
    seq, feats = problem
    m = seq.model
    dt = float(seq.times_s[1] - seq.times_s[0])
    front = _Hiding(lambda images, q, s, frame: feats[frame], m.n_links, [m.link_names.index("index_dip")])
    config = TrackConfig(reextract=0, filter=FilterConfig(report_solve=True)).merged(
        {"support": {"enabled": True}, "prior": {"restore_hidden_below": 0.5}})
    tracker = Tracker(m, seq.cameras, front, config, dt_s=dt)
    state = tracker.init(seq.q[0])
    for k in range(3):
        state, report = tracker.step(state, [None], k)
    assert report.confidence >= 0.5
    dip = m.q_lookup("index_dip")
    np.testing.assert_array_equal(state.hidden, [dip])   # the only joint that moves index_dip alone
    np.testing.assert_array_equal(state.q_trusted, report.q_filtered)
    trusted = np.clip(seq.q[0] + 0.3, m.q_lower, m.q_upper)
    doubtful = dataclasses.replace(state, confidence=0.4, q_trusted=trusted)
    pred = np.asarray(state.ghk.x)
    after = tracker.step(doubtful, [None], 3)[1].q_pred
    assert after[dip] == pytest.approx(trusted[dip], abs=1e-12)
    others = np.arange(m.n_q) != dip
    np.testing.assert_allclose(after[others], pred[others], rtol=0, atol=1e-12)
    assert abs(pred[dip] - trusted[dip]) > 0.1   # sanity: the restore moved it
    # after a good frame the prediction is the filter's, whatever the trusted pose
    np.testing.assert_allclose(tracker.step(dataclasses.replace(state, q_trusted=trusted), [None], 3)[1].q_pred,
                               pred, rtol=0, atol=1e-12)
    # a frame under the level keeps the old trusted pose
    low = _Hiding(front.fn, m.n_links, [], score=0.0)
    low_state, low_report = Tracker(m, seq.cameras, low, config, dt_s=dt).step(doubtful, [None], 3)
    assert low_report.confidence < 0.5
    np.testing.assert_array_equal(low_state.q_trusted, trusted)


def test_a_joint_long_unmeasured_starts_from_its_last_measured_value(problem):
    """``prior.hold_unseen_frames``: index_dip's line goes missing from frame 2; after two frames
    without it the DIP is predicted at its estimate of frame 1, still; the other joints as before."""
    import equinox as eqx

    seq, feats = problem
    m = seq.model
    link = m.link_names.index("index_dip")
    dip = m.q_lookup("index_dip")

    def without_dip(frame):
        if frame < 2:
            return feats[frame]
        return tuple(eqx.tree_at(lambda f: f.line_valid, f, f.line_valid.at[link].set(False)) for f in feats[frame])

    front = FunctionFrontEnd(lambda images, q, s, frame: without_dip(frame))
    config = TrackConfig(reextract=0, filter=FilterConfig(report_solve=True)).merged(
        {"prior": {"hold_unseen_frames": 2}})
    tracker = Tracker(m, seq.cameras, front, config, dt_s=float(seq.times_s[1] - seq.times_s[0]))
    state = tracker.init(seq.q[0])
    counts = []
    for k in range(4):
        state, report = tracker.step(state, [None], k)
        counts.append(int(state.unseen[dip]))
        if k == 1:
            seen_dip = report.q_filtered[dip]
    assert counts == [0, 0, 1, 2]
    assert state.unseen.sum() == 2   # the DIP alone moves nothing but index_dip's link
    assert state.q_seen[dip] == seen_dip
    pred = np.asarray(state.ghk.x)
    after = tracker.step(state, [None], 4)[1].q_pred
    assert after[dip] == seen_dip
    others = np.arange(m.n_q) != dip
    np.testing.assert_allclose(after[others], pred[others], rtol=0, atol=1e-12)
    assert abs(pred[dip] - seen_dip) > 1e-6   # sanity: the hold moved it
    with pytest.raises(jh.InputError, match=r"prior\.hold_unseen_frames: expected a finite number >= 0"):
        PriorConfig(hold_unseen_frames=-1)


def test_thumb_rest_prior_pulls_the_thumb_alone_towards_rest_where_the_image_does_not_see():
    """``prior.thumb_rest_sigma_deg``: a second information-weighted prior, around the default
    pose, on the joints of the finger that is not planar (a thumb) and on nothing else."""
    import equinox as eqx

    from jaxhand.track._flexion import thumb_joints

    hand = jh.builtin_model("hand21")
    assert [hand.q_names[i] for i in thumb_joints(hand)] == ["thumb_cmc_pa", "thumb_cmc_ra", "thumb_mcp_ab",
                                                             "thumb_mcp", "thumb_ip"]
    assert len(thumb_joints(jh.builtin_model("two_fingers"))) == 0
    seq = make_preset("full_hand_spread_flex", frames=2, size=(160, 120))
    m, rig, fractions = seq.model, seq.cameras, jh.FitConfig().link_fractions
    priors = _Priors.of(m, PriorConfig(temporal_sigma_deg=15.0, information_ratio=1.0, thumb_rest_sigma_deg=20.0))
    rest_pose = np.asarray(m.q_default)
    thumb, pip = m.q_lookup("thumb_mcp"), m.q_lookup("index_pip")
    d_thumb = np.zeros(m.n_q)
    d_thumb[thumb] = np.radians(10.0)
    d_pip = np.zeros(m.n_q)
    d_pip[pip] = np.radians(10.0)
    seen = tuple(features_from_pose(m, rig, jnp.asarray(seq.q[0])))
    unseen = tuple(eqx.tree_at(lambda f: (f.line_valid, f.tip_valid), f,
                               (jnp.zeros_like(f.line_valid), jnp.zeros_like(f.tip_valid))) for f in seen)
    q = jnp.asarray(seq.q[0])
    _, rest_unseen = priors.at(m, rig, unseen, q, q, fractions)[:2]
    _, rest_seen = priors.at(m, rig, seen, q, q, fractions)[:2]
    np.testing.assert_array_equal(np.asarray(rest_unseen.q_pred), rest_pose)
    # nothing seen: the full prior, 10 deg off at sigma 20 is a residual of 0.5 on the thumb's MCP alone
    r = np.asarray(rest_unseen(jnp.asarray(rest_pose + d_thumb)))
    assert r[thumb] == pytest.approx(0.5, rel=1e-9) and np.abs(np.delete(r, thumb)).max() < 1e-12
    # a finger's joint is never held, seen or not
    for rest in (rest_unseen, rest_seen):
        assert np.abs(np.asarray(rest(jnp.asarray(rest_pose + d_pip)))).max() < 1e-12
    # seen, the thumb is held less
    assert np.linalg.norm(np.asarray(rest_seen(jnp.asarray(rest_pose + d_thumb)))) < 0.5
    with pytest.raises(jh.InputError, match=r"prior\.thumb_rest_sigma_deg: is information-weighted"):
        PriorConfig(temporal_sigma_deg=15.0, thumb_rest_sigma_deg=20.0)
    # a model without a thumb gets no rest prior at all
    two = _Priors.of(jh.builtin_model("two_fingers"), PriorConfig(temporal_sigma_deg=15.0, information_ratio=1.0,
                                                                  thumb_rest_sigma_deg=20.0))
    assert two.rest_weight is None and two.rest_pose is None
