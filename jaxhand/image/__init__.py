"""Image front end (thesis ch. 4, appendix D; DigitEyes §4): an image and a predicted pose in,
link lines and tip points out, as :class:`jaxhand.features.Features`.

NumPy, OpenCV and shapely only: trackers are placed from one jitted kinematics call, every profile
of a frame is sampled in one ``cv2.remap``, searched as one array, and windowed by point tests on
the pill outlines.

- :func:`extract_features` is the entry point; :class:`ImageConfig` selects the search by name
  (:data:`SEARCH_NAMES`) and holds every setting, grouped in its sub-configs.
- :func:`capture_templates` stores unoccluded profile templates in an :class:`ImageState`, which
  the tracker carries between frames for the WSSD search (:func:`refresh_templates` re-takes them
  at a solved pose only where the frame vouches for it); :func:`measure_widths` and
  :func:`update_widths` keep the phalanx radii estimated from the images there (appendix E,
  ``ImageConfig.width_gain``).
- :class:`Diagnostics` (and :class:`WindowOutlines`, for overlays) report what was seen.

The pieces (tracker placement, profile sampling, visibility, searches, regressions, line
fitting) are shared with tests, benchmarks and figures through :mod:`jaxhand.image.internal`,
which is documented but not a stable interface.
"""

from ._config import (
    ImageConfig,
    LineConfig,
    RecentreConfig,
    RefreshConfig,
    SamplerConfig,
    SearchConfig,
    TipConfig,
    VisibilityConfig,
    WidthConfig,
)
from ._diagnostics import Diagnostics, WindowOutlines
from ._extract import extract_features
from ._state import ImageState
from ._templates import capture_templates, refresh_templates
from ._widths import measure_widths, update_widths
from .searches import SEARCH_NAMES

__all__ = [
    "extract_features", "capture_templates", "refresh_templates", "measure_widths", "update_widths", "ImageState",
    "Diagnostics", "WindowOutlines", "SEARCH_NAMES",
    "ImageConfig", "SamplerConfig", "SearchConfig", "VisibilityConfig", "LineConfig", "TipConfig", "RecentreConfig",
    "RefreshConfig", "WidthConfig",
]
