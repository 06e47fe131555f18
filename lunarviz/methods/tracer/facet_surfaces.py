"""The surfaces on the traced bodies' facets: the lunar albedo map's values per Moon facet, the
Earth's albedo (or a physical Earth's reflectance toward the Moon) per Earth facet, and a spectral
run's Earth components, each computed once per trace (the lunar map's once per process)."""

from __future__ import annotations

import numpy as np

from lunarviz.caches import BoundedCache, file_key, mesh_digest
from lunarviz.geometry.scene_geometry import unit
from lunarviz.methods.tracer.traced_bodies import TracedBodies
from lunarviz.methods.transport import Transport
from lunarviz.surfaces.earth_spectra import components, facet_weight_fields, facet_weights, grey_albedos
from lunarviz.surfaces.maps import facet_field_at, map_frame
from lunarviz.surfaces.moon_map import moon_facet_values
from lunarviz.surfaces.physical_earth import facet_reflectance, reflectance

#: per-facet lunar map values per (map, mesh, frame) (:meth:`FacetSurfaces.moon_map_values`)
MOON_MAP_VALUES = BoundedCache(8)


class FacetSurfaces:
    """Per-facet surface values of :class:`TracedBodies` ``bodies``."""

    def __init__(self, bodies: TracedBodies):
        self.bodies = bodies
        self._moon_albedo = self._earth_albedo = None
        #: a spectral run's Earth components (:func:`lunarviz.surfaces.earth_spectra.components`): the
        #: mapped Earth's transports then carry one beam array each (``e_beam_parts``)
        self.earth_parts: tuple | None = None
        #: a physical Earth's spectral run: the node wavelengths [nm] its components are
        self.earth_part_wavelengths = None
        self._mapped = None

    def moon_facet_albedo(self, spread: bool = False):
        """Per-facet values of the lunar albedo map (area averages, :mod:`lunarviz.surfaces.maps`),
        or ``None`` without a map; ``spread``: ``(mean, std)`` over each facet."""
        amap = self.bodies.settings.moon_map()
        if amap is None:
            return None
        if self._moon_albedo is None:
            self._moon_albedo = self.moon_map_values()
        return self._moon_albedo if spread else self._moon_albedo[0]

    def moon_map_values(self):
        """(mean, std) of the lunar map over each facet (:func:`lunarviz.surfaces.moon_map.moon_facet_values`
        over the whole mesh). On dates the Moon's mesh turns with the Moon, so a facet covers the
        same part of the map at every date: the values are kept per map, mesh and frame for the
        process (:data:`MOON_MAP_VALUES`), and a time series computes them once."""
        M, amap = self.bodies.moon, self.bodies.settings.moon_map()
        frame = map_frame(self.bodies.scene, "moon")
        turned = M.rotation is not None and np.array_equal(frame, M.rotation)  # body frame: date-independent
        mesh = M.geometry["mesh"]
        key = (file_key(amap.source()), amap.mean, mesh_digest(mesh), float(M.radius),
               "body" if turned else frame.tobytes())
        got = MOON_MAP_VALUES.get(key)
        if got is None:
            got = moon_facet_values(amap, M, frame)
            MOON_MAP_VALUES[key] = got
        return got

    def earth_mapped(self) -> bool:
        """Whether the Earth's albedo varies over its facets: a map that is not one value
        (:meth:`~lunarviz.surfaces.earth_surface.EarthSurface.albedo_constant`), or the physical
        Earth, or any map of a spectral run with components (:attr:`earth_parts`: their spectra
        differ). Then :meth:`earth_facet_albedo` is an array; decided from the maps, without
        computing the facets' values (call it once :attr:`earth_parts` is set)."""
        if self._mapped is None:
            surf = self.bodies.settings.surface()
            # a spectral run's components differ in their spectra even where their grey albedos agree
            self._mapped = surf.varies(in_colour=self.earth_parts is not None)
        return self._mapped

    def earth_facet_albedo(self):
        """Per-facet Lambert albedo of the Earth (area averages of its surface and clouds), or
        ``None`` for a uniform Earth (then :meth:`earth_albedo_value`; a map of one value is that
        uniform Earth, bit for bit)."""
        surf = self.bodies.settings.surface()
        if surf.uniform:
            return None
        if self._earth_albedo is None:
            frame = self._earth_frame()
            if surf.physical:  # each facet's reflectance toward the Moon as its albedo (earth_optics.planet)
                sc = self.bodies.scene
                self._earth_albedo = facet_reflectance(surf, self.bodies.earth, frame, sc.sun, sc.moon,
                                                       [surf.wavelength_nm])[:, 0]
                return self._earth_albedo
            if not self.earth_mapped():  # one value: any facet's average is it
                self._earth_albedo = float(surf.facet_albedo(self.bodies.earth, frame, only=np.zeros(1, int))[0])
            else:
                self._earth_albedo = surf.facet_albedo(self.bodies.earth, frame)
        return None if isinstance(self._earth_albedo, float) else self._earth_albedo

    def earth_element_values(self, faces: np.ndarray, at: np.ndarray, y: np.ndarray, m: np.ndarray):
        """(albedo (n,), component weights (n, C) or ``None``) of the mapped Earth's surface elements
        at points y (n, 3) with normals m on the facets ``faces[at]``.

        A map's Earth: each component's weight is its facet's linear field at the element
        (:func:`~lunarviz.surfaces.earth_spectra.facet_weight_fields`), the albedo their grey sum.
        The facets' means alone put a coastline's light at the facet's centre: at level 6 that, and
        the means' sampling noise, erred by up to 7.4e-5 of an albedo-1 Earth's earthshine on the
        land-ocean map with zonal clouds; the fields (zeroth and first moments, 576 points a facet)
        by 1.1e-5 on the same dates (docs: accuracy, "A mapped Earth"). The weights may leave
        [0, 1] near a facet's corners (the transport is linear in them, but for the map's light
        clipped at 0 per cell and lunar point, which no cell's sum reaches). The physical Earth,
        whose reflectance toward the Moon changes across a facet: each element's own, at its point
        with its facet's mean class weights (second order in the elements, where the facet's centre
        alone left ~5e-4 at a thin crescent)."""
        surf = self.bodies.settings.surface()
        if not surf.physical:
            body = self.bodies.earth
            value, grad = facet_weight_fields(surf, body, self._earth_frame(), faces)
            w = facet_field_at(value[at], grad[at], body.vertices, body.faces[faces[at]], y - body.centre,
                               radial=body.mode(self.bodies.settings.shading) == "exact")
            grey = grey_albedos(surf)
            return w @ np.array([grey[c] for c in components(surf)]), w if self.earth_parts is not None else None
        sc = self.bodies.scene
        frame = self._earth_frame()
        lam = [surf.wavelength_nm] + list(self.earth_part_wavelengths if self.earth_parts is not None else [])
        w = facet_weights(surf, self.bodies.earth, frame, faces)[at]
        r = reflectance(surf, w, m @ frame, m, unit(sc.sun - y), unit(sc.moon - y), lam)
        return r[:, 0], (r[:, 1:] if self.earth_parts is not None else None)

    def _earth_frame(self) -> np.ndarray:
        return map_frame(self.bodies.scene, "earth", self.bodies.settings.earth_rotation_deg)

    def earth_albedo_value(self) -> float:
        """The uniform Earth's albedo: ``earth_albedo``, or a uniform map's one value (a mapped
        Earth's: ``earth_albedo``)."""
        if self.earth_mapped():
            return float(self.bodies.settings.earth_albedo)
        self.earth_facet_albedo()
        return self._earth_albedo if isinstance(self._earth_albedo, float) else float(self.bodies.settings.earth_albedo)

    def with_moon_albedo(self, tr: Transport, owner=None, values=None) -> Transport:
        """``tr`` with the lunar map's (mean, spread) per sample: ``values`` as given, or the
        facet values at the samples' owning facets ``owner``; unchanged without a map."""
        if values is None and owner is not None:
            v = self.moon_facet_albedo(spread=True)
            values = None if v is None else (v[0][owner], v[1][owner])
        if values is not None:
            tr.albedo, tr.albedo_std = values
            tr.albedo_absolute = self.bodies.settings.moon_map().absolute
        return tr
