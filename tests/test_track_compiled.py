"""The tracker's fused per-frame program and the geometric residual Jacobian it solves with.

- the fused step (solve, robust passes, filter in one compiled program) gives what the unfused
  sequence of public calls gives (fit, feature_distances, reweight, fit, ..., the g-h-k step);
- ``residuals_and_jacobian`` equals ``jax.jacfwd(residuals)`` (and central differences) on
  random poses of fixed, free and planar bases, with orthographic and perspective cameras,
  weights, masked slots holding NaN, points behind a perspective camera and a zero quaternion;
- no recompilation across frames, nor for a second tracker of the same structure;
- bad features still raise a clear InputError from ``Tracker.step``.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from _params import model_params
from helpers import CompileCounter, FunctionFrontEnd, fit_camera, fixed_front_end

import jaxhand as jh
from jaxhand.camera import look_at_rotation
from jaxhand.check import central_difference_jacobian
from jaxhand.features import Features, features_from_pose
from jaxhand.render import make_preset
from jaxhand.residuals import feature_distances, make_residual_args, residuals, residuals_and_jacobian
from jaxhand.solve import FitConfig, StateSpace, solve_least_squares
from jaxhand.solve.levenberg_marquardt import make_levenberg_marquardt
from jaxhand.track import ExactFrontEnd, FilterConfig, LossConfig, RobustConfig, TrackConfig, Tracker, reweight
from jaxhand.track._compiled import filter_update

_filter_step = eqx.filter_jit(filter_update)
_distances = eqx.filter_jit(feature_distances)

_jacfwd_and_r = eqx.filter_jit(jax.jacfwd(lambda q, args: (residuals(q, args),) * 2, has_aux=True))
_geometric = eqx.filter_jit(residuals_and_jacobian)


def _rig(model):
    ortho = fit_camera(model, R=look_at_rotation([1.0, -0.5, -2.0], [0, 0, 0]))
    persp = jh.Perspective.look_at([80.0, -60.0, -500.0], [0.0, 0.0, 0.0])
    return ortho, persp


def _noisy_features(model, rig, q, rng):
    """Noisy features of q with random weights, one line and one tip masked (NaN inside)."""
    out = []
    for f in features_from_pose(model, rig, q, noise_px=1.0, rng=rng):
        lines = np.array(f.lines)
        tips = np.array(f.tips)
        lv, tv = np.array(f.line_valid), np.array(f.tip_valid)
        lv[0], tv[-1] = False, False
        lines[0], tips[-1] = np.nan, np.nan
        out.append(Features(lines=jnp.asarray(lines), line_valid=jnp.asarray(lv),
                            line_weight=jnp.asarray(rng.uniform(0.2, 3.0, model.n_links)), tips=jnp.asarray(tips),
                            tip_valid=jnp.asarray(tv), tip_weight=jnp.asarray(rng.uniform(0.2, 3.0, model.n_tips))))
    return tuple(out)


@pytest.mark.parametrize("name", model_params(["two_fingers", "hand21", "hand27", "mouse3d"]))
@pytest.mark.slow
def test_geometric_jacobian_equals_jacfwd(name):
    m = jh.builtin_model(name)
    rng = np.random.default_rng(5)
    rig = _rig(m)
    poses = jh.random_q(m, rng, 6)
    poses[0] = np.asarray(m.q_upper)                         # at the limits
    if m.base_kind == "free":
        poses[0, :4] = [0.0, 0.0, 0.0, 1.0]
        poses[1, :4] = [np.cos(1.55), np.sin(1.55), 0.0, 0.0]  # base rotated near pi
        poses[2, :4] *= 3.0                                     # not normalised
    worst, worst_r = 0.0, 0.0
    for k, q in enumerate(poses):   # one orthographic and one perspective camera
        args = make_residual_args(m, rig, _noisy_features(m, rig, poses[(k + 1) % len(poses)], rng), (0.1, 0.5, 0.9))
        J_ad, r_ad = (np.asarray(x) for x in _jacfwd_and_r(jnp.asarray(q), args))
        r, J = (np.asarray(x) for x in _geometric(jnp.asarray(q), args))
        assert np.all(np.isfinite(J)) and J.shape == J_ad.shape
        worst = max(worst, np.abs(J - J_ad).max() / max(1.0, np.abs(J_ad).max()))
        worst_r = max(worst_r, np.abs(r - r_ad).max())
    assert worst < 1e-9, worst
    assert worst_r < 1e-9, worst_r


@pytest.mark.parametrize("name", model_params(["hand27", "mouse3d"]))
def test_geometric_jacobian_matches_central_differences(name):
    m = jh.builtin_model(name)
    rng = np.random.default_rng(11)
    rig = _rig(m)
    q = jh.random_q(m, rng)
    args = make_residual_args(m, rig, _noisy_features(m, rig, jh.random_q(m, rng), rng))
    _, J = _geometric(jnp.asarray(q), args)
    batch = jax.jit(jax.vmap(lambda x: residuals(x, args)))
    fd = central_difference_jacobian(lambda qs: batch(jnp.asarray(qs)), q)
    J = np.asarray(J)
    assert np.abs(J - fd).max() / max(1.0, np.abs(J).max()) < 1e-6


def test_geometric_jacobian_at_the_singular_points():
    # A zero quaternion (the kinematics map it to the identity, so nothing moves with it) and
    # link points behind a perspective camera (their depth is clamped): finite, equal to jacfwd.
    m = jh.builtin_model("hand27")
    rng = np.random.default_rng(2)
    q = jh.random_q(m, rng)
    inside = jh.Perspective.look_at(np.asarray(q[4:7]) + [0.0, 0.0, -20.0], np.asarray(q[4:7]) + [0.0, 0.0, 100.0])
    zero_quat = np.concatenate([np.zeros(4), q[4:]])
    for cams, q_at in (((_rig(m)[1],), zero_quat), ((inside,), q)):
        args = make_residual_args(m, cams, _noisy_features(m, cams, jh.random_q(m, rng), rng), validate=False)
        r, J = (np.asarray(x) for x in _geometric(jnp.asarray(q_at), args))
        J_ad = np.asarray(_jacfwd_and_r(jnp.asarray(q_at), args)[0])
        assert np.all(np.isfinite(r)) and np.all(np.isfinite(J))
        np.testing.assert_allclose(J, J_ad, rtol=0, atol=1e-9 * max(1.0, np.abs(J_ad).max()))
        if q_at is zero_quat:
            assert np.all(J[:, :4] == 0.0)


@pytest.mark.slow
def test_fit_with_geometric_jacobian_equals_autodiff():
    m = jh.builtin_model("index_thumb")
    rng = np.random.default_rng(4)
    rig = _rig(m)
    for _ in range(3):
        q_true = jh.random_q(m, rng, margin=0.1)
        feats = features_from_pose(m, rig, q_true, noise_px=0.5, rng=rng)
        q0 = np.clip(q_true + rng.normal(0, 0.05, m.n_q), m.q_lower, m.q_upper)
        for solver in ("lm", "bounded"):
            a = jh.fit(m, rig, feats, q0, solver=solver, config=FitConfig(max_steps=30))
            b = jh.fit(m, rig, feats, q0, solver=solver, config=FitConfig(max_steps=30, jacobian="geometric"))
            np.testing.assert_allclose(np.asarray(b.q), np.asarray(a.q), atol=1e-7)
            np.testing.assert_allclose(float(b.cost), float(a.cost), rtol=1e-9)
            assert b.status_name() == a.status_name()


def test_skipping_the_rank_test_reports_full_rank():
    # index with its DIP link and tip masked: the DIP joint is undetermined (rank 2 of 3); the
    # tracker's intermediate robust passes skip the SVD (rank_test False, here traced).
    m = jh.builtin_model("index")
    rig = _rig(m)
    q_true = jh.random_q(m, np.random.default_rng(8), margin=0.1)
    dip = m.link_lookup("index_dip")
    feats = tuple(Features(lines=f.lines.at[dip].set(jnp.nan), line_valid=f.line_valid.at[dip].set(False),
                           line_weight=f.line_weight, tips=f.tips.at[0].set(jnp.nan),
                           tip_valid=f.tip_valid.at[0].set(False), tip_weight=f.tip_weight)
                  for f in features_from_pose(m, rig, q_true))
    config = FitConfig(jacobian="geometric")
    args = make_residual_args(m, rig, feats)
    space = StateSpace.of(m)
    build = make_levenberg_marquardt(config, space)
    q0 = jnp.asarray(np.clip(q_true + 0.05, m.q_lower, m.q_upper))

    @jax.jit
    def solve(q0, flag):
        return solve_least_squares(residuals, build, q0, args, space, config, jac=residuals_and_jacobian,
                                   rank_test=flag)

    tested, skipped = solve(q0, True), solve(q0, False)
    assert int(tested.rank) == 2 and tested.status_name() == "singular"
    assert int(skipped.rank) == 3 and skipped.status_name() == "ok"
    np.testing.assert_array_equal(np.asarray(skipped.q), np.asarray(tested.q))
    determined = np.arange(m.n_q) != m.q_lookup("index_dip")
    assert np.abs(np.asarray(tested.q) - q_true)[determined].max() < 1e-8


def _reference_step(tracker, state, features):
    """The tracker's frame, call by call as before the fused program: fit, then robust passes of
    feature_errors -> reweight -> fit, then the jitted g-h-k step (no loss on these frames)."""
    cfg = tracker.config
    fit_config = cfg.fit
    q_pred = state.ghk.x
    result = jh.fit(tracker.model, tracker.cameras, features, q_pred, solver=cfg.solver, config=fit_config)
    for _ in range(cfg.robust.passes):
        errors = _distances(tracker.model, tracker.cameras, tuple(features), result.q, fit_config.link_fractions)
        weighted = reweight(tuple(features), errors, cfg.robust.scale_px)
        result = jh.fit(tracker.model, tracker.cameras, weighted, result.q, solver=cfg.solver, config=fit_config)
    filtered, ghk = _filter_step(tracker.model, state.ghk, result.q, jnp.asarray(tracker.theta),
                                 jnp.asarray(tracker.dt_s), cfg.filter.enabled)
    return result, np.asarray(filtered), ghk


@pytest.mark.parametrize("preset, solver", [("two_finger_occlusion", "lm"),
                                            pytest.param("two_camera_hand", "bounded", marks=pytest.mark.slow)])
def test_fused_step_equals_the_unfused_calls(preset, solver):
    seq = make_preset(preset, frames=5, size=(160, 120))
    truth_features = [features_from_pose(seq.model, seq.cameras, q, noise_px=0.5, rng=np.random.default_rng(k))
                      for k, q in enumerate(seq.q)]
    tracker = Tracker(seq.model, seq.cameras, FunctionFrontEnd(lambda images, q, s, frame: truth_features[frame]),
                      TrackConfig(solver=solver, filter=FilterConfig(theta=0.6), robust=RobustConfig(gate_scale_px=0.0),
                                  reextract=0),
                      dt_s=float(seq.times_s[1] - seq.times_s[0]))
    state = tracker.init(seq.q[0])
    for k in range(len(seq.q)):
        result, filtered, ghk = _reference_step(tracker, state, truth_features[k])
        state, rep = tracker.step(state, [None] * len(seq.cameras), k, float(seq.times_s[k]))
        np.testing.assert_allclose(rep.q_solved, np.asarray(result.q), rtol=0, atol=1e-8)
        np.testing.assert_allclose(rep.q_filtered, filtered, rtol=0, atol=1e-8)
        np.testing.assert_allclose(np.asarray(state.ghk.x), np.asarray(ghk.x), rtol=0, atol=1e-8)
        np.testing.assert_allclose(np.asarray(state.ghk.v), np.asarray(ghk.v), rtol=0, atol=1e-6)
        np.testing.assert_allclose(rep.cost, float(result.cost), rtol=1e-8)
        n_res = 2 * (seq.model.n_tips + seq.model.n_links) * len(seq.cameras)   # every feature valid
        assert rep.rms_px == pytest.approx(np.sqrt(2 * float(result.cost) / n_res), rel=1e-8)
        assert rep.valid_share == 1.0 and not rep.lost
        assert rep.status == result.status_name() and rep.iterations == int(result.iterations)
        # sanity: 0.5 px noise on 160x120 views leaves a few degrees on average
        assert np.degrees(np.abs(rep.q_solved - seq.q[k])[seq.model.is_angle]).mean() < 6.0


def test_fused_step_compiles_once_per_structure():
    seq = make_preset("two_finger_occlusion", frames=12, size=(160, 120))
    dt = float(seq.times_s[1] - seq.times_s[0])
    images = [np.zeros((120, 160), np.uint8)]
    tracker = Tracker(seq.model, seq.cameras, ExactFrontEnd(seq.model, seq.cameras, seq.q), dt_s=dt)
    state = tracker.init(seq.q[0])
    state, _ = tracker.step(state, images)
    with CompileCounter() as counter:
        for k in range(1, 6):
            state, rep = tracker.step(state, images, k)
        # a second tracker of the same structure, other numbers (filter, scores, frame rate)
        other = Tracker(seq.model, seq.cameras, ExactFrontEnd(seq.model, seq.cameras, seq.q[6:]),
                        TrackConfig(filter=FilterConfig(theta=0.3), robust=RobustConfig(scale_px=4.0),
                                    loss=LossConfig(max_rms_px=9.0)), dt_s=dt / 2)
        s2 = other.init(seq.q[6])
        for k in range(3):
            s2, rep2 = other.step(s2, images, k)
    assert counter.count == 0
    # sanity: the exact features (0.5 px noise) are solved to a few degrees on average
    assert np.degrees(np.abs(rep.q_solved - seq.q[5])).mean() < 4.0
    assert np.degrees(np.abs(rep2.q_solved - seq.q[8])).mean() < 4.0


def test_bad_features_raise_from_step():
    seq = make_preset("two_finger_occlusion", frames=3, size=(160, 120))
    m = seq.model
    good = features_from_pose(m, seq.cameras, seq.q[0])[0]
    nan_line = eqx.tree_at(lambda f: f.lines, good, good.lines.at[1, 2].set(jnp.nan))
    long_normal = eqx.tree_at(lambda f: f.lines, good, good.lines.at[0, :2].multiply(1.1))
    negative = eqx.tree_at(lambda f: f.tip_weight, good, good.tip_weight.at[0].set(-1.0))
    short = eqx.tree_at(lambda f: f.tips, good, good.tips[:1])
    # NaN in a masked slot is fine
    masked = eqx.tree_at(lambda f: (f.lines, f.line_valid), good,
                         (good.lines.at[1].set(jnp.nan), good.line_valid.at[1].set(False)))
    for feats, message in ((nan_line, r"features\[0\]: a valid line or tip holds NaN"),
                           (long_normal, r"features\[0\]\.lines: \(a, b\) must be unit normals"),
                           (negative, r"features\[0\]\.tip_weight: weights must be finite and >= 0"),
                           (short, r"features\[0\]\.tips: expected shape \(2, 2\)"),
                           ((good, good), r"expected one Features per camera \(1\), got 2"),
                           (masked, None)):
        tracker = Tracker(m, seq.cameras, fixed_front_end(feats))
        state = tracker.init(seq.q[0])
        if message is None:
            _, rep = tracker.step(state, [None])
            assert np.all(np.isfinite(rep.q_filtered)) and rep.valid_share == pytest.approx(7 / 8)
        else:
            with pytest.raises(jh.InputError, match=message):
                tracker.step(state, [None])
    with pytest.raises(jh.InputError, match="fit.jacobian: expected one of autodiff, geometric"):
        TrackConfig(fit=FitConfig(jacobian="numeric"))
    with pytest.raises(jh.InputError, match="config.jacobian"):
        jh.fit(m, seq.cameras, good, seq.q[0], config=FitConfig(jacobian="numeric"))


@pytest.mark.parametrize("damp", [True, False])
def test_a_hidden_joint_is_not_carried_on(damp):
    """The middle DIP flexes at a steady rate for 20 frames, then its phalanx and tip are hidden
    (invalid) for 60 frames while the truth stands still: damped by its unseen share
    (FilterConfig.damp_unseen), its prediction stops within about v tau of where it was last
    seen; without, the g-h-k filter carries it on to its limit."""
    seq = make_preset("two_finger_occlusion", frames=5, size=(160, 120))
    m = seq.model
    dip, link = m.q_lookup("middle_dip"), m.link_lookup("middle_dip")
    tip = m.tip_links.index(link)
    dt = 1 / 25
    q = np.tile(seq.q[0], (80, 1))
    q[:, dip] = np.radians(-10.0) - np.radians(1.5) * np.minimum(np.arange(80), 20)   # -40 deg from frame 20
    exact = [features_from_pose(m, seq.cameras, qk)[0] for qk in q]

    def features(images, q_start, state, frame):
        f = exact[frame]
        if frame >= 20:
            f = eqx.tree_at(lambda g: (g.line_valid, g.tip_valid), f,
                            (f.line_valid.at[link].set(False), f.tip_valid.at[tip].set(False)))
        return (f,)

    tracker = Tracker(m, seq.cameras, FunctionFrontEnd(features), TrackConfig(filter=FilterConfig(damp_unseen=damp)),
                      dt_s=dt)
    state = tracker.init(q[0])
    for k in range(80):
        state, rep = tracker.step(state, [None], k)
    drift = np.degrees(float(state.ghk.x[dip]) - q[-1, dip])
    if damp:
        # 1.5 deg/frame kept at exp(-0.04 / 0.2) per frame sums to about 1.5 / (1 - 0.82) = 8 deg
        assert abs(drift) < 12.0
    else:
        assert drift < -20.0      # carried on towards the limit


@pytest.mark.parametrize("gain", [0.0, 0.5, 1.0])
def test_reported_solve_prediction_forgets_a_stop(gain):
    """A joint flexes at 6 deg per frame for 15 frames, then stands still; the solve is reported
    (FilterConfig.report_solve). With velocity_gain 1 the prediction is the last two estimates'
    straight line, exact again two frames after the stop; 0.5 halves its velocity each frame; with
    theta's gains (0) the velocity it had is forgotten only slowly, so the prediction overshoots."""
    m = jh.builtin_model("hand21")
    j = m.q_lookup("middle_pip")
    dt = 1 / 30
    steps = -np.radians(6.0) * np.minimum(np.arange(40), 15)   # hand21 flexes to negative angles
    ghk = jh.filter.ghk_init(jnp.zeros(m.n_q))
    over = []
    for k, angle in enumerate(steps):
        q_meas = jnp.zeros(m.n_q).at[j].set(angle)
        filtered, ghk = _filter_step(m, ghk, q_meas, jnp.asarray(0.873), jnp.asarray(dt), True, True,
                                     velocity_gain=jnp.asarray(gain))
        np.testing.assert_array_equal(np.asarray(filtered), np.asarray(q_meas))   # the solve is reported
        over.append(np.degrees(steps[min(k + 1, 39)] - float(ghk.x[j])))         # the next frame's prediction past it
    if gain == 1.0:
        assert np.abs(over[16:]).max() < 1e-9 and np.abs(over[1:14]).max() < 1e-9
        assert float(ghk.a[j]) == 0.0
    elif gain == 0.5:
        # the velocity at the stop is 1 - 0.5^15 of 6 deg per frame
        np.testing.assert_allclose(over[16:20], 6.0 * 0.5 ** np.arange(1, 5), rtol=1e-4)
    else:
        assert min(over[16:26]) > 1.5   # still carried on 10 frames after the stop


@pytest.mark.parametrize("ratio", [0.5, 2.0 / 3.0])
def test_a_hidden_dip_follows_the_coupling_ratio(ratio):
    """The middle DIP's phalanx and tip are hidden: with the DIP-PIP coupling
    (PriorConfig.dip_pip_weight) nothing else places it, so the solve sets it to dip_pip_ratio
    times its PIP."""
    seq = make_preset("two_finger_occlusion", frames=5, size=(160, 120))
    m = seq.model
    pip, dip, link = m.q_lookup("middle_pip"), m.q_lookup("middle_dip"), m.link_lookup("middle_dip")
    q = np.array(seq.q[0])
    q[pip], q[dip] = np.radians(-60.0), 0.0
    f = features_from_pose(m, seq.cameras, q)[0]
    f = eqx.tree_at(lambda g: (g.line_valid, g.tip_valid), f,
                    (f.line_valid.at[link].set(False), f.tip_valid.at[m.tip_links.index(link)].set(False)))
    config = TrackConfig(prior=jh.track.PriorConfig(dip_pip_weight=4.0, dip_pip_ratio=ratio))
    tracker = Tracker(m, seq.cameras, FunctionFrontEnd(lambda images, q_start, state, frame: (f,)), config,
                      dt_s=1 / 25)
    _, rep = tracker.step(tracker.init(q), [None], 0)
    assert abs(np.degrees(rep.q_solved[pip]) + 60.0) < 0.5
    assert abs(np.degrees(rep.q_solved[dip] - ratio * rep.q_solved[pip])) < 0.1
