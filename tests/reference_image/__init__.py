"""A frozen copy of the image front end as it stood before its split and speed-up (commit d8d81f2),
kept as the reference the new front end is tested against (tests/test_image_reference.py): the new
one must give the same features bit for bit (or within 0.01 px with the same valid masks).

Test-only; never edit it to follow the package. Original docstring:

Image front end (thesis ch. 4, appendix D; DigitEyes §4): an image and a predicted pose in,
link lines and tip points out, as :class:`jaxhand.features.Features`.

NumPy, OpenCV and shapely only: trackers are placed from one jitted kinematics call, every profile
of a frame is sampled in one ``cv2.remap``, searched as one array, and windowed with shapely's
vectorised predicates.

- :func:`extract_features` is the entry point; :class:`ImageConfig` selects the search by name
  (:data:`SEARCH_NAMES`) and holds every setting.
- :func:`capture_templates` stores unoccluded profile templates in an :class:`ImageState`, which
  the tracker carries between frames for the WSSD search; :func:`update_widths` keeps the
  phalanx radii estimated from the images there (appendix E, ``ImageConfig.width_gain``).
- The pieces (tracker placement, profile sampling, visibility, searches, regressions, line
  fitting) are public for tests, benchmarks and figures.
"""

from ._config import (
    INTERPOLATIONS,
    POLARITIES,
    ImageConfig,
    LineConfig,
    SamplerConfig,
    SearchConfig,
    TipConfig,
    VisibilityConfig,
)
from ._extract import (
    CameraDiagnostics,
    Diagnostics,
    WindowOutlines,
    as_images,
    capture_templates,
    extract_features,
    measure_widths,
    update_widths,
)
from ._lines import axial_line, line_params, line_point_direction, offset_towards, ransac_pca
from ._regression import imwplls, mwplls, plls
from ._sampling import as_grey, sample_profiles
from ._state import ImageState
from ._trackers import LinkSamplers, TipSamplers, place_link_samplers, place_tip_samplers, refine_tip
from ._visibility import Visibility, compute_visibility, pill_outlines, same_chain, window_masks
from .searches import SEARCH_NAMES, SEARCHES, Edges, Profiles, search_named

__all__ = [
    "extract_features", "capture_templates", "measure_widths", "update_widths", "ImageState", "Diagnostics",
    "CameraDiagnostics", "WindowOutlines",
    "ImageConfig", "SamplerConfig", "SearchConfig", "VisibilityConfig", "LineConfig", "TipConfig",
    "INTERPOLATIONS", "POLARITIES", "SEARCH_NAMES", "SEARCHES", "search_named", "Profiles", "Edges",
    "as_grey", "as_images", "sample_profiles",
    "LinkSamplers", "TipSamplers", "place_link_samplers", "place_tip_samplers", "refine_tip",
    "Visibility", "compute_visibility", "pill_outlines", "same_chain", "window_masks",
    "ransac_pca", "axial_line", "line_params", "line_point_direction", "offset_towards",
    "plls", "mwplls", "imwplls",
]
