"""Hand landmarks (the 21 points of MediaPipe and OpenPose): the point convention on jaxhand's
models, 2-D/3-D keypoint residuals in the residual stack, single, batched and whole-sequence
fits, hand calibration, landmark files, and per-frame landmark poses and solve terms for the
tracker."""

from ._convention import BUILTIN_HANDEDNESS, POINT_NAMES, TIP_CONVENTIONS, LandmarkMap, landmark_map, landmark_positions
from ._fit import LANDMARK_SOLVERS, BatchConfig, fit_landmarks, fit_landmarks_batch
from ._io import LandmarkFileError, LandmarkSequence, load_landmarks, mirror_x, save_landmarks_csv
from ._paths import START_FRACTIONS, block_costs, independent_blocks, joint_starts, smoothest_paths
from ._pipeline import (
    PATH_SCALES,
    SEQUENCE_INITS,
    SequenceFit,
    calibrate_landmarks,
    camera_from_fov,
    fit_landmark_sequence,
    initial_starts,
    projected_landmarks,
    save_calibrated_model,
    track_landmarks,
)
from ._poses import LANDMARK_FITS, MIN_POINTS, ON_FINGERS_PX, LandmarkPoses, fit_landmark_poses, landmark_agreement
from ._prior import LandmarkPrior, LandmarkTerm, landmark_term
from ._residuals import (
    LandmarkArgs,
    Landmarks,
    landmark_residual_labels,
    landmark_residuals,
    landmark_residuals_and_jacobian,
    make_landmark_args,
    make_landmarks,
    stacked_residuals,
    stacked_residuals_and_jacobian,
)
from ._sequence import SequenceConfig, SequenceResult, fit_sequence
from ._shape import HandShape, apply_shape, hand_shape

__all__ = ["POINT_NAMES", "BUILTIN_HANDEDNESS", "TIP_CONVENTIONS", "LandmarkMap", "landmark_map", "landmark_positions",
           "Landmarks", "LandmarkArgs", "make_landmarks", "make_landmark_args", "landmark_residuals",
           "landmark_residuals_and_jacobian", "stacked_residuals", "stacked_residuals_and_jacobian",
           "landmark_residual_labels", "BatchConfig", "fit_landmarks", "fit_landmarks_batch", "LANDMARK_SOLVERS",
           "LandmarkSequence", "LandmarkFileError", "load_landmarks", "save_landmarks_csv", "mirror_x",
           "SequenceConfig", "SequenceResult", "fit_sequence", "HandShape", "hand_shape", "apply_shape",
           "SequenceFit", "fit_landmark_sequence", "track_landmarks", "initial_starts", "calibrate_landmarks",
           "save_calibrated_model", "projected_landmarks", "camera_from_fov", "LandmarkPoses", "fit_landmark_poses",
           "LANDMARK_FITS", "MIN_POINTS", "ON_FINGERS_PX", "landmark_agreement", "LandmarkTerm", "LandmarkPrior",
           "landmark_term", "SEQUENCE_INITS", "START_FRACTIONS", "independent_blocks", "joint_starts",
           "smoothest_paths", "block_costs", "PATH_SCALES"]
