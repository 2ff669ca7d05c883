"""The image front end's fast paths give the same answers as the straightforward shapely / NumPy
versions they replace: the point-in-outline test against shapely unions, the WSSD valley descent
against a plain PLLS loop, the lazily converted window outlines against the eager list, and the
front end's compiled kinematics against :func:`jaxhand.kinematics.project_pose`."""

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pytest
import shapely

from jaxhand.image import ImageConfig, WindowOutlines, extract_features
from jaxhand.image.internal import (
    CameraContext,
    Clock,
    as_grey,
    compute_visibility,
    convex_edges,
    inside_polygons,
    observe,
    off_other_links,
    pill_outlines,
    plls,
    predicted_geometry,
    row_unions,
    same_chain,
    window_masks,
)
from jaxhand.image.internal import wssd_descend as _descend
from jaxhand.kinematics import project_pose
from jaxhand.render import RenderConfig, make_preset, render_frame
from jaxhand.track import ImageFrontEnd


def _off_other_links_union(obs, points, links=None):
    """The reference for :func:`_off_other_links`: one shapely union of the other outlines per link."""
    outlines = obs.visibility.outlines
    L = len(outlines)
    links = np.arange(L) if links is None else np.asarray(links, int)
    present = ~shapely.is_empty(outlines)
    others = np.array([shapely.union_all(outlines[present & (np.arange(L) != i)]) for i in links], dtype=object)
    return ~window_masks(others, points)


def _frames(name, frames, picks):
    seq = make_preset(name, frames=frames)
    out = []
    for i in picks:
        q = seq.q[i]
        images = [render_frame(seq.model, cam, q, RenderConfig(antialias=3)).image for cam in seq.cameras]
        out.append((q, images))
    return seq, out


@pytest.fixture(scope="module")
def two_fingers():
    # Orthographic, the fingers crossing in the middle of the motion.
    return _frames("two_finger_occlusion", 80, [0, 30, 40, 55])


@pytest.fixture(scope="module")
def hand27():
    # 27 DOF under two perspective cameras: each end circle has its own radius.
    return _frames("two_camera_hand", 40, [0, 20, 39])


def _observations(data, q_offset_deg=0.0):
    seq, frames = data
    config = ImageConfig()
    chain = same_chain(seq.model.link_frame, seq.model.ancestors)
    rng = np.random.default_rng(0)
    for q, images in frames:
        q = q + np.where(seq.model.is_angle, np.radians(q_offset_deg) * rng.standard_normal(len(q)), 0.0)
        for cam, image in zip(seq.cameras, images):
            yield observe(CameraContext(grey=as_grey(image), model=seq.model, camera=cam, chain=chain, config=config,
                                        clock=Clock()), q)


def _probe_points(obs):
    """Every profile sample, the background probes either side of every profile (1.1-1.4 radii)
    and points along each link's axis and outline edges: many lie on or near another outline."""
    s = obs.samplers
    at = np.array([-1.4, -1.25, -1.1, -1.0, 1.0, 1.1, 1.25, 1.4])
    probes = s.centres[:, :, None, :] + (s.radius_px[:, None] * at)[:, None, :, None] * s.normal[:, None, None, :]
    L = len(s.ok)
    return np.concatenate([s.points.reshape(L, -1, 2), probes.reshape(L, -1, 2)], 1)


@pytest.mark.parametrize("data_name", ["two_fingers", "hand27"])
@pytest.mark.parametrize("offset_deg", [0.0, 6.0])
def test_off_other_links_equals_the_shapely_union(request, data_name, offset_deg):
    data = request.getfixturevalue(data_name)
    n_off = n_on = 0
    for obs in _observations(data, offset_deg):
        pts = _probe_points(obs)
        fast = off_other_links(obs, pts)
        ref = _off_other_links_union(obs, pts)
        np.testing.assert_array_equal(fast, ref)
        n_off, n_on = n_off + int(fast.sum()), n_on + int((~fast).sum())
        # a subset of links (the tips' use)
        tl = np.array([len(obs.start) - 1, 0])
        np.testing.assert_array_equal(off_other_links(obs, pts[tl], tl), _off_other_links_union(obs, pts[tl], tl))
    assert n_off > 100 and n_on > 100  # the test covers both answers


def test_inside_polygons_equals_contains_xy():
    rng = np.random.default_rng(1)
    circle = np.stack([np.cos(np.linspace(0, 2 * np.pi, 17)[:-1]), np.sin(np.linspace(0, 2 * np.pi, 17)[:-1])], -1)
    convex = [shapely.Polygon(c + r * circle) for c, r in (((10.0, 10.0), 5.0), ((14.0, 12.0), 3.0), ((0.0, 0.0), 1.0))]
    cw = shapely.Polygon(np.array([[0.0, 0.0], [0.0, 4.0], [4.0, 4.0], [4.0, 0.0]]))  # clockwise square
    polys = np.array(convex + [cw, shapely.Polygon()], dtype=object)
    pts = np.concatenate([rng.uniform(-2, 20, (3000, 2)),
                          shapely.get_coordinates(polys),        # vertices: on the boundary
                          [[2.0, 0.0], [4.0, 2.0], [2.0, 2.0], [np.nan, 1.0]]])
    shapely.prepare(polys)
    ref = shapely.contains_xy(polys[None, :], np.nan_to_num(pts[:, 0])[:, None], np.nan_to_num(pts[:, 1])[:, None])
    ref &= np.all(np.isfinite(pts), -1)[:, None]
    got = inside_polygons(polys, pts)
    np.testing.assert_array_equal(got, ref)
    assert got[:-4].any() and not got[-4:-2].any() and got[-2, 3] and not got[-1].any()
    # a non-convex polygon is left to shapely
    ell = np.array([shapely.Polygon([(0, 0), (4, 0), (4, 1), (1, 1), (1, 4), (0, 4)])], dtype=object)
    assert convex_edges(ell) is None
    np.testing.assert_array_equal(inside_polygons(ell, np.array([[0.5, 3.0], [3.0, 3.0], [3.0, 0.5]])),
                                  [[True], [False], [True]])


def _descend_reference(W, curve_ok, S, max_iter):
    """The valley descent of thesis §4.3.2 written plainly, one PLLS call per iteration."""
    L, M, K = W.shape
    x = np.arange(M, dtype=float)
    finite = np.isfinite(W)
    wall = np.where(finite, W, -np.inf).max(initial=0.0) * 2 + 1.0
    Wf = np.where(finite, W, wall)
    yhat = np.zeros((L, M), int)
    fit_ok = curve_ok.sum(-1) >= 2
    active = fit_ok.copy()
    for _ in range(max_iter):
        if not active.any():
            break
        k = yhat + S
        up = np.take_along_axis(Wf, np.minimum(k + 1, K - 1)[..., None], -1)[..., 0]
        down = np.take_along_axis(Wf, np.maximum(k - 1, 0)[..., None], -1)[..., 0]
        c, ok = plls(x, yhat - np.sign(up - down), curve_ok)
        new = np.clip(np.rint(c[:, 0, None] + c[:, 1, None] * x), -S, S).astype(int)
        step = active & ok
        changed = np.any((new != yhat) & curve_ok, axis=-1)
        yhat = np.where(step[:, None], new, yhat)
        fit_ok = fit_ok & np.where(active, ok, True)
        active = step & changed
    return yhat, fit_ok


@pytest.mark.parametrize("seed", [2, 3, 4])
def test_wssd_descent_equals_the_plain_loop(seed):
    # Noisy surfaces make the rounded lines of some links cycle, which the fast descent
    # resolves at once; the result after any number of steps must be the plain loop's.
    rng = np.random.default_rng(seed)
    L, M, S = 7, 8, 6
    shifts = np.arange(-S, S + 1)
    centre = rng.uniform(-4, 4, (L, 1)) + rng.uniform(-0.3, 0.3, (L, 1)) * np.arange(M)
    W = (shifts[None, None, :] - centre[..., None]) ** 2 + rng.uniform(0, 3 * seed, (L, M, 2 * S + 1))
    W[0, :, :2] = np.inf  # no terms counted at some shifts
    curve_ok = rng.uniform(size=(L, M)) > 0.2
    curve_ok[1] = False  # no profile
    curve_ok[2, 1:] = False  # one profile: no line
    for max_iter in (1, 2, 3, 7, 20):
        yhat, ok = _descend(W, curve_ok, S, max_iter)
        y_ref, ok_ref = _descend_reference(W, curve_ok, S, max_iter)
        np.testing.assert_array_equal(yhat, y_ref)
        np.testing.assert_array_equal(ok, ok_ref)
    assert ok[0] and not ok[1] and not ok[2] and np.any(yhat != 0)
    # some link still moves after 20 steps: the cycle shortcut is exercised
    assert np.any(_descend_reference(W, curve_ok, S, 21)[0] != y_ref)


def test_window_outlines_are_the_eager_coordinates(hand27):
    seq, frames = hand27
    q, images = frames[1]
    config = ImageConfig(method="gaussian")
    _, diag = extract_features(images, seq.model, seq.cameras, q, config)
    eager = [[np.asarray(w.exterior.coords) for w in cd.visibility.windows
              if w is not None and not w.is_empty and w.geom_type == "Polygon"] for cd in diag.cameras]
    lazy = WindowOutlines(diag)
    assert len(lazy) == len(eager) == 2
    for c in (0, 1, -1):
        assert len(lazy[c]) == len(eager[c]) > 0
        for a, b in zip(lazy[c], eager[c]):
            np.testing.assert_array_equal(a, b)
    assert [len(w) for w in lazy] == [len(w) for w in eager] and len(lazy[:1]) == 1
    with pytest.raises(IndexError):
        lazy[2]
    # what the tracker's front end hands to the overlay video
    windows = ImageFrontEnd(seq.model, seq.cameras, config).extract(images, q, None, 0).diagnostics.windows
    assert len(windows) == 2 and all(np.asarray(p).shape[-1] == 2 for p in windows[0])
    np.testing.assert_array_equal(np.concatenate(windows[1]), np.concatenate(eager[1]))


@pytest.mark.parametrize("data_name", ["two_fingers", "hand27"])
@pytest.mark.parametrize("offset_deg", [0.0, 6.0])
def test_window_mask_equals_the_window_polygons(request, data_name, offset_deg):
    """The pill-distance window test gives shapely's answer on the built window polygons, for
    profile samples and for dense points jittered around them (many inside the band where the
    polygon and the pill differ, decided by shapely)."""
    data = request.getfixturevalue(data_name)
    rng = np.random.default_rng(3)
    n_in = n_out = 0
    for obs in _observations(data, offset_deg):
        vis = obs.visibility
        pts = _probe_points(obs)
        pts = np.concatenate([pts, pts + rng.uniform(-0.6, 0.6, pts.shape)], 1)
        fast = vis.window_mask(pts)
        np.testing.assert_array_equal(fast, window_masks(vis.windows, pts))
        n_in, n_out = n_in + int(fast.sum()), n_out + int((~fast).sum())
        tl = np.array([len(obs.start) - 1, 0])
        np.testing.assert_array_equal(vis.rows(tl).window_mask(pts[tl]), window_masks(vis.windows[tl], pts[tl]))
    assert n_in > 100 and n_out > 100


@pytest.mark.parametrize("name", ["full_hand_spread_flex", "two_finger_occlusion", "two_camera_hand"])
def test_predicted_geometry_is_project_pose(name):
    # Bit for bit at perturbed poses, for every camera, and for a model with other radii (a new
    # model object, as width estimation makes each frame), whose radii must show.
    seq = make_preset(name, frames=12)
    rng = np.random.default_rng(3)
    thicker = eqx.tree_at(lambda m: m.link_radius_mm, seq.model, seq.model.link_radius_mm * 1.3)
    for model in (seq.model, thicker):
        for cam in seq.cameras:
            for k in range(0, 12, 4):
                q = np.asarray(seq.q[k]) + np.where(model.is_angle, 0.05 * rng.standard_normal(model.n_q), 0.0)
                v, g = project_pose(model, cam, jnp.asarray(q)), predicted_geometry(model, cam, q)
                for want, got in ((v.link_start_px, g.start), (v.link_end_px, g.end), (v.link_depth, g.depth),
                                  (v.link_radius_px, g.radius), (v.tips_px, g.tips)):
                    assert np.array_equal(np.asarray(want), got)
    base = predicted_geometry(seq.model, seq.cameras[0], np.asarray(seq.q[0])).radius
    np.testing.assert_allclose(predicted_geometry(thicker, seq.cameras[0], np.asarray(seq.q[0])).radius, 1.3 * base,
                               rtol=1e-12)


def test_row_unions_are_one_union_all_per_row():
    rng = np.random.default_rng(3)
    start = rng.uniform(20, 80, (9, 2))
    pills = pill_outlines(start, start + rng.uniform(-30, 30, (9, 2)), rng.uniform(2, 8, 9), rng.uniform(2, 8, 9),
                          12, 0.25)
    take = rng.random((6, 9)) < 0.35
    take[np.arange(6), rng.integers(0, 9, 6)] = True   # every row takes one at least
    got = row_unions(pills, take)
    assert [g.wkb for g in got] == [shapely.union_all(pills[row]).wkb for row in take]


@pytest.mark.parametrize("arc_points", [4, 12])
@pytest.mark.parametrize("tolerance", [0.25, 1.0])
def test_pill_outlines_keep_the_topology_preserving_vertices(arc_points, tolerance):
    # Random pills from sub-pixel to 40 px radii: the outlines are the hull simplified by GEOS's
    # topology-preserving simplifier, vertex for vertex (the ring may start elsewhere).
    rng = np.random.default_rng(5)
    n = 4000
    start = rng.uniform(-50, 370, (n, 2))
    end = start + rng.uniform(-60, 60, (n, 2)) * (rng.random((n, 1)) < 0.8)
    r0 = np.exp(rng.uniform(np.log(0.2), np.log(40), n))
    r1 = r0 * rng.uniform(0.5, 1.5, n)
    start[:3] = np.nan   # rows without a pill: empty outlines
    r0[3:6] = 0.0
    got = pill_outlines(start, end, r0, r1, arc_points, tolerance)
    want = shapely.simplify(pill_outlines(start, end, r0, r1, arc_points, 0.0), tolerance)
    assert shapely.is_empty(got[:6]).all() and not shapely.is_empty(got[6:]).any()
    assert shapely.equals_exact(shapely.normalize(got), shapely.normalize(want), tolerance=0).all()
    assert (shapely.get_num_coordinates(want) <= 7).sum() > 50   # the small rings the fallback keeps are tried


def test_visible_polygons_are_the_outlines_less_their_nearer_cutters():
    # Random overlapping scenes: each visible polygon has the area of its outline less the union of
    # every nearer pill of another chain (the covers' box test, as in compute_visibility).
    rng = np.random.default_rng(11)
    config = ImageConfig().visibility
    for _ in range(20):
        n = 12
        start = rng.uniform(40, 160, (n, 2))
        end = start + rng.uniform(-40, 40, (n, 2))
        depth = rng.uniform(90, 110, (n, 2))
        r0, r1 = rng.uniform(2, 9, n), rng.uniform(2, 9, n)
        chain = np.eye(n, dtype=bool)
        chain[0, 1] = chain[1, 0] = True
        vis = compute_visibility(start, end, depth, r0, r1, chain, (200, 200), config)
        for i in range(n):
            cut = vis.outlines[vis.nearer[i]]
            want = shapely.difference(vis.outlines[i], shapely.union_all(cut)) if len(cut) else vis.outlines[i]
            assert shapely.area(vis.visible[i]) == pytest.approx(shapely.area(want), rel=1e-12, abs=1e-12)
        assert vis.nearer.sum() > 5   # occlusion is exercised
