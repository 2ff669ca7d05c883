"""The image front end's settings of the global image score (``ImageConfig.score``), and the
foreground model they choose for a frame."""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np

from .._errors import InputError
from ._foreground import (
    THRESHOLD_METHODS,
    AbstractForeground,
    BackgroundForeground,
    SkinForeground,
    ThresholdForeground,
)
from ._score import ScoreConfig
from ._sequence import ColourSequenceBackground, SequenceBackground
from ._silhouette import capsules_from_model, rasterize

__all__ = ["FOREGROUNDS", "ScoreSection", "foreground_for", "foreground_kind", "sequence_foreground",
           "skin_foreground"]

#: The foreground choices of :attr:`ScoreSection.foreground`.
FOREGROUNDS = ("auto", "threshold", "background", "sequence", "skin", "none")


@dataclasses.dataclass(frozen=True)
class ScoreSection:
    """How :meth:`jaxhand.ImageFrontEnd.score` scores poses (host values).

    ``"auto"`` takes the skin model on colour frames (BGR with any chroma) and the histogram
    threshold on grey ones: jaxhand's frame sources deliver grey frames, and the dark backgrounds
    of the thesis and the dev set suit a threshold. A background learned from the first frames is
    not offered: the dev set's palm and forearm never move, so they would be learned as
    background; give a background image instead.

    Attributes:
        foreground: "auto" (skin on colour, a threshold on grey), "threshold", "background"
            (needs ``background_image``), "sequence" (a still camera over any background: a
            :class:`SequenceBackground` learned from ``sequence_frames`` frames spread over the
            sequence, anchored at the model's silhouette at the first pose, and from the tracked
            poses as tracking goes; built by the front end from the frames
            :func:`jaxhand.track_sequence` passes it), "skin",
            or "none" (the default): no image score, the
            tracker judges frames by their residuals alone. Off by default: a frame lost by the
            score is held, and without recovery that costs jaxhand's own experiments more than the
            better loss flag gains (benchmarks/README.md).
        threshold_method: :class:`ThresholdForeground` method ("triangle", "otsu", "fixed").
        threshold: the grey level of the "fixed" method (0..255).
        background_image: path of an image of the empty scene, for "background".
        background_difference: grey-level difference from the background that counts as foreground.
        sequence_frames: how many frames, spread evenly over the sequence, "sequence" learns from.
        skin_max_distance: Mahalanobis distance of the generic skin model's chrominance (see
            :class:`SkinForeground`).
        skin_fit: "skin" (and "auto" on colour frames) fits the skin model to the hand's own
            colour in the first frame, inside the model's silhouette at the first pose
            (:func:`skin_foreground`), rather than the generic model: a generic skin colour also
            takes wood, walls and clothes under warm light.
        skin_fit_distance: the Mahalanobis distance of the fitted model.
        silhouette: how a silhouette is compared with the frame (:class:`ScoreConfig`).
    """

    foreground: str = "none"
    threshold_method: str = "triangle"
    threshold: float = 10.0
    background_image: str = ""
    background_difference: float = 12.0
    sequence_frames: int = 60
    skin_max_distance: float = 2.5
    skin_fit: bool = True
    skin_fit_distance: float = 3.5
    silhouette: ScoreConfig = ScoreConfig()

    def __post_init__(self):
        if self.foreground not in FOREGROUNDS:
            raise InputError(f"score.foreground: must be one of {', '.join(FOREGROUNDS)}, got {self.foreground!r}")
        if self.threshold_method not in THRESHOLD_METHODS:
            raise InputError(f"score.threshold_method: must be one of {', '.join(THRESHOLD_METHODS)}, "
                             f"got {self.threshold_method!r}")
        if self.foreground == "background" and not self.background_image:
            raise InputError("score.background_image: foreground 'background' needs the path of an image of the "
                             "empty scene")
        if not (isinstance(self.sequence_frames, int) and self.sequence_frames >= 3):
            raise InputError(f"score.sequence_frames: need an integer >= 3, got {self.sequence_frames!r}")
        for name in ("skin_max_distance", "skin_fit_distance"):
            if not getattr(self, name) > 0:
                raise InputError(f"score.{name}: need > 0, got {getattr(self, name)!r}")
        if not isinstance(self.skin_fit, bool):
            raise InputError(f"score.skin_fit: expected true or false, got {self.skin_fit!r}")
        if not isinstance(self.silhouette, ScoreConfig):
            raise InputError(f"score.silhouette: expected a ScoreConfig, got {type(self.silhouette).__name__}")

    @property
    def enabled(self) -> bool:
        """Whether poses are scored at all."""
        return self.foreground != "none"

    @property
    def reads_colour(self) -> bool:
        """Whether the foreground reads colour ("skin", "sequence"): frame sources should then
        keep colour (:func:`jaxhand.io.open_frames`; grey frames stay grey). "auto" keeps to grey
        frames, and so to the threshold, unless the caller opens colour frames itself."""
        return self.foreground in ("skin", "sequence")

    @property
    def needs_colour(self) -> bool:
        """Whether the foreground fails on grey frames ("skin"; "sequence" learns from either)."""
        return self.foreground == "skin"


def _is_colour(image: np.ndarray) -> bool:
    a = np.asarray(image)
    return a.ndim == 3 and a.shape[2] == 3 and not (np.array_equal(a[..., 0], a[..., 1])
                                                    and np.array_equal(a[..., 1], a[..., 2]))


def foreground_kind(section: ScoreSection, image) -> str:
    """The foreground ``section`` takes for ``image``: its own, or for "auto" "skin" on colour
    frames and "threshold" on grey ones."""
    if section.foreground == "auto":
        return "skin" if _is_colour(image) else "threshold"
    return section.foreground


def foreground_for(section: ScoreSection, image) -> AbstractForeground:
    """The foreground model ``section`` chooses for ``image`` (the "auto" rule in :class:`ScoreSection`).

    Raises:
        InputError: foreground "none", or a background image that cannot be read.
    """
    kind = foreground_kind(section, image)
    if kind == "threshold":
        return ThresholdForeground(method=section.threshold_method, threshold=section.threshold)
    if kind == "skin":
        if not _is_colour(image):
            raise InputError("score.foreground 'skin' reads colour, but the frames are grey: give colour frames "
                             "(jaxhand.io.open_frames(..., colour=True)) or choose 'sequence' or 'threshold'")
        return SkinForeground(max_distance=section.skin_max_distance)
    if kind == "background":
        bg = cv2.imread(section.background_image, cv2.IMREAD_UNCHANGED)
        if bg is None:
            raise InputError(f"score.background_image: cannot read {section.background_image!r} as an image")
        return BackgroundForeground.from_image(bg, difference=section.background_difference)
    if kind == "sequence":
        raise InputError("score.foreground 'sequence' learns from the whole sequence: track with "
                         "jaxhand.track_sequence (or `jaxhand track`), or give ImageFrontEnd background_frames")
    raise InputError("score.foreground is 'none': no foreground model")


def sequence_foreground(model, camera, q0, frames) -> SequenceBackground | ColourSequenceBackground:
    """The "sequence" foreground of one camera: a :class:`SequenceBackground` of ``frames`` (a
    :class:`ColourSequenceBackground` where they are in colour) seeded by the model's silhouette
    (pills and occluders) at the first frame's pose ``q0``."""
    mask = rasterize(capsules_from_model(model, np.asarray(q0, float)), camera).mask
    if len(frames) and _is_colour(frames[0]):
        return ColourSequenceBackground(frames, mask)
    return SequenceBackground(frames, mask)


def skin_foreground(model, camera, q0, image, section: ScoreSection) -> AbstractForeground:
    """The "skin" foreground of one camera for a sequence whose first frame is ``image``: with
    ``section.skin_fit``, a :class:`SkinForeground` fitted to the pixels of ``image`` the generic
    model calls skin inside the model's silhouette at the first pose ``q0`` (shrunk by 2 px, off
    the outline), holes under 100 px filled; the generic model where half of that
    silhouette is not skin (the first pose is not on the hand) or without ``skin_fit``."""
    generic = foreground_for(dataclasses.replace(section, foreground="skin"), image)
    if not section.skin_fit:
        return generic
    mask = rasterize(capsules_from_model(model, np.asarray(q0, float)), camera).mask
    inside = cv2.erode(mask.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
    skin = inside & generic.mask(image)
    if skin.sum() < max(10, 0.5 * inside.sum()):
        return generic
    return SkinForeground.fit(image, skin, max_distance=section.skin_fit_distance, fill_px=100)
