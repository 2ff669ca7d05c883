"""The state the image front end carries between frames: the stored templates (thesis §4.3.1)."""

from __future__ import annotations

import dataclasses

import numpy as np

__all__ = ["ImageState"]


@dataclasses.dataclass(frozen=True)
class ImageState:
    """Stored profile templates, one set per camera.

    A template is a link's profiles sampled where the link was seen unoccluded (thesis fig. 4.8);
    the WSSD search matches the current profiles against it under the visibility windows.
    Profiles are measured in units of the link's predicted radius, so a template stays valid while
    the finger's image size changes, as long as the sampler layout (samplers per link, points per
    profile) is the same.

    Attributes:
        templates: per camera, (links, samplers, points) grey levels (0 where none is stored).
        template_valid: per camera, (links,) a template is stored.
        layout: (samplers per link, points per profile, scope) the templates were sampled with.
    """

    templates: tuple[np.ndarray, ...]
    template_valid: tuple[np.ndarray, ...]
    layout: tuple[int, int, float]

    @classmethod
    def empty(cls, n_cameras: int, n_links: int, layout: tuple[int, int, float]) -> ImageState:
        m, n, _ = layout
        return cls(templates=tuple(np.zeros((n_links, m, n)) for _ in range(n_cameras)),
                   template_valid=tuple(np.zeros(n_links, bool) for _ in range(n_cameras)), layout=layout)

    def matches(self, n_cameras: int, n_links: int, layout: tuple[int, int, float]) -> bool:
        """Whether the state fits this rig, model and sampler layout."""
        return (self.layout == layout and len(self.templates) == n_cameras
                and all(t.shape == (n_links, layout[0], layout[1]) for t in self.templates))
