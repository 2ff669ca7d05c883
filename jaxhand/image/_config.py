"""Configuration of the image front end: frozen dataclasses with documented defaults.

Nothing here enters jitted code (the front end is NumPy/OpenCV/shapely), so every field is a plain
host value. Lengths across a profile are given in units of the link's predicted radius in pixels
(``r``), so a profile always holds the same number of samples across a phalanx whatever its size in
the image; this also makes stored templates independent of the finger's image scale.
"""

from __future__ import annotations

import dataclasses

from .._errors import InputError
from ..score import ScoreSection, SilhouetteTermConfig

__all__ = ["SamplerConfig", "SearchConfig", "VisibilityConfig", "LineConfig", "TipConfig", "RecentreConfig",
           "RefreshConfig", "WidthConfig", "ImageConfig", "INTERPOLATIONS", "POLARITIES"]

INTERPOLATIONS = ("nearest", "bilinear", "bicubic")
POLARITIES = ("bright", "dark")


def _check(cond: bool, where: str, msg: str) -> None:
    if not cond:
        raise InputError(f"{where}: {msg}")


@dataclasses.dataclass(frozen=True)
class SamplerConfig:
    """Link samplers (thesis §4.1, fig. 4.2) and profile sampling (§4.2).

    Attributes:
        per_link: samplers (profiles) per link, spread evenly along the projected link.
        along: first and last sampler position as fractions of the projected link (0 = start,
            1 = end); staying off the joints keeps profiles away from the neighbouring phalanx.
        points: samples per profile (the thesis uses 20); 48 puts samples about 1 px apart on a
            phalanx 13 px in radius, and sub-sample edges need the profile no coarser than that.
        scope: half length of a profile in units of the predicted radius ``r``; the profile spans
            ``±scope · r`` about the predicted axis, so it reaches past both predicted boundaries.
        interpolation: "nearest", "bilinear" or "bicubic" (OpenCV's remap kernels, thesis §4.2).
        min_length_px: a link whose projection is shorter than this (px) gets no samplers (its
            direction in the image is undefined or meaningless): the slot is invalid.
    """

    per_link: int = 8
    along: tuple[float, float] = (0.2, 0.8)
    points: int = 48
    scope: float = 1.75
    interpolation: str = "bilinear"
    min_length_px: float = 2.0

    def __post_init__(self):
        w = "SamplerConfig"
        _check(isinstance(self.per_link, int) and self.per_link >= 2, f"{w}.per_link", f"need an int >= 2, got "
               f"{self.per_link!r}")
        _check(len(self.along) == 2 and 0.0 <= self.along[0] < self.along[1] <= 1.0, f"{w}.along",
               f"need 0 <= first < last <= 1, got {self.along!r}")
        _check(isinstance(self.points, int) and self.points >= 8, f"{w}.points", f"need an int >= 8, got "
               f"{self.points!r}")
        _check(self.scope > 1.0, f"{w}.scope", f"the profile must reach past the radius (> 1), got {self.scope!r}")
        _check(self.interpolation in INTERPOLATIONS, f"{w}.interpolation",
               f"unknown {self.interpolation!r}; valid: {', '.join(INTERPOLATIONS)}")
        _check(self.min_length_px >= 0, f"{w}.min_length_px", f"must be >= 0, got {self.min_length_px!r}")

    @property
    def centre(self) -> float:
        """Index of the profile sample on the predicted axis (between two samples for even counts)."""
        return (self.points - 1) / 2

    @property
    def samples_per_radius(self) -> float:
        """Profile samples per predicted radius (the same for every link)."""
        return (self.points - 1) / (2 * self.scope)


@dataclasses.dataclass(frozen=True)
class SearchConfig:
    """Feature searches (thesis §4.3, appendix D); lengths in radius units ``r`` unless named.

    Attributes:
        polarity: "bright" when the hand is brighter than what surrounds it (the first boundary,
            on the side of smaller profile index, is a rising edge), "dark" for the opposite.
        min_strength: weakest accepted edge, grey levels per pixel (derivative searches) or the
            weakest template contrast (wssd, grey levels); below it a boundary is invalid, which
            is how a flat profile ends up masked.
        sigma: standard deviation of the Gaussian derivative (thesis §11.1.2), in samples.
        template_sigma: width (standard deviation, samples) of each of the two peaks of the
            synthetic width template (§11.2.2); narrow peaks keep a neighbouring finger's edge from
            pulling the correlation maximum.
        search_window: width τ of each restricted search window (thesis §11.2.1), in ``r``.
        max_shift: largest template displacement searched by correlation or WSSD, in ``r``.
        subsample: refine integer peaks and valley points with a parabola through their two
            neighbours (not in the thesis, whose positions are whole samples; it takes the edge
            error from half a sample to a small fraction of one).
        crest_floor: MWPLLS and iMWPLLS weigh each point of a correlation curve by its amplitude
            above this share of the curve's maximum (negative parts never count). 0 is the thesis's
            plain amplitude weighting, which §11.3.2 notes is pulled towards each curve's centre of
            mass; the default keeps only the upper half of the crest.
        crest_halfwidth: iMWPLLS keeps the points of the correlation surface within this distance of
            the current line (thesis §11.3.3), in ``r``.
        max_iter: iteration cap of iMWPLLS and of the WSSD valley descent (thesis §4.3.2).
        min_window: a profile takes part in WSSD matching only when this share of its samples is
            visible (thesis §4.3.1); fewer gives no edge for that profile.
        max_mismatch: a WSSD match is accepted only when its RMS difference is at most this share
            of the windowed template's standard deviation (rejects a profile that no longer shows
            the phalanx).
        snap: WSSD boundaries that lie against the background (no other link's outline just
            outside them) and where the link is seen move to the strongest Gaussian-derivative
            edge of the right sign within this distance (in ``r``), so the measurement rests on
            the image's edge rather than on where an earlier, possibly slightly misplaced,
            template put it (template drift); 0 keeps the template's boundaries (the thesis).
        zero_mean: where most of a camera's links fail WSSD's mismatch test at once (the hand
            shading as a whole, not an occluder), each failing link is matched again with the
            mean difference between profile and template taken out (the variance of the
            difference instead of its mean square): fingers that turn in the light as they
            close fast still match. False: the thesis's WSSD alone.
    """

    polarity: str = "bright"
    min_strength: float = 8.0
    sigma: float = 1.0
    template_sigma: float = 0.5
    search_window: float = 1.0
    max_shift: float = 1.0
    subsample: bool = True
    crest_floor: float = 0.5
    crest_halfwidth: float = 0.25
    max_iter: int = 20
    min_window: float = 0.15
    max_mismatch: float = 0.5
    snap: float = 0.2
    zero_mean: bool = False

    def __post_init__(self):
        w = "SearchConfig"
        _check(self.polarity in POLARITIES, f"{w}.polarity", f"unknown {self.polarity!r}; valid: "
               f"{', '.join(POLARITIES)}")
        _check(self.min_strength >= 0, f"{w}.min_strength", f"must be >= 0, got {self.min_strength!r}")
        _check(self.sigma > 0, f"{w}.sigma", f"must be > 0, got {self.sigma!r}")
        _check(self.template_sigma > 0, f"{w}.template_sigma", f"must be > 0, got {self.template_sigma!r}")
        _check(0 <= self.crest_floor < 1, f"{w}.crest_floor", f"must lie in [0, 1), got {self.crest_floor!r}")
        _check(self.search_window > 0, f"{w}.search_window", f"must be > 0, got {self.search_window!r}")
        _check(self.max_shift > 0, f"{w}.max_shift", f"must be > 0, got {self.max_shift!r}")
        _check(self.crest_halfwidth > 0, f"{w}.crest_halfwidth", f"must be > 0, got {self.crest_halfwidth!r}")
        _check(isinstance(self.max_iter, int) and self.max_iter >= 1, f"{w}.max_iter",
               f"need an int >= 1, got {self.max_iter!r}")
        _check(0 < self.min_window <= 1, f"{w}.min_window", f"must lie in (0, 1], got {self.min_window!r}")
        _check(self.max_mismatch > 0, f"{w}.max_mismatch", f"must be > 0, got {self.max_mismatch!r}")
        _check(self.snap >= 0, f"{w}.snap", f"must be >= 0, got {self.snap!r}")
        _check(isinstance(self.zero_mean, bool), f"{w}.zero_mean", f"expected true or false, got {self.zero_mean!r}")

    @property
    def sign(self) -> float:
        """+1 when the first boundary is a rising edge (bright hand), -1 otherwise."""
        return 1.0 if self.polarity == "bright" else -1.0


@dataclasses.dataclass(frozen=True)
class VisibilityConfig:
    """Visibility ordering and window functions (thesis §4.3.3).

    Attributes:
        occlusion: compute windows from depth-sorted pill polygons; False treats every link as
            fully visible (windows cover its whole polygon).
        arc_points: vertices per hemisphere outline when a pill's outline is built (before the
            convex hull and simplification).
        simplify_px: tolerance of the polygon simplification (Douglas-Peucker), px.
        window_pad: a link's own polygon is grown by this much (in ``r``) before the occluders are
            cut out, so a window would keep a strip of background on each side. The default 0 is
            the thesis's window (the truncated polygon itself): the background beside a finger
            changes whenever another finger comes close, and a strip of it in the window then
            spoils the template match.
        occluder_margin_px: occluding polygons are grown by this much (px) before subtraction, so
            the occluder's own boundary stays out of the occluded link's window.
        background_reach: a profile's boundary counts as seen against the background when the
            points these many radii (``r``) from the profile's centre on that side lie off every
            other link's outline; several distances, so a thin gap next to a finger is not taken
            for background (used by the WSSD snap, template re-centring and width measures).
    """

    occlusion: bool = True
    arc_points: int = 12
    simplify_px: float = 0.25
    window_pad: float = 0.0
    occluder_margin_px: float = 1.5
    background_reach: tuple[float, ...] = (1.1, 1.25, 1.4)

    def __post_init__(self):
        w = "VisibilityConfig"
        _check(isinstance(self.arc_points, int) and self.arc_points >= 2, f"{w}.arc_points",
               f"need an int >= 2, got {self.arc_points!r}")
        _check(self.simplify_px >= 0, f"{w}.simplify_px", f"must be >= 0, got {self.simplify_px!r}")
        _check(self.window_pad >= 0, f"{w}.window_pad", f"must be >= 0, got {self.window_pad!r}")
        _check(self.occluder_margin_px >= 0, f"{w}.occluder_margin_px",
               f"must be >= 0, got {self.occluder_margin_px!r}")
        _check(len(self.background_reach) >= 1 and all(a > 0 for a in self.background_reach),
               f"{w}.background_reach", f"need one or more distances > 0, got {self.background_reach!r}")


@dataclasses.dataclass(frozen=True)
class LineConfig:
    """Line fitting (thesis §4.4) and the link slot's validity and weight.

    Attributes:
        tau_px: RANSAC inlier distance τ (px, Euclidean point-line distance).
        min_inliers: fewest inliers for a boundary line.
        det_eps: |det V| at or below which two boundary lines count as parallel and the axial point
            is their points' midpoint (thesis eq. 4.4; the thesis uses 1e-9).
        single_edge: when only one boundary is found, offset it by the predicted radius towards
            the predicted axis (DigitEyes §4) instead of dropping the link.
        single_edge_weight: weight factor of a link measured from one boundary only.
        weight_by_visibility: multiply a link's weight by the visible share of its polygon.
        min_visible: a link whose visible share (occlusion and image border) is below this is
            invalid.
    """

    tau_px: float = 1.0
    min_inliers: int = 3
    det_eps: float = 1e-9
    single_edge: bool = True
    single_edge_weight: float = 0.5
    weight_by_visibility: bool = True
    min_visible: float = 0.1

    def __post_init__(self):
        w = "LineConfig"
        _check(self.tau_px > 0, f"{w}.tau_px", f"must be > 0, got {self.tau_px!r}")
        _check(isinstance(self.min_inliers, int) and self.min_inliers >= 2, f"{w}.min_inliers",
               f"need an int >= 2, got {self.min_inliers!r}")
        _check(self.det_eps >= 0, f"{w}.det_eps", f"must be >= 0, got {self.det_eps!r}")
        _check(0 <= self.single_edge_weight <= 1, f"{w}.single_edge_weight",
               f"must lie in [0, 1], got {self.single_edge_weight!r}")
        _check(0 <= self.min_visible <= 1, f"{w}.min_visible", f"must lie in [0, 1], got {self.min_visible!r}")


@dataclasses.dataclass(frozen=True)
class TipConfig:
    """Tip features (thesis §4.1 eq. 4.1, §11.1.1).

    Attributes:
        points: samples along the tip sampler.
        scope: half length of the tip sampler in ``r``; it is centred on the predicted tip
            boundary (the refined tip centre plus one radius along the terminal axial line).
        sigma: Gaussian derivative scale along the tip sampler, samples (0: simple difference).
        min_strength: weakest accepted tip edge, grey levels per pixel.
        need_line: a tip counts only when its terminal link's line was measured in this frame,
            so its sampler lies on the measured axis (eq. 4.1); along the predicted axis alone a
            misplaced prediction can find another edge. Off by default: on the two-finger
            sequence the tips it drops cost more than the wrong ones it avoids.
        beyond: a tip counts only when the points these many radii (``r``) past it along the
            axis lie off every other link's outline: over another link the tip's boundary is
            weak or missing and the strongest derivative lies elsewhere (thesis §4.4 assumes a
            clear tip).
        over_farther: a tip whose ``beyond`` points lie only on other fingers' links farther from
            the camera than its own (a thumb across the fingers) still counts where its terminal
            link's line was measured and that link's projection shows at least this share of its
            length (in (0, 1]; 0.5: up to 60 deg out of the image plane): its boundary is an
            occluding contour of its own, and without its tip such a finger may slide along its
            line (a fingertip pointing at the camera, seen end on, has no such boundary). 0 (the
            default, the thesis's rule): such tips never count.
    """

    points: int = 32
    scope: float = 1.0
    sigma: float = 1.0
    min_strength: float = 8.0
    need_line: bool = False
    beyond: tuple[float, ...] = (1.1, 1.4)
    over_farther: float = 0.0

    def __post_init__(self):
        w = "TipConfig"
        _check(isinstance(self.points, int) and self.points >= 4, f"{w}.points", f"need an int >= 4, got "
               f"{self.points!r}")
        _check(self.scope > 0, f"{w}.scope", f"must be > 0, got {self.scope!r}")
        _check(self.sigma >= 0, f"{w}.sigma", f"must be >= 0, got {self.sigma!r}")
        _check(self.min_strength >= 0, f"{w}.min_strength", f"must be >= 0, got {self.min_strength!r}")
        _check(all(a > 0 for a in self.beyond), f"{w}.beyond", f"distances must be > 0, got {self.beyond!r}")
        _check(isinstance(self.over_farther, (int, float)) and not isinstance(self.over_farther, bool)
               and 0 <= self.over_farther < float("inf"), f"{w}.over_farther",
               f"need a finite number >= 0 (0: off), got {self.over_farther!r}")


@dataclasses.dataclass(frozen=True)
class RecentreConfig:
    """Template re-centring (``ImageConfig.template_recentre``): where each new template shows its
    link's axis. Lengths in radius units ``r`` or profile samples, as named.

    Attributes:
        core: a profile counts only when the link's window covers its samples within this many
            ``r`` of the centre (no nearer finger across the phalanx's middle).
        width_tolerance: ... and when its two boundaries lie ``2 r`` apart within this many ``r``
            (a boundary taken from a neighbour gives another width).
        refits: the PLLS line of a link's midpoints is refitted this many times, each without the
            midpoints off it by more than ``outlier_samples``.
        outlier_samples: that distance (samples): a midpoint further off is a wrong boundary.
        min_profiles: a link needs at least this many counted profiles, and at least half of
            them, for a line (fewer could be one wrong boundary).
        deadband: a link whose line stays within this many samples of the centre everywhere is not
            moved: shading shifts the two boundaries unequally by a fraction of a sample, so only
            a template off by more than that (drift) is corrected.
    """

    core: float = 0.7
    width_tolerance: float = 0.4
    refits: int = 2
    outlier_samples: float = 1.0
    min_profiles: int = 3
    deadband: float = 0.75

    def __post_init__(self):
        w = "RecentreConfig"
        _check(self.core >= 0, f"{w}.core", f"must be >= 0, got {self.core!r}")
        _check(self.width_tolerance > 0, f"{w}.width_tolerance", f"must be > 0, got {self.width_tolerance!r}")
        _check(isinstance(self.refits, int) and self.refits >= 0, f"{w}.refits",
               f"need an int >= 0, got {self.refits!r}")
        _check(self.outlier_samples > 0, f"{w}.outlier_samples", f"must be > 0, got {self.outlier_samples!r}")
        _check(isinstance(self.min_profiles, int) and self.min_profiles >= 2, f"{w}.min_profiles",
               f"need an int >= 2, got {self.min_profiles!r}")
        _check(self.deadband >= 0, f"{w}.deadband", f"must be >= 0, got {self.deadband!r}")


@dataclasses.dataclass(frozen=True)
class RefreshConfig:
    """When a tracker's refresh re-takes a link's template at the solved pose
    (:func:`jaxhand.image.refresh_templates`): only where the frame can vouch for that pose, so a
    slightly wrong solve is not stored and matched again (template drift).

    Attributes:
        min_move: re-take a link's template only once one of its projected ends has moved at
            least this many radii ``r`` since the last time: each refresh at a solved pose may
            store a little of the solve's error, so refreshing per frame drifts more the slower
            the hand moves; per unit of motion, the same path gets the same refreshes at any
            speed (0.2 stops the drift of ``benchmarks/long.py`` only with
            ``FilterConfig.damp_unseen``, and costs other runs; benchmarks/README.md). 0: every
            frame (the thesis).
        min_clear: ... and only when at least this share of its profiles (those its window
            covers across the middle) show both boundaries against the background, where the
            re-centring can check the template's axis. 0: any link seen well enough (the thesis).
    """

    min_move: float = 0.0
    min_clear: float = 0.0

    def __post_init__(self):
        _check(self.min_move >= 0, "RefreshConfig.min_move", f"must be >= 0, got {self.min_move!r}")
        _check(0 <= self.min_clear <= 1, "RefreshConfig.min_clear", f"must lie in [0, 1], got {self.min_clear!r}")


@dataclasses.dataclass(frozen=True)
class WidthConfig:
    """Width measures and the radius estimate (thesis appendix E; :func:`jaxhand.image.measure_widths`).

    Attributes:
        core: a profile measures a width only when the link's window covers its samples within
            this many radii ``r`` of the centre (no nearer finger across the phalanx's middle).
        ratio_range: a width measure outside these multiples of the radius in use is implausible
            (the profile spans ``±scope`` radii, so a boundary beyond it cannot be seen anyway).
        min_count: a link's measures count only when at least this many of them agree ...
        agreement: ... with their median to this share (an edge taken from a touching neighbour
            stands out).
        radius_range: the estimated radii stay within these multiples of the model's, so a run of
            wrong poses cannot shrink or grow a phalanx without bound.
    """

    core: float = 0.5
    ratio_range: tuple[float, float] = (0.5, 1.6)
    min_count: int = 4
    agreement: float = 0.1
    radius_range: tuple[float, float] = (0.5, 2.0)

    def __post_init__(self):
        w = "WidthConfig"
        _check(self.core >= 0, f"{w}.core", f"must be >= 0, got {self.core!r}")
        _check(len(self.ratio_range) == 2 and 0 < self.ratio_range[0] < self.ratio_range[1], f"{w}.ratio_range",
               f"need 0 < low < high, got {self.ratio_range!r}")
        _check(isinstance(self.min_count, int) and self.min_count >= 1, f"{w}.min_count",
               f"need an int >= 1, got {self.min_count!r}")
        _check(self.agreement > 0, f"{w}.agreement", f"must be > 0, got {self.agreement!r}")
        _check(len(self.radius_range) == 2 and 0 < self.radius_range[0] <= 1 <= self.radius_range[1],
               f"{w}.radius_range", f"need 0 < low <= 1 <= high, got {self.radius_range!r}")


@dataclasses.dataclass(frozen=True)
class ImageConfig:
    """Everything the image front end needs for one run.

    Attributes:
        method: the feature search, by name (see :data:`jaxhand.image.SEARCH_NAMES`): "derivative",
            "gaussian", "width", "width_compensated", "plls", "mwplls", "imwplls" or "wssd" (the
            thesis's occlusion-aware method, the default).
        samplers: link samplers and profile sampling.
        search: feature search parameters.
        visibility: visibility ordering and windows.
        lines: line fitting and link validity.
        tips: tip features.
        recentre: how template re-centring finds the axis a new template shows.
        refresh: when a tracker's refresh may re-take a link's template at the solved pose.
        widths: width measures and the radius estimate.
        template_min_visible: a view updates a link's template only when at least this share of
            the link's outline is visible (and then only the samples that show it).
        template_recentre: re-centre every new template on the axis the template itself shows
            (the midpoint of its two Gaussian-derivative boundaries, a line per link), so a
            template taken at a slightly wrong pose does not carry that error into the next
            frames' matches (template drift, which refreshing at each solved pose otherwise
            accumulates). A link whose boundaries cannot be found keeps its template uncentred.
        width_gain: gain g of the phalanx width estimate (thesis appendix E): after each good
            frame :func:`jaxhand.image.update_widths` moves every link's radius by g times the
            mean innovation of its width measures at the solved pose, and the front end then
            places samplers, windows and templates with the estimated radii. 0 (the default)
            keeps the model's radii; 0.1-0.3 adapts a model to a hand whose phalanges are
            thicker or thinner than the model's.
        reacquire_deg: where the prediction shows a link but the search finds no line for it
            (while its parent link's line is found), search again with the link's joint turned
            by each of these angles (degrees) both ways and take the line found with the most
            boundary inliers (not in the documents: a phalanx that turns faster than the
            filter predicts is found again). Empty: never.
        reacquire_min_visible: only a link predicted with at least this visible share is searched
            for again: a link partly behind another is missing for that reason, not because it
            turned.
        score: the global image score of :meth:`~jaxhand.ImageFrontEnd.score` (its foreground
            model; :class:`jaxhand.score.ScoreSection`).
        silhouette_term: the silhouette as residuals of every solve and as a judge of the
            hypotheses (:class:`jaxhand.score.SilhouetteTermConfig`; its foreground is chosen by
            ``score``'s settings, "auto" when the score is off).
    """

    method: str = "wssd"
    samplers: SamplerConfig = SamplerConfig()
    search: SearchConfig = SearchConfig()
    visibility: VisibilityConfig = VisibilityConfig()
    lines: LineConfig = LineConfig()
    tips: TipConfig = TipConfig()
    recentre: RecentreConfig = RecentreConfig()
    refresh: RefreshConfig = RefreshConfig()
    widths: WidthConfig = WidthConfig()
    template_min_visible: float = 0.25
    template_recentre: bool = True
    width_gain: float = 0.0
    reacquire_deg: tuple[float, ...] = ()
    reacquire_min_visible: float = 0.9
    score: ScoreSection = ScoreSection()
    silhouette_term: SilhouetteTermConfig = SilhouetteTermConfig()

    def __post_init__(self):
        from .searches import SEARCH_NAMES

        _check(self.method in SEARCH_NAMES, "ImageConfig.method",
               f"unknown search {self.method!r}; valid: {', '.join(SEARCH_NAMES)}")
        _check(0 < self.template_min_visible <= 1, "ImageConfig.template_min_visible",
               f"must lie in (0, 1], got {self.template_min_visible!r}")
        _check(0 <= self.width_gain <= 1, "ImageConfig.width_gain", f"must lie in [0, 1], got {self.width_gain!r}")
        _check(all(0 < a <= 90 for a in self.reacquire_deg), "ImageConfig.reacquire_deg",
               f"angles must lie in (0, 90] degrees, got {self.reacquire_deg!r}")
        _check(0 <= self.reacquire_min_visible <= 1, "ImageConfig.reacquire_min_visible",
               f"must lie in [0, 1], got {self.reacquire_min_visible!r}")

    def replace(self, **changes) -> ImageConfig:
        """A copy with some fields changed (``config.replace(method="gaussian")``)."""
        return dataclasses.replace(self, **changes)
