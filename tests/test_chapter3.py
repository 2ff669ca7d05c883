import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxhand as jh
from jaxhand.examples import chapter3 as ch3
from jaxhand.features import features_from_pose
from jaxhand.residuals import ResidualArgs, cost, residual_jacobian, residuals

pytestmark = pytest.mark.slow   # end to end: left out of `make test-fast`


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """Run the module as its command line does, once; keep the output folder and the results."""
    out = tmp_path_factory.mktemp("chapter3")
    assert ch3.main(["--out", str(out)]) == 0
    results = {ex.key: ch3.run_example(ex) for ex in ch3.EXAMPLES}   # compiled already: fast
    return out, results


def _example(key):
    return next(e for e in ch3.EXAMPLES if e.key == key)


def _ours(result, k):
    return np.asarray(result.history_q)[k], float(np.asarray(result.history_cost)[k])


def _rr_args():
    ex = _example("RR")
    return ResidualArgs(model=jh.builtin_model("planar_rr"), cameras=(ch3.thesis_camera(),),
                        features=(ch3.thesis_features(ex),), fractions=jnp.asarray(ch3.FRACTIONS))


def test_the_module_writes_every_figure_and_the_tables(run):
    out, _ = run
    for name in ("fig3_17_pr_overlay", "fig3_23_rr_overlay", "fig3_27_rr_divergence_overlay",
                 "fig3_30_rr_eta_overlay", "fig3_31_rr_cost_surface"):
        path = out / f"{name}.png"
        assert path.exists() and path.stat().st_size > 10_000, name
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    text = (out / "tables.txt").read_text()
    for number in ("3.1", "3.2", "3.3", "3.4", "3.5", "3.6"):
        assert f"thesis Table {number}" in text


def test_rr_features_are_the_thesis_numbers_and_the_lines_through_the_ideal_links():
    ex = _example("RR")
    f = ch3.thesis_features(ex)
    np.testing.assert_allclose(np.asarray(f.lines), [[0.5, -0.866, 1.5], [1.0, 0.0, 7.3301]], atol=5e-5)
    exact = features_from_pose(jh.builtin_model("planar_rr"), ch3.thesis_camera(), np.array(ex.q_ideal))[0]
    sign = np.sign(np.asarray(exact.lines)[:, :1] * np.asarray(f.lines)[:, :1])
    np.testing.assert_allclose(sign * np.asarray(exact.lines), np.asarray(f.lines), atol=1e-12)
    np.testing.assert_allclose(np.asarray(exact.tips), np.asarray(f.tips), atol=1e-12)


@pytest.mark.parametrize("key, table", [("R", "3.1"), ("P", "3.2"), ("PR", "3.3")])
def test_r_p_pr_reproduce_thesis_tables_3_1_to_3_3(run, key, table):
    _, results = run
    t = ch3.THESIS_TABLES[table]
    r = results[key]
    assert r.status_name() == "ok"
    for k, q_t, H_t in zip(t.k, t.q, t.H):
        q, H = _ours(r, k)   # past the last iteration the history repeats the result
        np.testing.assert_allclose(q, q_t, atol=1.5e-4, err_msg=f"Table {table}, k={k}")
        if (table, k) != ("3.3", 5):
            assert abs(H - H_t) < 1.5e-4, (table, k, H, H_t)
    if table == "3.3":
        # Table 3.3 prints H = 0.0005 beside q_5 = (2.9998, -0.5237); H there is ~1e-8 (our k = 4
        # has H = 0.0005): the table's cost entry is one iteration late.
        assert _ours(r, 4)[1] == pytest.approx(0.0005, abs=5e-5)
        assert _ours(r, 5)[1] < 1e-6


def test_rr_tables_agree_on_the_start_and_first_step_and_on_the_cost_model(run):
    _, results = run
    H = jax.jit(cost)
    args = _rr_args()
    for table, key in (("3.4", "RR"), ("3.5", "RR divergence"), ("3.6", "RR eta=0.1")):
        t = ch3.THESIS_TABLES[table]
        r = results[key]
        q0, H0 = _ours(r, 0)
        np.testing.assert_allclose(q0, t.q[0], atol=1e-4)
        assert abs(H0 - t.H[0]) < 1e-4, (table, H0)
        # our cost at every iterate the thesis prints is the cost it prints (4-digit rounding of q)
        for q_t, H_t in zip(t.q, t.H):
            assert abs(float(H(jnp.asarray(q_t), args)) - H_t) < 2e-3 * max(1.0, H_t), (table, q_t)
    # the first update of Tables 3.5 and 3.6 is reproduced to the printed digits
    for table, key in (("3.5", "RR divergence"), ("3.6", "RR eta=0.1")):
        t = ch3.THESIS_TABLES[table]
        q1, H1 = _ours(results[key], 1)
        np.testing.assert_allclose(q1, t.q[1], atol=1e-4)
        assert abs(H1 - t.H[1]) < 1e-4
    # the initial divergence of Table 3.5: the first Gauss-Newton update raises the cost
    assert _ours(results["RR divergence"], 1)[1] > _ours(results["RR divergence"], 0)[1]


def test_rr_runs_end_where_exact_gauss_newton_must(run):
    _, results = run
    ideal = np.array(ch3._RR_IDEAL)
    for key in ("RR", "RR divergence", "RR eta=0.1", "RR adaptive eta"):
        r = results[key]
        assert r.status_name() == "ok", key
        np.testing.assert_allclose(np.asarray(r.q), ideal, atol=2e-4, err_msg=key)
    # eta = 0.1 converges linearly (error x 0.9 per step): about the thesis's 97 iterations
    assert 85 <= int(results["RR eta=0.1"].iterations) <= 115
    assert int(results["RR adaptive eta"].iterations) <= 15
    # Table 3.5 ends at (3.3974, -4.5082), where the gradient of this cost is far from zero: the
    # thesis's later iterates are not Gauss-Newton steps on this cost (README, "Chapter 3 examples")
    args = _rr_args()
    q_end = jnp.asarray(ch3.THESIS_TABLES["3.5"].q[-1])
    g = np.asarray(residual_jacobian(q_end, args)).T @ np.asarray(jax.jit(residuals)(q_end, args))
    assert np.linalg.norm(g) > 1.0
    assert math.isclose(ch3.FRACTIONS[0] * 5, 3.0) and math.isclose(ch3.FRACTIONS[1] * 5, 2.0)
