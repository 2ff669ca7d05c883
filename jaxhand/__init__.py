"""jaxhand: model-based tracking of articulated objects (first of all the human hand).

Importing jaxhand enables JAX's float64 mode: Jacobian checks against finite differences and
solver tolerances of 1e-10 on the cost need double precision, and on the CPU the small dense
problems of hand tracking cost about the same in float64 as in float32.
"""

import jax as _jax

_jax.config.update("jax_enable_x64", True)

from ._errors import CameraError, InputError, JaxhandError, JaxhandWarning, ModelFileError, OutputExistsError  # noqa: E402
from .camera import Orthographic, Perspective, as_rig, load_camera, save_camera  # noqa: E402
from .features import Features, features_from_pose  # noqa: E402
from .image import ImageConfig, ImageState, capture_templates, extract_features  # noqa: E402
from .kinematics import Pose, View, forward, project_pose, random_q, validate_q, views  # noqa: E402
from .model import (  # noqa: E402
    Model,
    builtin_model,
    builtin_names,
    get_model,
    load_model,
    model_from_dict,
    model_to_dict,
    save_model,
)
from .solve import SOLVERS, FitConfig, FitResult, Status, fit, fit_batch  # noqa: E402
from .track import (  # noqa: E402
    AbstractFrontEnd,
    ExactFrontEnd,
    FilterConfig,
    ImageFrontEnd,
    LossConfig,
    PriorConfig,
    RobustConfig,
    StepReport,
    TrackConfig,
    Tracker,
    TrackState,
    accuracy_summary,
    load_track_config,
    save_track_config,
    track_sequence,
)

__version__ = "0.1.0"

__all__ = [
    "JaxhandError", "ModelFileError", "InputError", "CameraError", "OutputExistsError", "JaxhandWarning",
    "Model", "builtin_model", "builtin_names", "get_model", "load_model", "save_model", "model_from_dict",
    "model_to_dict",
    "Orthographic", "Perspective", "as_rig", "load_camera", "save_camera",
    "Pose", "View", "forward", "project_pose", "views", "random_q", "validate_q",
    "fit", "fit_batch", "FitConfig", "FitResult", "Status", "SOLVERS",
    "extract_features", "capture_templates", "ImageConfig", "ImageState",
    "Features", "features_from_pose",
    "Tracker", "TrackState", "StepReport", "TrackConfig", "FilterConfig", "RobustConfig", "LossConfig", "PriorConfig",
    "load_track_config", "save_track_config", "AbstractFrontEnd", "ImageFrontEnd", "ExactFrontEnd",
    "track_sequence", "accuracy_summary",
]
