"""The image front end's annotations hold at run time: every function of ``jaxhand.image`` is
checked by jaxtyping + beartype while a frame runs through the whole pipeline (templates,
re-acquisition, widths), in a fresh interpreter so the import hook sees the package's modules."""

import subprocess
import sys
import typing

import numpy as np
import pytest

from jaxhand.image.internal import edges_to_px

SCRIPT = """
import jax
jax.config.update("jax_enable_x64", True)
from jaxtyping import install_import_hook
with install_import_hook(["jaxhand.image"], "beartype.beartype"):
    import jaxhand.image as im
from jaxhand.render import RenderConfig, make_preset, render_frame
seq = make_preset("two_camera_hand", frames=20)
q = seq.q[10]
images = [render_frame(seq.model, c, q, RenderConfig(antialias=3)).image for c in seq.cameras]
config = im.ImageConfig(reacquire_deg=(10.0,), width_gain=0.2)
state = im.capture_templates(images, seq.model, seq.cameras, q, config)
feats, diag = im.extract_features(images, seq.model, seq.cameras, q + 0.05, config, state)
state = im.update_widths(images, seq.model, seq.cameras, q, config, diag.state)
print("ok", sum(int(f.line_valid.sum()) for f in feats))
"""


@pytest.mark.slow
def test_pipeline_under_runtime_type_checking():
    pytest.importorskip("beartype")
    out = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-3000:]
    assert out.stdout.startswith("ok ") and int(out.stdout.split()[1]) > 5


def test_edges_to_px_returns_what_it_declares():
    # the annotation once said a single array where a pair comes back
    hints = typing.get_type_hints(edges_to_px)
    assert typing.get_origin(hints["return"]) is tuple
    from jaxhand.image.internal import Edges, LinkSamplers

    s = LinkSamplers(direction=np.array([[1.0, 0.0]]), normal=np.array([[0.0, -1.0]]), radius_px=np.array([2.0]),
                     length_px=np.array([10.0]), ok=np.array([True]), centres=np.zeros((1, 2, 2)),
                     spacing_px=np.array([0.5]), points=np.zeros((1, 2, 4, 2)))
    e = Edges(pos=np.full((1, 2, 2), 1.5), strength=np.ones((1, 2, 2)), valid=np.ones((1, 2, 2), bool))
    out = edges_to_px(s, e, 1.5)
    assert isinstance(out, tuple) and len(out) == len(typing.get_args(hints["return"])) == 2
    np.testing.assert_array_equal(out[0], np.zeros((1, 2, 2, 2)))
