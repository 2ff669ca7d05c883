"""Temporal filters (thesis ch. 5, app. E) as pure predict/update functions."""

from ._ghk import GHKState as GHKState
from ._ghk import ghk_follow as ghk_follow
from ._ghk import ghk_gains as ghk_gains
from ._ghk import ghk_init as ghk_init
from ._ghk import ghk_predict as ghk_predict
from ._ghk import ghk_update as ghk_update
from ._hidden import damp_unseen as damp_unseen
from ._hidden import marginal_information as marginal_information
from ._hidden import seen_share as seen_share
from ._kalman import KalmanState as KalmanState
from ._kalman import kalman_predict as kalman_predict
from ._kalman import kalman_update as kalman_update
from ._prior import PriorState as PriorState
from ._prior import prior_information as prior_information
from ._prior import prior_init as prior_init
from ._prior import prior_predict as prior_predict
from ._prior import prior_residuals as prior_residuals
from ._prior import prior_update as prior_update
from ._prior import prior_update_map as prior_update_map
from ._prior import solve_information as solve_information
from ._width import width_update as width_update

__all__ = ["GHKState", "ghk_gains", "ghk_init", "ghk_predict", "ghk_update", "ghk_follow", "KalmanState",
           "kalman_predict",
           "kalman_update", "width_update", "PriorState", "prior_init", "prior_predict", "prior_update",
           "prior_update_map", "prior_residuals", "prior_information", "solve_information", "marginal_information",
           "seen_share", "damp_unseen"]
