"""The ray tracer's settings (composed of option groups) and its tuning constants, each with its reason."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np

import lunarviz.constants as C
from lunarviz.bodies.sphere_mesh import packaged_sphere
from lunarviz.caches import file_key, memoize
from lunarviz.errors import LunarvizError
from lunarviz.methods.accuracy import DEFAULT_RAYS
from lunarviz.options import DEFAULT_LEVELS, DEFAULT_ORDERS, SHADINGS, compose, validate
from lunarviz.surfaces.earth_surface import EarthSurface
from lunarviz.surfaces.moon_map import MoonAlbedoMap

#: Shadow-ray origins are offset along the normal by this fraction of the body radius
#: (0.17 m on the Moon: above float32's 0.125 m step at the lunar radius, far below any facet).
NORMAL_OFFSET = 1e-7
#: Share of Monte Carlo lunar samples drawn ∝ facet area (defensive mixture).
UNIFORM_SHARE = 0.1
#: Facets straddling a kink (terminator, penumbra edge, limb) are split REFINE² ways.
REFINE = 4
#: Samples wanted across the width of the lit-and-visible lune (see ``lunar_refinement``).
LUNE_SAMPLES = 16
#: Order of the sphere rule for lunar samples that see the Sun partly below the horizon.
#: Sun-cone Gauss order (radial × 2·order azimuthal) where the Earth's disc overlaps the Sun's
#: (lunar eclipses): the Earth's limb is a discontinuity inside the cone; order 16 puts
#: 512 beams across it (the penumbra then agrees with the exact disc overlap to ~1e-3).
ECLIPSE_ORDER = 16
PENUMBRA_ORDER = 6
#: Kink refinement is skipped when the lune is within this angle [rad] of a hemisphere.
KINK_FREE_WIDTH = 0.05
PATHS = {"moonshine": "sun", "earthshine": "earth"}
#: Gauss order (radial; twice that in azimuth) of the beams over the bounding cone of a source
#: that is a user mesh (not an analytic sphere): its silhouette is resolved by the beams.
MESH_SOURCE_ORDER = 16
#: Lunar samples per batch: bounds memory (≈ CHUNK × beams × 30 doubles) for any ray count.
CHUNK = 1 << 14
#: Facets per block in the per-facet passes (candidate tests, shadow edges): bounds their
#: temporaries (≈ 100 doubles per facet) on multi-million-facet meshes.
FACET_BLOCK = 1 << 18
#: Facets of a mapped Earth that its terminator crosses are split this many ways per side.
TERMINATOR_SUB = 8
#: A mapped Earth's facets are grouped into at most this many cells per side of its disc seen
#: from the Moon, four beams a cell (``mapped_earth_transport``; an albedo-1 Earth under Hapke's
#: surge at θ = 160°: 16 cells a side err by 3.5e-6, 24 by 1.1e-6 at 2.2 times the beams, 12 by
#: 1.7e-5; one beam a cell of 24 erred by 8.2e-5, with 0.55 times the beams of 16)
EARTH_CELLS = 16
#: a mapped Earth's lit facets that the Earth's limb seen from some lunar point crosses (where
#: cos_y kinks) are split LIMB_SUB² ways (:mod:`lunarviz.methods.tracer.mapped_earth`)
LIMB_SUB = 4
#: lunar samples × Earth order² per batch of the Earth's rule about the zero-phase point (its rows
#: hold up to ~18·order² beams: two φ-intervals on each of up to nine t-segments): ~0.5 GB a batch
POLE_RULE_NODES = 1 << 17
#: the poles the Earth's beam rules may take (:attr:`TraceSettings.earth_pole`)
EARTH_POLES = ("centre", "detector", "detector-cut")
#: the least Earth order :func:`horizon_band_order` gives the samples whose horizon cuts the
#: Earth, on the plain rule (the rule cut along the kinks keeps its own order). The plain rule's
#: error in one such sample's earthlight (eight samples across an orbit date's band,
#: 2026-05-10T00:00Z, the paper's Moon; tests/test_zero_phase_rule.py): 2.0e-2, 1.2e-2, 3.0e-3,
#: 4.7e-4, 4.9e-5 and 4.5e-7 at orders 4, 5, 6, 7, 8 and 10. A row takes it times the band's share of
#: its earthshine: at most 3.4e-4 (Hapke) and 1.1e-5 (Lambert) from a 550 km orbit and from sites,
#: up to 9.8e-4 for a detector 25,000 km from the Moon (the band's beams weighed out; ~2e-5 of
#: such a row at order 4, outside the orbits and sites the error models hold). At order 4
#: rather than 6, rows at the orders ``--rtol 1e-4`` takes moved by at most 1.8e-5 (median 5e-8;
#: the paper's DHG Moon, the year's 8,760 hourly orbit dates) and an orbit date's earthshine traces
#: ~15 % faster; the error models are measured with this rule
HORIZON_CUT_LEAST_ORDER = 4
#: the same where the detector's view of the Moon is cut (:func:`horizon_band_order`)
VIEW_CUT_BAND_LEAST_ORDER = 6
#: a quick look's settings (an explorer's first picture): the fewest beams to each source, the
#: Earth's rule about each sample's sub-point, no refinement at edges
QUICK_TRACE = {"earth_order": 2, "sun_order": 2, "earth_pole": "centre", "refine": False}
#: a picture's settings (the explorer's converged one): the Earth's rule about each facet's
#: sub-point, not its zero-phase point. Off the Earth's centre a rough, surging BRDF's earthshine
#: then errs by up to ~5e-3 (docs: accuracy), nothing on a colour scale; the numbers beside a
#: picture are the sweep's rows, with their bounds
PICTURE_TRACE = {"earth_pole": "centre"}


@dataclass(frozen=True)
@compose("earth", "meshes", "trace", "surfaces")
class TraceSettings:
    """The ray tracer's settings: the options of the ``earth``, ``meshes``, ``trace`` and
    ``surfaces`` groups of :mod:`lunarviz.options` (icosphere levels ``None`` resolve to
    :data:`~lunarviz.options.DEFAULT_LEVELS`, the Earth's rotation ``None`` to 0), and:"""

    #: the option groups whose fields this class takes from the schema
    GROUPS: ClassVar[tuple] = ("earth", "meshes", "trace", "surfaces")
    #: split facets that a terminator, limb, penumbra or cast-shadow edge crosses (lune refinement)
    refine: bool = True
    #: threads per trace (``None``: the machine's cores); no number depends on it
    threads: int | None = None
    #: per-body shading overriding ``shading``, e.g. ``(("earth", "flat"),)`` (mesh studies)
    body_shading: tuple = ()
    #: a mapped Earth's earthlight: ``facets`` (default: summed per facet into disc cells,
    #: :meth:`~lunarviz.methods.tracer.mapped_earth.MappedEarthTransport.transport`) or ``beams``
    #: (the uniform Earth's Gauss beams
    #: with each hit facet's albedo: ~2 % off at a map's edges; a diagnostic for comparisons)
    mapped_earth: str = "facets"
    #: lunar samples from the lune rule of this Gauss order (one for both paths, or a pair:
    #: moonshine, earthshine) where it applies (the packaged exact
    #: sphere, no lunar map, no shadow edge across the lune:
    #: :meth:`~lunarviz.methods.tracer.lunar_sampling.LunarSampling.lune_rule_applies`); ``None``:
    #: samples on the facets (per-facet arrays, images and every other Moon take those)
    lune_order: int | None = None
    #: the Gauss orders (Sun, Earth) of the beams from the lune rule's samples, where the tolerance
    #: chose them from the lune rule's own error model (:func:`~lunarviz.methods.accuracy.trace_choice`);
    #: ``None``: ``sun_order`` and ``earth_order``, which the facets' samples always take
    lune_source_orders: tuple | None = None
    #: the physical Earth's parameters (``--param earth.NAME=VALUE``) as sorted (name, value) pairs
    earth_params: tuple = ()
    #: the pole of the Earth's beam rules: ``centre`` (the sub-point of each lunar sample: the
    #: zero-phase point where the detector is at the Earth's centre) or ``detector`` (the zero-phase
    #: point itself, :func:`~lunarviz.methods.sources.zero_phase_points`: where a BRDF's opposition
    #: surge and roughness kink sit for a detector off the centre; docs: accuracy), or
    #: ``detector-cut`` (that pole, and the rule also cut along the roughness's kinks through it:
    #: :func:`~lunarviz.methods.sources.roughness_kink_cuts`)
    earth_pole: str = "centre"
    #: the Gauss order of the Earth's rule about the zero-phase point (``earth_pole`` not
    #: ``centre``) at the lunar samples whose horizon cuts the Earth, where they are summed into
    #: rows (per-facet arrays and images keep ``earth_order``): the band of the earthlight's
    #: penumbra, where μ0 ≤ sin ρ_E ≈ 0.017 and which holds at most ~1e-3 of the earthshine
    #: (:data:`HORIZON_CUT_LEAST_ORDER`), so that a coarser rule there errs by as little as the
    #: full one elsewhere (the error models are measured with it:
    #: scripts/off_centre_earth_model.py); ``None``:
    #: :func:`horizon_band_order` of the row's Earth order (the rule cut along the kinks: that order)
    earth_horizon_order: int | None = None

    def moon_map(self):
        """The parsed lunar albedo map, or ``None``."""
        if self.moon_albedo_map is None:
            return None
        src = Path(str(self.moon_albedo_map).strip())  # (its name, and a file's content key when it is one)
        return _parsed_moon_map(self.moon_albedo_map, file_key(src) if src.is_file() else None)

    def surface(self):
        """The Earth's :class:`~lunarviz.surfaces.earth_surface.EarthSurface`."""
        return EarthSurface.from_options(self)

    def __post_init__(self):
        for body in ("moon", "earth", "sun"):  # None: the mesh study's default level
            if getattr(self, f"{body}_level") is None:
                object.__setattr__(self, f"{body}_level", DEFAULT_LEVELS[body])
        for name, value in (("sun_order", DEFAULT_ORDERS["sun"]), ("earth_order", DEFAULT_ORDERS["earth"]),
                            ("rays", DEFAULT_RAYS)):  # None: the fixed default (sweeps resolve --rtol first)
            if getattr(self, name) is None:
                object.__setattr__(self, name, value)
        if self.lune_order is not None:
            pair = self.lune_order if isinstance(self.lune_order, tuple) else (self.lune_order,) * 2
            if len(pair) != 2 or not all(isinstance(o, (int, np.integer)) and 2 <= o <= 128 for o in pair):
                raise LunarvizError(f"lune_order={self.lune_order!r} must be an integer in [2, 128], a pair of them "
                                    "(moonshine, earthshine) or None")
            object.__setattr__(self, "lune_order", tuple(int(o) for o in pair))
        if self.earth_rotation_deg is None:
            object.__setattr__(self, "earth_rotation_deg", 0.0)
        validate(self)
        for body, mode in self.body_shading:
            if body not in ("moon", "earth", "sun") or mode not in SHADINGS:
                raise LunarvizError(f"body shading {body}={mode} is not valid")
        if not isinstance(self.refine, (bool, np.bool_)):
            raise LunarvizError(f"refine={self.refine!r} must be True or False")
        self.surface()
        self.moon_map()
        if self.earth_horizon_order is not None and not (
                isinstance(self.earth_horizon_order, (int, np.integer)) and 2 <= self.earth_horizon_order <= 128):
            raise LunarvizError(f"earth_horizon_order={self.earth_horizon_order!r} must be an integer in [2, 128] "
                                "or None")
        if self.earth_pole not in EARTH_POLES:
            raise LunarvizError(f"earth_pole {self.earth_pole!r} is not one of {', '.join(EARTH_POLES)}")
        if self.mapped_earth not in ("facets", "beams"):
            raise LunarvizError(f"mapped_earth {self.mapped_earth!r} is not one of facets, beams")


def horizon_band_order(order: int, asked: int | None = None, cut: bool = False, view_cut: bool = False) -> int:
    """The Earth order of the zero-phase rule at lunar samples whose horizon cuts the Earth
    (:attr:`TraceSettings.earth_horizon_order`): ``asked`` where given; else, for the plain rule,
    a third of the row's ``order`` rounded up, at least :data:`HORIZON_CUT_LEAST_ORDER` and at most
    ``order``: it never falls as ``order`` grows (4 from order 4 to 12, a third beyond), so refining
    the Earth's rule never coarsens these samples, though between orders 5 and 12 it leaves them as
    they are; for the rule ``cut`` along the kinks, ``order`` itself. The cut rule is taken for
    tolerances finer than the plain rule's orders meet, and a band at order 6 left its rows
    ~1e-6 off (2026-05-18T13:00Z from a 550 km orbit, the paper's Moon: 1.0e-6, 9.9e-7 and 9.9e-7
    at cut orders 7, 8 and 10, against 1.8e-7, 3.3e-8 and 6.1e-10 with the band at the rule's order).
    Where the detector's view of the Moon is cut (``view_cut``: a Moon partly hidden by the Earth's
    limb or a horizon, whose visible part may lie mostly near the lunar limb, where the band is), half
    the order, rounded up, at least 6: a second before the Moon set behind the Earth from a 550 km
    orbit (2026-10-28T16:00:02Z, 3.4 % of its diameter in sight) the plain rule at order 12 erred by
    7.4e-5 with the band at order 4 and 4.6e-5 at order 6 (its table: 3.5e-5)."""
    if asked is not None:
        return int(asked)
    if cut:
        return int(order)
    if view_cut:
        return min(int(order), max(VIEW_CUT_BAND_LEAST_ORDER, -(-int(order) // 2)))
    return min(int(order), max(HORIZON_CUT_LEAST_ORDER, -(-int(order) // 3)))


def body_mesh_m(body: str, level, path, units: str = "m", radius: float | None = None):
    """The mesh of ``body`` in metres, body frame: a user mesh (``path``, read in ``units``)
    or the packaged icosphere at ``level`` tagged as an analytic sphere of ``radius``.
    Cached by the file's content key (a rewritten file is read again) and the arguments."""
    return _body_mesh_cached(body, level, None if path is None else file_key(path), units, radius)


@memoize(maxsize=8)
def _parsed_moon_map(text: str, key: tuple | None):
    """:meth:`MoonAlbedoMap.parse` of ``text`` (``key``: the file's :func:`file_key`, where the whole
    text names a file): parsed and checked once, not at every one of a trace's many calls."""
    return MoonAlbedoMap.parse(text)


@memoize(maxsize=16)
def _body_mesh_cached(body: str, level, key, units: str, radius: float | None):
    if key is not None:
        from lunarviz.bodies.meshes import NOMINAL_RADII, load_user_mesh
        nominal = NOMINAL_RADII[body] if radius is None else radius
        return load_user_mesh(key[0], body=body, units=units, nominal_radius=nominal)
    if radius is None:
        radius = {"moon": C.R_MOON_M, "earth": C.R_EARTH_M, "sun": C.R_SUN_M}[body]
    mesh = packaged_sphere(body, level, radius)
    if mesh is None:
        from lunarviz.bodies.meshes import analytic_sphere
        mesh = analytic_sphere(body, level, radius)
    return mesh
