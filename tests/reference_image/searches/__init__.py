"""Feature searches (thesis §4.3 and appendix D), one module each, all with the signature
``search(profiles: Profiles, config: SearchConfig) -> Edges`` so they can be swapped by name.

=====================  ==========================================================  ==============
name                   method                                                      thesis
=====================  ==========================================================  ==============
``derivative``         simple-difference derivative peaks of the right sign        §11.1.1
``gaussian``           Gaussian-derivative peaks                                   §11.1.2
``width``              peaks restricted to windows about the predicted boundaries  §11.2.1
``width_compensated``  the same windows re-centred by a width-template correlation §11.2.2
``plls``               PLLS line through the correlation surface's maxima          §11.3.1
``mwplls``             modified weighted PLLS over the correlation surface         §11.3.2
``imwplls``            iterative MWPLLS                                            §11.3.3
``wssd``               windowed SSD against templates, valley descent (occlusion)  §4.3.1-4.3.2
=====================  ==========================================================  ==============
"""

from __future__ import annotations

from collections.abc import Callable

from jaxhand import InputError

from ._common import Edges, Profiles
from ._derivative import derivative_peaks
from ._gaussian import gaussian_peaks
from ._rectilinear import imwplls_crest, mwplls_crest, plls_crest
from ._width import width_compensated, width_restricted
from ._wssd import wssd_valley

__all__ = ["Profiles", "Edges", "SEARCHES", "SEARCH_NAMES", "search_named", "derivative_peaks", "gaussian_peaks",
           "width_restricted", "width_compensated", "plls_crest", "mwplls_crest", "imwplls_crest", "wssd_valley"]

SEARCHES: dict[str, Callable] = {
    "derivative": derivative_peaks,
    "gaussian": gaussian_peaks,
    "width": width_restricted,
    "width_compensated": width_compensated,
    "plls": plls_crest,
    "mwplls": mwplls_crest,
    "imwplls": imwplls_crest,
    "wssd": wssd_valley,
}
SEARCH_NAMES: tuple[str, ...] = tuple(SEARCHES)

# Searches that need stored templates and honour the visibility windows.
TEMPLATE_SEARCHES = frozenset({"wssd"})


def search_named(name: str) -> Callable:
    """The search function called ``name``; an unknown name lists the valid ones.

    Raises:
        InputError: unknown name.
    """
    try:
        return SEARCHES[name]
    except KeyError:
        raise InputError(f"unknown feature search {name!r}; valid: {', '.join(SEARCH_NAMES)}") from None
