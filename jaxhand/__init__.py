"""jaxhand: model-based tracking of articulated objects (first of all the human hand).

jaxhand computes in float64 and asks for it: call :func:`enable_x64` once at the start (the CLI
does). Importing jaxhand changes nothing in JAX's global settings, so a program's own float32
code keeps its behaviour; building a model with float64 off is a one-line error saying what to do.
"""

from ._compiled_cache import memory_maps, release_compiled  # noqa: E402
from ._errors import CameraError, InputError, JaxhandError, JaxhandWarning, ModelFileError, OutputExistsError  # noqa: E402
from ._precision import enable_single_thread_cpu, enable_sync_dispatch, enable_x64, x64_enabled  # noqa: E402
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
    HypothesisConfig,
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
    "enable_x64", "x64_enabled", "enable_sync_dispatch", "enable_single_thread_cpu", "release_compiled", "memory_maps",
    "JaxhandError", "ModelFileError", "InputError", "CameraError", "OutputExistsError", "JaxhandWarning",
    "Model", "builtin_model", "builtin_names", "get_model", "load_model", "save_model", "model_from_dict",
    "model_to_dict",
    "Orthographic", "Perspective", "as_rig", "load_camera", "save_camera",
    "Pose", "View", "forward", "project_pose", "views", "random_q", "validate_q",
    "fit", "fit_batch", "FitConfig", "FitResult", "Status", "SOLVERS",
    "extract_features", "capture_templates", "ImageConfig", "ImageState",
    "Features", "features_from_pose",
    "Tracker", "TrackState", "StepReport", "TrackConfig", "FilterConfig", "RobustConfig", "LossConfig", "PriorConfig",
    "HypothesisConfig", "load_track_config", "save_track_config", "AbstractFrontEnd", "ImageFrontEnd", "ExactFrontEnd",
    "track_sequence", "accuracy_summary",
]
