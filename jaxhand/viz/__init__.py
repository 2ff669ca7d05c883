"""Drawing and plotting: model overlays on images (OpenCV) and joint-angle plots (matplotlib)."""

from ._draw import draw_points as draw_points
from ._draw import draw_view as draw_view
from ._draw import sketch_model as sketch_model
from ._plots import joint_groups as joint_groups
from ._plots import plot_joint_angles as plot_joint_angles
from ._plots import plot_line as plot_line
from ._video import VideoWriter as VideoWriter

__all__ = ["draw_view", "draw_points", "sketch_model", "plot_joint_angles", "joint_groups", "plot_line", "VideoWriter"]
