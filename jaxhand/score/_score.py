"""The global image score: the whole model against the whole image (thesis ch. 7, issue 13 item 3).

The feature residuals only say how well each link's edges were found along its own profiles; a
model that slid onto the wrong finger, or onto clutter, can fit those edges well. The global score
compares the model's silhouette with the image everywhere, in two independent ways:

1. **Region**: the silhouette S against the foreground F (:mod:`._foreground`), inside a region of
   interest (the silhouette's bounding box grown by ``roi_margin_px``, so a forearm or a second
   object far from the hand does not count): ``iou = |S n F| / |S u F|`` and
   ``coverage = |S n F| / |S|`` (the share of the model on the foreground; it ignores foreground
   the model lacks, such as a palm).
2. **Contour** (chamfer): the model's contour C (the silhouette's outline, plus the boundaries
   between overlapping capsules that do not touch end to end: occluding contours) against the
   image's edges E (Canny): the distance transform ``D`` of E gives each contour pixel its
   distance to the nearest image edge; ``chamfer_px = mean(min(D, tau))`` over C and
   ``chamfer_score = 1 - chamfer_px / tau``. Measured model to image only, so clutter edges away
   from the model cost nothing.

3. **Worst link**: one finger on the wrong place moves the whole-hand figures by a few percent
   only, so each tracked (non-occluder) link also gets its own ``link_score``, the mean of its
   visible pixels' coverage and its own contour's chamfer score, and ``worst_link`` is the lowest
   of them over links with at least ``min_link_px`` visible pixels.

``score`` is the weighted mean of iou, coverage, chamfer_score and worst_link, in [0, 1] (1: the
model covers the foreground exactly and every contour pixel lies on an image edge).

Pixels the foreground model cannot call (:meth:`~jaxhand.score.AbstractForeground.doubtful`: a
learned background's pixel that matches a mode a hand part may have taught it) count on neither
side of the region figures and the links' coverage.

The image side (foreground, edge distance) is computed once per frame by :func:`image_evidence`
and shared by every hypothesis scored on that frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from jaxtyping import Bool, Float

from .._errors import InputError
from ._foreground import AbstractForeground, as_grey
from ._silhouette import Capsules, Silhouette, camera_numbers, capsules_from_model, capsules_from_model_batch, rasterize

__all__ = ["ScoreConfig", "ImageEvidence", "ImageScore", "image_evidence", "model_contour", "score_silhouette",
           "score_frame", "score_poses"]


@dataclass(frozen=True)
class ScoreConfig:
    """How the image score is computed (host values; nothing here is traced).

    Attributes:
        canny_low, canny_high: Canny hysteresis thresholds (grey-level gradient, Sobel 3x3).
        blur_sigma_px: Gaussian blur before Canny (px); 0 for none. Noise and texture make
            spurious edges, which only make the chamfer score too kind.
        chamfer_tau_px: distances are truncated at tau (px): a contour pixel farther than this
            from any edge counts as missing, whatever the distance.
        roi_margin_px: the region-of-interest margin around the silhouette's bounding box (px);
            None compares whole images.
        occluding_contours: include the boundaries between overlapping capsules in the contour.
        w_iou, w_coverage, w_chamfer, w_worst_link: weights of the four parts in ``score`` (>= 0,
            not all 0).
        min_link_px: links with fewer visible pixels are not judged on their own (px).
        rim_points: samples on each sphere's rim when rasterising (see :func:`rasterize`).
        side_edge_px: the reach (px) along each link side's normal within which
            :meth:`jaxhand.ImageFrontEnd.support` looks for an edge across the side
            (:mod:`jaxhand.score._sides`); each link's support is then at most the share of its
            visible side points that find one: a finger lying wrongly over the hand finds the
            hand's edges near its outline, but few of them run along its sides (0: off).
        side_edge_gradient: the gradient across a side (grey levels per px, after the blur) that
            counts as its edge.
        side_fractions: where along each link its side points lie (0: start, 1: end).
    """

    canny_low: float = 20.0
    canny_high: float = 50.0
    blur_sigma_px: float = 1.0
    chamfer_tau_px: float = 5.0
    roi_margin_px: int | None = 20
    occluding_contours: bool = True
    w_iou: float = 1.0
    w_coverage: float = 1.0
    w_chamfer: float = 1.0
    w_worst_link: float = 1.0
    min_link_px: int = 30
    rim_points: int = 32
    side_edge_px: float = 0.0
    side_edge_gradient: float = 8.0
    side_fractions: tuple[float, ...] = (0.15, 0.25, 0.35, 0.45, 0.55, 0.65, 0.75, 0.85)

    def __post_init__(self):
        w = self.weights
        if not (np.all(np.isfinite(w)) and np.all(w >= 0) and w.sum() > 0):
            raise InputError(f"ScoreConfig: weights must be finite, >= 0 and not all 0, got {w.tolist()}")
        if not self.chamfer_tau_px > 0:
            raise InputError(f"ScoreConfig.chamfer_tau_px: need > 0, got {self.chamfer_tau_px!r}")
        if not 0 <= self.canny_low <= self.canny_high:
            raise InputError(f"ScoreConfig: need 0 <= canny_low <= canny_high, got {self.canny_low!r}, "
                             f"{self.canny_high!r}")
        if not (np.isfinite(self.side_edge_px) and self.side_edge_px >= 0
                and np.isfinite(self.side_edge_gradient) and self.side_edge_gradient > 0):
            raise InputError(f"ScoreConfig.side_edge_px, side_edge_gradient: need >= 0 and > 0, got "
                             f"{self.side_edge_px!r}, {self.side_edge_gradient!r}")
        if not (len(self.side_fractions) and all(0 <= f <= 1 for f in self.side_fractions)):
            raise InputError(f"ScoreConfig.side_fractions: need at least one fraction in [0, 1], got "
                             f"{self.side_fractions!r}")
        if self.roi_margin_px is not None and self.roi_margin_px < 0:
            raise InputError(f"ScoreConfig.roi_margin_px: need >= 0 or None, got {self.roi_margin_px!r}")

    @property
    def weights(self) -> np.ndarray:
        """(iou, coverage, chamfer, worst link) weights as an array."""
        return np.array([self.w_iou, self.w_coverage, self.w_chamfer, self.w_worst_link], float)


@dataclass(frozen=True)
class ImageEvidence:
    """One frame's side of the comparison.

    Attributes:
        foreground: (H, W) bool foreground mask.
        edges: (H, W) bool Canny edges.
        edge_distance_px: (H, W) float32 distance of every pixel centre to the nearest edge pixel (px).
        doubtful: (H, W) bool, foreground pixels the foreground model cannot call
            (:meth:`~jaxhand.score.AbstractForeground.doubtful`), left out of the scores; None: none.
    """

    foreground: Bool[np.ndarray, "H W"]
    edges: Bool[np.ndarray, "H W"]
    edge_distance_px: Float[np.ndarray, "H W"]
    doubtful: Bool[np.ndarray, "H W"] | None = None


@dataclass(frozen=True)
class ImageScore:
    """The score of one model pose on one frame.

    Attributes:
        score: weighted mean of iou, coverage, chamfer_score and worst_link, in [0, 1].
        iou: |S n F| / |S u F| in the region of interest (0 when both are empty).
        coverage: |S n F| / |S| (0 for an empty silhouette).
        chamfer_px: mean truncated distance of the model's contour to the image's edges (px).
        chamfer_score: 1 - chamfer_px / tau, in [0, 1].
        worst_link: the lowest ``link_score`` of a judged link (0 when none is judged).
        worst_link_index: that link's capsule index (-1 when none).
        link_score: (n,) per capsule, mean of its coverage and its contour's chamfer score (NaN
            for capsules not judged: occluders, or fewer than ``min_link_px`` visible pixels).
        silhouette_px: pixels of the silhouette (the doubtful ones left out); contour_px: pixels of
            its contour.
    """

    score: float
    iou: float
    coverage: float
    chamfer_px: float
    chamfer_score: float
    worst_link: float
    worst_link_index: int
    link_score: Float[np.ndarray, " n"]
    silhouette_px: int
    contour_px: int


def image_evidence(image, foreground: AbstractForeground | np.ndarray, config: ScoreConfig = ScoreConfig()
                   ) -> ImageEvidence:
    """Foreground mask and edge distance of one frame.

    Args:
        image: (H, W) grey or (H, W, 3) BGR frame.
        foreground: a foreground model, or a ready (H, W) bool mask.
        config: edge settings.

    Raises:
        InputError: a malformed image, or a mask of another size.
    """
    grey = as_grey(image)
    fg = foreground.mask(image) if isinstance(foreground, AbstractForeground) else np.asarray(foreground, bool)
    if fg.shape != grey.shape:
        raise InputError(f"foreground: expected a mask of shape {grey.shape}, got {fg.shape}")
    g = cv2.GaussianBlur(grey, (0, 0), config.blur_sigma_px) if config.blur_sigma_px > 0 else grey
    edges = cv2.Canny(g, config.canny_low, config.canny_high, L2gradient=True) > 0
    # distanceTransform measures to the nearest zero pixel: edges are the zeros.
    # The 5x5 chamfer mask is within 2 % of exact L2 and twice as fast as DIST_MASK_PRECISE.
    dist = cv2.distanceTransform(np.where(edges, 0, 255).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_5)
    doubtful = foreground.doubtful(image, fg) if isinstance(foreground, AbstractForeground) else None
    return ImageEvidence(foreground=fg, edges=edges, edge_distance_px=dist,
                         doubtful=doubtful if doubtful is not None and doubtful.any() else None)


def model_contour(silhouette: Silhouette, *, occluding: bool = True) -> Bool[np.ndarray, "H W"]:
    """(H, W) bool: the silhouette's outline and, optionally, its occluding contours.

    A model pixel is on the contour when a 4-neighbour shows the background (outline), or another
    capsule that does not touch its own end to end (occluding contour; both sides are marked).
    """
    out = np.zeros(silhouette.mask.shape, bool)
    rows, cols = silhouette.crop()
    out[rows, cols] = _contour_crop(silhouette, occluding)
    return out


def _contour_crop(silhouette: Silhouette, occluding: bool) -> np.ndarray:
    """:func:`model_contour` on the silhouette's box (the box has a background margin of 1 px,
    except where it meets the image border, which counts as background as in the full image)."""
    rows, cols = silhouette.crop()
    mask = silhouette.mask[rows, cols]
    if mask.size == 0:
        return np.zeros(mask.shape, bool)
    # The outline: model pixels with a background 4-neighbour (mask minus its 4-erosion).
    cross = cv2.getStructuringElement(cv2.MORPH_CROSS, (3, 3))
    inner = cv2.erode(mask.astype(np.uint8), cross, borderType=cv2.BORDER_CONSTANT, borderValue=0).astype(bool)
    out = mask & ~inner
    if not occluding or len(silhouette.occluder) < 2:
        return out
    lab = silhouette.label[rows, cols]
    touch = silhouette.adjacent | np.eye(len(silhouette.occluder), dtype=bool)
    for sl_a, sl_b in (((slice(None), slice(None, -1)), (slice(None), slice(1, None))),
                       ((slice(None, -1), slice(None)), (slice(1, None), slice(None)))):
        a, b = lab[sl_a], lab[sl_b]
        ys, xs = np.nonzero((a != b) & (a >= 0) & (b >= 0))  # label changes inside the model only
        occl = ~touch[a[ys, xs], b[ys, xs]]
        ys, xs = ys[occl], xs[occl]
        out[sl_a][ys, xs] = True
        out[sl_b][ys, xs] = True
    return out


def _roi(mask: np.ndarray, margin: int | None) -> tuple[slice, slice]:
    if margin is None or not mask.any():
        return slice(None), slice(None)
    x, y, w, h = cv2.boundingRect(mask.astype(np.uint8))
    return slice(max(y - margin, 0), y + h + margin), slice(max(x - margin, 0), x + w + margin)


def score_silhouette(silhouette: Silhouette, evidence: ImageEvidence, config: ScoreConfig = ScoreConfig()
                     ) -> ImageScore:
    """Score one rasterised pose against one frame's evidence (see the module docstring)."""
    S = silhouette.mask
    if S.shape != evidence.foreground.shape:
        raise InputError(f"silhouette: shape {S.shape} differs from the frame's {evidence.foreground.shape}")
    rows, cols = _roi(S, config.roi_margin_px)
    s, f = S[rows, cols], evidence.foreground[rows, cols]
    if evidence.doubtful is not None:   # neither side's
        known = ~evidence.doubtful[rows, cols]
        s, f = s & known, f & known
    inter = int(np.count_nonzero(s & f))
    union = int(np.count_nonzero(s | f))
    n_s = int(np.count_nonzero(s))   # the box holds all of S
    iou = inter / union if union else 0.0
    coverage = inter / n_s if n_s else 0.0
    box_rows, box_cols = silhouette.crop()
    contour = _contour_crop(silhouette, config.occluding_contours)  # on the box only
    n_c = int(np.count_nonzero(contour))
    tau = float(config.chamfer_tau_px)
    dist = evidence.edge_distance_px[box_rows, box_cols]
    chamfer_px = float(np.minimum(dist[contour], tau).mean()) if n_c else tau
    chamfer_score = 1.0 - chamfer_px / tau
    link_score = _link_scores(silhouette, evidence, contour, config)
    judged = np.isfinite(link_score)
    worst_i = int(np.argmin(np.where(judged, link_score, np.inf))) if judged.any() else -1
    worst = float(link_score[worst_i]) if worst_i >= 0 else 0.0
    w = config.weights
    score = float(w @ np.array([iou, coverage, chamfer_score, worst]) / w.sum())
    return ImageScore(score=score, iou=iou, coverage=coverage, chamfer_px=chamfer_px, chamfer_score=chamfer_score,
                      worst_link=worst, worst_link_index=worst_i, link_score=link_score, silhouette_px=n_s,
                      contour_px=n_c)


def _link_scores(silhouette: Silhouette, evidence: ImageEvidence, contour: np.ndarray, config: ScoreConfig
                 ) -> np.ndarray:
    """Per capsule: mean of its visible pixels' foreground share and its contour's chamfer score
    (``contour`` is on the silhouette's box)."""
    n = len(silhouette.occluder)
    rows, cols = silhouette.crop()
    lab = silhouette.label[rows, cols]
    inside = silhouette.mask[rows, cols]
    if evidence.doubtful is not None:   # a doubtful pixel supports no link and counts against none
        inside = inside & ~evidence.doubtful[rows, cols]
    ids = lab[inside]
    vis = np.bincount(ids, minlength=n)
    on = np.bincount(ids, weights=evidence.foreground[rows, cols][inside], minlength=n)
    tau = float(config.chamfer_tau_px)
    cids = lab[contour]
    cnt = np.bincount(cids, minlength=n)
    dist = np.bincount(cids, weights=np.minimum(evidence.edge_distance_px[rows, cols][contour], tau), minlength=n)
    judged = ~silhouette.occluder & (vis >= config.min_link_px) & (cnt > 0)
    cover = on / np.maximum(vis, 1)
    chamfer = 1.0 - dist / np.maximum(cnt, 1) / tau
    return np.where(judged, 0.5 * (cover + chamfer), np.nan)


def score_frame(model, camera, q, image, foreground: AbstractForeground | np.ndarray, *,
                occluders: Capsules | None = None, config: ScoreConfig = ScoreConfig()) -> ImageScore:
    """The image score of ``model`` at state ``q`` on one frame (the convenience entry point).

    Args:
        model: the tracked model; its pills are drawn.
        camera: the camera that took ``image``.
        q: (n_q,) state (rad, mm).
        image: the frame, (H, W) grey or (H, W, 3) BGR, of the camera's size.
        foreground: a foreground model or a ready mask.
        occluders: scene capsules the model lacks (a static palm, a forearm), drawn as well.
        config: score settings.
    """
    caps = capsules_from_model(model, q)
    if occluders is not None:
        caps = caps + occluders
    sil = rasterize(caps, camera, rim_points=config.rim_points)
    return score_silhouette(sil, image_evidence(image, foreground, config), config)


def score_poses(model, camera, qs, evidence: ImageEvidence, *, occluders: Capsules | None = None,
                config: ScoreConfig = ScoreConfig()) -> list[ImageScore]:
    """Scores of several poses (hypotheses) on one frame whose evidence is already computed.

    Args:
        model: the tracked model.
        camera: the camera of the frame.
        qs: (k, n_q) states; the kinematics of all of them is one vmapped call.
        evidence: :func:`image_evidence` of the frame.
        occluders: scene capsules the model lacks, drawn with every pose.
        config: score settings.

    Returns:
        One :class:`ImageScore` per row of ``qs``.
    """
    cam = camera_numbers(camera)
    out = []
    for caps in capsules_from_model_batch(model, qs):
        if occluders is not None:
            caps = caps + occluders
        out.append(score_silhouette(rasterize(caps, cam, rim_points=config.rim_points), evidence, config))
    return out
