"""Front ends: what turns a frame's images into :class:`~jaxhand.features.Features`.

The tracker measures with a front end and estimates with the solver; the front end never
solves. :class:`AbstractFrontEnd` is the interface the tracker calls; the final classes are the
image front end (:class:`ImageFrontEnd`) and the exact-feature oracle (:class:`ExactFrontEnd`).
"""

from __future__ import annotations

import abc
import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any, ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._errors import InputError
from ..camera import as_rig
from ..features import Features, features_from_pose
from ..image import ImageConfig, ImageState, WindowOutlines, extract_features, refresh_templates, update_widths
from ..image.searches import TEMPLATE_SEARCHES
from ..model import Model
from ..score import (
    AbstractForeground,
    camera_numbers,
    capsules_from_model_batch,
    foreground_for,
    foreground_kind,
    frame_digest,
    image_evidence,
    rasterize,
    roi_box,
    score_silhouette,
    sequence_foreground,
    side_edge_share,
    silhouette_term,
    skin_foreground,
)
from ._support import ImageSupport, largest_unexplained_px

__all__ = ["AbstractFrontEnd", "FrontEndDiagnostics", "FrontEndResult", "ImageFrontEnd", "ExactFrontEnd",
           "image_front_end"]

@dataclasses.dataclass(frozen=True)
class FrontEndDiagnostics:
    """What a front end reports about one extraction besides the features.

    Attributes:
        windows: per camera, the visibility window polygons (a :class:`jaxhand.image.WindowOutlines`,
            converted when read; for overlays), or None.
        timings_s: the front end's own stage timings (s), e.g. ``{"visibility": ...}``.
        method: the feature search used ("" when none).
    """

    windows: Sequence | None = None
    timings_s: Mapping[str, float] = dataclasses.field(default_factory=dict)
    method: str = ""


@dataclasses.dataclass(frozen=True)
class FrontEndResult:
    """One extraction: the features (one per camera), the front end's next state, diagnostics,
    and the frame's extra measured solve terms (:class:`jaxhand.priors.AbstractTerm`, e.g. the
    silhouette term), which the tracker adds to every solve of the frame."""

    features: tuple[Features, ...]
    state: Any
    diagnostics: FrontEndDiagnostics = FrontEndDiagnostics()
    terms: tuple = ()


class AbstractFrontEnd(abc.ABC):
    """The interface between the tracker and whatever measures features.

    Subclasses implement :meth:`extract`; :meth:`refresh` (updating the state at the solved
    pose) defaults to returning the state unchanged, :meth:`observe` (learning from the frame's
    estimate) to nothing, :meth:`score` (the global image score of candidate poses) to None.
    :attr:`reextracts` says whether searching again around the solved pose can find better
    features (:attr:`TrackConfig.reextract`).
    """

    #: Whether a second extraction around the solved pose of the same frame can help.
    reextracts: ClassVar[bool] = True

    @abc.abstractmethod
    def extract(self, images: Sequence[np.ndarray | None], q_start: np.ndarray, state: Any, frame: int
                ) -> FrontEndResult:
        """Features of frame ``frame`` (its ``images``, one per camera) searched around the state
        ``q_start``, given the front end's ``state`` (None before the first frame)."""

    def refresh(self, images: Sequence[np.ndarray | None], q: np.ndarray | None, state: Any) -> Any:
        """The front end's state updated at the solved pose ``q`` (after a frame not lost)."""
        return state

    def observe(self, images: Sequence[np.ndarray | None], q: np.ndarray) -> None:
        """Learn from the frame's reported estimate ``q`` (after a frame not lost): nothing by default."""
        return None

    def score(self, images: Sequence[np.ndarray | None], qs: np.ndarray, state: Any) -> np.ndarray | None:
        """The global image score in [0, 1] (1: the model's silhouette matches the image) of each
        candidate pose ``qs`` (k, n_q) of this frame, or None when the front end has no image
        score (the default): the tracker then judges poses by their residuals alone."""
        return None

    @property
    def scores(self) -> bool:
        """Whether :meth:`score` may give scores (by default, whether a subclass overrides it).
        Without them the tracker chooses among its starts in the compiled frame program."""
        return type(self).score is not AbstractFrontEnd.score

    def support(self, images: Sequence[np.ndarray | None], q: np.ndarray, state: Any, margin_px: int = 1
                ) -> ImageSupport | None:
        """The image's support of the pose ``q`` (:class:`~jaxhand.track.ImageSupport`:
        per link, and the foreground it leaves unexplained beyond ``margin_px``), or None when the
        front end measures none (the default)."""
        return None


class ImageFrontEnd(AbstractFrontEnd):
    """The image front end: :func:`jaxhand.image.extract_features` carrying its state
    (templates, phalanx widths) from frame to frame.

    :meth:`extract` searches around ``q_start``; on the first frame with
    ``config.width_gain`` > 0 the radii measured at the hand-set pose replace the model's at
    once. :meth:`refresh` re-estimates the widths and re-takes the templates at the solved pose
    (thesis §4.3.1: templates come from unoccluded views) where the frame vouches for that pose
    (:func:`jaxhand.image.refresh_templates`, ``config.refresh``); a search that keeps no templates with
    no width estimate returns the state untouched. :meth:`score` scores poses with
    ``config.score`` (None when its foreground is "none"). With ``config.silhouette_term`` on,
    every extraction also returns the frame's silhouette terms, one per camera.
    """

    reextracts: ClassVar[bool] = True

    def __init__(self, model: Model, cameras, config: ImageConfig | None = None, *,
                 background_frames: Sequence[np.ndarray] | None = None,
                 foregrounds: Sequence[AbstractForeground] | None = None):
        """``background_frames``: per camera, (N, H, W[, 3]) frames spread over the sequence, the
        first of them the sequence's first frame, for the "sequence" foreground (``config.score``).
        ``foregrounds``: per camera, a foreground model that replaces the one ``config.score``
        chooses (a caller's own segmentation), wherever a foreground is read."""
        self.model, self.cameras = model, as_rig(cameras)
        self.config = ImageConfig() if config is None else config
        if background_frames is not None and len(background_frames) != len(self.cameras):
            raise InputError(f"background_frames: expected one stack per camera ({len(self.cameras)}), "
                             f"got {len(background_frames)}")
        if foregrounds is not None and (len(foregrounds) != len(self.cameras)
                                        or not all(isinstance(f, AbstractForeground) for f in foregrounds)):
            raise InputError(f"foregrounds: expected one jaxhand.score.AbstractForeground per camera "
                             f"({len(self.cameras)}), got {foregrounds!r}")
        self.background_frames = background_frames
        self._given_fg = None if foregrounds is None else tuple(foregrounds)
        self._sequence_fg: tuple | None = None   # the "sequence" foregrounds, built at the first frame's pose
        self._skin_fg: tuple | None = None   # the "skin" foregrounds, fitted at the first frame's pose
        self._cams = tuple(camera_numbers(c) for c in self.cameras) if self.config.score.enabled else ()
        self._evidence: tuple[tuple[bytes, ...], tuple] | None = None   # the last frame's, by content
        self._terms: tuple[int, tuple] | None = None   # the last frame's silhouette terms, by frame number
        self._rims: tuple[float, ...] | None = None   # per camera, the measured rim_px where it is "auto"

    def extract(self, images, q_start, state: ImageState | None, frame: int) -> FrontEndResult:
        q = np.asarray(q_start)
        if self.config.width_gain > 0 and (state is None or state.radius_mm is None):
            state = update_widths(images, self.model, self.cameras, q, self.config, state, gain=1.0,
                                  fill_unmeasured=True)
        if self.background_frames is not None and self._sequence_fg is None:
            self._sequence_fg = tuple(sequence_foreground(self.model, cam, q, frames)
                                      for cam, frames in zip(self.cameras, self.background_frames))
        if self._skin_fg is None and self._given_fg is None:
            section = self._section()
            self._skin_fg = tuple(skin_foreground(self.model, cam, q, im, section)
                                  if im is not None and foreground_kind(section, im) == "skin" else None
                                  for cam, im in zip(self._cameras(), images))
        features, diag = extract_features(images, self.model, self.cameras, q, self.config, state)
        timings = dict(diag.timings_s) if diag.timings_s else {}
        return FrontEndResult(tuple(features), diag.state,
                              FrontEndDiagnostics(windows=WindowOutlines(diag), timings_s=timings, method=diag.method),
                              self._silhouette_terms(images, frame, q))

    def _silhouette_terms(self, images, frame: int, q: np.ndarray) -> tuple:
        """The frame's silhouette terms, built at its first extraction, their foreground outline
        limited to the region of interest of the model at that extraction's start ``q``."""
        config = self.config.silhouette_term
        if not config.enabled:
            return ()
        if self._terms is None or self._terms[0] != frame:
            section = self._section()
            boxes = [None] * len(images)
            if config.roi_margin is not None:
                caps = capsules_from_model_batch(self.model, q.astype(float).reshape(1, -1))[0]
                boxes = [roi_box(rasterize(caps, cam).mask, config.roi_margin, config.roi_min_px)
                         for cam in self._cameras()]
            rims = self._rims or (None,) * len(images)
            terms = tuple(silhouette_term(im, self._foreground(section, c, im), c, config, box=box, rim_px=rim)
                          for c, (im, box, rim) in enumerate(zip(images, boxes, rims)))
            if config.rim_px == "auto" and self._rims is None:   # the first frame: its pose is the caller's
                self._rims = tuple(-t.bind(self.model, self.cameras).outline_bias_px(q) for t in terms)
                terms = tuple(eqx.tree_at(lambda t: t.rim_px, t, jnp.asarray(rim, t.rim_px.dtype))
                              for t, rim in zip(terms, self._rims))
            self._terms = (frame, terms)
        return self._terms[1]

    @property
    def rims_px(self) -> tuple[float, ...] | None:
        """Per camera, the ``silhouette_term.rim_px`` measured at the first frame's pose where it
        is "auto" (None before that frame, or where it is not)."""
        return self._rims

    def refresh(self, images, q, state: ImageState | None) -> ImageState | None:
        q = np.asarray(q)
        if self.config.width_gain > 0:
            state = update_widths(images, self.model, self.cameras, q, self.config, state)
        if self.config.method not in TEMPLATE_SEARCHES:
            return state
        return refresh_templates(images, self.model, self.cameras, q, self.config, state)

    def observe(self, images, q) -> None:
        """The "sequence" foregrounds learn the background where the model at ``q`` leaves each
        camera's image free (:meth:`jaxhand.score.SequenceBackground.observe`)."""
        if self._sequence_fg is None:
            return
        caps = capsules_from_model_batch(self.model, np.asarray(q, float).reshape(1, -1))[0]
        for fg, cam, image in zip(self._sequence_fg, self._cameras(), images):
            if image is not None:
                fg.observe(image, rasterize(caps, cam).mask)

    @property
    def scores(self) -> bool:
        return self.config.score.enabled

    def score(self, images, qs, state) -> np.ndarray | None:
        """The mean over cameras of :func:`jaxhand.score.score_silhouette` of each pose (the
        model's pills and occluder pills drawn) against each camera's image. The frame's evidence
        (foreground and edge distance) is computed once and kept for further calls on the same
        images (recognised by their content)."""
        section = self.config.score
        if not section.enabled:
            return None
        qs = np.asarray(qs, float).reshape(-1, self.model.n_q)
        evidence = self._frame_evidence(images)
        scores = np.zeros((len(qs), len(self.cameras)))
        for k, caps in enumerate(capsules_from_model_batch(self.model, qs)):
            for c, (cam, ev) in enumerate(zip(self._cams, evidence)):
                sil = rasterize(caps, cam, rim_points=section.silhouette.rim_points)
                scores[k, c] = score_silhouette(sil, ev, section.silhouette).score
        return scores.mean(1)

    def support(self, images, q, state, margin_px: int = 1) -> ImageSupport:
        """Each link's :func:`jaxhand.score.score_silhouette` link score at ``q`` per camera (at
        most its :func:`jaxhand.score.side_edge_share` where ``side_edge_px`` is set) and the
        largest 8-connected blob of foreground outside the silhouette grown by ``margin_px``, on
        the score's foreground ("auto" where the score is off, as for the silhouette term)."""
        section = self._section()
        caps = capsules_from_model_batch(self.model, np.asarray(q, float).reshape(1, -1))[0]
        links, unexplained = [], 0
        for c, (cam, ev) in enumerate(zip(self._cameras(), self._frame_evidence(images))):
            sil = rasterize(caps, cam, rim_points=section.silhouette.rim_points)
            score = score_silhouette(sil, ev, section.silhouette).link_score[:self.model.n_links]
            if section.silhouette.side_edge_px > 0:
                share = side_edge_share(images[c], self.model, self.cameras[c], q, section.silhouette)
                score = np.where(np.isfinite(share), np.minimum(score, share), score)   # NaN score: not judged
            links.append(score)
            fg = ev.foreground if ev.doubtful is None else ev.foreground & ~ev.doubtful
            unexplained = max(unexplained, largest_unexplained_px(fg, sil.mask, margin_px))
        return ImageSupport(link_score=np.stack(links), unexplained_px=float(unexplained))

    def _section(self):
        """The score's settings, with the "auto" foreground where the score itself is off."""
        section = self.config.score
        return section if section.enabled else dataclasses.replace(section, foreground="auto")

    def _cameras(self) -> tuple:
        return self._cams or tuple(camera_numbers(c) for c in self.cameras)

    def _frame_evidence(self, images) -> tuple:
        key = tuple(frame_digest(im) for im in images)
        if self._evidence is None or self._evidence[0] != key:
            section = self._section()
            self._evidence = (key, tuple(image_evidence(im, self._foreground(section, c, im), section.silhouette)
                                         for c, im in enumerate(images)))
        return self._evidence[1]

    def _foreground(self, section, c: int, image):
        """Camera ``c``'s foreground model for ``image``: the caller's, else the learned one for
        "sequence", the one fitted at the first frame for "skin"."""
        if self._given_fg is not None:
            return self._given_fg[c]
        if section.foreground == "sequence" and self._sequence_fg is not None:
            return self._sequence_fg[c]
        if self._skin_fg is not None and self._skin_fg[c] is not None and section.foreground in ("skin", "auto"):
            return self._skin_fg[c]
        return foreground_for(section, image)


def image_front_end(model: Model, cameras, config: ImageConfig, sources, n_frames: int | None = None,
                    foregrounds: Sequence[AbstractForeground] | None = None) -> ImageFrontEnd:
    """The :class:`ImageFrontEnd` for a sequence read from ``sources`` (one frame source per camera,
    :func:`jaxhand.io.open_frames`), given the frames its "sequence" foreground learns from;
    ``foregrounds`` as :class:`ImageFrontEnd`'s."""
    frames = None
    if config.score.foreground == "sequence" and foregrounds is None:
        frames = [s.spread(config.score.sequence_frames, n_frames) for s in sources]
    return ImageFrontEnd(model, cameras, config, background_frames=frames, foregrounds=foregrounds)


class ExactFrontEnd(AbstractFrontEnd):
    """An oracle for experiments: frame k gets the exact features of ``truth[k]`` in every camera
    with Gaussian pixel noise of ``noise_px``, ignoring the images. Tracking with it measures
    what the solver and the filter can do with perfect image analysis.

    The noise of every frame is drawn at construction, frame after frame from one generator
    seeded with ``seed``, so frame k's features depend on k alone, not on the calls before.
    """

    reextracts: ClassVar[bool] = False   # the same frame's features again gain nothing

    def __init__(self, model: Model, cameras, truth, *, noise_px: float = 0.5, seed: int = 0):
        rng = np.random.default_rng(seed)
        self.model, self.cameras = model, as_rig(cameras)
        self._features = tuple(features_from_pose(model, self.cameras, q, noise_px=noise_px, rng=rng)
                               for q in np.asarray(truth))

    def __len__(self) -> int:
        return len(self._features)

    def extract(self, images, q_start, state, frame: int) -> FrontEndResult:
        return FrontEndResult(self._features[frame], state)
