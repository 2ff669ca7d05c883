"""TrackConfig: defaults, validation, dict and TOML round trips, unknown keys."""

import tomllib

import numpy as np
import pytest

import jaxhand as jh
from jaxhand.track import (
    FilterConfig,
    LossConfig,
    PriorConfig,
    RobustConfig,
    TrackConfig,
    config_from_dict,
    config_to_dict,
    config_to_toml,
    load_track_config,
    save_track_config,
)


def _leaves(config):
    """Every value of the tree, flattened, with its path (bit-level comparison of floats)."""
    out = {}

    def walk(d, prefix):
        for k, v in d.items():
            if isinstance(v, dict):
                walk(v, prefix + k + ".")
            else:
                out[prefix + k] = np.asarray(v).tobytes() + repr(type(v)).encode()
    walk(config_to_dict(config), "")
    return out


def _odd_config():
    """A config whose every section differs from the defaults, with awkward floats."""
    return TrackConfig(solver="lm", fit=jh.FitConfig(max_steps=7, jacobian="autodiff", link_fractions=(0.1, 1 / 3, 0.9),
                                                     xtol=1e-13, divergence_factor=np.inf),
                       image=jh.ImageConfig(method="gaussian", reacquire_deg=(15.0, 30.5), width_gain=0.1),
                       filter=FilterConfig(theta=0.1 + 0.2, theta_rate_hz=None, enabled=False, report_solve=True),
                       robust=RobustConfig(passes=0, scale_px=1e-3, gate_scale_px=0.0),
                       loss=LossConfig(min_valid_share=2 / 3, hold=False),
                       prior=PriorConfig(temporal_sigma_deg=1 / 3, temporal_sigma_mm=None, information_ratio=0.1 + 0.2,
                                         dip_pip_weight=10, soft_limit_weight=1e-300, soft_limit_margin_deg=2.5),
                       reextract=3, refresh_templates=False)


def test_tracker_defaults_are_those_of_the_benchmarks():
    c = TrackConfig()
    assert (c.solver, c.fit.max_steps, c.fit.jacobian) == ("bounded", 20, "geometric")
    assert (c.filter.theta, c.filter.theta_rate_hz, c.filter.enabled) == (0.85, 25.0, True)
    assert (c.robust.passes, c.robust.scale_px, c.robust.gate_scale_px) == (2, 2.0, 2.0)
    assert (c.loss.rms_scale_px, c.loss.min_valid_share, c.loss.max_rms_px, c.loss.hold) == (2.0, 0.15, 6.0, True)
    assert (c.reextract, c.refresh_templates) == (1, True)
    assert c.prior == PriorConfig() and not c.prior.temporal and not c.filter.report_solve   # priors off
    assert c.image == jh.ImageConfig()
    # jaxhand.fit keeps its own defaults
    assert (jh.FitConfig().max_steps, jh.FitConfig().jacobian) == (50, "autodiff")


@pytest.mark.parametrize("config", [TrackConfig(), _odd_config()], ids=["default", "odd"])
def test_dict_and_toml_round_trips_are_exact(config, tmp_path):
    d = config_to_dict(config)
    assert d["format_version"] == 1
    back = config_from_dict(d)
    assert back == config and _leaves(back) == _leaves(config)
    assert isinstance(back.image.reacquire_deg, tuple) and isinstance(back.fit, jh.FitConfig)
    text = config_to_toml(config)
    assert config_from_dict(tomllib.loads(text)) == config
    save_track_config(config, tmp_path / "run.toml")
    loaded = load_track_config(tmp_path / "run.toml")
    assert loaded == config and _leaves(loaded) == _leaves(config)
    np.testing.assert_array_equal(np.asarray(loaded.fit.link_fractions), np.asarray(config.fit.link_fractions))


def test_missing_keys_keep_their_defaults_and_merged_applies_changes():
    assert config_from_dict({}) == TrackConfig()
    c = config_from_dict({"filter": {"theta": 0.5}, "fit": {"max_steps": 3}})
    assert c.filter.theta == 0.5 and c.filter.theta_rate_hz == 25.0 and c.fit.max_steps == 3
    assert c.fit.jacobian == "geometric"   # the tracker's default, not FitConfig's
    assert TrackConfig().merged({"loss": {"hold": False}}).loss == LossConfig(hold=False)


@pytest.mark.parametrize("data, message", [
    ({"filter": {"theta_rat_hz": 10}}, r"filter\.theta_rat_hz: unknown key; did you mean 'theta_rate_hz'\?"),
    ({"solvr": "lm"}, r"solvr: unknown key; did you mean 'solver'\?"),
    ({"image": {"search": {"sigmaa": 1.0}}}, r"image\.search\.sigmaa: unknown key; did you mean 'sigma'\?"),
    ({"fit": {"max_stepz": 3}}, r"fit\.max_stepz: unknown key; did you mean 'max_steps'\?"),
    ({"zzz": 1}, r"zzz: unknown key; valid keys: solver, fit"),
    ({"format_version": 2}, r"format_version: this jaxhand reads version 1, got 2"),
    ({"filter": {"theta": 1.5}}, r"filter\.theta: theta must lie in \[0, 1\]"),
    ({"filter": {"velocity_gain": 2.0}}, r"filter\.velocity_gain: expected a number in \[0, 2\)"),
    ({"filter": {"velocity_gain": 1.0}}, r"filter\.velocity_gain: acts on a filter that reports the solve"),
    ({"fit": {"jacobian": "numeric"}}, r"fit\.jacobian: expected one of autodiff, geometric"),
    ({"solver": "gn2"}, r"unknown solver 'gn2'"),
    ({"robust": {"passes": -1}}, r"robust\.passes: expected an integer >= 0"),
    ({"reextract": -1}, r"reextract: expected an integer >= 0"),
    ({"loss": {"hold": 1}}, r"loss\.hold: expected true or false"),
    ({"filter": 3}, r"filter: expected a table"),
    ({"prior": {"temporal_sigma_deg": -1.0}}, r"prior\.temporal_sigma_deg: expected a finite number >= 0"),
    ({"prior": {"dip_pip_weight": float("inf")}}, r"prior\.dip_pip_weight: expected a finite number >= 0"),
    ({"prior": {"soft_limit_margin_deg": float("nan")}}, r"prior\.soft_limit_margin_deg: expected a finite number"),
    ({"prior": {"information_ratio": 1.0}}, r"prior\.information_ratio: weighs the temporal prior"),
    ({"prior": {"temporal_merit": 0.1}}, r"prior\.temporal_merit: counts the temporal prior: set temporal_sigma_deg"),
    ({"prior": {"temporal_merit": -0.1}}, r"prior\.temporal_merit: expected a finite number >= 0"),
    ({"prior": {"temporal_min_confidence": 0.5}}, r"prior\.temporal_min_confidence: gates the temporal prior: set"),
    ({"prior": {"temporal_sigma_deg": 5.0, "temporal_min_confidence": 1.5}},
     r"prior\.temporal_min_confidence: must lie in \[0, 1\], got 1\.5"),
    ({"prior": {"restore_hidden_below": 2.0}}, r"prior\.restore_hidden_below: must lie in \[0, 1\], got 2\.0"),
    ({"prior": {"restore_hidden_below": 0.5}},
     r"prior\.restore_hidden_below: needs the image support .* support\.enabled"),
    ({"prior": {"temporal_sigma_dg": 5.0}},
     r"prior\.temporal_sigma_dg: unknown key; did you mean 'temporal_sigma_deg'"),
    ({"filter": {"report_solve": 1}}, r"filter\.report_solve: expected true or false"),
])
def test_bad_keys_and_values_name_the_field(data, message):
    with pytest.raises(jh.InputError, match=message):
        config_from_dict(data)


def test_a_bad_file_names_the_file(tmp_path):
    path = tmp_path / "run.toml"
    path.write_text("format_version = 1\n[robust]\npases = 1\n")
    with pytest.raises(jh.InputError, match=r"run\.toml: robust\.pases: unknown key; did you mean 'passes'\?"):
        load_track_config(path)
    path.write_text("solver = \n")
    with pytest.raises(jh.InputError, match=r"run\.toml: "):
        load_track_config(path)


def test_theta_per_frame_follows_the_rate():
    assert FilterConfig().theta_per_frame(0.04) == pytest.approx(0.85, abs=1e-12)
    assert FilterConfig().theta_per_frame(0.1) == pytest.approx(0.85 ** 2.5)
    assert FilterConfig(theta_rate_hz=None).theta_per_frame(0.1) == 0.85
    assert FilterConfig(theta_rate_hz=None) == FilterConfig(theta_rate_hz=0.0)


def test_presets_apply_named_changes_and_unknown_names_are_listed():
    assert TrackConfig().preset("thesis") == TrackConfig()
    robust = TrackConfig().preset("robust")
    assert robust.image.silhouette_term.weight == 0.5 and robust.hypotheses.flips == 4 and robust.hypotheses.rest
    assert robust.filter.report_solve and not robust.loss.hold and robust.prior.dip_pip_weight == 4.0
    limits = TrackConfig().preset("robust-limits")
    assert limits.prior.soft_limit_weight == 30.0 and limits.prior.soft_limit_margin_deg == -10.0
    assert limits.hypotheses.finger_level == 0.2 and robust.hypotheses.finger_level == 0.0
    assert limits.loss.valid_share_good == 0.5 and robust.loss.valid_share_good == 1.0
    assert limits.image.tips.over_farther == 0.5 and robust.image.tips.over_farther == 0.0
    assert limits.support.tip_links and (limits.support.lost, limits.support.good) == (0.67, 0.83)
    assert not robust.support.tip_links and (robust.support.lost, robust.support.good) == (0.80, 0.96)
    assert limits.image.silhouette_term == robust.image.silhouette_term
    assert limits.merged({"prior": {"soft_limit_weight": 0.0, "soft_limit_margin_deg": 0.0},
                          "hypotheses": {"finger_level": 0.0}, "loss": {"valid_share_good": 1.0},
                          "image": {"tips": {"over_farther": 0.0}},
                          "support": {"tip_links": False, "lost": 0.80, "good": 0.96}}) == robust
    assert config_from_dict(config_to_dict(limits)) == limits
    assert config_from_dict(config_to_dict(robust)) == robust
    temporal = TrackConfig().preset("robust-temporal")   # robust-limits with the temporal prior and the restart
    assert temporal.merged({"prior": {"temporal_sigma_deg": 0.0, "temporal_sigma_mm": 0.0, "information_ratio": 0.0,
                                      "temporal_merit": 0.0, "restore_hidden_below": 0.0,
                                      "thumb_rest_sigma_deg": 0.0},
                            "hypotheses": {"prediction_margin": 0.0, "verify_below": 0.0,
                                           "review_jump_deg": 0.0, "fold_passage_deg": 0.0, "coarse_steps": 0},
                            "support": {"whole_lost": 0.0, "whole_good": 0.0}, "loss": {"doubt_level": 0.5},
                            "filter": {"velocity_gain": 0.0},
                            "image": {"search": {"zero_mean": False},
                                      "score": {"silhouette": {"side_edge_px": 0.0}}}}) == limits
    assert (temporal.hypotheses.prediction_margin, temporal.hypotheses.verify_below) == (0.05, 0.5)
    assert (temporal.hypotheses.fold_passage_deg, temporal.hypotheses.coarse_steps) == (12.0, 2)
    assert (temporal.prior.temporal_sigma_deg, temporal.prior.information_ratio) == (15.0, 1.0)
    assert (temporal.prior.temporal_merit, temporal.prior.restore_hidden_below) == (0.1, 0.5)
    assert temporal.prior.thumb_rest_sigma_deg == 20.0
    assert temporal.image.score.silhouette.side_edge_px == 4.0
    assert (temporal.support.whole_lost, temporal.support.whole_good) == (0.5, 0.8)
    assert temporal.image.search.zero_mean and not limits.image.search.zero_mean
    assert (temporal.loss.doubt_level, limits.loss.doubt_level) == (0.8, 0.5)
    assert (temporal.filter.velocity_gain, limits.filter.velocity_gain) == (1.0, 0.0)
    assert temporal.filter.report_solve
    with pytest.raises(jh.InputError,
                       match="preset: unknown preset 'fast'; valid: thesis, robust, robust-limits, coupled, "
                             "robust-temporal"):
        TrackConfig().preset("fast")
