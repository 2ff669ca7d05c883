"""The image front end's entry point, :func:`extract_features`.

Per camera (thesis ch. 4, DESIGN.md data flow):

1. one jitted kinematics call gives the predicted link ends, depths, radii and tips in pixels,
   converted to NumPy once;
2. place the link samplers (§4.1) and compute the visibility windows (§4.3.3);
3. sample every profile in one ``cv2.remap`` (§4.2);
4. search every profile for both boundaries with the configured search (§4.3, app. D);
5. fit both boundary lines of every link (RANSAC + PCA) and the axial line between them, or
   offset a lone boundary by the radius (§4.4, DigitEyes §4);
6. place the tip samplers on the terminal axial lines (eq. 4.1), sample them in a second remap
   and take the strongest derivative of the right sign as the tip boundary (§11.1.1).

Steps 1-3 live in :mod:`._context` (:func:`observe`), 4-6 in :mod:`._view`; templates,
re-acquisition and widths have modules of their own.
"""

from __future__ import annotations

import dataclasses
from typing import no_type_check

import jax
import numpy as np

from ..features import Features
from ..model import Model
from ._config import ImageConfig
from ._context import CameraContext, matching_state, observe, prepare
from ._diagnostics import CameraDiagnostics, Clock, Diagnostics
from ._reacquire import reacquire
from ._state import ImageState
from ._templates import take_templates
from ._view import search_view
from .searches import TEMPLATE_SEARCHES, search_named

__all__ = ["extract_features"]


@jax.jit
def _to_features(lines, line_valid, line_weight, tips, tip_valid) -> Features:
    """One camera's feature arrays as device :class:`Features` in one compiled call: a jitted call
    converts its NumPy arguments on its fast path and builds the Module by unflattening, far cheaper
    than ``jax.device_put`` and ``Features.__init__`` (the same values; a tip's weight is its validity)."""
    return Features(lines=lines, line_valid=line_valid, line_weight=line_weight, tips=tips, tip_valid=tip_valid,
                    tip_weight=tip_valid.astype(float))


@no_type_check   # validates its arguments itself (InputError naming the argument), which a checker would preempt
def extract_features(images, model: Model, cameras, q_pred, config: ImageConfig | None = None,
                     state: ImageState | None = None) -> tuple[tuple[Features, ...], Diagnostics]:
    """Link lines and tip points of every camera's image, searched around the predicted pose.

    Args:
        images: one image per camera, in the rig's order (a single array for one camera): 2-D
            uint8 or float grey levels (0-255), or (H, W, 3) uint8 BGR; each must have its
            camera's size. NaN pixels are allowed (profiles through them are dropped). A float
            image whose finite pixels all lie in [0, 1] is refused (scale it by 255).
        model: the model.
        cameras: a camera or a rig.
        q_pred: (n_q,) the predicted pose that places the trackers and the windows.
        config: settings (default :class:`ImageConfig`, the WSSD search).
        state: stored templates (for the "wssd" search; see :func:`capture_templates`). Links
            without a template get one from this frame at ``q_pred`` when enough of them is seen,
            as the thesis's first frame does with its hand-set pose; the updated state comes back
            in ``diagnostics.state``. Templates are never refreshed here: the prediction is not
            the pose the image shows; refresh them with :func:`capture_templates` at the solved pose.

    Returns:
        (features, diagnostics): one :class:`~jaxhand.features.Features` per camera (lines with
        unit normals oriented like :func:`~jaxhand.features.line_through` of each predicted link,
        weights scaled by each link's visible share) and the :class:`Diagnostics`.

    Raises:
        InputError: bad images (count, type, dtype, shape, size, range), q_pred or config.
    """
    config, rig, greys, q, chain = prepare(images, model, cameras, q_pred, config, "q_pred")
    search = search_named(config.method)
    state = matching_state(state, len(rig), model, config)
    model = state.model_radii(model)
    features, diags, templates, masks = [], [], [], []
    clock = Clock()
    for c, (grey, cam) in enumerate(zip(greys, rig)):
        ctx = CameraContext(grey=grey, model=model, camera=cam, chain=chain, config=config, clock=clock,
                            search=search)
        obs = observe(ctx, q)
        tmpl, tmask = state.templates[c], state.template_mask[c]
        if config.method in TEMPLATE_SEARCHES:
            tmpl, tmask = take_templates(obs, config, tmpl, tmask, only_missing=True)
        templates.append(tmpl)
        masks.append(tmask)
        ctx = dataclasses.replace(ctx, templates=tmpl, template_mask=tmask)
        view = search_view(ctx, obs)
        reacquired = np.zeros(model.n_links, bool)
        if config.reacquire_deg:
            view, reacquired = reacquire(ctx, q, obs, view)
        fit, tips = view.fit, view.tips
        features.append(_to_features(fit.lines, fit.valid, fit.weight, tips.tips, tips.valid))
        diags.append(CameraDiagnostics(samplers=obs.samplers, visibility=obs.visibility, profiles=view.profiles,
                                       edges=view.edges, edge_px=view.edge_px, boundary_lines=fit.boundary,
                                       boundary_valid=fit.bvalid, inliers=fit.inliers, axial_lines=fit.lines,
                                       single_edge=fit.single, tip_samplers=tips.ts, tip_edge_px=tips.edge,
                                       tip_strength=tips.strength, reacquired=reacquired))
    new_state = dataclasses.replace(state, templates=tuple(templates), template_mask=tuple(masks))
    return tuple(features), Diagnostics(method=config.method, cameras=tuple(diags), state=new_state,
                                        timings_s=dict(clock.totals))
