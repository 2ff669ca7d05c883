"""Render settings and backgrounds.

Rendering runs in NumPy outside jitted code, so the configuration is a plain frozen dataclass
(nothing in it is traced). Every field has a default and a unit.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path

import cv2
import numpy as np

from .._errors import InputError

__all__ = ["RenderConfig", "make_background", "parse_background", "MODES"]

MODES = ("shaded", "binary")


@dataclass(frozen=True)
class RenderConfig:
    """How a frame is drawn.

    Attributes:
        mode: ``"shaded"`` (z-buffer with Lambert/Phong lighting, thesis app. C.2) or ``"binary"``
            (silhouettes painted with ``foreground``, app. C.1).
        background: ``"black"``, ``"constant:V"`` (grey level V in 0..255), ``"noise"`` (a seeded
            procedural texture), a path to an image file (converted to grey and resized), a
            number (grey level) or an (H, W) uint8 array of the image size.
        foreground: grey level of binary silhouettes (0..255).
        light_dir: direction from the surface towards a distant light, camera frame (x right,
            y down, z forward); normalised. The default lights from above-left of the camera.
        albedo: diffuse reflectance in [0, 1]; one value or one per link.
        ambient: ambient light level in [0, 1] (the brightness of surfaces facing away from the light).
        specular: Phong specular strength in [0, 1]; ``shininess`` is its exponent.
        noise_sigma: standard deviation of additive Gaussian pixel noise (grey levels); 0 for none.
        blur_sigma_px: standard deviation of a Gaussian blur applied before the noise (pixels).
        antialias: samples per pixel along each axis (odd); the image averages them, the
            ground-truth maps use the pixel-centre sample.
        seed: seed of the noise texture and of the pixel noise (combined with the frame index).
    """

    mode: str = "shaded"
    background: str | float | np.ndarray = "black"
    foreground: int = 255
    light_dir: tuple[float, float, float] = (-0.35, -0.45, -1.0)
    albedo: float | tuple[float, ...] = 0.8
    ambient: float = 0.25
    specular: float = 0.2
    shininess: float = 20.0
    noise_sigma: float = 0.0
    blur_sigma_px: float = 0.0
    antialias: int = 1
    seed: int = 0

    def __post_init__(self):
        if self.mode not in MODES:
            raise InputError(f"render mode must be one of {', '.join(MODES)}, got {self.mode!r}")
        if not (isinstance(self.antialias, (int, np.integer)) and self.antialias >= 1 and self.antialias % 2 == 1):
            raise InputError(f"antialias must be an odd positive integer, got {self.antialias!r}")
        for name in ("noise_sigma", "blur_sigma_px"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise InputError(f"{name} must be finite and >= 0, got {v!r}")
        for name in ("ambient", "specular"):
            v = getattr(self, name)
            if not (np.isfinite(v) and 0 <= v <= 1):
                raise InputError(f"{name} must lie in [0, 1], got {v!r}")
        alb = np.asarray(self.albedo, float)
        if alb.ndim > 1 or not np.all((alb >= 0) & (alb <= 1)):
            raise InputError(f"albedo must be a value or a list of values in [0, 1], got {self.albedo!r}")
        ld = np.asarray(self.light_dir, float)
        if ld.shape != (3,) or not np.all(np.isfinite(ld)) or np.linalg.norm(ld) == 0:
            raise InputError(f"light_dir must be a non-zero 3-vector, got {self.light_dir!r}")
        if not 0 <= self.foreground <= 255:
            raise InputError(f"foreground must be a grey level in 0..255, got {self.foreground!r}")
        if isinstance(self.background, str):
            parse_background(self.background)  # fail early on a malformed spec or missing file

    def to_dict(self) -> dict:
        """JSON-ready settings (an array background is recorded as ``"array"``)."""
        d = asdict(self)
        if isinstance(self.background, np.ndarray):
            d["background"] = "array"
        d["light_dir"] = list(self.light_dir)
        d["albedo"] = self.albedo if np.ndim(self.albedo) == 0 else list(self.albedo)
        return d


def parse_background(spec: str) -> tuple[str, object]:
    """Split a background spec into (kind, value): black, constant (grey), noise, or file (Path).

    Raises:
        InputError: a malformed ``constant:V`` or a path that does not exist.
    """
    s = spec.strip()
    if s == "black":
        return "constant", 0.0
    if s == "noise":
        return "noise", None
    if s.startswith("constant:"):
        try:
            v = float(s.split(":", 1)[1])
        except ValueError:
            v = float("nan")
        if not 0 <= v <= 255:
            raise InputError(f"background {spec!r}: expected constant:V with a grey level V in 0..255")
        return "constant", v
    p = Path(s)
    if not p.is_file():
        raise InputError(f"background {spec!r}: not 'black', 'constant:V', 'noise' or an existing image file")
    return "file", p


def _noise_texture(size: tuple[int, int], seed: int) -> np.ndarray:
    """A smooth procedural texture: value noise summed over octaves, grey levels about 30..110."""
    w, h = size
    rng = np.random.default_rng(seed)
    img = np.zeros((h, w))
    amp, total = 1.0, 0.0
    for cells in (4, 8, 16, 32, 64):  # cells across the longer side, coarse to fine
        gw = max(2, int(round(cells * w / max(w, h))) + 1)
        gh = max(2, int(round(cells * h / max(w, h))) + 1)
        coarse = rng.uniform(-1, 1, (gh, gw)).astype(np.float32)
        img += amp * cv2.resize(coarse, (w, h), interpolation=cv2.INTER_CUBIC)
        total += amp
        amp *= 0.55
    return np.clip(70.0 + 40.0 * img / total, 0, 255)


def make_background(spec, size: tuple[int, int], seed: int = 0) -> np.ndarray:
    """The (H, W) float background image (grey levels 0..255) for a spec of :class:`RenderConfig`.

    Raises:
        InputError: an unreadable image file or an array of the wrong shape.
    """
    w, h = size
    if isinstance(spec, np.ndarray):
        if spec.shape != (h, w):
            raise InputError(f"background array: expected shape ({h}, {w}), got {spec.shape}")
        return spec.astype(float)
    if isinstance(spec, (int, float, np.number)):
        if not 0 <= float(spec) <= 255:
            raise InputError(f"background grey level must lie in 0..255, got {spec!r}")
        return np.full((h, w), float(spec))
    kind, value = parse_background(str(spec))
    if kind == "constant":
        return np.full((h, w), float(value))
    if kind == "noise":
        return _noise_texture((w, h), seed)
    img = cv2.imread(str(value), cv2.IMREAD_GRAYSCALE)
    if img is None:
        raise InputError(f"background {str(value)!r}: cannot read as an image")
    return cv2.resize(img, (w, h), interpolation=cv2.INTER_AREA).astype(float)
