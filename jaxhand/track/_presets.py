"""Named changes to the tracker's defaults (:meth:`jaxhand.track.TrackConfig.preset`)."""

__all__ = ["PRESETS"]

#: Named changes to the defaults. "thesis": the documents' tracker as it is (one start, the
#: g-h-k filter reported, a lost frame held). "robust": for images jaxhand did not draw: the
#: silhouette term in every solve and as the judge of six starts (the prediction, four flips of
#: the least observed joints, the last solve) plus the rest pose, a weak DIP-PIP coupling, the
#: solve reported (the filter only predicts), no hold, and the weakest finger's image support in
#: the confidence. "robust-limits": "robust" with soft limits from 10 deg inside each joint limit,
#: up to the default pose and zero (a finger stuck at its limits mirrors a pose the view cannot
#: tell from it), and after a frame of confidence under 0.2 a start with the finger the image
#: supports least bent (``hypotheses.finger_level``): a finger that took another's image is
#: brought back; half the feature slots valid is enough for full confidence (fingers crossing
#: hide the rest on right frames); a fingertip in front of other fingers keeps its tip where the
#: link shows at least half its length (``image.tips.over_farther``: a thumb across the hand);
#: the confidence judges each finger by its fingertip's link (``support.tip_links``, on a ramp
#: from 0.67 to 0.83), so a proximal phalanx off its edges with the tip in place is not a loss.
#: More accurate on the dev set than "robust".
#: "robust-temporal": "robust-limits" with an information-weighted temporal prior around the
#: prediction (15 deg, 10 mm; free where the features or the silhouette see a direction) that
#: also judges the starts (``prior.temporal_merit`` 0.1), and after a frame of confidence under
#: 0.5 the joints the image did not show restarted from the last trusted pose
#: (``prior.restore_hidden_below``): its loss flag means more, and it holds a thumb from starts a
#: little off, at some accuracy on fast or occluding motion (benchmarks/README.md, 2026-12-04).
#: After a trusted frame another start must beat the prediction's merit by 5 % to win
#: (``hypotheses.prediction_margin``): a start that won by noise moved a joint the image
#: hardly sees (benchmarks/README.md, 2026-12-05, third session). The thumb's joints carry an
#: information-weighted prior of 20 deg towards the default pose (``prior.thumb_rest_sigma_deg``):
#: one camera hardly sees a thumb's depth, and small feature biases had carried it far off
#: (benchmarks/README.md, 2026-12-05, fourth session). Each link's support is capped by the share
#: of its visible sides with an image edge across them within 4 px (``score.silhouette.side_edge_px``):
#: a finger lying wrongly over the hand finds the hand's edges near it, but not along its sides.
#: Each whole finger's support also lowers the confidence, ramped from 0.5 to 0.8
#: (``support.whole_lost``): a finger folded the wrong way whose tip link still lies on edges
#: (benchmarks/README.md, 2026-12-05, fifth session). Where most of a camera's links fail WSSD's
#: mismatch test at once, they are matched again without the brightness offset
#: (``search.zero_mean``): fingers closing fast shade darker as a whole (same section).
#: After an estimate whose support confidence is under 0.5, the finger the image supports least
#: is searched again from starts of its own (bent, its hinges reflected across their folds, back
#: at the last trusted pose), each with features searched around itself, and the best by finger
#: support replaces it (``hypotheses.verify_below``): a finger folded the wrong way keeps the
#: features of its fold (benchmarks/README.md, 2026-12-05, sixth session).
#: Its confidence is reported with 0.8 of its own at 0.5 (``loss.doubt_level``): on the dev set
#: the frames far off lie between its 0.5 and 0.8, the right ones mostly above (benchmarks/README.md,
#: 2026-12-06, second session). It predicts each frame on the straight line through the last two
#: estimates (``filter.velocity_gain`` 1): theta's gains, made for a filter that keeps its own
#: position, forgot a stop only over some 20 frames and carried a finger hidden in a fist on to
#: its limit (benchmarks/README.md, 2026-12-06, third session). After a trusted frame won by
#: another start 15 deg or more from the prediction, the frames before it are tracked again
#: backward (``hypotheses.review_jump_deg``): fingers opening towards the camera had followed the
#: wrong side of their fold for six frames before the rest start found the right one
#: (benchmarks/README.md, 2026-12-06, fourth session). With one camera, a hinge whose estimate
#: came fast to within 12 deg of its fold and turned back there is tried reflected across it
#: (``hypotheses.fold_passage_deg``): a finger opening from a fist passes through the angle one
#: view cannot follow, a lagging estimate turned back and followed the mirror image out
#: (benchmarks/README.md, 2026-12-07, eleventh session). Where the merit alone picks the start (no
#: image score), each start runs two iterations and the best one's alone is solved in full
#: (``hypotheses.coarse_steps`` 2): several times faster, as accurate on the dev set and held out
#: (benchmarks/README.md, 2026-12-07, twelfth session).
#: "coupled": the DIP-PIP coupling in every solve (``prior.dip_pip_weight`` 4/rad), so a hidden
#: or drifting DIP follows its PIP instead of the filter's extrapolation or a stale template: no
#: drift on benchmarks/long.py's slow path, but worse where a hand's DIP does not follow 2/3 of
#: its PIP (the DIP = PIP experiments of tracking.py), hence not the default (issue 13;
#: benchmarks/README.md, dev-set and long.py tables).
_ROBUST = {"image": {"silhouette_term": {"weight": 0.5}}, "loss": {"hold": False}, "filter": {"report_solve": True},
           "prior": {"dip_pip_weight": 4.0},
           "hypotheses": {"flips": 4, "flip_deg": 40.0, "last_solve": True, "rest": True},
           "support": {"enabled": True}}
PRESETS: dict[str, dict] = {
    "thesis": {},
    "robust": _ROBUST,
    "robust-limits": {**_ROBUST, "image": {**_ROBUST["image"], "tips": {"over_farther": 0.5}},
                      "prior": {**_ROBUST["prior"], "soft_limit_weight": 30.0,
                                           "soft_limit_margin_deg": -10.0},
                      "hypotheses": {**_ROBUST["hypotheses"], "finger_level": 0.2},
                      "loss": {**_ROBUST["loss"], "valid_share_good": 0.5},
                      "support": {**_ROBUST["support"], "tip_links": True, "lost": 0.67, "good": 0.83}},
    "coupled": {"prior": {"dip_pip_weight": 4.0}},
}
PRESETS["robust-temporal"] = {**PRESETS["robust-limits"],
                              "prior": {**PRESETS["robust-limits"]["prior"], "temporal_sigma_deg": 15.0,
                                        "temporal_sigma_mm": 10.0, "information_ratio": 1.0, "temporal_merit": 0.1,
                                        "restore_hidden_below": 0.5, "thumb_rest_sigma_deg": 20.0},
                              "hypotheses": {**PRESETS["robust-limits"]["hypotheses"], "prediction_margin": 0.05,
                                             "verify_below": 0.5, "review_jump_deg": 15.0,
                                             "fold_passage_deg": 12.0, "coarse_steps": 2},
                              "support": {**PRESETS["robust-limits"]["support"], "whole_lost": 0.5, "whole_good": 0.8},
                              "loss": {**PRESETS["robust-limits"]["loss"], "doubt_level": 0.8},
                              "filter": {**PRESETS["robust-limits"]["filter"], "velocity_gain": 1.0},
                              "image": {**PRESETS["robust-limits"]["image"], "search": {"zero_mean": True},
                                        "score": {"silhouette": {"side_edge_px": 4.0}}}}
