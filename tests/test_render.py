"""The pill renderer: silhouettes, depth, link IDs, visibility, shading and backgrounds."""

import cv2
import numpy as np
import pytest
from helpers import fit_camera

import jaxhand as jh
from jaxhand.camera import look_at_rotation
from jaxhand.model import model_from_dict
from jaxhand.render import RenderConfig, degrade, make_background, render_frame


def _pill_model(pills):
    """A fixed-base model with one revolute frame per pill (default 0): (name, a_mm, d_mm, theta_deg,
    length_mm, radius_mm); each frame hangs off the base, so its pill starts at (a, 0, d) along RotZ(theta) x."""
    frames = [{"name": n, "parent": "base", "alpha_deg": 0.0, "a_mm": a, "d_mm": d, "theta_deg": th,
               "joint": "revolute", "limits": [-180.0, 180.0], "default": 0.0,
               "link": {"axis": "x", "length_mm": length, "radius_mm": r, "tip": True}}
              for n, a, d, th, length, r in pills]
    return model_from_dict({"format_version": 1, "name": "pills", "base": {"kind": "fixed"}, "frames": frames})


def _ortho(R=None, scale=4.0, size=(200, 120), center=(100.0, 60.0)):
    return jh.Orthographic(R=np.eye(3) if R is None else R, t=[0.0, 0.0, 200.0], scale=scale, center=center, size=size)


def _segment_distance(px, a, b):
    """Distance of pixel centres px (..., 2) from the 2D segment [a, b]."""
    d = b - a
    s = np.clip(((px - a) @ d) / (d @ d), 0.0, 1.0)
    return np.linalg.norm(px - (a + s[..., None] * d), axis=-1)


def _pixel_grid(size):
    w, h = size
    xs, ys = np.meshgrid(np.arange(w), np.arange(h))  # pixel (x, y) of image[y, x]
    return np.stack([xs, ys], -1).astype(float)


@pytest.mark.parametrize("tilt_deg", [0.0, 35.0])
def test_single_pill_matches_its_analytic_stadium(tilt_deg):
    # Under an orthographic camera a pill's outline is the stadium of its projected axis grown by
    # scale * radius, whatever the axis's tilt out of the image plane.
    m = _pill_model([("p", -12.0, 0.0, 20.0, 24.0, 5.0)])
    c, s = np.cos(np.radians(tilt_deg)), np.sin(np.radians(tilt_deg))
    cam = _ortho(R=np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]))
    res = render_frame(m, cam, np.zeros(1))
    v = jh.project_pose(m, cam, np.zeros(1))
    dist = _segment_distance(_pixel_grid(cam.size), np.asarray(v.link_start_px[0]), np.asarray(v.link_end_px[0]))
    r_px = 4.0 * 5.0
    analytic = dist <= r_px
    rendered = res.link_id == 0
    assert analytic.sum() > 1000
    wrong = analytic != rendered
    assert np.all(np.abs(dist[wrong] - r_px) < 1.0)  # any disagreement lies on the outline (within 1 px)
    assert wrong.sum() <= 2
    assert res.alone_px[0] == rendered.sum()
    np.testing.assert_allclose(res.visible_fraction, [1.0])


def test_antialiased_coverage_matches_stadium_area():
    m = _pill_model([("p", -12.0, 0.0, 20.0, 24.0, 5.0)])
    cam = _ortho()
    res = render_frame(m, cam, np.zeros(1), RenderConfig(mode="binary", antialias=5))
    area_px = (24.0 * 2 * 5.0 + np.pi * 5.0**2) * 4.0**2
    np.testing.assert_allclose(res.image.sum() / 255.0, area_px, rtol=2e-3)
    # the ground-truth maps use the pixel-centre sample, so they equal the unsampled render's
    plain = render_frame(m, cam, np.zeros(1), RenderConfig(mode="binary"))
    np.testing.assert_array_equal(res.link_id, plain.link_id)
    np.testing.assert_array_equal(res.depth, plain.depth)


def test_depth_on_the_axis_is_the_analytic_front_surface():
    # Orthographic, axis tilted by phi out of the image plane: along a pixel's ray the surface lies
    # r / cos(phi) in front of the axis point.
    m = _pill_model([("p", -15.0, 0.0, 0.0, 30.0, 6.0)])
    phi = np.radians(25.0)
    R = np.array([[np.cos(phi), 0, np.sin(phi)], [0, 1, 0], [-np.sin(phi), 0, np.cos(phi)]])
    cam = _ortho(R=R)
    res = render_frame(m, cam, np.zeros(1))
    pose = jh.forward(m, np.zeros(1))
    a, b = np.asarray(pose.link_start[0]), np.asarray(pose.link_end[0])
    for s in np.linspace(0.1, 0.9, 9):
        p_cam = R @ (a + s * (b - a)) + np.asarray(cam.t)
        x = cam.scale * p_cam[0] + cam.center[0]
        y = cam.scale * p_cam[1] + cam.center[1]
        xi, yi = int(round(float(x))), int(round(float(y)))
        # move the axis point to the pixel centre along the axis's image direction (y is exact: 0)
        z_axis = p_cam[2] - (xi - float(x)) / float(cam.scale) * np.tan(phi)  # axis z falls as x grows
        assert abs(yi - float(y)) < 1e-9
        np.testing.assert_allclose(res.depth[yi, xi], z_axis - 6.0 / np.cos(phi), atol=1e-9)


def test_perspective_depth_on_the_optical_axis():
    # A pill parallel to the image plane whose axis crosses the optical axis at depth 300 mm: the
    # principal ray meets its surface at 300 - r.
    m = _pill_model([("p", -20.0, 0.0, 0.0, 40.0, 7.0)])
    cam = jh.Perspective(K=[[300.0, 0, 50.0], [0, 300.0, 40.0], [0, 0, 1]], R=np.eye(3), t=[0.0, 0.0, 300.0],
                         size=(101, 81))
    res = render_frame(m, cam, np.zeros(1))
    np.testing.assert_allclose(res.depth[40, 50], 300.0 - 7.0, atol=1e-9)
    assert res.link_id[40, 50] == 0 and res.link_id[0, 0] == -1 and np.isinf(res.depth[0, 0])


def test_front_pill_occludes_the_back_one():
    # Pill "back" along x at depth 0; pill "front" 20 mm nearer the camera, along y, crossing it.
    m = _pill_model([("back", -20.0, 0.0, 0.0, 40.0, 5.0), ("front", 0.0, -20.0, 90.0, 30.0, 4.0)])
    cam = _ortho()
    res = render_frame(m, cam, np.zeros(2))
    v = jh.project_pose(m, cam, np.zeros(2))
    grid = _pixel_grid(cam.size)
    d = [_segment_distance(grid, np.asarray(v.link_start_px[k]), np.asarray(v.link_end_px[k])) for k in range(2)]
    r_px = 4.0 * np.asarray(m.link_radius_mm)
    inside = [d[k] <= r_px[k] for k in range(2)]
    sure = [np.abs(d[k] - r_px[k]) > 1.0 for k in range(2)]  # pixels clear of either outline
    clear = sure[0] & sure[1]
    both = inside[0] & inside[1] & clear
    assert both.sum() > 50
    assert np.all(res.link_id[both] == 1)  # the nearer pill wins wherever both project
    assert np.all(res.link_id[inside[0] & ~inside[1] & clear] == 0)
    assert np.all(res.link_id[~inside[0] & ~inside[1] & clear] == -1)
    assert res.visible_fraction[1] == 1.0
    expected_back = (inside[0] & ~inside[1]).sum() / inside[0].sum()
    np.testing.assert_allclose(res.visible_fraction[0], expected_back, atol=0.01)
    assert 0.5 < res.visible_fraction[0] < 0.95
    np.testing.assert_array_equal(res.visible_px, [np.sum(res.link_id == k) for k in range(2)])
    # depth: the front pill's surface is 20 mm nearer than the back pill's
    np.testing.assert_allclose(res.depth[res.link_id == 1].min(), 200.0 - 20.0 - 4.0, atol=1e-6)
    np.testing.assert_allclose(res.depth[res.link_id == 0].min(), 200.0 - 5.0, atol=1e-6)


def _reference_depth(model, camera, q, steps=300):
    """Slow, independent reference: sphere tracing of the union of capsule distance fields."""
    from jaxhand.render._frame import pill_geometry
    from jaxhand.render._raycast import pills_in_camera, ray_grid

    start, end, radius = pill_geometry(model, q)
    pills = pills_in_camera(camera, start, end, radius)
    grid = ray_grid(camera, 1)
    o, d = grid.rays(0, grid.shape[0], 0, grid.shape[1])
    o = np.stack(np.broadcast_arrays(*o, np.zeros(grid.shape)))[:3]
    d = np.stack(np.broadcast_arrays(*d, np.zeros(grid.shape)))[:3]
    if not grid.perspective:
        o = o.copy()
        o[2] = -1000.0  # start every orthographic ray well in front of the model
    dn = d / np.linalg.norm(d, axis=0)
    t = np.zeros(grid.shape)
    for _ in range(steps):
        p = o + t * dn
        sdf = np.full(grid.shape, np.inf)
        for a, b, r in zip(pills.a, pills.b, pills.radius):
            ba = b - a
            s = np.clip(np.einsum("i,i...->...", ba, p - a[:, None, None]) / (ba @ ba), 0, 1)
            sdf = np.minimum(sdf, np.linalg.norm(p - a[:, None, None] - s * ba[:, None, None], axis=0) - r)
        t = np.where(t < 5000, t + sdf, t)
    p = o + t * dn
    return np.where(sdf < 1e-6, p[2], np.inf)


@pytest.mark.parametrize("kind", ["orthographic", "perspective"])
def test_vectorised_renderer_matches_sphere_tracing_reference(kind):
    m = jh.builtin_model("hand21")
    q = jh.random_q(m, np.random.default_rng(5), margin=0.1)
    if kind == "orthographic":
        cam = fit_camera(m, q, size=(64, 48), R=look_at_rotation([1, -1, -3], [0, 0, 0]))
    else:
        cam = jh.Perspective.look_at([60.0, -250.0, -300.0], [0.0, -90.0, 0.0], fov_deg=45, size=(64, 48))
    res = render_frame(m, cam, q)
    ref = _reference_depth(m, cam, q)
    hit, ref_hit = np.isfinite(res.depth), np.isfinite(ref)
    assert hit.sum() > 200
    assert (hit != ref_hit).sum() <= 0.01 * hit.sum()  # only grazing rays may disagree
    both = hit & ref_hit
    np.testing.assert_allclose(res.depth[both], ref[both], atol=1e-6)  # sphere tracing stops at sdf < 1e-6


def test_bounding_boxes_change_nothing():
    m = jh.builtin_model("two_fingers")
    q = jh.random_q(m, np.random.default_rng(2))
    for cam in (fit_camera(m, q, size=(80, 60)),
                jh.Perspective.look_at([-300.0, -200.0, -250.0], [0.0, -100.0, 0.0], fov_deg=50, size=(80, 60))):
        fast = render_frame(m, cam, q)
        naive = render_frame(m, cam, q, use_bbox=False)
        np.testing.assert_array_equal(fast.image, naive.image)
        np.testing.assert_array_equal(fast.link_id, naive.link_id)
        np.testing.assert_array_equal(fast.alone_px, naive.alone_px)


@pytest.mark.parametrize("model_name,kind", [("hand21", "orthographic"), ("hand27", "perspective"),
                                             ("index_thumb", "orthographic")])
def test_binary_and_shaded_agree_on_the_silhouette(model_name, kind):
    m = jh.builtin_model(model_name)
    q = np.asarray(m.q_default)
    if kind == "orthographic":
        cam = fit_camera(m, q, size=(160, 120))
    else:
        cam = jh.Perspective.look_at([80.0, -300.0, -350.0], [0.0, -90.0, 0.0], fov_deg=45, size=(160, 120))
    binary = render_frame(m, cam, q, RenderConfig(mode="binary")).image > 0
    shaded = render_frame(m, cam, q, RenderConfig(mode="shaded")).image > 0
    iou = (binary & shaded).sum() / (binary | shaded).sum()
    assert iou >= 0.99
    assert set(np.unique(render_frame(m, cam, q, RenderConfig(mode="binary")).image)) == {0, 255}


def test_shading_separates_overlapping_fingers_and_background():
    # thesis fig. 10.8: in a shaded image the occluding finger's outline shows over the finger behind.
    m = jh.builtin_model("two_fingers")
    q = np.radians([-40.0, -45.0, -30.0, -20.0, -30.0, -20.0])  # index straighter, lying across the middle
    R = np.array([[1.0, 0, 0], [0, np.sqrt(0.5), -np.sqrt(0.5)], [0, np.sqrt(0.5), np.sqrt(0.5)]])
    cam = fit_camera(m, q, size=(240, 180), R=R)
    res = render_frame(m, cam, q)
    img = res.image.astype(int)
    fg = res.link_id >= 0
    assert img[fg].min() >= 40 and img[~fg].max() == 0
    middle = np.isin(res.link_id, [m.link_lookup(n) for n in ("middle_mcp", "middle_pip", "middle_dip")])
    index = np.isin(res.link_id, [m.link_lookup(n) for n in ("index_mcp", "index_pip", "index_dip")])
    # pixel pairs straddling the index/middle boundary, horizontally and vertically
    steps = []
    for a, b, ia, ib in ((img[:, :-1], img[:, 1:], index[:, :-1], middle[:, 1:]),
                         (img[:, 1:], img[:, :-1], index[:, 1:], middle[:, :-1]),
                         (img[:-1], img[1:], index[:-1], middle[1:]), (img[1:], img[:-1], index[1:], middle[:-1])):
        steps.append(np.abs(a - b)[ia & ib])
    steps = np.concatenate(steps)
    assert len(steps) > 20
    # the edge pixel of the index is darkened (surface turning away), the middle finger behind is lit
    assert np.median(steps) >= 25  # about 90 with the default light; a binary image gives 0


def test_lambert_brightest_where_the_normal_faces_the_light():
    m = _pill_model([("p", -15.0, 0.0, 0.0, 30.0, 6.0)])
    cam = _ortho()
    cfg = RenderConfig(light_dir=(0.0, 0.0, -1.0), specular=0.0, ambient=0.2, albedo=1.0)
    img = render_frame(m, cam, np.zeros(1), cfg).image.astype(float)
    column = img[:, 100]  # across the pill: the normal turns from facing the camera to sideways
    assert column[60] == 255
    inside = np.nonzero(column)[0]
    # on the cylinder, brightness = 255 (a + (1 - a) cos(angle)), cos = sqrt(1 - (offset / r)^2)
    offset_mm = (inside - 60.0) / 4.0
    expected = 255 * (0.2 + 0.8 * np.sqrt(np.clip(1 - (offset_mm / 6.0) ** 2, 0, 1)))
    np.testing.assert_allclose(column[inside], expected, atol=0.51)


def test_backgrounds(tmp_path):
    m = jh.builtin_model("index")
    cam = fit_camera(m, size=(64, 48))
    q = np.asarray(m.q_default)
    res = render_frame(m, cam, q, RenderConfig(background="constant:90"))
    assert np.all(res.image[res.link_id < 0] == 90)
    noise = make_background("noise", (64, 48), seed=3)
    assert noise.shape == (48, 64) and noise.std() > 5
    np.testing.assert_array_equal(noise, make_background("noise", (64, 48), seed=3))
    assert not np.array_equal(noise, make_background("noise", (64, 48), seed=4))
    path = tmp_path / "bg.png"
    cv2.imwrite(str(path), np.tile(np.arange(0, 256, 2, dtype=np.uint8), (96, 1)))  # 128x96 ramp
    res = render_frame(m, cam, q, RenderConfig(background=str(path)))
    bg = res.link_id < 0
    ramp = cv2.resize(np.tile(np.arange(0, 256, 2, dtype=np.uint8), (96, 1)), (64, 48), interpolation=cv2.INTER_AREA)
    np.testing.assert_array_equal(res.image[bg], ramp[bg])
    arr = np.full((48, 64), 33, np.uint8)
    assert np.all(render_frame(m, cam, q, RenderConfig(background=arr)).image[bg] == 33)
    with pytest.raises(jh.InputError, match=r"expected shape \(48, 64\)"):
        render_frame(m, cam, q, RenderConfig(background=np.zeros((10, 10))))
    with pytest.raises(jh.InputError, match="existing image file"):
        RenderConfig(background=str(tmp_path / "missing.png"))
    with pytest.raises(jh.InputError, match="constant:V"):
        RenderConfig(background="constant:300")
    bad = tmp_path / "not_an_image.png"
    bad.write_text("hello")
    with pytest.raises(jh.InputError, match="cannot read as an image"):
        render_frame(m, cam, q, RenderConfig(background=str(bad)))


def test_noise_and_blur():
    m = jh.builtin_model("index")
    cam = fit_camera(m, size=(160, 120))
    q = np.asarray(m.q_default)
    clean = render_frame(m, cam, q, RenderConfig(background="constant:128")).image.astype(float)
    cfg = RenderConfig(background="constant:128", noise_sigma=6.0, seed=1)
    a = render_frame(m, cam, q, cfg, frame_index=0)
    b = render_frame(m, cam, q, cfg, frame_index=0)
    c = render_frame(m, cam, q, cfg, frame_index=1)
    np.testing.assert_array_equal(a.image, b.image)  # same seed and frame: same bits
    assert not np.array_equal(a.image, c.image)
    bg = a.link_id < 0
    np.testing.assert_allclose(np.std(a.image[bg] - clean[bg]), 6.0, rtol=0.05)
    np.testing.assert_array_equal(a.link_id, render_frame(m, cam, q).link_id)  # ground truth stays exact
    blurred = render_frame(m, cam, q, RenderConfig(blur_sigma_px=2.0)).image.astype(float)
    sharp = render_frame(m, cam, q).image.astype(float)
    assert np.abs(np.diff(blurred, axis=1)).max() < 0.6 * np.abs(np.diff(sharp, axis=1)).max()


def test_degrade_blurs_adds_seeded_noise_and_rounds():
    flat = np.full((60, 80), 100.4)
    np.testing.assert_array_equal(degrade(flat), np.full((60, 80), 100, np.uint8))   # rounded only
    a = degrade(flat, noise_sigma=5.0, rng=np.random.default_rng(7))
    np.testing.assert_array_equal(a, degrade(flat, noise_sigma=5.0, rng=np.random.default_rng(7)))
    assert a.dtype == np.uint8 and abs(np.std(a.astype(float)) - 5.0) < 0.3
    step = np.zeros((20, 40))
    step[:, 20:] = 200.0
    blurred = degrade(step, blur_sigma_px=1.0).astype(float)
    assert blurred[0, 19] > 20 and blurred[0, 20] < 180   # the step is spread over pixels
    np.testing.assert_allclose(blurred.mean(), step.mean(), atol=1.0)
    assert degrade(np.full((4, 4), 300.0))[0, 0] == 255   # clipped to 8 bits
    with pytest.raises(jh.InputError, match="must be >= 0"):
        degrade(flat, blur_sigma_px=-1.0)
    with pytest.raises(jh.InputError, match="needs a random generator"):
        degrade(flat, noise_sigma=2.0)


def test_bad_inputs():
    m = jh.builtin_model("index")
    cam = fit_camera(m, size=(64, 48))
    with pytest.raises(jh.InputError, match=r"expected shape \(3,\)"):
        render_frame(m, cam, np.zeros(4))
    with pytest.raises(jh.InputError, match="non-finite"):
        render_frame(m, cam, [0.0, np.nan, 0.0])
    with pytest.raises(jh.InputError, match="Orthographic or Perspective"):
        render_frame(m, "camera", np.zeros(3))
    with pytest.raises(jh.InputError, match="mode"):
        RenderConfig(mode="wireframe")
    with pytest.raises(jh.InputError, match="antialias"):
        RenderConfig(antialias=2)
    with pytest.raises(jh.InputError, match="noise_sigma"):
        RenderConfig(noise_sigma=-1.0)
    with pytest.raises(jh.InputError, match="albedo"):
        render_frame(m, cam, np.zeros(3), RenderConfig(albedo=(0.5, 0.5)))
    with pytest.raises(jh.InputError, match="light_dir"):
        RenderConfig(light_dir=(0.0, 0.0, 0.0))


def test_pill_outside_the_image_and_behind_the_camera():
    m = _pill_model([("p", -15.0, 0.0, 0.0, 30.0, 6.0)])
    far = _ortho(center=(5000.0, 60.0))
    res = render_frame(m, far, np.zeros(1))
    assert res.alone_px[0] == 0 and res.visible_fraction[0] == 0.0 and np.all(res.image == 0)
    behind = jh.Perspective(K=[[100.0, 0, 32], [0, 100.0, 24], [0, 0, 1]], R=np.eye(3), t=[0.0, 0.0, -300.0],
                            size=(64, 48))
    res = render_frame(m, behind, np.zeros(1))
    assert np.all(res.link_id == -1)
