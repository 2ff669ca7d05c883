import numpy as np
import pytest

import jaxhand as jh
from jaxhand.mouse import mouse_state


def test_mouse_state_maps_palm_height_and_buttons():
    m = jh.builtin_model("mouse3d")
    q = np.asarray(m.q_default).copy()
    q[m.q_lookup("palm_x")], q[m.q_lookup("palm_y")] = 30.0, -12.0
    for n in ("index_mcp", "index_pip", "index_dip"):
        q[m.q_lookup(n)] = 0.0
    s = mouse_state(m, q)
    np.testing.assert_allclose(s.base_xy_mm, [30.0, -12.0])
    assert s.height_mm == pytest.approx(0.0, abs=1e-9)  # a straight finger lies on the table plane
    q[m.q_lookup("index_mcp")] = np.radians(30)  # raising the index (extension is positive)
    s = mouse_state(m, q)
    assert s.height_mm == pytest.approx((40 + 24 + 20) * np.sin(np.radians(30)), rel=1e-9)
    assert not s.thumb_button and not s.ring_button
    q[m.q_lookup("thumb_abd")] = np.radians(20)
    assert mouse_state(m, q).thumb_button
    with pytest.raises(jh.InputError, match="needs the planar-palm 'mouse3d' model"):
        mouse_state(jh.builtin_model("index"), np.zeros(3))
