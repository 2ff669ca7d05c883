"""Hand landmarks (MediaPipe/OpenPose 21 points): residuals, fitting, calibration, files."""

from ._convention import BUILTIN_HANDEDNESS, POINT_NAMES, LandmarkMap, landmark_map, landmark_positions
from ._fit import LANDMARK_SOLVERS, BatchConfig, fit_landmarks, fit_landmarks_batch
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

__all__ = ["POINT_NAMES", "BUILTIN_HANDEDNESS", "LandmarkMap", "landmark_map", "landmark_positions",
           "Landmarks", "LandmarkArgs", "make_landmarks", "make_landmark_args", "landmark_residuals",
           "landmark_residuals_and_jacobian", "stacked_residuals", "stacked_residuals_and_jacobian",
           "landmark_residual_labels", "BatchConfig", "fit_landmarks", "fit_landmarks_batch", "LANDMARK_SOLVERS"]
