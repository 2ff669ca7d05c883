"""Drawing and plotting: model overlays on images (OpenCV) and joint-angle plots (matplotlib)."""

from ._draw import draw_view as draw_view
from ._draw import sketch_model as sketch_model

__all__ = ["draw_view", "sketch_model"]
