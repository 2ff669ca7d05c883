"""The capsule rasteriser against the ray-casting renderer's pixel-centre link-ID map."""

import numpy as np
import pytest
from helpers import fit_camera

import jaxhand as jh
from jaxhand.model import builtin_model
from jaxhand.render import render_frame
from jaxhand.score import Capsules, camera_numbers, capsule_outlines, capsules_from_model, model_contour, rasterize


def _posed(m):
    q = np.asarray(m.q_default).copy()
    for name, v in (("index_mcp", -0.5), ("index_pip", -0.6), ("middle_abd", 0.2), ("thumb_mcp", -0.4)):
        q[m.q_lookup(name)] = v
    return q


@pytest.mark.parametrize("kind", ["orthographic", "perspective"])
def test_mask_and_labels_match_the_renderer(kind):
    m = builtin_model("hand21")
    q = _posed(m)
    if kind == "orthographic":
        cam = fit_camera(m)
    else:
        pose = jh.forward(m, q)
        centre = np.asarray(pose.link_end).mean(0)
        cam = jh.Perspective.look_at(centre + np.array([60.0, -40.0, -350.0]), centre, fov_deg=45)
    truth = render_frame(m, cam, q).link_id
    sil = rasterize(capsules_from_model(m, q), cam)
    outline = model_contour(sil, occluding=False).sum()
    wrong = np.count_nonzero(sil.mask != (truth >= 0))
    # Only pixels on the outline can differ (rounding of pixel centres near the boundary); measured
    # 65 of ~1000 outline pixels (orthographic) at shrink_px = 0.5.
    assert wrong < 0.12 * outline
    both = sil.mask & (truth >= 0)
    a, b = sil.label[both], truth[both]
    # The painter's order (mean depth) differs from the z-buffer where joined pills overlap at a
    # joint; between capsules that do not join (an occluding contour) the labels must agree.
    assert np.mean((a == b) | sil.adjacent[a, b]) > 0.99
    assert sil.label.dtype == np.int16 and sil.mask.shape == (240, 320)


def test_orthographic_circle_is_exact_to_a_pixel():
    cam = jh.Orthographic(R=np.eye(3), t=np.zeros(3), scale=2.0, center=np.array([50.0, 40.0]), size=(100, 80))
    caps = Capsules.from_arrays([[0.0, 0.0, 10.0]], [[0.0, 0.0, 10.0]], [10.0])  # a sphere: 20 px radius
    sil = rasterize(caps, cam)
    yy, xx = np.mgrid[0:80, 0:100]
    disc = (xx - 50.0) ** 2 + (yy - 40.0) ** 2 < 20.0**2
    assert np.count_nonzero(sil.mask != disc) <= 0.1 * 2 * np.pi * 20  # a tenth of the perimeter
    assert abs(int(sil.mask.sum()) - np.pi * 400) < 20


def test_perspective_sphere_rim_is_the_tangent_cone():
    K = np.array([[300.0, 0, 159.5], [0, 300.0, 119.5], [0, 0, 1]])
    cam = jh.Perspective(K=K, R=np.eye(3), t=np.zeros(3), size=(320, 240))
    c, r = np.array([40.0, -20.0, 200.0]), 15.0
    caps = Capsules.from_arrays([c], [c], [r])
    pts, depth, drawable = capsule_outlines(caps, camera_numbers(cam), rim_points=16)
    assert drawable[0] and depth[0] == pytest.approx(200.0)
    # Every rim pixel's ray is tangent to the sphere: its distance from the centre equals r.
    rays = np.concatenate([pts[0], np.ones((32, 1))], 1) @ np.linalg.inv(K).T
    rays /= np.linalg.norm(rays, axis=1, keepdims=True)
    dist = np.linalg.norm(np.cross(rays, c), axis=1)
    np.testing.assert_allclose(dist, r, rtol=1e-9)


def test_capsule_around_the_camera_is_not_drawn():
    cam = jh.Perspective.look_at([0.0, 0, -100], [0.0, 0, 0])
    caps = Capsules.from_arrays([[0.0, 0, -110], [0.0, 0, 0]], [[0.0, 0, -90], [10.0, 0, 0]], [20.0, 5.0])
    sil = rasterize(caps, cam)
    assert np.all(sil.label != 0) and np.any(sil.label == 1)


def test_occluders_join_and_chains_join():
    m = builtin_model("hand21")
    caps = capsules_from_model(m, m.q_default)
    sil = rasterize(caps, fit_camera(m))
    i, j = m.link_lookup("index_mcp"), m.link_lookup("index_pip")
    assert sil.adjacent[i, j] and not sil.adjacent[i, m.link_lookup("middle_mcp")]
    palm = Capsules.from_arrays([[0.0, 0, 0], [20.0, 0, 0]], [[0.0, 50, 0], [20.0, 50, 0]], [10.0, 10.0],
                                [True, True])
    both = rasterize(caps + palm, fit_camera(m))
    assert both.adjacent[-1, -2] and both.occluder[-1]


def test_empty_and_bad_capsules():
    cam = jh.Orthographic(R=np.eye(3), t=np.zeros(3), scale=1.0, center=np.zeros(2), size=(10, 8))
    sil = rasterize(Capsules.from_arrays(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0)), cam)
    assert not sil.mask.any()
    with pytest.raises(ValueError, match="radii"):
        Capsules.from_arrays([[0.0, 0, 0]], [[1.0, 0, 0]], [-1.0])
    with pytest.raises(ValueError, match="expected start"):
        Capsules.from_arrays([[0.0, 0]], [[1.0, 0]], [1.0])


def _slow_contour(sil):
    """Reference: every model pixel with a 4-neighbour (outside the image counts) that is
    background or a capsule it does not join."""
    lab = sil.label
    h, w = lab.shape
    out = np.zeros((h, w), bool)
    for y, x in zip(*np.nonzero(lab >= 0)):
        for dy, dx in ((0, 1), (0, -1), (1, 0), (-1, 0)):
            yy, xx = y + dy, x + dx
            other = lab[yy, xx] if 0 <= yy < h and 0 <= xx < w else -1
            if other < 0 or (other != lab[y, x] and not sil.adjacent[lab[y, x], other]):
                out[y, x] = True
    return out


def test_contour_matches_a_slow_reference_also_at_the_image_border():
    m = builtin_model("hand21")
    q = _posed(m)
    q[m.q_lookup("little_mcp")] = -1.2  # a finger across the palm: occluding contours
    cam = fit_camera(m)
    cam = jh.Orthographic(R=cam.R, t=cam.t, scale=cam.scale, center=cam.center + np.array([0.0, 60.0]),
                          size=cam.size)  # shifted down: the hand leaves the image
    sil = rasterize(capsules_from_model(m, q), cam)
    assert sil.mask[-1].any()  # touches the bottom border
    np.testing.assert_array_equal(model_contour(sil), _slow_contour(sil))
