"""The traced scene: a scene's three bodies as Embree meshes and the tracer's jobs, each an
explicit collaborator that is handed what it uses.

* :class:`~lunarviz.methods.tracer.traced_bodies.TracedBodies` (``bodies``): the meshes in their
  centred frames, the rays cast and the source facets hit, the trace's threads;
* :class:`~lunarviz.methods.tracer.facet_surfaces.FacetSurfaces` (``surfaces``): the lunar map's
  and the Earth's values per facet;
* :class:`~lunarviz.methods.tracer.lunar_sampling.LunarSampling` (``sampling``): the lunar samples
  (facets worth tracing, refinement, the lune rule) and the detector's view;
* :class:`~lunarviz.methods.tracer.source_rules.SourceRules` (``sources``): the beams toward the
  Sun and the Earth, eclipses, the sources' radiance;
* :class:`~lunarviz.methods.tracer.mapped_earth.MappedEarthTransport` (``mapped_earth``): the
  earthlight of a mapped Earth summed facet by facet;
* :class:`~lunarviz.methods.tracer.deterministic.DeterministicTransport` (``deterministic``) and
  :class:`~lunarviz.methods.tracer.montecarlo.MonteCarloTransport` (``montecarlo``): the two
  estimators' transports.
"""

from __future__ import annotations

from lunarviz.geometry.scene_geometry import SceneGeometry
from lunarviz.methods.tracer.deterministic import DeterministicTransport
from lunarviz.methods.tracer.facet_surfaces import FacetSurfaces
from lunarviz.methods.tracer.lunar_sampling import LunarSampling
from lunarviz.methods.tracer.mapped_earth import MappedEarthTransport
from lunarviz.methods.tracer.montecarlo import MonteCarloTransport
from lunarviz.methods.tracer.settings import TraceSettings
from lunarviz.methods.tracer.source_rules import SourceRules
from lunarviz.methods.tracer.traced_bodies import TracedBodies


class TraceScene:
    """The three bodies of a :class:`~lunarviz.geometry.scene_geometry.SceneGeometry` as Embree
    meshes, and the tracer's jobs on them.

    Parameters
    ----------
    scene : SceneGeometry
        The bodies' positions and the detector [m].
    settings : TraceSettings
        The tracer's settings.

    Attributes
    ----------
    scene, settings, moon, earth, sun, source_hits
        The traced bodies' (:attr:`bodies`), for the callers that read them.
    bodies, surfaces, sampling, sources, mapped_earth, deterministic, montecarlo
        The collaborators (module docstring).
    """

    def __init__(self, scene: SceneGeometry, settings: TraceSettings = TraceSettings()):
        self.bodies = TracedBodies(scene, settings)
        self.scene, self.settings = scene, settings
        self.moon, self.earth, self.sun = self.bodies.moon, self.bodies.earth, self.bodies.sun
        self.source_hits = self.bodies.source_hits
        self.surfaces = FacetSurfaces(self.bodies)
        self.sampling = LunarSampling(self.bodies, self.surfaces)
        self.sources = SourceRules(self.bodies, self.surfaces, self.sampling)
        self.mapped_earth = MappedEarthTransport(self.bodies, self.surfaces, self.sources)
        self.deterministic = DeterministicTransport(self.bodies, self.surfaces, self.sampling, self.sources,
                                                    self.mapped_earth)
        self.montecarlo = MonteCarloTransport(self.bodies, self.surfaces, self.sampling, self.sources,
                                              self.deterministic)

    @property
    def rays_cast(self) -> int:
        """Rays traced so far in this scene."""
        return self.bodies.rays_cast
