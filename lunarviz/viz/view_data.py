"""What a view shows, computed before anything is drawn (no PyVista here): the per-facet arrays
of one task, a few light paths, and the numbers beside them."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

from lunarviz.methods.tracer.facet_result import FacetResult


@dataclass
class ViewData:
    """One task as the views draw it.

    Parameters
    ----------
    facets : FacetResult
        Per-facet arrays of the Moon (and the other bodies) for the BRDF shown.
    rays : dict
        ``{"moonshine": [polyline (k, 3) [m], ...], "earthshine": [...]}``: sample light paths.
    numbers : dict
        The task's geometry, irradiances [W m⁻²], ratio and albedos, as the numbers panel shows them.
    """

    facets: FacetResult
    rays: dict
    numbers: dict


#: how a viewer gets a new :class:`ViewData` when its phase, date or BRDF changes: ``compute(key, brdf)``
ComputeView = Callable[[object, str], ViewData]
