"""Image validation and profile sampling (thesis §4.2).

Every profile of a frame is sampled in one ``cv2.remap`` call: the sample positions of all
samplers are laid out as one map, and OpenCV interpolates them with nearest-neighbour, bilinear
or bicubic weights. OpenCV's pixel convention (integer coordinates at pixel centres) is jaxhand's,
so positions pass through unchanged. Note that OpenCV rounds the fractional part of bilinear and
bicubic positions to 1/32 pixel.
"""

from __future__ import annotations

import cv2
import numpy as np

from .._errors import InputError
from ._xy import finite_xy

__all__ = ["as_grey", "sample_profiles", "INTERPOLATION_FLAGS"]

INTERPOLATION_FLAGS = {"nearest": cv2.INTER_NEAREST, "bilinear": cv2.INTER_LINEAR, "bicubic": cv2.INTER_CUBIC}
# Samples per row of the remap map when they do not fit in one row (OpenCV limits map sizes to below
# 32767 per side).
_ROW = 1024
_ROW_MAX = 32766
# Positions are clipped to this far outside the image before remapping (they are masked anyway),
# so huge or non-finite coordinates never reach OpenCV's fixed-point conversion.
_CLIP_PX = 4.0


def as_grey(image, where: str = "image", size: tuple[int, int] | None = None) -> np.ndarray:
    """Check an image and convert it once to a float32 grey image in grey levels.

    Accepted: 2-D uint8 or float (float images are read on the same 0-255 scale as uint8; one whose
    finite pixels all lie in [0, 1], not all 0, is refused as a likely [0, 1]-scaled image), an
    (H, W, 1) array of those, or an (H, W, 3) uint8 BGR image (converted with OpenCV's weights).
    NaN or inf pixels are allowed: profiles through them are masked later.

    Args:
        image: the image.
        where: how to name the image in an error (``"images[0]"``).
        size: expected (width, height) in pixels, e.g. the camera's; None skips the check.

    Raises:
        InputError: naming ``where`` and what is wrong (type, dtype, shape, size, a [0, 1] range).
    """
    try:
        a = np.asarray(image)
    except Exception as err:  # noqa: BLE001 - anything that cannot become an array is a user error
        raise InputError(f"{where}: cannot read as an array ({err})") from err
    if a.dtype == object or not (a.dtype == np.uint8 or np.issubdtype(a.dtype, np.floating)):
        raise InputError(f"{where}: dtype {a.dtype} is not supported; pass uint8 or float grey levels")
    if a.ndim == 3 and a.shape[2] == 1:
        a = a[:, :, 0]
    if a.ndim == 3 and a.shape[2] == 3:
        if a.dtype != np.uint8:
            raise InputError(f"{where}: a colour image must be uint8 BGR, got dtype {a.dtype}")
        a = cv2.cvtColor(np.ascontiguousarray(a), cv2.COLOR_BGR2GRAY)
    if a.ndim != 2:
        raise InputError(f"{where}: expected a 2-D grey image or an (H, W, 3) BGR image, got shape {a.shape}")
    if a.shape[0] == 0 or a.shape[1] == 0:
        raise InputError(f"{where}: the image is empty (shape {a.shape})")
    if np.issubdtype(a.dtype, np.floating):
        finite = a[np.isfinite(a)]
        # A float image scaled to [0, 1] would be read as almost black, its edges far below every
        # strength threshold, and would silently give no features.
        if finite.size and finite.min() >= 0 and 0 < finite.max() <= 1:
            raise InputError(f"{where}: a float image with values in [0, 1]; jaxhand reads grey levels on the "
                             f"0-255 scale: pass image * 255 (or a uint8 image)")
    if size is not None and (a.shape[1], a.shape[0]) != tuple(size):
        raise InputError(f"{where}: size {a.shape[1]}x{a.shape[0]} (width x height) does not match the camera's "
                         f"{size[0]}x{size[1]}")
    return np.ascontiguousarray(a, dtype=np.float32)


def sample_profiles(grey: np.ndarray, points: np.ndarray, interpolation: str = "bilinear"
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Intensities at many sub-pixel positions in one ``cv2.remap`` call.

    Args:
        grey: (H, W) float32 image from :func:`as_grey`.
        points: (..., 2) pixel positions (x, y).
        interpolation: "nearest", "bilinear" or "bicubic".

    Returns:
        (values, usable): float64 intensities with shape (...) (0 where not usable), and True where
        the position lies inside the image (between the centres of the border pixels), is finite,
        and its interpolated value is finite.
    """
    pts = np.asarray(points, float)
    shape = pts.shape[:-1]
    h, w = grey.shape
    flat = pts.reshape(-1, 2)
    fx, fy = flat[:, 0], flat[:, 1]
    finite = finite_xy(flat)
    inside = finite & (fx >= 0) & (fx <= w - 1) & (fy >= 0) & (fy <= h - 1)
    n = len(flat)
    # One map row when it fits (each output depends on its own position only, so the layout does not
    # change a value), else rows of _ROW padded at the end.
    rows, width = (1, max(n, 1)) if n <= _ROW_MAX else (-(-n // _ROW), _ROW)
    mx = np.empty(rows * width, np.float32)
    my = np.empty(rows * width, np.float32)
    mx[n:] = my[n:] = -_CLIP_PX
    # np.clip's bounds as minimum/maximum (the same values for the finite coordinates left after where)
    for f, size, m in ((fx, w, mx), (fy, h, my)):
        np.minimum(np.maximum(np.where(finite, f, -_CLIP_PX), -_CLIP_PX), size - 1 + _CLIP_PX, out=m[:n],
                   casting="unsafe")
    out = cv2.remap(grey, mx.reshape(rows, width), my.reshape(rows, width), INTERPOLATION_FLAGS[interpolation],
                    borderMode=cv2.BORDER_REPLICATE)
    vals = out.reshape(-1)[:n].astype(np.float64)
    usable = inside & np.isfinite(vals)
    return np.where(usable, vals, 0.0).reshape(shape), usable.reshape(shape)
