import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from _params import model_params
from helpers import CompileCounter, fit_camera
from hypothesis import given, settings
from hypothesis import strategies as st

import jaxhand as jh
from jaxhand.features import Features, features_from_pose
from jaxhand.residuals import make_residual_args, residual_jacobian, residuals
from jaxhand.solve import (
    SOLVERS,
    FitConfig,
    StateSpace,
    Status,
    features_from_poses,
    solve_least_squares,
    status_name,
)
from jaxhand.solve._damped import make_damped_gauss_newton
from jaxhand.solve.gauss_newton import gauss_newton_config
from jaxhand.solve.levenberg_marquardt import make_levenberg_marquardt

# One static config for the solver-by-model grid and the tests that can share its compilations.
GRID = FitConfig(history=True)
N_PROBLEMS = 200


def oblique_rig(model):
    """Two orthographic cameras with different oblique view rotations (a single view leaves the
    hands' flexion and the free palm's depth undetermined; see README)."""
    from scipy.spatial.transform import Rotation

    return tuple(fit_camera(model, R=Rotation.from_euler("xyz", e, degrees=True).as_matrix())
                 for e in ((40, 25, 0), (-35, -30, 10)))


def thesis_camera():
    return jh.Orthographic(R=np.eye(3), t=np.zeros(3), scale=1.0, center=[3.0, 0.0], size=(32, 32))


def rig_for(model):
    # The planar chains of thesis §3.2 move in the image plane: one camera determines them.
    return (thesis_camera(),) if model.name.startswith("planar") else oblique_rig(model)


def perturb(model, Q, sigma_deg, rng, sigma_mm=5.0):
    """Starts: every angle + N(0, sigma), every length + N(0, sigma_mm * sigma/5deg), the free
    palm's quaternion turned by a random rotation of N(0, sigma) per axis; clipped to the limits."""
    Q0 = np.array(Q, dtype=float)
    s = np.radians(sigma_deg)
    kinds = np.array(model.q_kinds)
    Q0[:, kinds == "angle"] += rng.normal(0, s, Q0[:, kinds == "angle"].shape)
    Q0[:, kinds == "length"] += rng.normal(0, sigma_mm * sigma_deg / 5.0, Q0[:, kinds == "length"].shape)
    if model.base_kind == "free":
        from scipy.spatial.transform import Rotation

        turn = Rotation.from_rotvec(rng.normal(0, s, (len(Q0), 3)))
        base = Rotation.from_quat(Q0[:, [1, 2, 3, 0]])   # scipy: (x, y, z, w)
        Q0[:, :4] = (turn * base).as_quat()[:, [3, 0, 1, 2]]
    Q0 = np.clip(Q0, np.asarray(model.q_lower), np.asarray(model.q_upper))
    if model.base_kind == "free":
        Q0[:, :4] /= np.linalg.norm(Q0[:, :4], axis=-1, keepdims=True)
    return Q0


def joint_error(model, q, q_true):
    """Largest |q - q_true| per problem, the quaternion compared up to its sign."""
    d = np.abs(q - q_true)
    if model.base_kind == "free":
        d[:, :4] = np.minimum(d[:, :4], np.abs(q[:, :4] + q_true[:, :4]))
    return d.max(axis=-1)


@functools.cache
def problems(name, n=N_PROBLEMS, sigma_deg=5.0, noise_px=0.0, seed=0):
    m = jh.builtin_model(name)
    rng = np.random.default_rng(seed)
    Q = jh.random_q(m, rng, n)
    rig = rig_for(m)
    return m, rig, Q, features_from_poses(m, rig, Q, noise_px=noise_px, rng=rng), perturb(m, Q, sigma_deg, rng)


# gn, gn_eta and lm_fixed share one compiled program, so they run in the same test.
PROGRAMS = [("gn", "gn_eta", "lm_fixed"), ("lm",), ("bounded",)]


@pytest.mark.parametrize("solvers", PROGRAMS, ids=lambda s: "+".join(s))
@pytest.mark.parametrize("name", model_params(jh.builtin_names(), fast=("two_fingers", "index_thumb", "planar_rr")))
def test_every_solver_fits_noise_free_problems_exactly_and_recovers_the_truth(name, solvers):
    m, rig, Q, F, Q0 = problems(name)
    lo, hi = np.asarray(m.q_lower), np.asarray(m.q_upper)
    for solver in solvers:
        r = jh.fit_batch(m, rig, F, Q0, solver=solver, config=GRID)
        q, H = np.asarray(r.q), np.asarray(r.cost)
        assert np.all(np.isfinite(q)) and np.all(np.isfinite(np.asarray(r.history_q)))
        exact = H < 1e-10
        err = joint_error(m, q, Q)
        assert exact.mean() >= 0.98, (solver, exact.mean())
        # two views (one for the planar chains) determine every DOF: the exact fits are the truth
        assert (exact & (err < 1e-6)).mean() >= 0.98, (solver, np.sort(err)[-5:])
        assert (np.asarray(r.status == Status.ok) & exact).mean() >= 0.98, solver
        hist = np.asarray(r.history_q)
        if m.base_kind == "free":   # the quaternion has unit norm at every iterate
            np.testing.assert_allclose(np.linalg.norm(hist[..., :4], axis=-1), 1.0, atol=1e-12)
        if solver == "bounded":     # ... and the bounded solver never leaves the limits
            box = StateSpace.of(m).bounded
            assert np.all(hist[..., box] >= lo[box]) and np.all(hist[..., box] <= hi[box])


@pytest.mark.slow
def test_solvers_agree_with_each_other_and_with_scipy_on_noisy_features():
    from scipy.optimize import least_squares

    m, rig, Q, F, Q0 = problems("index_thumb", noise_px=0.5, seed=1)   # grid shapes: no new compile
    results = {s: jh.fit_batch(m, rig, F, Q0, solver=s, config=GRID) for s in SOLVERS}
    ok = np.all([np.asarray(r.status == Status.ok) for r in results.values()], axis=0)
    assert ok.mean() >= 0.95
    ref = np.asarray(results["lm"].q)
    assert np.abs(ref - Q).max() < np.radians(5)  # 0.5 px noise: close to the truth, not on it
    # with noise the unconstrained optimum can lie beyond a limit; there the bounded solver
    # rightly differs, so it is compared where the unconstrained optimum is inside the box
    inside = np.all((ref > np.asarray(m.q_lower)) & (ref < np.asarray(m.q_upper)), axis=-1)
    assert inside.mean() > 0.8
    for s, r in results.items():
        same = ok & inside if s == "bounded" else ok
        assert np.abs(np.asarray(r.q)[same] - ref[same]).max() < 1e-6, s
    # scipy's MINPACK Levenberg-Marquardt on the same residuals and Jacobian
    res = jax.jit(residuals)
    jac = jax.jit(residual_jacobian)
    for i in range(5):
        args = make_residual_args(m, rig, [jax.tree_util.tree_map(lambda x, i=i: x[i], f) for f in F])
        sol = least_squares(lambda q, a=args: np.asarray(res(jnp.asarray(q), a)), Q0[i], method="lm",
                            jac=lambda q, a=args: np.asarray(jac(jnp.asarray(q), a)), xtol=1e-14, ftol=1e-14)
        np.testing.assert_allclose(ref[i], sol.x, atol=1e-6)


# ---- bounded solver ----

def _index_problem(q_true, R_deg=((40, 25, 0), (-35, -30, 10))):
    from scipy.spatial.transform import Rotation

    m = jh.builtin_model("index")
    rig = tuple(fit_camera(m, R=Rotation.from_euler("xyz", e, degrees=True).as_matrix()) for e in R_deg)
    return m, rig, features_from_pose(m, rig, np.asarray(q_true, float))


@settings(max_examples=8, deadline=None)
@given(seed=st.integers(0, 10_000), outside=st.booleans())
def test_bounded_solver_never_leaves_the_box(seed, outside):
    rng = np.random.default_rng(seed)
    m, _, _ = _index_problem(np.zeros(3))
    lo, hi = np.asarray(m.q_lower), np.asarray(m.q_upper)
    q_true = jh.random_q(m, rng)
    if outside:   # features from a pose beyond the limits pull the fit against them
        q_true = q_true + rng.choice([-1, 1], 3) * np.radians(40)
    m, rig, feats = _index_problem(q_true)
    q0 = rng.uniform(lo, hi)
    r = jh.fit(m, rig, feats, q0, solver="bounded", config=GRID)
    hist = np.asarray(r.history_q)
    assert np.all(np.isfinite(hist))
    assert np.all(hist >= lo) and np.all(hist <= hi)


def test_bounded_solver_finds_the_constrained_optimum():
    from scipy.optimize import least_squares

    # dip at +25 deg lies beyond its upper limit (0 deg): the features are exact at q_true, so the
    # unconstrained optimum (H = 0) is outside the box
    q_true = np.radians([-20.0, -30.0, 25.0])
    m, rig, feats = _index_problem(q_true)
    q0 = np.radians([-10.0, -15.0, -10.0])
    r = jh.fit(m, rig, feats, q0, solver="bounded", config=GRID)
    assert r.status_name() == "ok"
    q = np.asarray(r.q)
    hi = np.asarray(m.q_upper)
    assert abs(q[2] - hi[2]) < 1e-8              # dip on its bound
    args = make_residual_args(m, rig, feats)
    res = jax.jit(residuals)
    jac = jax.jit(residual_jacobian)
    g = np.asarray(jac(jnp.asarray(q), args)).T @ np.asarray(res(jnp.asarray(q), args))
    assert np.abs(g[:2]).max() < 1e-6 * max(1.0, abs(g[2]))   # stationary in the free joints
    assert g[2] < 0                                # and H would fall beyond the bound (KKT sign)
    ref = least_squares(lambda x: np.asarray(res(jnp.asarray(x), args)), q0, method="trf",
                        jac=lambda x: np.asarray(jac(jnp.asarray(x), args)),
                        bounds=(np.asarray(m.q_lower), hi), xtol=1e-15, ftol=1e-15, gtol=1e-15)
    np.testing.assert_allclose(q, ref.x, atol=1e-6)
    assert float(r.cost) <= ref.cost * (1 + 1e-9) + 1e-12


# ---- degenerate problems: finite q and an honest status ----

def _mask_link_everywhere(feats, link, tip):
    """Every camera's line of ``link`` and tip ``tip`` invalid (and NaN, which must not leak)."""
    return tuple(Features(lines=f.lines.at[..., link, :].set(jnp.nan),
                          line_valid=f.line_valid.at[..., link].set(False), line_weight=f.line_weight,
                          tips=f.tips.at[..., tip, :].set(jnp.nan), tip_valid=f.tip_valid.at[..., tip].set(False),
                          tip_weight=f.tip_weight) for f in feats)


@pytest.mark.parametrize("solvers", PROGRAMS, ids=lambda s: "+".join(s))
def test_a_link_with_every_feature_masked_gives_singular_and_leaves_its_joint_alone(solvers):
    m, rig, Q, F, Q0 = problems("index")        # the grid's shapes: its compilations are reused
    masked = _mask_link_everywhere(F, m.link_lookup("index_dip"), 0)
    dip = m.q_lookup("index_dip")
    for solver in solvers:
        r = jh.fit_batch(m, rig, masked, Q0, solver=solver, config=GRID)
        q = np.asarray(r.q)
        assert np.all(np.isfinite(q)) and np.all(np.isfinite(np.asarray(r.cost)))
        ok = np.asarray(r.converged)
        assert ok.mean() >= 0.98 and np.all(status_name(r.status)[ok] == "singular"), solver
        assert np.all(np.asarray(r.rank)[ok] == 2)
        # the unobserved joint keeps its start (which the bounded solver first moves 1e-10 inside)
        np.testing.assert_allclose(q[:, dip], Q0[:, dip], atol=2e-10 if solver == "bounded" else 1e-12)
        others = np.arange(3) != dip
        assert (np.abs(q[:, others] - Q[:, others]).max(-1) < 1e-6).mean() >= 0.98, solver


@pytest.mark.slow
def test_a_rank_deficient_view_gives_singular_not_nan():
    # mouse3d seen from above: the index flexes along the viewing direction, so its link lines
    # cannot see the flexion and only the tip constrains it (rank 6 of 8 at every pose). The
    # second camera of the grid's rig sees nothing (all features masked): same shapes, same
    # compiled programs.
    m, rig, Q, F, Q0 = problems("mouse3d")
    top = fit_camera(m)
    rig = (top, rig[1])
    F = features_from_poses(m, rig, Q)
    blind = Features(lines=F[1].lines, line_valid=jnp.zeros_like(F[1].line_valid), line_weight=F[1].line_weight,
                     tips=F[1].tips, tip_valid=jnp.zeros_like(F[1].tip_valid), tip_weight=F[1].tip_weight)
    for solver in SOLVERS:
        r = jh.fit_batch(m, rig, (F[0], blind), Q0, solver=solver, config=GRID)
        assert np.all(np.isfinite(np.asarray(r.q))), solver
        exact = np.asarray(r.cost) < 1e-10
        assert exact.mean() >= 0.98, solver                                  # fits the data exactly ...
        assert np.all(np.asarray(r.rank)[exact] == 6), solver
        assert np.all(status_name(r.status)[exact] == "singular"), solver    # ... and says it is not unique


def _scalar_space():
    return StateSpace(lower=jnp.array([-jnp.inf]), upper=jnp.array([jnp.inf]), is_length=(False,),
                      has_quaternion=False, dof=1)


def test_a_nonfinite_solve_returns_the_start_and_says_so():
    # r = sqrt(q) + 1: the Gauss-Newton step from q = 1 lands on q = -3, where r is NaN
    def fn(q, args):
        return jnp.sqrt(q) + 1.0

    cfg = FitConfig(history=True, max_steps=10)
    solver = make_damped_gauss_newton(gauss_newton_config(FitConfig()), _scalar_space())
    r = jax.jit(lambda q0: solve_least_squares(fn, solver, q0, None, _scalar_space(), cfg))(jnp.array([1.0]))
    assert status_name(r.status) == "nonfinite" and not bool(r.converged)
    assert float(r.q[0]) == 1.0 and float(r.cost) == 2.0
    assert np.all(np.isfinite(np.asarray(r.history_q))) and np.all(np.isfinite(np.asarray(r.history_cost)))


def test_a_diverging_solve_returns_the_start_and_says_so():
    # r = cbrt(q): each Gauss-Newton step maps q to -2 q, so H grows by 2^(2/3) per step
    def fn(q, args):
        return jnp.cbrt(q)

    cfg = FitConfig(max_steps=50, divergence_factor=1e3)
    solver = make_damped_gauss_newton(gauss_newton_config(FitConfig()), _scalar_space())
    r = jax.jit(lambda q0: solve_least_squares(fn, solver, q0, None, _scalar_space(), cfg))(jnp.array([1.0]))
    assert status_name(r.status) == "diverged" and not bool(r.converged)
    assert float(r.q[0]) == 1.0 and float(r.cost) == 0.5
    assert 10 <= int(r.iterations) < 50
    # the trust region refuses those steps and converges to the minimum at 0
    lm = make_levenberg_marquardt(FitConfig(), _scalar_space())
    r = jax.jit(lambda q0: solve_least_squares(fn, lm, q0, None, _scalar_space(), FitConfig(max_steps=200)))(
        jnp.array([1.0]))
    assert abs(float(r.q[0])) < 1e-6 and np.isfinite(float(r.cost))


# ---- the thesis's fast mode, compilation, input validation ----

@pytest.mark.slow
def test_fast_mode_is_exactly_one_gauss_newton_update():
    m = jh.builtin_model("planar_rr")
    q_true = np.array([-np.pi / 3, -np.pi / 2 - np.pi / 6])
    feats = features_from_pose(m, thesis_camera(), q_true)
    q0 = np.radians([-42.0, -102.0])
    r = jh.fit(m, thesis_camera(), feats, q0, solver="gn", config=FitConfig(max_steps=1))
    args = make_residual_args(m, thesis_camera(), feats)
    J = np.asarray(residual_jacobian(jnp.asarray(q0), args))
    q1 = q0 - np.linalg.pinv(J) @ np.asarray(residuals(jnp.asarray(q0), args))   # thesis eq. 3.4
    np.testing.assert_allclose(np.asarray(r.q), q1, atol=1e-12)
    assert int(r.iterations) == 1 and r.status_name() == "max_steps" and not bool(r.converged)
    assert float(r.cost) < float(r.start_cost)


def test_new_features_starts_and_tolerances_do_not_recompile():
    m, rig, Q, F, Q0 = problems("index")
    m2, rig2, Q2, F2, Q02 = problems("index", n=N_PROBLEMS, seed=7)
    one = [jax.tree_util.tree_map(lambda x: x[0], f) for f in F]
    jh.fit_batch(m, rig, F, Q0, solver="lm", config=GRID)
    jh.fit(m, rig, one, Q0[0], solver="bounded", config=GRID)
    with CompileCounter() as counter:
        r = jh.fit_batch(m, rig2, F2, Q02, solver="lm", config=GRID)
        jh.fit_batch(m, rig, F, Q0, solver="lm", config=FitConfig(history=True, xtol=1e-8, mu=0.1))
        for i in range(3):
            jh.fit(m, rig2, [jax.tree_util.tree_map(lambda x, i=i: x[i], f) for f in F2], Q02[i], solver="bounded",
                   config=GRID)
    assert counter.count == 0
    assert np.asarray(r.cost).max() < 1e-10


def test_inputs_are_validated_at_the_boundary():
    m, rig, feats = _index_problem(np.radians([-20.0, -30.0, -25.0]))
    q0 = np.zeros(3)
    with pytest.raises(jh.InputError, match="unknown solver 'newton'; valid solvers: gn, gn_eta, lm_fixed, lm, "
                                            "bounded"):
        jh.fit(m, rig, feats, q0, solver="newton")
    with pytest.raises(jh.InputError, match=r"q0: expected shape \(3,\)"):
        jh.fit(m, rig, feats, np.zeros(4))
    with pytest.raises(jh.InputError, match="non-finite value for 'index_pip'"):
        jh.fit(m, rig, feats, np.array([0.0, np.nan, 0.0]))
    with pytest.raises(jh.InputError, match="one Features per camera"):
        jh.fit(m, rig, feats[0], q0)
    with pytest.raises(jh.InputError, match="config.mu"):
        jh.fit(m, rig, feats, q0, config=FitConfig(mu=0.0))
    with pytest.raises(jh.InputError, match="config.max_steps"):
        jh.fit(m, rig, feats, q0, config=FitConfig(max_steps=0))
    _, _, _, F, Q0 = problems("index")
    with pytest.raises(jh.InputError, match=r"q0: expected shape \(200, 3\) or \(3,\)"):
        jh.fit_batch(m, rig, F, Q0[:5])
    short = (F[0], jax.tree_util.tree_map(lambda x: x[:5], F[1]))
    with pytest.raises(jh.InputError, match="batch size 5 differs from 200"):
        jh.fit_batch(m, rig, short, Q0)
    with pytest.raises(jh.InputError, match=r"expected shape \(B, 3, 3\)"):
        jh.fit_batch(m, rig, feats, Q0)


@pytest.mark.slow
def test_non_unit_start_quaternions_are_normalised():
    m, rig, Q, F, Q0 = problems("hand27")
    Q0 = Q0.copy()
    Q0[:, :4] *= np.linspace(0.2, 5.0, len(Q0))[:, None]
    r = jh.fit_batch(m, rig, F, Q0, solver="lm", config=GRID)
    np.testing.assert_allclose(np.linalg.norm(np.asarray(r.history_q)[..., :4], axis=-1), 1.0, atol=1e-12)
    assert (joint_error(m, np.asarray(r.q), Q) < 1e-6).mean() >= 0.98
