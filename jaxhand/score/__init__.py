"""The global image score (thesis ch. 7, "widening the scope of evaluation"; issue 13 item 3).

Host-side (NumPy/OpenCV), after the solve: measure (image front end), estimate (solve), then
judge (here). The tracker, once per frame:

1. ``evidence = image_evidence(frame, foreground, config)``: the foreground mask and the edge
   distance transform, shared by every hypothesis of the frame;
2. per pose: ``sil = rasterize(capsules_from_model(model, q) + occluders, camera)`` and
   ``s = score_silhouette(sil, evidence, config)``, or for a stack of hypotheses
   ``score_poses(model, camera, qs, evidence, occluders=..., config=...)``;
3. ``confidence, lost = frame_confidence(s.score, residual_rms_px, valid_share)``.

- :class:`Capsules`, :func:`capsules_from_model`, :func:`rasterize`: the model's silhouette.
- :class:`AbstractForeground` with :class:`ThresholdForeground` (dark background, fixed or Otsu),
  :class:`BackgroundForeground` (a background image or the first frames),
  :class:`SequenceBackground` (a still camera's background learned while tracking) and
  :class:`SkinForeground` (colour video).
- :class:`ScoreConfig`, :class:`ImageScore`, :func:`score_frame`: IoU, coverage and chamfer in [0, 1].
- :func:`side_edge_share`, :func:`link_sides`: each link's share of visible side points with an
  image edge across the side (a finger lying wrongly over the hand finds few).
- :class:`SilhouetteTermConfig`, :class:`SilhouetteTerm`, :func:`silhouette_term`: the silhouette
  as residuals of the solve (``ImageConfig.silhouette_term``), and as a judge of hypotheses.
- :class:`ConfidenceConfig`, :func:`frame_confidence`: the loss rule.
- :class:`ScoreSection` (``ImageConfig.score``), :func:`foreground_for`: the image front end's
  settings, and the foreground model they choose for a frame.
"""

from ._confidence import ConfidenceConfig as ConfidenceConfig
from ._confidence import frame_confidence as frame_confidence
from ._foreground import AbstractForeground as AbstractForeground
from ._foreground import BackgroundForeground as BackgroundForeground
from ._foreground import SkinForeground as SkinForeground
from ._foreground import ThresholdForeground as ThresholdForeground
from ._foreground import as_grey as as_grey
from ._foreground import fill_holes as fill_holes
from ._masks import MaskForeground as MaskForeground
from ._masks import frame_digest as frame_digest
from ._score import ImageEvidence as ImageEvidence
from ._score import ImageScore as ImageScore
from ._score import ScoreConfig as ScoreConfig
from ._score import image_evidence as image_evidence
from ._score import model_contour as model_contour
from ._score import score_frame as score_frame
from ._score import score_poses as score_poses
from ._score import score_silhouette as score_silhouette
from ._section import FOREGROUNDS as FOREGROUNDS
from ._section import ScoreSection as ScoreSection
from ._section import foreground_for as foreground_for
from ._section import foreground_kind as foreground_kind
from ._section import sequence_foreground as sequence_foreground
from ._section import skin_foreground as skin_foreground
from ._sequence import ColourSequenceBackground as ColourSequenceBackground
from ._sequence import SequenceBackground as SequenceBackground
from ._sides import link_sides as link_sides
from ._sides import side_edge_share as side_edge_share
from ._silhouette import CameraNumbers as CameraNumbers
from ._silhouette import Capsules as Capsules
from ._silhouette import Silhouette as Silhouette
from ._silhouette import camera_numbers as camera_numbers
from ._silhouette import capsule_outlines as capsule_outlines
from ._silhouette import capsules_from_model as capsules_from_model
from ._silhouette import capsules_from_model_batch as capsules_from_model_batch
from ._silhouette import rasterize as rasterize
from ._term import SilhouettePrior as SilhouettePrior
from ._term import SilhouetteTerm as SilhouetteTerm
from ._term import SilhouetteTermConfig as SilhouetteTermConfig
from ._term import pill_images as pill_images
from ._term import roi_box as roi_box
from ._term import silhouette_term as silhouette_term

__all__ = ["Capsules", "Silhouette", "CameraNumbers", "camera_numbers", "capsules_from_model",
           "capsules_from_model_batch", "capsule_outlines",
           "rasterize", "AbstractForeground", "ThresholdForeground", "BackgroundForeground", "SkinForeground",
           "MaskForeground", "frame_digest",
           "as_grey", "ScoreConfig", "ImageEvidence", "ImageScore", "image_evidence", "model_contour",
           "score_silhouette", "score_frame", "score_poses", "ConfidenceConfig", "frame_confidence", "FOREGROUNDS",
           "ScoreSection", "foreground_for", "foreground_kind", "sequence_foreground", "skin_foreground",
           "SequenceBackground", "ColourSequenceBackground", "fill_holes",
           "SilhouetteTermConfig", "SilhouetteTerm",
           "SilhouettePrior", "silhouette_term", "pill_images", "roi_box", "link_sides", "side_edge_share"]
