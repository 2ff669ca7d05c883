"""The state the image front end carries between frames: the stored templates (thesis §4.3.1)
and the estimated phalanx radii (appendix E)."""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._errors import InputError

__all__ = ["ImageState"]


@dataclasses.dataclass(frozen=True)
class ImageState:
    """Stored profile templates, one set per camera.

    A template is a link's profiles sampled where the link was seen (thesis fig. 4.8), with a mask
    of the samples that showed the link (inside its own outline, off any nearer finger, inside the
    image); the WSSD search matches the current profiles against the masked template under the
    current visibility windows. Each capture overwrites the samples it sees and keeps the others,
    so a template stays as complete as the link's views have been and as recent as possible.
    Profiles are measured in units of the link's predicted radius, so a template stays usable
    while the finger's image size changes, as long as the sampler layout (samplers per link,
    points per profile, scope) is the same.

    Attributes:
        templates: per camera, (links, samplers, points) grey levels (0 where none is stored).
        template_mask: per camera, (links, samplers, points) the template sample showed the link.
        layout: (samplers per link, points per profile, scope) the templates were sampled with.
        radius_mm: (links,) the phalanx radii estimated from the images
            (:func:`jaxhand.image.update_widths`), which the front end uses in place of the
            model's; None: the model's radii.
        refreshed_px: per camera, (links, 2, 2) the projected link ends (px) where
            :func:`jaxhand.image.refresh_templates` last re-took each template (NaN: never);
            None: no refresh yet.
    """

    templates: tuple[np.ndarray, ...]
    template_mask: tuple[np.ndarray, ...]
    layout: tuple[int, int, float]
    radius_mm: np.ndarray | None = None
    refreshed_px: tuple[np.ndarray, ...] | None = None

    @property
    def template_valid(self) -> tuple[np.ndarray, ...]:
        """Per camera, (links,) a template is stored."""
        return tuple(m.any(axis=(1, 2)) for m in self.template_mask)

    @classmethod
    def empty(cls, n_cameras: int, n_links: int, layout: tuple[int, int, float]) -> ImageState:
        m, n, _ = layout
        return cls(templates=tuple(np.zeros((n_links, m, n)) for _ in range(n_cameras)),
                   template_mask=tuple(np.zeros((n_links, m, n), bool) for _ in range(n_cameras)), layout=layout)

    def matches(self, n_cameras: int, n_links: int, layout: tuple[int, int, float]) -> bool:
        """Whether the state's templates fit this rig, model and sampler layout."""
        return (self.layout == layout and len(self.templates) == n_cameras
                and all(t.shape == (n_links, layout[0], layout[1]) for t in self.templates))

    def model_radii(self, model):
        """``model`` with this state's estimated radii (``model`` itself when there are none)."""
        if self.radius_mm is None:
            return model
        if np.shape(self.radius_mm) != (model.n_links,):
            raise InputError(f"ImageState.radius_mm: expected shape ({model.n_links},), got {np.shape(self.radius_mm)}")
        return eqx.tree_at(lambda m: m.link_radius_mm, model, jnp.asarray(self.radius_mm, float))
