"""Synthetic images and sequences with exact ground truth (thesis app. C).

- :func:`render_frame`: binary silhouettes or shaded grey images of any model's pills for any
  orthographic or perspective camera, with per-pixel link-ID and depth maps and per-link visibility.
- :func:`degrade`: a camera's blur and sensor noise on any image (the dev set's recipe).
- :func:`make_preset`: the experiments of thesis ch. 6 and DigitEyes §6 as :class:`Sequence`\\ s.
- :func:`joint_trajectory` / :func:`minimum_jerk`: smooth motion through key poses.
- :func:`write_sequence` / :func:`load_sequence`: folders of PNG frames with a ground-truth JSON.
"""

from ._config import RenderConfig as RenderConfig
from ._config import make_background as make_background
from ._frame import RenderResult as RenderResult
from ._frame import degrade as degrade
from ._frame import render_frame as render_frame
from ._io import SequenceFolder as SequenceFolder
from ._io import load_sequence as load_sequence
from ._io import write_sequence as write_sequence
from ._presets import PRESET_DESCRIPTIONS as PRESET_DESCRIPTIONS
from ._presets import Sequence as Sequence
from ._presets import fit_orthographic as fit_orthographic
from ._presets import fit_perspective as fit_perspective
from ._presets import make_preset as make_preset
from ._presets import parse_size as parse_size
from ._presets import preset_names as preset_names
from ._trajectory import joint_trajectory as joint_trajectory
from ._trajectory import min_jerk_profile as min_jerk_profile
from ._trajectory import minimum_jerk as minimum_jerk

__all__ = ["RenderConfig", "RenderResult", "render_frame", "degrade", "make_background",
           "Sequence", "make_preset", "preset_names", "PRESET_DESCRIPTIONS", "parse_size",
           "fit_orthographic", "fit_perspective", "joint_trajectory", "minimum_jerk", "min_jerk_profile",
           "write_sequence", "load_sequence", "SequenceFolder"]
