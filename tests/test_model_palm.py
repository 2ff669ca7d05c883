"""add_palm: palm and forearm occluder pills laid out from a hand model's finger bases."""

from pathlib import Path

import numpy as np
import pytest

import jaxhand as jh
from jaxhand.cli import main
from jaxhand.kinematics import forward, occluder_pills
from jaxhand.model import add_palm, builtin_model, get_model, model_from_dict, model_to_dict, save_model
from jaxhand.score import capsules_from_model, rasterize

DEV_HAND = Path(__file__).resolve().parents[1] / "data" / "mujoco" / "models" / "hand.xml"


def _without_occluders(model):
    d = model_to_dict(model)
    d.pop("occluders")
    return model_from_dict(d)


def _world_pills(model, q):
    p = occluder_pills(model, forward(model, q))
    return {n: (np.asarray(p.start[k]), np.asarray(p.end[k]), float(p.radius_mm[k]))
            for k, n in enumerate(model.occluder_names)}


def test_the_dev_set_hand_palm_is_reproduced_from_its_fingers():
    dev = get_model(DEV_HAND)
    ours = add_palm(_without_occluders(dev), forearm_mm=100.0)
    assert sorted(ours.occluder_names) == sorted(dev.occluder_names)
    q = np.asarray(dev.q_default)
    truth, got = _world_pills(dev, q), _world_pills(ours, q)
    for name in ("palm_index", "palm_middle", "palm_ring", "palm_little"):
        (s0, e0, r0), (s1, e1, r1) = truth[name], got[name]
        assert np.linalg.norm(s1 - s0) < 2.5 and np.linalg.norm(e1 - e0) < 1.0 and abs(r1 - r0) < 0.3, name
    (s0, e0, r0), (s1, e1, r1) = truth["forearm"], got["forearm"]
    ends = np.array([[np.linalg.norm(a - b) for b in (s1, e1)] for a in (s0, e0)])
    assert max(ends[0, 1], ends[1, 0]) < 1.0  # the same segment, drawn from the wrist outwards
    assert abs(r1 - r0) < 1.0


def test_the_palm_moves_with_a_free_palm_and_fills_the_silhouette():
    m = builtin_model("hand27_right")
    palm = add_palm(m)
    rng = np.random.default_rng(0)
    q0, q1 = np.asarray(m.q_default), jh.random_q(m, rng, margin=0.1)
    # the distance from each palm pill's end to its finger's base is the same at any palm pose
    def gaps(q):
        f, pills = forward(palm, q), _world_pills(palm, q)
        return [np.linalg.norm(pills[f"palm_{n}"][1] - np.asarray(f.link_start)[palm.link_names.index(f"{n}_mcp")])
                for n in ("index", "middle", "ring", "little")]

    d0, d1 = gaps(q0), gaps(q1)
    np.testing.assert_allclose(d1, d0, atol=1e-9)
    assert max(d0) < 6.0
    cam = jh.Orthographic.fit(np.concatenate([forward(palm, q0).link_end, _world_pills(palm, q0)["forearm"][1][None]]),
                              size=(160, 160))
    bare, full = (rasterize(capsules_from_model(x, q0), cam).mask > 0 for x in (m, palm))
    assert full.sum() > 1.8 * bare.sum() and (bare & ~full).sum() == 0


def test_the_palm_survives_a_model_file(tmp_path):
    palm = add_palm(builtin_model("hand21"), forearm_mm=200.0)
    back = get_model(save_model(palm, tmp_path / "palm.toml"))
    assert back.occluder_names == ("palm_little", "palm_ring", "palm_middle", "palm_index", "forearm")
    np.testing.assert_allclose(np.asarray(back.occluder_end_mm), np.asarray(palm.occluder_end_mm), atol=1e-9)
    assert np.linalg.norm(np.asarray(back.occluder_end_mm[4] - back.occluder_start_mm[4])) == pytest.approx(
        200.0 + 0.05 * np.mean([68.0, 80.0, 85.0, 80.0]), abs=3.0)


def test_bad_models_and_lengths_are_refused():
    with pytest.raises(jh.InputError, match="already has occluders"):
        add_palm(get_model(DEV_HAND))
    with pytest.raises(jh.InputError, match="has 1 finger"):
        add_palm(builtin_model("index"))
    with pytest.raises(jh.InputError, match="forearm_mm must be >= 0"):
        add_palm(builtin_model("hand21"), forearm_mm=-1.0)


def test_cli_models_palm(capsys):
    assert main(["models", "hand27", "--palm", "--forearm-mm", "150"]) == 0
    out = capsys.readouterr().out
    assert "5 occluders (palm_little, palm_ring, palm_middle, palm_index, forearm)" in out
