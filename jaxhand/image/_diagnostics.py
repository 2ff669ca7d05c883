"""What the image front end reports besides its features: per-camera diagnostics for overlays
(thesis figs. 4.2-4.23), the stage timings, and the window outlines as coordinates."""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence

import numpy as np

from ._state import ImageState
from ._trackers import LinkSamplers, TipSamplers
from ._visibility import Visibility
from .searches import Edges, Profiles

__all__ = ["CameraDiagnostics", "Diagnostics", "WindowOutlines", "Clock"]


@dataclasses.dataclass(frozen=True)
class CameraDiagnostics:
    """What one camera's analysis saw and decided, for overlays like thesis figs. 4.2-4.23.

    Attributes:
        samplers: link sampler placement (centres, sample positions, ``ends`` for drawing).
        visibility: pill outlines, truncated polygons, window polygons, depth order, visible share.
        profiles: the sampled profiles, their usable samples, windows and templates.
        edges: the search's raw result (positions in samples, strengths, surface if any).
        edge_px: (links, samplers, 2, 2) boundary points in pixels (NaN where not found).
        boundary_lines: (links, 2, 3) fitted boundary lines (a, b, rho).
        boundary_valid: (links, 2) the boundary line was fitted.
        inliers: (links, 2, samplers) RANSAC inliers of each boundary line.
        axial_lines: (links, 3) the link features' lines (a, b, rho).
        single_edge: (links,) the axial line came from one boundary offset by the radius.
        tip_samplers: tip sampler placement (refined tips, directions, sample positions).
        tip_edge_px: (tips, 2) tip boundary points found (NaN where none).
        tip_strength: (tips,) derivative at the tip boundary, grey levels per pixel.
        reacquired: (links,) the link's line (and tip) came from a search with its joint turned
            (``ImageConfig.reacquire_deg``); the other diagnostics show the search at the
            prediction.
    """

    samplers: LinkSamplers
    visibility: Visibility
    profiles: Profiles
    edges: Edges
    edge_px: np.ndarray
    boundary_lines: np.ndarray
    boundary_valid: np.ndarray
    inliers: np.ndarray
    axial_lines: np.ndarray
    single_edge: np.ndarray
    tip_samplers: TipSamplers
    tip_edge_px: np.ndarray
    tip_strength: np.ndarray
    reacquired: np.ndarray | None = None


@dataclasses.dataclass(frozen=True)
class Diagnostics:
    """Diagnostics of one :func:`jaxhand.image.extract_features` call.

    Attributes:
        method: the search used.
        cameras: one :class:`CameraDiagnostics` per camera.
        state: the image state after this frame (templates filled in for links that had none and
            were seen well enough); pass it to the next frame.
        timings_s: wall time of each stage summed over the cameras (s): "kinematics", "samplers",
            "visibility", "sampling", "search", "lines", "tips".
    """

    method: str
    cameras: tuple[CameraDiagnostics, ...]
    state: ImageState
    timings_s: dict[str, float] = dataclasses.field(default_factory=dict)


class Clock:
    """Accumulates the wall time of named stages."""

    def __init__(self):
        self.totals: dict[str, float] = {}
        self._t = time.perf_counter()

    def lap(self, name: str) -> None:
        t = time.perf_counter()
        self.totals[name] = self.totals.get(name, 0.0) + (t - self._t)
        self._t = t


class WindowOutlines(Sequence):
    """Per camera, the exterior coordinates of the window polygons (for overlays), converted
    from shapely only when a camera's list is first read.

    ``windows[c]`` is a list of (k, 2) arrays, one per non-empty polygonal window of camera
    ``c``, in link order; it behaves as a read-only list of such lists.
    """

    def __init__(self, diagnostics: Diagnostics):
        self._visibility = [cd.visibility for cd in diagnostics.cameras]
        self._coords: dict[int, list[np.ndarray]] = {}

    def __len__(self) -> int:
        return len(self._visibility)

    def __getitem__(self, c):
        if isinstance(c, slice):
            return [self[i] for i in range(*c.indices(len(self)))]
        c = range(len(self))[c]  # negative indices; IndexError past the end
        if c not in self._coords:
            self._coords[c] = [np.asarray(w.exterior.coords) for w in self._visibility[c].windows
                               if w is not None and not w.is_empty and w.geom_type == "Polygon"]
        return self._coords[c]

    def __repr__(self) -> str:
        return f"WindowOutlines({len(self)} cameras)"
