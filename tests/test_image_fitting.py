"""Hand-computed cases for the image front end's regressions (thesis app. D §11.3) and line fitting
(thesis §4.4): PLLS, MWPLLS, iMWPLLS, RANSAC + PCA, the axial line and its rules."""

import numpy as np
import pytest

from jaxhand.image.internal import (
    axial_line,
    imwplls,
    line_params,
    line_point_direction,
    mwplls,
    offset_towards,
    plls,
    ransac_pca,
    refine_tip,
)

# ---- PLLS (§11.3.1) ----


def test_plls_exact_line():
    c, ok = plls(np.arange(3.0), np.array([1.0, 3.0, 5.0]), np.ones(3, bool))
    assert ok and np.allclose(c, [1.0, 2.0])


def test_plls_least_squares_by_hand():
    # x = 0..3, y = (0, 1, 1, 3): mean (1.5, 1.25), Sxy = 4.5, Sxx = 5 -> c1 = 0.9, c0 = 1.25 - 1.35 = -0.1
    c, ok = plls(np.arange(4.0), np.array([0.0, 1.0, 1.0, 3.0]), np.ones(4, bool))
    assert ok and np.allclose(c, [-0.1, 0.9])


def test_plls_mask_drops_points_and_singular_is_flagged():
    y = np.array([1.0, 100.0, 5.0])
    c, ok = plls(np.arange(3.0), y, np.array([True, False, True]))
    assert ok and np.allclose(c, [1.0, 2.0])
    c, ok = plls(np.arange(3.0), y, np.array([True, False, False]))  # one point: no line
    assert not ok and np.all(c == 0)


def test_plls_batched():
    x = np.arange(4.0)
    y = np.stack([2 + 0.5 * x, -1 - x])
    c, ok = plls(x, y, np.ones((2, 4), bool))
    assert ok.all() and np.allclose(c, [[2, 0.5], [-1, -1]])


# ---- MWPLLS (§11.3.2) ----


def test_mwplls_two_curves_by_hand():
    # curve 0 (x=0): weights 1 at y=0 and y=1 -> sum w = 2, W_0 = (0 + 1) * 2 = 2
    # curve 1 (x=1): weights 1 at y=1 and y=2 -> sum w = 2, W_1 = (1 + 2) * 2 = 6
    # R = 4 [[1,0],[0,0]] + 4 [[1,1],[1,1]] = [[8,4],[4,4]], r = [8, 6] -> c = (0.5, 1)
    w = np.array([[1.0, 1.0, 0.0], [0.0, 1.0, 1.0]])
    c, ok = mwplls(np.arange(2.0), np.arange(3.0), w, np.ones(2, bool))
    assert ok and np.allclose(c, [0.5, 1.0])


def test_mwplls_weighs_curves_by_squared_mass():
    # centres of mass 0, 1, 3 with masses 1, 1, 2 -> weighted LS with weights 1, 1, 4:
    # R = [[6, 9], [9, 17]], r = [13, 25], det 21 -> c0 = -4/21, c1 = 33/21
    w = np.zeros((3, 5))
    w[0, 0] = w[1, 1] = w[2, 2] = w[2, 4] = 1.0
    c, ok = mwplls(np.arange(3.0), np.arange(5.0), w, np.ones(3, bool))
    assert ok and np.allclose(c, [-4 / 21, 33 / 21])


def test_mwplls_without_mass_is_singular():
    c, ok = mwplls(np.arange(3.0), np.arange(4.0), np.zeros((3, 4)), np.ones(3, bool))
    assert not ok and np.all(np.isfinite(c))


# ---- iMWPLLS (§11.3.3) ----


def test_imwplls_drops_a_far_spurious_peak():
    # every curve i peaks at y = i; curve 1 also has a spurious peak at y = 8.
    # MWPLLS by hand: centroids (0, 4.5, 2, 3), weights (1, 4, 1, 1): R = [[7, 9], [9, 17]],
    # r = [23, 31] -> c = (112/38, 10/38). Points within 3 of that line are exactly the true peaks
    # (the spurious one is 4.79 away), so the refit is y = x, which then stays put.
    ys = np.arange(9.0)
    w = np.zeros((4, 9))
    w[np.arange(4), np.arange(4)] = 1.0
    w[1, 8] = 1.0
    mask = np.ones(4, bool)
    c0, _ = mwplls(np.arange(4.0), ys, w, mask)
    assert np.allclose(c0, [112 / 38, 10 / 38])
    c, ok, iters = imwplls(np.arange(4.0), ys, w, mask, halfwidth=3.0, max_iter=10)
    assert ok and np.allclose(c, [0.0, 1.0]) and iters == 2


def test_imwplls_respects_iteration_cap():
    ys = np.arange(9.0)
    w = np.zeros((4, 9))
    w[np.arange(4), np.arange(4)] = 1.0
    w[1, 8] = 1.0
    c, ok, iters = imwplls(np.arange(4.0), ys, w, np.ones(4, bool), halfwidth=3.0, max_iter=1)
    assert iters == 1 and np.allclose(c, [0.0, 1.0])


# ---- RANSAC + PCA (§4.4) ----


def test_ransac_pca_rejects_outlier_and_refines():
    pts = np.array([[0.0, 2.0], [2.0, 3.0], [4.0, 4.0], [3.0, 10.0], [6.0, 5.0]])  # (3, 10) is off y = 2 + x/2
    p, v, ok, inl = ransac_pca(pts, np.ones(5, bool), tau_px=0.5, min_inliers=3)
    assert ok
    assert inl.tolist() == [True, True, True, False, True]
    assert np.allclose(p, [3.0, 3.5])  # centre of mass of the inliers
    assert np.isclose(abs(v @ np.array([2.0, 1.0]) / np.sqrt(5)), 1.0)


def test_ransac_pca_total_least_squares_by_hand():
    # symmetric scatter about y = 0: PCA gives the x axis through the centroid (1.5, 0)
    pts = np.array([[0.0, 0.1], [1.0, -0.1], [2.0, -0.1], [3.0, 0.1]])
    p, v, ok, inl = ransac_pca(pts, np.ones(4, bool), tau_px=0.5, min_inliers=2)
    assert ok and inl.all() and np.allclose(p, [1.5, 0.0]) and np.isclose(abs(v[0]), 1.0)


def test_ransac_pca_ties_go_to_the_first_pair():
    # two groups of two points, each pair alone on its line: pair (0, 1) comes first
    pts = np.array([[0.0, 0.0], [1.0, 0.0], [3.0, 5.0], [4.0, 7.0]])
    p, v, ok, inl = ransac_pca(pts, np.ones(4, bool), tau_px=0.1, min_inliers=2)
    assert ok and inl.tolist() == [True, True, False, False]


def test_ransac_pca_needs_enough_inliers_and_valid_points():
    pts = np.array([[0.0, 0.0], [1.0, 0.0], [5.0, 5.0], [9.0, -3.0]])
    _, _, ok, inl = ransac_pca(pts, np.ones(4, bool), tau_px=0.1, min_inliers=3)
    assert not ok and not inl.any()
    valid = np.array([True, False, False, False])
    p, v, ok, _ = ransac_pca(pts, valid, tau_px=1.0, min_inliers=2)
    assert not ok and np.all(np.isfinite(p)) and np.all(np.isfinite(v))
    dup = np.zeros((3, 2))  # coincident points define no line
    _, _, ok, _ = ransac_pca(dup, np.ones(3, bool), tau_px=1.0, min_inliers=2)
    assert not ok


# ---- axial line (§4.4, eqs. 4.2-4.4) ----


def test_axial_line_parallel_boundaries_use_the_midpoint():
    # y = 0 and y = 2 with opposite directions: |v1 + v2| = 0 < |v1 - v2| picks (v1 - v2)/2, det V = 0
    p, v = axial_line(np.array([0.0, 0.0]), np.array([1.0, 0.0]), np.array([5.0, 2.0]), np.array([-1.0, 0.0]))
    assert np.allclose(p, [2.5, 1.0]) and np.allclose(v, [1.0, 0.0])


def test_axial_line_crossing_boundaries_meet_at_the_intersection():
    a = np.radians(10.0)
    v1, v2 = np.array([np.cos(a), np.sin(a)]), np.array([np.cos(a), -np.sin(a)])
    p, v = axial_line(10 * v1, v1, 5 * v2, v2)  # both lines pass through the origin
    assert np.allclose(p, [0.0, 0.0], atol=1e-12) and np.allclose(v, [1.0, 0.0])


def test_axial_line_direction_rule_and_tie():
    a = np.radians(10.0)
    v1, v2 = np.array([np.cos(a), np.sin(a)]), -np.array([np.cos(a), -np.sin(a)])  # v2 flipped
    _, v = axial_line(np.zeros(2), v1, np.array([0.0, 1.0]), v2)
    assert np.allclose(v, [0.0, 1.0]) or np.allclose(np.abs(v), [1.0, 0.0])
    # |v1 + v2| = |v1 - v2| for perpendicular lines: the rule's ">=" takes the sum, the 45-degree bisector
    _, v = axial_line(np.zeros(2), np.array([1.0, 0.0]), np.zeros(2), np.array([0.0, 1.0]))
    assert np.allclose(v, [np.sqrt(0.5), np.sqrt(0.5)])


def test_axial_line_flipped_direction_still_bisects():
    a = np.radians(10.0)
    v1, v2 = np.array([np.cos(a), np.sin(a)]), np.array([np.cos(a), -np.sin(a)])
    _, v = axial_line(10 * v1, v1, -5 * v2, -v2)  # v2 reversed: the rule picks (v1 - v2)/2
    assert np.allclose(np.abs(v), [1.0, 0.0])


def test_axial_line_determinant_threshold():
    v1 = np.array([1.0, 0.0])
    p1, p2 = np.array([0.0, 0.0]), np.array([0.0, 2.0])
    for s, expect_mid in ((1e-10, True), (1e-8, False)):  # |det V| = s
        v2 = np.array([np.sqrt(1 - s * s), s])
        p, _ = axial_line(p1, v1, p2, v2, det_eps=1e-9)
        if expect_mid:
            assert np.allclose(p, [0.0, 1.0])
        else:  # the lines meet at x = -2 / s far away; the point lies on the first line there
            assert np.isclose(p[1], 0.0) and np.isclose(p[0], -2.0 / s * np.sqrt(1 - s * s), rtol=1e-6)


def test_line_params_and_back():
    lines = line_params(np.array([0.0, 2.0]), np.array([1.0, 0.0]))
    assert np.allclose(lines, [0.0, -1.0, -2.0])  # 0 x - y = -2, i.e. y = 2
    flipped = line_params(np.array([0.0, 2.0]), np.array([-3.0, 0.0]), reference=np.array([1.0, 0.1]))
    assert np.allclose(flipped, lines)
    p, v = line_point_direction(lines)
    assert np.allclose(line_params(p, v), lines) and np.isclose(p @ lines[:2], lines[2])


def test_offset_towards_the_predicted_axis():
    p = offset_towards(np.array([0.0, 0.0]), np.array([1.0, 0.0]), np.array([7.0, 5.0]), np.array(3.0))
    assert np.allclose(p, [0.0, 3.0])
    p = offset_towards(np.array([0.0, 0.0]), np.array([1.0, 0.0]), np.array([7.0, -5.0]), np.array(3.0))
    assert np.allclose(p, [0.0, -3.0])


def test_refine_tip_eq_4_1():
    tip, v0 = refine_tip(np.array([3.0, 4.0]), np.array([0.0, 0.0]), np.array([2.0, 0.0]))
    assert np.allclose(tip, [3.0, 0.0]) and np.allclose(v0, [1.0, 0.0])
    tip, v0 = refine_tip(np.array([3.0, 4.0]), np.array([1.0, 1.0]), np.array([0.0, 0.0]))  # no direction
    assert np.allclose(tip, [1.0, 1.0]) and np.all(np.isfinite(v0))


@pytest.mark.parametrize("seed", [0, 1])
def test_ransac_pca_matches_slow_reference(seed):
    rng = np.random.default_rng(seed)
    pts = rng.normal(0, 1, (6, 2, 7, 2)) * [5.0, 0.3] + rng.normal(0, 0.05, (6, 2, 7, 2))
    pts[..., 3, 1] += rng.choice([0.0, 4.0], (6, 2))  # some outliers
    valid = rng.random((6, 2, 7)) > 0.15
    p, v, ok, inl = ransac_pca(pts, valid, tau_px=0.4, min_inliers=3)
    for a in range(6):
        for b in range(2):
            P, V = pts[a, b], valid[a, b]
            best, best_in = -1, None
            for i in range(7):
                for j in range(i + 1, 7):
                    d = P[j] - P[i]
                    if not (V[i] and V[j]) or np.linalg.norm(d) <= 1e-9:
                        continue
                    n = np.array([-d[1], d[0]]) / np.linalg.norm(d)
                    inside = V & (np.abs((P - P[i]) @ n) < 0.4)
                    if inside.sum() > best:
                        best, best_in = inside.sum(), inside
            assert ok[a, b] == (best >= 3)
            if ok[a, b]:
                assert (inl[a, b] == best_in).all()
                Y = P[best_in]
                w, E = np.linalg.eigh(np.cov(Y.T))
                assert np.allclose(p[a, b], Y.mean(0))
                assert np.isclose(abs(v[a, b] @ E[:, 1]), 1.0)
