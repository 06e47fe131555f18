"""The option schema: every scene and method option of lunarviz, declared once.

Each :class:`Option` gives an option's Python name (the :class:`lunarviz.Scene` keyword and the
settings field), its type, default, unit, one-line doc, allowed values or range, command-line
flag and group. Everything else is derived from :data:`OPTIONS`:

* the command line's flags (:func:`add_arguments`) and the keywords they give a Scene
  (:func:`scene_options`);
* :class:`lunarviz.Scene`'s keywords, their defaults (:func:`defaults`) and its docstring
  (:func:`numpydoc_parameters`);
* the method settings, whose fields are the options of their groups (:func:`compose`), their
  validation (:func:`validate`) and their JSON round trip (:func:`from_settings_dict`).

Adding an option is one :class:`Option` here plus the code that uses it.

Groups: ``photometry`` (the lunar BRDFs), ``earth`` (the Earth's reflectance), ``geometry``
(where the detector is), ``sky`` (dates and observers), ``meshes`` (bodies and their shapes),
``surfaces`` (albedo maps), ``trace`` (the ray tracer's estimator and source rules) and
``analytic`` (the paper's quadrature).
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass, field, fields
from typing import Any, Callable

import lunarviz.constants as C
from lunarviz.errors import FLAG_KEYWORDS, LunarvizError, any_case, close_match, short_repr, unknown_choice

# ---- allowed values (each declared once, here; the modules that implement them import them) ----
#: how a sweep computes: the paper's point-source quadrature, Embree ray tracing of the meshes, or the
#: exact extended-source reference
METHODS = ("analytic", "raytrace", "reference")
#: lunar BRDFs: Lambert, Hapke with a single or double Henyey-Greenstein phase function
BRDF_NAMES = ("lambert", "shg", "dhg")
#: Hapke's H-function: the 1981 approximation (the paper's), the 2002 one, or the exact integral
H_FUNCTIONS = ("hapke1981", "hapke2002", "exact")
#: sign convention of the double Henyey-Greenstein function: as the paper prints it, or Hapke 2012
DHG_CONVENTIONS = ("paper", "hapke2012")
#: the Earth's intensity law in the analytic method: a Lambert sphere, or the paper's printed Eq. 8
EARTH_LAWS = ("lambert", "paper_eq8")
#: the analytic method's lunar surface grid: converged Gauss, or the paper's 1° grid
GRIDS = ("converged", "paper")
#: the ray tracer's estimators
ESTIMATORS = ("deterministic", "montecarlo")
#: ``auto``: the exact sphere for analytic spheres (the packaged icospheres, a documented fast
#: path), the facets for every other mesh; ``smooth``: crease-limited interpolated normals on
#: user meshes; ``flat``: the facets everywhere
SHADINGS = ("auto", "smooth", "flat")
#: units of a user mesh's vertices (``radius``: multiples of the body's nominal radius)
MESH_UNITS = ("m", "km", "radius")
#: the bodies of the scene
BODIES = ("sun", "earth", "moon")
#: where sweeps and studies run their tasks: local worker processes or a Dask cluster
EXECUTORS = ("local", "dask")
#: packaged solar spectra (``lunarviz/data/spectra``) and the paper's flat grey Sun; or a CSV file
SOLAR_SPECTRA = ("tsis1-hsrs", "grey")
#: the Earth's surface classes in a spectral run: their packaged spectra, or their grey albedos
EARTH_SPECTRA = ("surface", "grey")
#: the lunar BRDF preset of the θ scene (the paper's Table 2) and of dated runs (fitted to the Moon's
#: observed phase law, with its albedo map; the exact reference, which integrates uniform bodies,
#: and ``h_function="exact"``, which takes one w, take the same fit without the map), where
#: ``moon_model`` is not given
THETA_MOON_MODEL = "paper"
DATED_MOON_MODEL = "rolo-fit-map"
DATED_UNIFORM_MOON_MODEL = "rolo-fit"


def default_moon_model(dated: bool, method: str = "raytrace", h_function: str = "hapke1981",
                       brdfs: tuple = ("dhg",)) -> str:
    """The lunar preset of a run that names none: the paper's in the θ scene; on dates the fitted
    one with its map, or without it where the run takes one w (the exact reference; the exact
    H-function with a Hapke BRDF)."""
    if not dated:
        return THETA_MOON_MODEL
    uniform = method == "reference" or (h_function == "exact" and any(b != "lambert" for b in brdfs))
    return DATED_UNIFORM_MOON_MODEL if uniform else DATED_MOON_MODEL
#: how the Earth reflects: Lambert facets, or the physical classes of :mod:`lunarviz.earth_optics`
EARTH_BRDFS = ("lambert", "physical")
#: Default Lambert albedos of the ``landocean`` Earth (broadband, visible):
#: ocean 0.06, the diffuse sea-surface albedo (Payne 1972, J. Atmos. Sci. 29, 959);
#: land 0.25, a mid value of land surfaces (0.1 forest to 0.4 desert; Hartmann 2016, Global
#: Physical Climatology, 2nd ed., Table 4.2); cloud 0.4, chosen so that with ``zonal`` clouds
#: the global mean is 0.30 (the paper's Earth; CERES Bond albedo 0.29, Stephens et al. 2015,
#: Rev. Geophys. 53, 141). They are parameters (``--land-albedo`` ...), not measurements.
LAND_ALBEDO, OCEAN_ALBEDO, CLOUD_ALBEDO = 0.25, 0.06, 0.40
#: the finest packaged-icosphere level a scene may ask for (20·4^8 = 1.3 M facets)
MAX_LEVEL = 8
#: icosphere levels of the packaged meshes when none is asked for (from the mesh study)
DEFAULT_LEVELS = {"sun": 5, "earth": 6, "moon": 4}
#: Gauss orders of the Sun's and the Earth's beams when neither an order nor a tolerance is given
#: (with the Moon's level 4: 8.7e-5 on the paper's scene)
DEFAULT_ORDERS = {"sun": 2, "earth": 6}
#: group names, in the order the documentation lists them, and their titles in ``--help``
GROUP_TITLES = {
    "photometry": "photometry (the lunar BRDFs)",
    "earth": "the Earth",
    "geometry": "geometry",
    "sky": "the real sky (with --time or --time-range)",
    "meshes": "bodies as meshes",
    "surfaces": "surfaces (equirectangular maps in the body frame: .npy, .png, .tif)",
    "accuracy": "accuracy (every method)",
    "trace": "the ray tracer (--method raytrace)",
    "analytic": "the analytic method",
    "spectral": "light in colour (without --wavelengths or --band a run is grey)",
    "polarisation": "polarised light (spectral runs)",
}
GROUPS = tuple(GROUP_TITLES)


@dataclass(frozen=True)
class Option:
    """One option: its name, type, default, unit, doc, allowed values, flag and group.

    ``kind`` is one of ``int``, ``float``, ``str``, ``bool``, ``path``, ``names`` (a tuple of
    names), ``xyz`` (three floats), ``params`` (``{brdf: {name: value}}``). ``None`` is allowed
    where the default is ``None``. A ``bool`` option whose default is ``True`` takes the flag
    ``--no-…`` on the command line.
    """

    name: str
    kind: str
    default: Any
    doc: str
    group: str
    unit: str | None = None
    choices: tuple | None = None
    lo: float | None = None
    hi: float | None = None
    flag: str | None = None
    metavar: str | None = None
    label: str | None = None
    #: help of a ``--no-…`` flag (what switching the option off means), where the doc says what it is on
    flag_help: str | None = None
    #: a list option given as text: a tuple or list of items is also taken (``("V", "B")``: ``"V,B"``)
    joins: bool = False
    #: the named values of an option that also takes a FILE: matched in any case (``LANDOCEAN``),
    #: and a name that is neither one of them nor a file gets their close match
    keywords: tuple | None = None

    @property
    def cli_flag(self) -> str:
        """The command-line flag (``--no-occlusion`` for ``occlusion``)."""
        if self.flag:
            return self.flag
        stem = self.name.replace("_", "-")
        return f"--no-{stem}" if self.kind == "bool" and self.default is True else f"--{stem}"

    @property
    def dest(self) -> str:
        """The attribute argparse stores the flag under."""
        return self.cli_flag[2:].replace("-", "_")

    @property
    def what(self) -> str:
        """How error messages name the option."""
        return self.label or self.name.replace("_", " ")

    def check(self, value) -> Any:
        """``value`` if it is valid for this option (tuples normalised), else a one-line
        :class:`~lunarviz.errors.LunarvizError` that names it."""
        if value is None and self.default is None:
            return None
        k = self.kind
        if k == "bool":
            if not isinstance(value, bool) and type(value).__name__ != "bool_":
                raise LunarvizError(f"{self.name}={value!r} must be True or False")
            return bool(value)
        if k == "int":
            if isinstance(value, bool) or not isinstance(value, int) and type(value).__module__ != "numpy" \
                    or not _finite(value) or not float(value).is_integer() or not self._in_range(value):
                raise LunarvizError(f"{self.name}={short_repr(value)} must be {self._integer_phrase()}")
            return value
        if k == "float":
            if isinstance(value, bool) or not isinstance(value, (int, float)) and type(value).__module__ != "numpy" \
                    or not _finite(value) or not self._in_range(value):
                raise LunarvizError(f"{self.what} {short_repr(value)} must be a finite number{self._range_text()}")
            return value
        if k in ("str", "path"):
            if self.joins and isinstance(value, (list, tuple)) and value \
                    and all(isinstance(x, (str, int, float)) and not isinstance(x, bool) for x in value):
                value = ",".join(str(x) for x in value)
            if not isinstance(value, str):
                raise LunarvizError(f"{self.what} {value!r} must be a string")
            if self.choices is not None and value not in self.choices:
                value = _choice_any_case(value, self.choices, self.what)
            if self.keywords is not None and value not in self.keywords:
                value = _keyword_or_file(value, self.keywords, self.what)
            return value
        if k == "names":
            if isinstance(value, str):
                value = tuple(x.strip() for x in value.split(","))
            if not isinstance(value, (list, tuple)) or not value or not all(isinstance(x, str) for x in value):
                raise LunarvizError(f"{self.name} {value!r} must be names such as ('lambert', 'dhg')")
            if self.choices is not None:
                value = [x if x in self.choices else _choice_any_case(x, self.choices, "BRDF") for x in value]
            return tuple(value)
        if k == "xyz":
            try:
                v = tuple(float(c) for c in value)
            except (TypeError, ValueError, OverflowError):
                raise LunarvizError(f"{self.name} {value!r} must be three numbers x, y, z [{self.unit}]") from None
            if len(v) != 3 or not all(math.isfinite(c) for c in v):
                raise LunarvizError(f"{self.name} {value!r} must be three finite numbers x, y, z [{self.unit}]")
            return v
        if k == "params":
            if not isinstance(value, dict) or not all(isinstance(v, dict) for v in value.values()):
                raise LunarvizError(f"params {value!r} must be {{brdf: {{name: value}}}}")
            return value
        raise AssertionError(f"option {self.name}: unknown kind {k!r}")  # a schema bug, not user input

    def _in_range(self, v) -> bool:
        return (self.lo is None or v >= self.lo) and (self.hi is None or v <= self.hi)

    def range_phrase(self, value=None) -> str:
        """What a value must be: ``positive``, ``non-negative``, ``at most HI``, ``in [lo, hi]``
        (for ``value``, the bound it breaks)."""
        below = value is not None and self.lo is not None and value < self.lo
        above = value is not None and self.hi is not None and value > self.hi
        if (below or self.hi is None) and self.lo == 1:
            return "positive"
        if (below or self.hi is None) and self.lo == 0:
            return "non-negative"
        if above and self.lo in (0, 1):
            return f"at most {self.hi:g}"
        return self._range_text().strip()

    def _integer_phrase(self) -> str:
        if self.lo in (0, 1):
            word = "positive" if self.lo == 1 else "non-negative"
            return f"a {word} integer" + (f" of at most {self.hi:g}" if self.hi is not None else "")
        return f"an integer{self._range_text()}"

    def _range_text(self) -> str:
        if self.lo is not None and self.hi is not None:
            return f" in [{self.lo:g}, {self.hi:g}]"
        if self.lo is not None:
            return " ≥ 1" if self.lo == 1 else f" ≥ {self.lo:g}"
        return ""


def _finite(value) -> bool:
    """``float(value)`` is finite (an integer of 400 digits overflows: not finite)."""
    try:
        return math.isfinite(float(value))
    except (OverflowError, TypeError, ValueError):
        return False


def _keyword_or_file(value: str, keywords, what: str) -> str:
    """``value`` as a keyword in any case (``LANDOCEAN``), or as it is where it may be a file; a
    name that is neither (no such file, no ``.``/``/`` in it) gets the keyword it most likely meant."""
    import os
    same = any_case(value.strip(), keywords)
    if same is not None:
        return same
    base = value.split(":")[0]
    if not os.path.exists(base) and not any(c in base for c in "./\\") and close_match(base, keywords):
        raise unknown_choice(what, value, keywords)
    return value


def _choice_any_case(value: str, choices, what: str) -> str:
    """The choice ``value`` names in another case (``DHG``: ``dhg``), else the one-line error."""
    same = any_case(value, choices)
    if same is None:
        raise unknown_choice(what, value, choices)
    return same


def _o(name, kind, default, doc, group, **kw) -> Option:
    return Option(name, kind, default, doc, group, **kw)


#: The physical Earth's parameters (``--earth-brdf physical``): given as ``--param earth.NAME=VALUE``
#: on the command line and ``params={"earth": {NAME: VALUE}}`` in Python, not as keywords of their own.
#: Cox & Munk fitted their glint to 1-14 m s⁻¹; the DISORT tables' optical depths end at 2 above
#: 100 hPa.
EARTH_PARAMETERS: tuple[Option, ...] = (
    _o("wind_speed", "float", 7.0, "the sea surface's wind speed (Cox-Munk glint)", "earth", unit="m s-1",
       lo=0.0, hi=30.0),
    _o("chlorophyll", "float", 0.1, "the open ocean's chlorophyll concentration (case-1 water: its colour, black in "
       "the near infrared)", "earth", unit="mg m-3", lo=0.02, hi=20.0),
    _o("ground_albedo", "float", C.EARTH_ALBEDO, "the uniform Earth's ground under the air (Lambert; "
       "--earth-surface uniform)", "earth", unit="1", lo=0.0, hi=1.0),
    _o("cloud_optical_depth", "float", 10.0, "the clouds' optical depth at 550 nm (liquid droplets, Mie phase "
       "function; tabulated 0.5-150)", "earth", unit="1", lo=0.5, hi=150.0),
    _o("cloud_top_hpa", "float", 700.0, "the cloud tops' pressure (the Rayleigh optical depth above them)",
       "earth", unit="hPa", lo=100.0, hi=1100.0),
    _o("ozone_du", "float", 300.0, "the ozone column above the air (Huggins and Chappuis bands; 0: none). Default: "
       "the global mean, ~300 DU (Fioletov et al. 2002)", "earth", unit="DU", lo=0.0, hi=700.0),
    _o("surface_hpa", "float", C.SEA_LEVEL_HPA, "the surface's pressure (the Rayleigh optical depth above it)",
       "earth", unit="hPa", lo=100.0, hi=1100.0),
    _o("wavelength_nm", "float", 550.0, "the wavelength at which a grey (not spectral) run evaluates the Earth",
       "earth", unit="nm", lo=300.0, hi=2500.0),
)
#: the physical Earth's parameters by name, with their defaults
EARTH_PARAMETER_DEFAULTS = {o.name: o.default for o in EARTH_PARAMETERS}


def earth_params(params: dict | None) -> dict:
    """The physical Earth's parameters: the defaults of :data:`EARTH_PARAMETERS` updated by
    ``params``, each checked (a one-line error names a bad one)."""
    if params is not None and not isinstance(params, dict):
        raise LunarvizError(f"earth parameters {params!r} must be a mapping {{name: value}}")
    out = dict(EARTH_PARAMETER_DEFAULTS)
    by_name = {o.name: o for o in EARTH_PARAMETERS}
    for k, v in (params or {}).items():
        if k not in by_name:
            raise unknown_choice("earth parameter", k, by_name)
        try:
            x = float("nan") if isinstance(v, bool) else float(v)
        except (TypeError, ValueError):
            x = float("nan")
        o = by_name[k]
        if not o.lo <= x <= o.hi:
            raise LunarvizError(f"earth.{k}={params[k]!r}: must be in {o.lo:g}…{o.hi:g}")
        out[k] = x
    return out


#: Every scene and method option (the :class:`lunarviz.Scene` keywords), in documentation order.
OPTIONS: tuple[Option, ...] = (
    # photometry: the lunar BRDFs
    _o("brdfs", "names", BRDF_NAMES, "lunar BRDFs: lambert, shg (Hapke, single HG), dhg (Hapke, double HG)",
       "photometry", choices=BRDF_NAMES, flag="--brdf", metavar="NAME[,NAME...]"),
    _o("dhg_convention", "str", "paper", "sign convention of the double Henyey-Greenstein function",
       "photometry", choices=DHG_CONVENTIONS, label="DHG convention"),
    _o("h_function", "str", "hapke1981", "Hapke's H-function (the paper uses Hapke 1981)", "photometry",
       choices=H_FUNCTIONS, label="H-function"),
    _o("moon_model", "str", None, "BRDF parameter preset: paper (Table 2), rolo-fit (fitted to ROLO, "
       "400-750 nm) or rolo-fit-map (fitted on the synthetic lunar albedo map, which it brings); in spectral runs "
       f"the rolo-fit presets take their band-by-band fits (350-2383.6 nm). Default: {THETA_MOON_MODEL} in the θ "
       f"scene (it reproduces the paper), {DATED_MOON_MODEL} on dates ({DATED_UNIFORM_MOON_MODEL} for --method "
       "reference and --h-function exact; on dates the paper's Moon is 0.6 mag too faint near full Moon and 3-6x "
       "too bright at crescents against the Moon's observed phase law)",
       "photometry", label="moon model", metavar="paper|rolo-fit|rolo-fit-map"),
    _o("params", "params", None, "BRDF parameter overrides {brdf: {name: value}}: w, h, B0, xi, b, c, albedo; "
       "Hapke: theta_bar [deg], Bc0, hc (command line: --param [BRDF.]NAME=VALUE, repeated)", "photometry",
       flag="--param", metavar="[BRDF.]NAME=VALUE"),
    # the Earth
    _o("earth_albedo", "float", C.EARTH_ALBEDO, "the uniform Earth's Lambert albedo, and the model Earth of every "
       "inversion", "earth", unit="1", lo=0.0, hi=1.0, label="Earth albedo"),
    _o("earth_law", "str", "lambert", "the analytic method's Earth intensity law: a Lambert sphere, or the "
       "paper's printed Eq. 8 (which drops a factor 2/3)", "analytic", choices=EARTH_LAWS, label="Earth law"),
    # geometry and sky
    _o("detector", "xyz", None, "detector position x,y,z in the θ scene (default: the Earth's centre)",
       "geometry", unit="m", metavar="X,Y,Z"),
    _o("observer", "str", "geocentre", "with a date: geocentre | site:LAT,LON[,HEIGHT_M] (WGS84) | tle:FILE | "
       "orbit:ALT_KM,INC_DEG,RAAN_DEG,ARGLAT_DEG[,EPOCH]", "sky"),
    # meshes
    _o("moon_mesh", "path", None, "a closed mesh for the Moon (PLY, OBJ, STL, OFF, GLB/GLTF): body-fixed frame, "
       "centred on its centre, in the mesh units; never rescaled", "meshes", metavar="FILE"),
    _o("earth_mesh", "path", None, "a closed mesh for the Earth (as for the Moon)", "meshes", metavar="FILE"),
    _o("sun_mesh", "path", None, "a closed mesh for the Sun (as for the Moon)", "meshes", metavar="FILE"),
    _o("mesh_units", "str", "m", "units of the mesh files' vertices (radius: multiples of the body's nominal "
       "radius)", "meshes", choices=MESH_UNITS, label="mesh units"),
    _o("moon_level", "int", None, f"the Moon's icosphere level (default {DEFAULT_LEVELS['moon']}, or from --rtol in "
       "sweeps)", "meshes",
       lo=0, hi=MAX_LEVEL, flag="--mesh-level"),
    _o("earth_level", "int", None, f"the Earth's icosphere level (default {DEFAULT_LEVELS['earth']})", "meshes",
       lo=0, hi=MAX_LEVEL),
    _o("sun_level", "int", None, f"the Sun's icosphere level (default {DEFAULT_LEVELS['sun']})", "meshes",
       lo=0, hi=MAX_LEVEL),
    _o("occlusion", "bool", True, "bodies shade and hide each other", "meshes",
       flag_help="the paper's assumption: bodies never shade each other"),
    _o("self_shadow", "bool", True, "a non-convex body shadows itself (independent of occlusion)", "meshes",
       flag_help="a non-convex body does not shadow itself (independent of --no-occlusion)"),
    _o("shading", "str", "auto", "auto: exact sphere for the packaged icospheres, facet normals for user meshes; "
       "smooth: crease-limited interpolated normals on user meshes; flat: facets everywhere", "meshes",
       choices=SHADINGS),
    # accuracy
    _o("rtol", "float", None, "relative tolerance of the moonshine and earthshine: the mesh level or lune order, "
       "beam orders, analytic order or Monte Carlo rays are chosen to meet it at least cost, from measured error "
       "models (default: 1e-4 ray traced, 1e-6 analytic and reference; Monte Carlo: the paper's 50,000 rays); "
       "settings given explicitly are kept; rows report the bound they meet (column rtol)", "accuracy", unit="1",
       lo=1e-8, hi=0.5, label="relative tolerance"),
    # the ray tracer
    _o("estimator", "str", "deterministic", "the ray tracer's estimator: deterministic beams or Monte Carlo",
       "trace", choices=ESTIMATORS),
    _o("rays", "int", None, "Monte Carlo rays per path and run (default: the paper's 50,000, or what --rtol needs; "
       "at most 1e9: memory is bounded by chunks of 16,384 samples, run time is not)", "trace", lo=1, hi=10**9),
    _o("runs", "int", 1, "Monte Carlo runs per phase (their spread gives the standard deviations)", "trace", lo=1),
    _o("seed", "int", 0, "Monte Carlo seed (runs and chunks draw from (seed, run, path, chunk))", "trace", lo=0),
    _o("earth_order", "int", None, f"Gauss order of the Earth's beams seen from each lunar sample (default "
       f"{DEFAULT_ORDERS['earth']}, or from --rtol in sweeps)", "trace", lo=1, hi=64),
    _o("sun_order", "int", None, f"Gauss order of the Sun's beams seen from each lunar sample (default "
       f"{DEFAULT_ORDERS['sun']}, or from --rtol in sweeps)", "trace", lo=1, hi=64),
    # the analytic method
    _o("grid", "str", "converged", "the analytic method's lunar surface grid: converged Gauss or the paper's",
       "analytic", choices=GRIDS),
    _o("order", "int", None, "the analytic method's Gauss order (default: from --rtol; 96 with a lunar albedo map, "
       "which it reads at its nodes)", "analytic", lo=2, hi=512),
    # surfaces
    _o("moon_albedo_map", "path", None, "per-facet lunar albedo: FILE scales each BRDF's albedo/w by map/mean; "
       "FILE:MEAN makes the map the albedo/w itself with area-weighted mean MEAN; 'synthetic' is the shipped "
       "demo map; 'none' drops a preset's map", "surfaces", metavar="FILE[:MEAN]"),
    _o("earth_surface", "str", "uniform", "uniform (the Earth albedo), landocean (a land mask with the land and "
       "ocean albedos) or a clear-sky albedo map FILE", "earth", metavar="uniform|landocean|FILE",
       keywords=("uniform", "landocean"), label="Earth surface"),
    _o("clouds", "str", "none", "cloud fraction: none, zonal (zonal means shipped with the package) or a map "
       "FILE; clouds reflect with the cloud albedo", "earth", metavar="none|zonal|FILE",
       keywords=("none", "zonal")),
    _o("earth_brdf", "str", "lambert", "how the Earth reflects: lambert (each place a Lambert surface of its albedo) "
       "or physical (Rayleigh atmosphere over Cox-Munk ocean, Ross-Li land and snow, DISORT clouds; its parameters: "
       + ", ".join(f"--param earth.{o.name}=" for o in EARTH_PARAMETERS) + ")",
       "earth", choices=EARTH_BRDFS, label="Earth BRDF"),
    _o("land_albedo", "float", LAND_ALBEDO, "Lambert albedo of clear land (Earth surface landocean)", "earth",
       unit="1", lo=0.0, hi=1.0, label="land albedo"),
    _o("ocean_albedo", "float", OCEAN_ALBEDO, "Lambert albedo of clear ocean (Earth surface landocean)",
       "earth", unit="1", lo=0.0, hi=1.0, label="ocean albedo"),
    _o("cloud_albedo", "float", CLOUD_ALBEDO, "Lambert albedo of clouds (with clouds)", "earth", unit="1",
       lo=0.0, hi=1.0, label="cloud albedo"),
    # light in colour
    _o("wavelengths", "str", None, "a row per wavelength: LIST or START:STOP:STEP (sweep rows: wavelength_nm, "
       "moonshine_W_m2_nm, earthshine_W_m2_nm, solar_irradiance_W_m2_nm; brdf --body earth: the reflectance there)",
       "spectral", unit="nm",
       metavar="LIST|START:STOP:STEP", joins=True),
    _o("bands", "str", None, "band-integrated rows (∫E S dλ): Johnson-Cousins U,B,V,R,I (Bessell 1990), packaged "
       "instrument bands (S2A-B1..B12, MODIS-TERRA-B1..B9), any speclite filter, LO-HI [nm] or a CSV FILE "
       "(wavelength_nm,response)", "spectral", flag="--band", metavar="NAME|LO-HI|FILE.csv[,...]", joins=True),
    _o("solar_spectrum", "str", "tsis1-hsrs", "the Sun's spectral irradiance at 1 au in spectral runs: tsis1-hsrs "
       "(TSIS-1 HSRS v2, Coddington et al. 2023), grey (the paper's Φ flat over 400-750 nm) or a CSV FILE "
       "(wavelength_nm,irradiance_W_m2_nm)", "spectral", metavar="tsis1-hsrs|grey|FILE.csv",
       keywords=("tsis1-hsrs", "grey")),
    _o("earth_spectra", "str", "surface", "spectral runs: the Earth's ocean, vegetation, desert and snow take their "
       "packaged USGS spectra (surface) or the grey ocean/land albedos (grey); clouds and the uniform Earth stay grey",
       "spectral", choices=EARTH_SPECTRA, label="Earth spectra"),
    _o("stokes", "bool", False, "spectral runs: the moonshine's Stokes Q and U in the scattering plane's frame, its "
       "degree and angle of linear polarisation (across or along that plane), the degree from the Moon's disc "
       "polarisation of ESA's LIME (phase angles 2-90 "
       "deg, 350-1640 nm; NaN elsewhere); dated rows add the scattering plane's position angle on the sky. The "
       "earthshine's polarisation is not modelled", "polarisation"),
    _o("earth_rotation_deg", "float", None, "θ scene only: the Earth's sub-solar longitude (default 0); dates "
       "turn the Earth themselves", "surfaces", unit="deg", label="Earth rotation"),
)

BY_NAME: dict[str, Option] = {o.name: o for o in OPTIONS}
FLAG_KEYWORDS.update({o.cli_flag: o.name for o in OPTIONS})  # (errors name keywords in the API)


def group(*names: str) -> tuple[Option, ...]:
    """The options of the named groups, in schema order."""
    unknown = set(names) - set(GROUPS)
    if unknown:
        raise AssertionError(f"unknown option group {sorted(unknown)[0]!r}")  # a programming error
    return tuple(o for o in OPTIONS if o.group in names)


def defaults(*groups: str) -> dict:
    """``{name: default}`` of every option (or of the named groups)."""
    return {o.name: o.default for o in (group(*groups) if groups else OPTIONS)}


def validate(obj, options=OPTIONS) -> None:
    """Check the attributes of ``obj`` named by ``options`` (those it has); normalised values
    (tuples for names and positions) are written back onto frozen dataclasses."""
    for o in options:
        if hasattr(obj, o.name):
            v = getattr(obj, o.name)
            checked = o.check(v)
            if checked is not v:
                object.__setattr__(obj, o.name, checked)


def compose(*groups: str, names: tuple[str, ...] = ()):
    """Class decorator (apply before ``@dataclass``): the fields of the named option groups (and
    the options ``names``), with the schema's types and defaults, ahead of the class's own fields."""

    group(*groups)  # (unknown group names are a programming error)
    unknown = set(names) - set(BY_NAME)
    if unknown:
        raise AssertionError(f"unknown option {sorted(unknown)[0]!r}")

    def deco(cls):
        own = dict(cls.__dict__.get("__annotations__", {}))
        ann = {}
        for o in OPTIONS:
            if o.group not in groups and o.name not in names:
                continue
            if o.name in own:
                continue  # the class declares its own (e.g. a resolved default)
            ann[o.name] = "Any"
            if o.kind == "params":
                setattr(cls, o.name, field(default_factory=dict))
            else:
                setattr(cls, o.name, o.default)
        ann.update(own)
        cls.__annotations__ = ann
        return cls

    return deco


#: what the model Earth of every inversion keeps of the real one: its Lambert albedo
MODEL_EARTH_KEEPS = ("earth_albedo",)


def model_earth(obj) -> dict:
    """The changes (for :func:`dataclasses.replace`) that make ``obj``'s Earth the model Earth of
    every inversion, the uniform Lambert sphere of its ``earth_albedo``: every other option of the
    ``earth`` group at its default, and no Earth parameters (``params["earth"]``, ``earth_params``).
    An option added to the group is reset with the others."""
    changes = {o.name: o.default for o in group("earth") if o.name not in MODEL_EARTH_KEEPS}
    if hasattr(obj, "params"):
        changes["params"] = {k: v for k, v in (obj.params or {}).items() if k != "earth"}
    if hasattr(obj, "earth_params"):
        changes["earth_params"] = ()
    return changes


def from_settings_dict(cls, d: dict, **extra):
    """Rebuild a settings dataclass from its JSON form (lists back to tuples)."""
    names = {f.name for f in fields(cls)}
    kw = {}
    for k, v in {**d, **extra}.items():
        if k not in names:
            continue
        kw[k] = tuple(v) if isinstance(v, list) else v
    return cls(**kw)


# ---- the command line ---------------------------------------------------------------------------
def _cli_type(o: Option) -> Callable | None:
    if o.kind == "int":
        def conv(text):
            try:
                v = int(text)
            except ValueError:
                raise argparse.ArgumentTypeError(f"{o.cli_flag} {text!r} is not an integer") from None
            if not o._in_range(v):
                raise argparse.ArgumentTypeError(f"{o.cli_flag} {v} must be {o.range_phrase(v)}")
            return v
        return conv
    if o.kind == "float":
        def convf(text):
            try:
                return float(text)
            except ValueError:
                raise argparse.ArgumentTypeError(f"{o.cli_flag} {text!r} is not a number") from None
        return convf
    return None


def add_arguments(parser, groups: tuple[str, ...] = (), names: tuple[str, ...] = (),
                  exclude: tuple[str, ...] = (), defaults: dict | None = None) -> None:
    """Add the flags of the options in ``groups`` (and those in ``names``, less ``exclude``)
    to an argparse ``parser``; ``defaults`` overrides a default for this command (e.g.
    ``{"brdfs": "dhg"}``)."""
    defaults = defaults or {}
    sections: dict = {}
    for o in OPTIONS:
        if (o.group not in groups and o.name not in names) or o.name in exclude:
            continue
        help_text = o.doc + (f" [{o.unit}]" if o.unit and o.unit != "1" else "")
        if o.group not in sections:
            sections[o.group] = parser.add_argument_group(GROUP_TITLES[o.group])
        where = sections[o.group]
        if o.kind == "bool":
            where.add_argument(o.cli_flag, dest=o.dest, action="store_true", help=o.flag_help or help_text)
            continue
        default = defaults.get(o.name, o.default)
        if o.kind in ("names",) and isinstance(default, tuple):
            default = ",".join(default)
        kw: dict[str, Any] = {"dest": o.dest, "default": default, "help": help_text}
        if o.kind == "params":
            kw.update(action="append", default=None)
        if o.choices is not None and o.kind == "str":
            kw["choices"] = list(o.choices)
        elif o.metavar:
            kw["metavar"] = o.metavar
        t = _cli_type(o)
        if t is not None:
            kw["type"] = t
        where.add_argument(o.cli_flag, **kw)


def scene_options(args, parse_value: dict[str, Callable] | None = None) -> dict:
    """The Scene keywords that the parsed command line ``args`` give (flags it has).

    ``parse_value`` maps an option's name to a function of ``(text, args)`` for options whose
    command-line text needs parsing (``params``, ``detector``)."""
    parse_value = parse_value or {}
    out = {}
    for o in OPTIONS:
        if not hasattr(args, o.dest):
            continue
        v = getattr(args, o.dest)
        if o.kind == "bool" and o.default is True:
            v = not v
        if o.name in parse_value:
            v = parse_value[o.name](v, args)
        out[o.name] = v
    return out


def numpydoc_parameters(options=OPTIONS, indent: str = "    ") -> str:
    """The numpydoc ``Parameters`` entries of ``options`` (for :class:`lunarviz.Scene`)."""
    kinds = {"names": "sequence of str", "xyz": "tuple of 3 float", "params": "dict", "path": "str"}
    lines = []
    for o in options:
        t = kinds.get(o.kind, o.kind) + (", optional" if o.default is None else "")
        unit = f" [{o.unit}]" if o.unit else ""
        choices = f" One of {', '.join(map(repr, o.choices))}." if o.choices and o.kind == "str" else ""
        lines.append(f"{indent}{o.name} : {t}")
        doc = o.doc[0].upper() + o.doc[1:] if o.doc[0].isascii() else o.doc
        lines.append(f"{indent}    {doc}{unit}.{choices} Default ``{o.default!r}``; "
                     f"command line ``{o.cli_flag}``.")
    return "\n".join(lines)
