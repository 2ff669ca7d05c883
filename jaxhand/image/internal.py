"""The image front end's pieces, shared with tests, benchmarks and figures but not a stable
interface (optimistix's ``internal`` idea): tracker placement, profile sampling, visibility and
point tests, searches, regressions, line fitting, and the per-camera context and observation the
pipeline passes between its steps. Users call :mod:`jaxhand.image`."""

from ._config import INTERPOLATIONS, POLARITIES
from ._context import CameraContext, Observation, against_background, as_images, observe, off_other_links
from ._diagnostics import CameraDiagnostics, Clock
from ._geometry import Geometry, predicted_geometry
from ._linefit import fit_rows, padded_rows
from ._lines import axial_line, line_params, line_point_direction, offset_towards, ransac_pca
from ._polygons import convex_edges, inside_polygons
from ._reacquire import reacquire, reacquire_full, search_turns, turns_to_try
from ._regression import imwplls, imwplls_crest_fit, mwplls, plls
from ._sampling import INTERPOLATION_FLAGS, as_grey, sample_profiles
from ._templates import clear_share, link_ends, refresh_gate, seen_axis_offsets, shift_profiles, take_templates
from ._trackers import LinkSamplers, TipSamplers, place_link_samplers, place_tip_samplers, refine_tip
from ._view import LineFit, TipFit, View, edges_to_px, find_tips, fit_links, search_view
from ._visibility import (
    OccluderPills,
    Visibility,
    compute_visibility,
    pill_outlines,
    row_unions,
    same_chain,
    window_masks,
)
from ._widths import width_ratios
from .searches import SEARCHES, TEMPLATE_SEARCHES, Edges, Profiles, search_named
from .searches._common import (
    correlate_last,
    correlate_shifts,
    derivative_kernel,
    gaussian_derivative,
    parabola_vertex,
    simple_derivative,
    width_template,
)
from .searches._wssd import _descend as wssd_descend
from .searches._wssd import wssd_surface

__all__ = [
    "INTERPOLATIONS", "POLARITIES", "INTERPOLATION_FLAGS", "SEARCHES", "TEMPLATE_SEARCHES", "search_named",
    "Profiles", "Edges", "as_grey", "as_images", "sample_profiles",
    "CameraContext", "Observation", "observe", "Geometry", "predicted_geometry", "off_other_links",
    "against_background", "CameraDiagnostics", "Clock",
    "LinkSamplers", "TipSamplers", "place_link_samplers", "place_tip_samplers", "refine_tip",
    "Visibility", "OccluderPills", "compute_visibility", "pill_outlines", "same_chain", "window_masks", "row_unions",
    "convex_edges",
    "inside_polygons", "ransac_pca", "axial_line", "line_params", "line_point_direction", "offset_towards",
    "plls", "mwplls", "imwplls", "imwplls_crest_fit", "fit_rows", "padded_rows",
    "LineFit", "TipFit", "View", "edges_to_px", "fit_links", "find_tips",
    "search_view", "reacquire", "reacquire_full", "search_turns", "turns_to_try", "seen_axis_offsets", "shift_profiles",
    "take_templates", "clear_share", "link_ends", "refresh_gate",
    "width_ratios", "correlate_last", "correlate_shifts", "derivative_kernel", "gaussian_derivative",
    "parabola_vertex", "simple_derivative", "width_template", "wssd_descend", "wssd_surface",
]
