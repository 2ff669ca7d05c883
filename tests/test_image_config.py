"""The thresholds that once hid in the front end's code are ImageConfig fields: documented,
validated, with the old values as defaults, and used (changing one changes the result)."""

import numpy as np
import pytest

import jaxhand as jh
from jaxhand.image import ImageConfig, RecentreConfig, TipConfig, VisibilityConfig, WidthConfig, measure_widths
from jaxhand.render import RenderConfig, make_preset, render_frame


def test_defaults_are_the_former_constants():
    c = ImageConfig()
    assert c.widths == WidthConfig(core=0.5, ratio_range=(0.5, 1.6), min_count=4, agreement=0.1,
                                   radius_range=(0.5, 2.0))
    assert c.recentre == RecentreConfig(core=0.7, width_tolerance=0.4, refits=2, outlier_samples=1.0,
                                        min_profiles=3, deadband=0.75)
    assert c.visibility.background_reach == (1.1, 1.25, 1.4) and c.tips.beyond == (1.1, 1.4)
    assert c.reacquire_min_visible == 0.9


@pytest.mark.parametrize("make, match", [
    (lambda: WidthConfig(ratio_range=(1.6, 0.5)), "WidthConfig.ratio_range"),
    (lambda: WidthConfig(min_count=0), "WidthConfig.min_count"),
    (lambda: WidthConfig(radius_range=(1.2, 2.0)), "WidthConfig.radius_range"),
    (lambda: RecentreConfig(refits=-1), "RecentreConfig.refits"),
    (lambda: RecentreConfig(deadband=-0.1), "RecentreConfig.deadband"),
    (lambda: VisibilityConfig(background_reach=()), "VisibilityConfig.background_reach"),
    (lambda: TipConfig(beyond=(0.0,)), "TipConfig.beyond"),
    (lambda: ImageConfig(reacquire_min_visible=1.5), "ImageConfig.reacquire_min_visible"),
])
def test_bad_values_name_the_field(make, match):
    with pytest.raises(jh.InputError, match=match):
        make()


def test_every_new_field_is_documented():
    for cls in (WidthConfig, RecentreConfig, VisibilityConfig, TipConfig, ImageConfig):
        for name in cls.__dataclass_fields__:
            assert f"{name}:" in cls.__doc__, f"{cls.__name__}.{name}"


def test_width_fields_take_effect():
    seq = make_preset("full_hand_spread_flex", frames=20)
    q = seq.q[5]
    image = render_frame(seq.model, seq.cameras[0], q, RenderConfig(antialias=3)).image
    _, ok = measure_widths(image, seq.model, seq.cameras[0], q)
    assert ok.sum() > 20
    _, ok_strict = measure_widths(image, seq.model, seq.cameras[0], q,
                                  ImageConfig(widths=WidthConfig(min_count=ok.shape[1] + 1)))
    assert not ok_strict.any()  # no link has more measures than samplers
    _, ok_narrow = measure_widths(image, seq.model, seq.cameras[0], q,
                                  ImageConfig(widths=WidthConfig(ratio_range=(0.5, 0.6))))
    assert ok_narrow.sum() < ok.sum()
    np.testing.assert_array_equal(ok, measure_widths(image, seq.model, seq.cameras[0], q, ImageConfig())[1])
