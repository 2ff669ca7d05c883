import json

import numpy as np
import pytest

import jaxhand as jh
from jaxhand.cli import main


def test_models_lists_every_builtin_with_dof_and_joints(capsys):
    assert main(["models"]) == 0
    out = capsys.readouterr().out
    for name in jh.builtin_names():
        assert name in out
    assert "hand21        21 DOF (21 q entries" in out
    assert "hand27        27 DOF (28 q entries, free base" in out
    assert "joints: palm_x, palm_y, palm_yaw, index_mcp" in out


def test_models_export_round_trips(tmp_path, capsys):
    path = tmp_path / "hand.toml"
    assert main(["models", "hand21", "--export", str(path)]) == 0
    assert "index_pip" in capsys.readouterr().out
    assert jh.load_model(path).structure() == jh.builtin_model("hand21").structure()


def test_errors_are_one_line_and_exit_2(tmp_path, capsys):
    assert main(["models", "hand99"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("jaxhand models: error: unknown model 'hand99'") and err.count("\n") == 1
    assert main(["track", str(tmp_path), "--out", str(tmp_path / "o")]) == 2
    assert "--model is required unless INPUT is a 'jaxhand synth' or a dev-set folder" in capsys.readouterr().err
    assert main(["synth", "two_finger_occlusion", str(tmp_path / "s"), "--frames", "2", "--size", "80x60"]) == 0
    capsys.readouterr()
    assert main(["track", str(tmp_path / "s"), "--out", str(tmp_path / "o"), "--reacquire", "15,x"]) == 2
    assert "--reacquire: expected angles in degrees separated by commas, got '15,x'" in capsys.readouterr().err


def test_sketch_writes_pngs(tmp_path, capsys):
    assert main(["sketch", "--model", "index_thumb", "--out", str(tmp_path), "--poses", "1"]) == 0
    paths = capsys.readouterr().out.split()
    assert len(paths) == 2 and all(p.endswith(".png") for p in paths)


@pytest.mark.slow
def test_track_a_synth_folder_end_to_end(tmp_path, capsys):
    from jaxhand.track import FilterConfig, RobustConfig, TrackConfig, config_to_dict, save_track_config

    assert main(["synth", "two_finger_occlusion", str(tmp_path / "seq"), "--frames", "6", "--size", "160x120"]) == 0
    # settings from a file, two of them overridden by flags
    save_track_config(TrackConfig(robust=RobustConfig(passes=1), filter=FilterConfig(theta_rate_hz=5.0)),
                      tmp_path / "run.toml")
    assert main(["track", str(tmp_path / "seq"), "--out", str(tmp_path / "out"), "--method", "gaussian",
                 "--theta-rate", "10", "--width-gain", "0.1", "--config", str(tmp_path / "run.toml")]) == 0
    out = capsys.readouterr().out
    assert "tracked 6 frames of two_fingers" in out
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["frames"] == 6 and "accuracy_filtered" in summary
    # the report holds the whole tree the run used: the file's, the flags' and the defaults
    want = TrackConfig(robust=RobustConfig(passes=1), filter=FilterConfig(theta_rate_hz=10.0),
                       image=jh.ImageConfig(method="gaussian", width_gain=0.1))
    assert summary["config"] == config_to_dict(want) and summary["front_end"] == "ImageFrontEnd"
    # 0.85 per frame at 10 frames/s, the synth folder's 25 frames/s: 0.85 ** 0.4
    assert summary["theta_per_frame"] == pytest.approx(0.937060, abs=1e-6)
    # the phalanx widths estimated from the frames: the rendered ones are the model's (phalanges
    # 4-5 px in radius at 160x120, where a third of a pixel is 8%)
    est, model_r = summary["link_radius_mm_estimated"], summary["link_radius_mm_model"]
    assert list(est) == ["middle_mcp", "middle_pip", "middle_dip", "index_mcp", "index_pip", "index_dip"]
    np.testing.assert_allclose([est[k] for k in est], [model_r[k] for k in est], rtol=0.12)
    rows = (tmp_path / "out" / "angles.csv").read_text().splitlines()
    assert rows[0].startswith("frame,time_s,middle_mcp_deg") and len(rows) == 7
    assert np.isfinite(np.array([r.split(",")[2:-2] for r in rows[1:]], float)).all()


def test_track_flags_override_the_config_file_and_help_shows_the_defaults(tmp_path, capsys):
    from jaxhand.cli import build_parser
    from jaxhand.cli_track import track_config_from_args
    from jaxhand.track import FilterConfig, TrackConfig, save_track_config

    parse = build_parser().parse_args
    assert track_config_from_args(parse(["track", "x", "--out", "o"])) == TrackConfig()
    save_track_config(TrackConfig(solver="lm", filter=FilterConfig(theta=0.5, enabled=False)), tmp_path / "a.toml")
    args = parse(["track", "x", "--out", "o", "--config", str(tmp_path / "a.toml"), "--steps", "5",
                  "--reacquire", "15,30"])
    config = track_config_from_args(args)
    assert (config.solver, config.filter.theta, config.filter.enabled) == ("lm", 0.5, False)   # the file's
    assert config.fit.max_steps == 5 and config.image.reacquire_deg == (15.0, 30.0)             # the flags'
    config = track_config_from_args(parse(["track", "x", "--out", "o", "--preset", "robust-temporal",
                                           "--foreground", "sequence", "--method", "gaussian"]))
    assert config.image.score.foreground == "sequence" and config.image.method == "gaussian"
    assert config.image.silhouette_term.weight == 0.5   # the preset's, kept
    # a file may lean on the preset: the passage needs the support the preset turns on
    (tmp_path / "lean.toml").write_text("[hypotheses]\nfold_passage_deg = 8.0\nfold_passage_speed_deg = 2.0\n")
    config = track_config_from_args(parse(["track", "x", "--out", "o", "--config", str(tmp_path / "lean.toml"),
                                           "--preset", "robust-temporal"]))
    assert config.hypotheses.fold_passage_deg == 12.0 and config.support.enabled   # the preset's, on top
    assert config.hypotheses.fold_passage_speed_deg == 2.0                          # the file's
    with pytest.raises(jh.InputError, match=r"lean.toml: hypotheses.fold_passage_deg: needs the image support"):
        track_config_from_args(parse(["track", "x", "--out", "o", "--config", str(tmp_path / "lean.toml")]))
    (tmp_path / "bad.toml").write_text("format_version = 1\n[filter]\ntheta_rat_hz = 10\n")
    assert main(["track", "x", "--out", "o", "--config", str(tmp_path / "bad.toml"), "--model", "index",
                 "--camera", "c.json"]) == 2
    assert "filter.theta_rat_hz: unknown key; did you mean 'theta_rate_hz'?" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["track", "--help"])
    text = " ".join(capsys.readouterr().out.split()).split("options:", 1)[1]
    d = TrackConfig()
    for flag, value in (("--steps STEPS", d.fit.max_steps), ("--theta THETA", d.filter.theta),
                        ("--solver SOLVER", d.solver), ("--theta-rate THETA_RATE", d.filter.theta_rate_hz),
                        ("--method METHOD", d.image.method)):
        # the first default after the flag is its own
        assert text.split(flag, 1)[1].split("default: ", 1)[1].startswith(f"{value})"), flag
