"""The resolved scene: every option of a run, checked, with the tasks it is made of.

A :class:`ResolvedScene` is immutable and typed: its fields are every option of
:mod:`lunarviz.options` (composed from the schema, with its defaults) and the run's own (the
phases or times, the method, the reference's orders). It is built once, from a
:class:`lunarviz.Scene` or its JSON, and checked when made (:func:`lunarviz.scene.checks.resolve`).
It gives each layer below its own typed inputs (:mod:`lunarviz.scene.inputs`: geometry, BRDF
models, tracer and analytic settings, the spectral request, the Earth model) and the tolerance's
choices (:mod:`lunarviz.scene.tolerance`); nothing below this layer takes the resolved scene
itself. :meth:`ResolvedScene.to_json` and :meth:`ResolvedScene.from_json` save and restore it
exactly (an output's ``settings``, a Dataset's ``attrs["settings_json"]``, a view's state).
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field, replace

import lunarviz.constants as C
from lunarviz.options import GROUPS, compose, from_settings_dict
from lunarviz.scene import checks, inputs, tolerance


@dataclass(frozen=True)
@compose(*GROUPS)
class ResolvedScene:
    """Everything needed to rerun a sweep, checked (written to every output's ``settings``).

    Its fields are every option of :mod:`lunarviz.options` (the :class:`lunarviz.Scene`
    keywords) and the run's own below. :meth:`from_dict` rereads :meth:`to_dict`, and
    :meth:`from_json` rereads :meth:`to_json`.

    Examples
    --------
    >>> from lunarviz.scene import ResolvedScene
    >>> s = ResolvedScene(phases_deg=(30.0, 90.0), method="raytrace", brdfs=("dhg",))
    >>> ResolvedScene.from_json(s.to_json()) == s
    True
    >>> sorted(s.brdf_models())
    ['dhg']
    """

    #: the orbital angles θ [deg] of the paper's scene (ignored with ``times``)
    phases_deg: tuple = C.PAPER_PHASES_DEG
    #: ``analytic``, ``raytrace`` or ``reference``
    method: str = "analytic"
    params: dict = field(default_factory=dict)  # {brdf: {name: value}}; the schema's None is {}
    #: the paper grid's step [deg] (``grid="paper"``)
    paper_step_deg: float = 1.0
    #: the exact reference's outer and inner Gauss orders (without a tolerance)
    reference_outer: int = 24
    reference_inner: int = 8
    #: UTC times (ISO 8601): when given, one task per time on the real sky, not per phase θ
    times: tuple | None = None
    #: ``facets`` (default) or ``beams``: see :class:`lunarviz.methods.tracer.settings.TraceSettings`
    mapped_earth: str = "facets"

    __post_init__ = checks.resolve

    # ---- the typed inputs of the layers below (lunarviz.scene.inputs) ----------------------
    brdf_models = inputs.brdf_models
    spectral_request = inputs.spectral_request
    spectral_inputs = inputs.spectral_inputs
    earth_model = inputs.earth_model
    surfaces = inputs.surfaces
    mapped_moon = inputs.mapped_moon
    analytic_settings = inputs.analytic_settings
    point_calibration_settings = inputs.point_calibration_settings
    reference_settings = inputs.reference_settings
    trace_settings = inputs.trace_settings
    observer_model = inputs.observer_model
    task = inputs.task
    geometry = inputs.geometry

    # ---- what a tolerance chooses (lunarviz.scene.tolerance) --------------------------------
    rtol_or_default = property(tolerance.rtol_or_default)
    reference_orders = tolerance.reference_orders
    trace_plan = tolerance.trace_plan
    modelled = tolerance.modelled
    unmodelled_reason = tolerance.unmodelled_reason
    analytic_row_bound = tolerance.analytic_row_bound
    earth_pole_at_zero_phase = tolerance.earth_pole_at_zero_phase
    reference_earth_pole = tolerance.reference_earth_pole
    warn_unmet_tolerance = tolerance.warn_unmet_tolerance
    traced_earth_mapped = tolerance.traced_earth_mapped
    mapped_earth_row_bound = tolerance.mapped_earth_row_bound
    expected_mapped_part = tolerance.expected_mapped_part
    expected_mapped_level = tolerance.expected_mapped_level

    @property
    def earth_uniform(self) -> bool:
        """One Lambert albedo over the whole Earth (the paper's)."""
        return self.earth_surface == "uniform" and self.clouds == "none" and self.earth_brdf == "lambert"

    def tasks(self) -> list:
        """One key per independent task: UTC labels with ``times``, else the phases θ [deg]."""
        return list(self.times) if self.times is not None else [float(p) for p in self.phases_deg]

    def replace(self, **changes) -> "ResolvedScene":
        """A copy with ``changes`` (option names), resolved and checked again."""
        return replace(self, **changes)

    # ---- JSON -------------------------------------------------------------------------------
    @classmethod
    def from_dict(cls, d: dict) -> "ResolvedScene":
        """The scene a :meth:`to_dict` (an output's ``settings``, a Dataset's
        ``attrs["settings_json"]``) describes."""
        return from_settings_dict(cls, d)

    def to_dict(self) -> dict:
        """The scene as plain JSON types (tuples as lists; without ``phases_deg`` on dates)."""
        d = asdict(self)
        d["brdfs"] = list(self.brdfs)
        d["phases_deg"] = list(self.phases_deg)
        if self.times is not None:
            d["times"] = list(self.times)
            d.pop("phases_deg")
        return d

    def to_json(self) -> str:
        """:meth:`to_dict` as JSON text (:meth:`from_json` restores the scene exactly)."""
        return json.dumps(self.to_dict(), sort_keys=True)

    @classmethod
    def from_json(cls, text: str) -> "ResolvedScene":
        """The scene a :meth:`to_json` text describes."""
        return cls.from_dict(json.loads(text))
