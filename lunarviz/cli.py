"""The ``lunarviz`` command: a thin layer over :mod:`lunarviz.api` (its reference is the docs' CLI page).

Every error in the user's input ends with one line ``lunarviz: error: …`` naming the bad value
and exit status 2, never a traceback, and no output file is left behind (results are written
atomically, after all work succeeded).
"""

from __future__ import annotations

import argparse
import math
import re
import sys
from pathlib import Path

from lunarviz.errors import LunarvizError, any_case, close_match, command_line_words, did_you_mean, unknown_choice
from lunarviz.options import BODIES, EXECUTORS, MAX_LEVEL, OPTIONS, add_arguments, scene_options
from lunarviz.parsing import parse_float_list

EXIT_USAGE = 2


class UsageError(LunarvizError):
    """Bad input from the user on the command line: printed as one line, naming flags."""

    def __str__(self) -> str:
        return ValueError.__str__(self)


class _HelpFormatter(argparse.RawDescriptionHelpFormatter):
    """Help that shows each option's default (where it has one) and keeps the examples' lines."""

    def _get_help_string(self, action):
        text = action.help or ""
        if action.option_strings and action.default is not None and action.default is not argparse.SUPPRESS \
                and action.default is not False and "%(default)" not in text and "default" not in text:
            text += " (default: %(default)s)"
        return text


class _Parser(argparse.ArgumentParser):
    def __init__(self, *args, **kwargs):
        kwargs.setdefault("formatter_class", _HelpFormatter)
        super().__init__(*args, **kwargs)

    def error(self, message):  # one line, no usage dump; a misspelt choice gets its close match
        m = re.search(r"invalid choice: '([^']*)' \(choose from (.*)\)", message)
        if m:
            message = message.replace(m.group(0), m.group(0)[:-1] + did_you_mean(m.group(1), re.findall(
                r"'([^']*)'", m.group(2))).replace(" (", "; "))
        raise UsageError(message)

    def _get_value(self, action, arg_string):
        """argparse's, with a choice in any case taken as the choice (``--shading SMOOTH``)."""
        value = super()._get_value(action, arg_string)
        if action.choices is not None and isinstance(value, str):
            return any_case(value, action.choices) or value
        return value

    def parse_args(self, args=None, namespace=None):
        """argparse's, with the options a misspelt one most likely meant (``--methd``: ``--method``)."""
        ns, extras = self.parse_known_args(args, namespace)
        if extras:
            self.error(f"unrecognized arguments: {' '.join(extras)}{self._suggestions(ns, extras)}")
        return ns

    def _suggestions(self, ns, extras) -> str:
        flags = list(self._option_string_actions)
        for action in self._actions:
            if isinstance(action, argparse._SubParsersAction) and getattr(ns, action.dest, None) in action.choices:
                flags += list(action.choices[getattr(ns, action.dest)]._option_string_actions)
        hits = {x.split("=")[0]: close_match(x.split("=")[0], flags) for x in extras if x.startswith("-")}
        hits = {k: v for k, v in hits.items() if v}
        if len(hits) == 1:
            return f" (did you mean {next(iter(hits.values()))}?)"
        return f" (did you mean {'; '.join(f'{v} for {k}' for k, v in hits.items())}?)" if hits else ""


# ---- parsing helpers ---------------------------------------------------------------------
def parse_params(items, brdfs) -> dict:
    """``--param NAME=VALUE`` or ``BRDF.NAME=VALUE`` → ``{brdf: {name: value}}``."""
    from lunarviz.options import EARTH_PARAMETER_DEFAULTS as EARTH_DEFAULTS
    from lunarviz.photometry.brdf import BRDF_PARAMETERS
    known = {**BRDF_PARAMETERS, "earth": tuple(EARTH_DEFAULTS)}
    out: dict = {b: {} for b in brdfs}
    for item in items or []:
        if "=" not in item:
            raise UsageError(f"malformed --param {item!r}: use NAME=VALUE or BRDF.NAME=VALUE")
        key, val = item.split("=", 1)
        try:
            value = float(val)
        except ValueError:
            raise UsageError(f"--param {item!r}: value {val!r} is not a number") from None
        targets = brdfs
        if "." in key:
            b, key = key.split(".", 1)
            if b == "earth":
                out.setdefault("earth", {})
            elif b not in brdfs:
                raise UsageError(f"--param {item!r}: BRDF {b!r} is not in this run")
            targets = [b]
        took = False
        for b in targets:
            if key in known.get(b, ()):
                out[b][key] = value
                took = True
        if not took:
            if targets == ["earth"]:
                raise UsageError(f"--param {item!r}: the Earth has no parameter {key!r} (one of "
                                 f"{', '.join(EARTH_DEFAULTS)})")
            raise UsageError(f"--param {item!r}: no BRDF in this run has a parameter {key!r}")
    return {b: p for b, p in out.items() if p}


def _brdf_list(text) -> list[str]:
    from lunarviz.photometry.brdf import BRDF_NAMES
    names = [t.strip().lower() for t in str(text).split(",") if t.strip()]
    if not names:
        raise UsageError("empty --brdf list")
    for n in names:
        if n not in BRDF_NAMES:
            raise UsageError(str(unknown_choice("BRDF", n, BRDF_NAMES)))
    return list(dict.fromkeys(names))


def _int_at_least(name, lo, hi: int = 10**9):
    """argparse's type for an integer from ``lo`` to ``hi`` (a bound on every count a user gives)."""
    def conv(text):
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} {text[:40]!r} is not an integer") from None
        if v < lo:
            raise argparse.ArgumentTypeError(f"{name} {v} must be {'positive' if lo == 1 else 'non-negative'}")
        if v > hi:
            raise argparse.ArgumentTypeError(f"{name} {str(v)[:40]} is more than {hi:,}")
        return v
    return conv


def _seconds(text):
    """An exposure: ``0.01``, ``8ms``, ``500us`` → seconds (argparse's type)."""
    from lunarviz.parsing import TIME_S, parse_quantity
    try:
        return parse_quantity(text, "exposure", TIME_S, "s")[0]
    except LunarvizError as exc:
        raise argparse.ArgumentTypeError(ValueError.__str__(exc)) from None


def _positive_int(name):
    return _int_at_least(name, 1)


def _nonneg_int(name):
    return _int_at_least(name, 0)


def _detector(text):
    if text is None:
        return None
    try:
        v = tuple(float(x) for x in text.split(","))
    except ValueError:
        raise UsageError(f"malformed --detector {text!r}: use x,y,z in metres") from None
    if len(v) != 3 or not all(math.isfinite(x) for x in v):
        raise UsageError(f"malformed --detector {text!r}: use x,y,z in metres")
    return v


def _check_out(path, suffixes):
    from lunarviz.outputs.writers import check_output_path
    try:
        return check_output_path(path, suffixes)
    except ValueError as exc:
        raise UsageError(str(exc)) from None


# ---- sub-commands ------------------------------------------------------------------------
#: the option groups (:mod:`lunarviz.options`) of the commands that run a scene; sweep adds ``analytic``
SCENE_GROUPS = ("photometry", "earth", "geometry", "sky", "meshes", "surfaces", "trace")
#: out of the schema's photometry group: ``brdf`` names its model with ``--model``
BRDF_TABLE_OPTIONS = ("dhg_convention", "h_function", "moon_model", "params")


def _add_time_options(p):
    p.add_argument("--time", default=None, metavar="ISO[,ISO...]",
                   help="UTC times (ISO 8601, e.g. 2025-03-14T06:58Z): the real sky from DE421, replacing θ")
    p.add_argument("--time-range", default=None, metavar="START,STOP,STEP",
                   help="UTC times from START to STOP by STEP (30s, 10min, 1h, 1d)")
    p.add_argument("--nights", default=None, metavar="START,STOP[,HH:MM]",
                   help="one time a night from date START to STOP, the nights with the Moon up; HH:MM is the "
                   "site's local mean solar time (HH:MMZ: UTC; default 00:00)")
    p.add_argument("--lunation", default=None, metavar="DATE[,HH:MM]",
                   help="as --nights, from the new Moon at or before DATE to the next")


def _add_scene_command(sub, name, helptext, groups=SCENE_GROUPS, brdfs=None):
    """A sub-command that runs a scene: every option of ``groups`` from the schema, and dates."""
    p = sub.add_parser(name, help=helptext)
    add_arguments(p, groups, defaults=None if brdfs is None else {"brdfs": brdfs})
    _add_time_options(p)
    return p


#: what --phase means: the paper's θ, not quite the phase angle (--theta is the same option)
THETA_WORDS = "θ (the paper's orbital angle of the Moon from full Moon; the phase angle differs from it by the " \
    "Sun's parallax, up to 0.15°: rows give it as alpha_deg)"


def _add_theta(p, many: bool = False, **kw) -> None:
    """``--phase`` (``--phases`` with ``many``), also spelt ``--theta`` (``--thetas``): the paper's θ."""
    flags = ("--phases", "--thetas") if many else ("--phase", "--theta")
    p.add_argument(*flags, dest=flags[0][2:], **kw)


#: the most craters ``mesh make craters`` places (each is a pass over the mesh's vertices)
MAX_CRATERS = 100_000


#: the options that give dates (one of them at most)
DATE_OPTIONS = ("time", "time_range", "nights", "lunation")


def _times(a):
    """UTC labels from --time, --time-range, --nights or --lunation, or None for the θ scene."""
    given = [n for n in DATE_OPTIONS if getattr(a, n, None) is not None]
    if not given:
        return None
    if len(given) > 1:
        raise UsageError(f"give one of --{', --'.join(n.replace('_', '-') for n in DATE_OPTIONS)}, not "
                         f"{' and '.join('--' + n.replace('_', '-') for n in given)}")
    if given[0] in ("time", "time_range"):
        from lunarviz.sky.ephemeris import time_list
        return time_list(a.time, a.time_range)
    from lunarviz.sky import nights
    from lunarviz.sky.observers import parse_observer
    observer = parse_observer(getattr(a, "observer", None))
    times = nights.nights_option(a.nights, observer) if a.nights is not None else \
        nights.lunation_option(a.lunation, observer)
    if not times:
        flag = "--nights" if a.nights is not None else "--lunation"
        raise UsageError(f"{flag} {getattr(a, given[0])!r}: the Moon is down at that time every night for "
                         f"observer {observer.spec!r}")
    return times


def _add_executor_options(p, workers_help="local worker processes"):
    p.add_argument("--executor", default="local", choices=list(EXECUTORS),
                   help="local worker processes, or a Dask distributed cluster")
    p.add_argument("--scheduler", default=None, help="with --executor dask: scheduler address (tcp://host:8786); "
                                                      "default a local cluster of --workers processes")
    p.add_argument("--workers", type=_positive_int("--workers"), default=None,
                   help=workers_help + " (default: one per core, at most one per task)")


def _parser_sweep(sub):
    from lunarviz.options import METHODS
    p = _add_scene_command(sub, "sweep", "moonshine, earthshine and albedo over phases",
                           SCENE_GROUPS + ("analytic", "accuracy", "spectral", "polarisation"))
    _add_theta(p, many=True, default=None,
               help=f"{THETA_WORDS} list [deg]: a,b,c or start:stop:step (default 0:180:5)")
    p.add_argument("--method", default="analytic", help=" | ".join(METHODS) + ": the paper's point-source "
                   "quadrature, Embree ray tracing of the meshes, or the exact extended-source reference")
    _add_executor_options(p)
    p.add_argument("--quiet", action="store_true", help="no progress bar and no summary on the terminal")
    p.add_argument("--dry-run", action="store_true",
                   help="print the tasks, those that will be skipped and an estimate of time and memory (one task "
                   "computed to time it), and write nothing")
    p.add_argument("--out", default=None, help=".json, .csv or .nc (NetCDF-4 through xarray), or - for the rows as "
                   "CSV on standard output; required unless --dry-run")
    p.add_argument("--plot", default=None, metavar="FILE.png",
                   help="also a figure: moonshine, earthshine, their ratio and p* against θ or time")
    p.add_argument("--state", default=None, metavar="FILE.json",
                   help="the row of a saved explorer state (lunarviz explore's Save), ray traced, instead of the "
                   "scene options")


def _parser_explore(sub):
    p = _add_scene_command(sub, "explore", "explore a scene: controls, the Moon, its light paths, curves and numbers "
                           "(a desktop window, or --web in a browser)", brdfs="dhg")
    _add_theta(p, many=True, default=None, help=f"{THETA_WORDS} [deg]: the slider's values (default 0:180:5)")
    p.add_argument("--band", dest="explore_band", default=None, help="a band shown first (B, V, R, S2A-B4, ...)")
    p.add_argument("--instrument", dest="explore_instrument", default=None, metavar="salex|bbso|FILE.toml",
                   help="an instrument shown first: its frame in counts with the pipeline's patches")
    p.add_argument("--panel", dest="explore_panel", default="brdf", choices=("brdf", "earth"),
                   help="the lower right panel: the Moon's BRDF map or the Earth seen from the Moon")
    p.add_argument("--state", default=None, metavar="FILE.json", help="start from a saved state")
    p.add_argument("--web", action="store_true",
                   help="serve the explorer to a browser through trame (no display needed)")
    p.add_argument("--port", type=int, default=None, help="with --web: TCP port (default: a free one)")
    p.add_argument("--host", default=None, help="with --web: interface to bind (default 127.0.0.1)")
    p.add_argument("--screenshot", default=None, metavar="FILE.png",
                   help="no window: write the converged picture of the state and exit")
    p.add_argument("--save-state", default=None, metavar="FILE.json", help="also write the state shown first")
    p.add_argument("--size", default="1280x800", help="WxH pixels of the picture")


def _parser_plot(sub):
    p = sub.add_parser("plot", help="figures of any sweep, study, measurement or bench output")
    p.add_argument("file", help="a .json (sweep, study, measure, bench, fit) or a sweep's .csv or .nc")
    p.add_argument("--out", required=True, help=".png, .pdf or .svg")


def _parser_brdf(sub):
    from lunarviz.earth_optics.classes import SURFACE_NAMES
    from lunarviz.options import BRDF_NAMES
    p = sub.add_parser("brdf", help="tabulate a lunar BRDF or the Earth's top-of-atmosphere reflectance")
    p.add_argument("--body", default="moon", choices=("moon", "earth"),
                   help="moon: a lunar BRDF (--model); earth: a surface class under the Rayleigh atmosphere "
                   "and the ozone (--surface)")
    p.add_argument("--model", default=None, help=" | ".join(BRDF_NAMES) + " (the Moon)")
    p.add_argument("--surface", default=None, help=" | ".join(SURFACE_NAMES) + " (the Earth)")
    p.add_argument("--no-atmosphere", action="store_true",
                   help="the Earth: the bare surface, no Rayleigh layer and no ozone")
    p.add_argument("--stokes", action="store_true",
                   help="the Earth (black and lambert:A grounds; the sea with --no-atmosphere): the Stokes "
                   "vector's Q and U, the degree and angle of linear polarisation, in the meridian plane of the view")
    p.add_argument("--incidence", required=True, help="incidence angles [deg]: a,b,c or start:stop:step")
    p.add_argument("--emission", required=True, help="emission angles [deg]: a,b,c or start:stop:step")
    p.add_argument("--azimuth", default="0", help="azimuths [deg]; 0 = viewer on the source's side")
    p.add_argument("--out", required=True,
                   help=".json or .csv: one row per (wavelength,) incidence, emission, azimuth")
    add_arguments(p, names=BRDF_TABLE_OPTIONS + ("wavelengths",), defaults={"wavelengths": "550"})


def _parser_trace(sub):
    p = _add_scene_command(sub, "trace", "ray trace one phase; write the lunar mesh with per-facet arrays",
                           brdfs="dhg")
    _add_theta(p, type=float, default=None,
               help=f"{THETA_WORDS} [deg] (or give --time)")
    p.add_argument("--out", required=True,
                   help="the Moon with per-facet arrays (.vtp, .vtk, .ply), or every body (.vtm multiblock: "
                        "moon, earth, sun in scene coordinates [m])")
    p.add_argument("--quiet", action="store_true", help="no summary on the terminal")


def _parser_pictures(sub):
    for name, helptext in (("render", "offscreen picture of a phase"), ("view", "interactive desktop viewer")):
        p = _add_scene_command(sub, name, helptext, brdfs="dhg")
        _add_theta(p, default=None,
                   help=f"{THETA_WORDS} [deg] (default 90); a list writes numbered frames" if name == "render"
                   else f"{THETA_WORDS} [deg] to start at (default 90); the viewer's slider moves through θ")
        p.add_argument("--view", default="composite", help="composite | moon | rays | maps | surfaces")
        p.add_argument("--size", default="1600x900", help="WxH pixels")
        if name == "render":
            p.add_argument("--out", required=True, help="PNG path; with several phases, frames FILE_000.png …")
            p.add_argument("--gif", default=None, help="also write an animated GIF of the frames")
            p.add_argument("--state", default=None, metavar="FILE.json",
                           help="the explorer's picture of a saved state (lunarviz explore's Save), instead of the "
                           "scene options")
        else:
            p.add_argument("--web", action="store_true",
                           help="serve the viewer to a browser through trame (no display needed)")
            p.add_argument("--port", type=int, default=None, help="with --web: TCP port (default: a free one)")
            p.add_argument("--host", default=None, help="with --web: interface to bind (default 127.0.0.1)")
        p.add_argument("--quiet", action="store_true", help="no progress bar and no summary on the terminal")


def _parser_image(sub):
    p = _add_scene_command(sub, "image", "synthetic camera image in radiance units (FITS, NPY or PNG)",
                           SCENE_GROUPS + ("spectral",), brdfs="dhg")
    _add_theta(p, default=None,
               help=f"{THETA_WORDS} [deg] (default 90); a list writes numbered frames")
    p.add_argument("--fov-deg", type=float, default=None, help="field of view across the width [deg] (default 0.75)")
    p.add_argument("--pixels", default=None, help="N or WxH (default 256)")
    p.add_argument("--supersample", type=int, default=None, help="K: K×K stratified rays per pixel (default 4)")
    p.add_argument("--pointing", default=None, help="moon or RA,DEC [deg] (ICRF on dates; default moon)")
    p.add_argument("--psf", default=None, help="none | gaussian:FWHM_ARCSEC | FILE.npy (2-D kernel, odd sides)")
    p.add_argument("--halo", default=None,
                   help="scattered-light wing FRACTION,INDEX[,CORE_ARCSEC]: (1+(r/core)^2)^(-INDEX/2)")
    g = p.add_argument_group("instrument (frames in counts: FITS EXPECTED_COUNTS and COUNTS)")
    _add_instrument_option(g)
    g.add_argument("--exposure", type=_seconds, default=None,
                   help="exposure time [s], or with a unit: 8ms, 500us (default: the instrument's)")
    g.add_argument("--plan", default=None, metavar="PLAN.json",
                   help="the instrument, exposure and θ or time of a lunarviz plan --out file")
    g.add_argument("--frames", type=int, default=1, help="noisy frames in the COUNTS cube (default 1); frame k "
                   "is drawn from numpy default_rng([SEED, k]) (--seed)")
    p.add_argument("--out", required=True, help=".fits, .npy or .png; several phases/times: FILE_000.ext …")
    p.add_argument("--gif", default=None, help="with several frames: also an animated GIF of the PNG stretch")
    p.add_argument("--quiet", action="store_true", help="no progress bar and no summary on the terminal")


def _add_instrument_option(p, required: bool = False):
    p.add_argument("--instrument", default=None, required=required, metavar="salex|bbso|FILE.toml",
                   help="an instrument: a packaged preset or a TOML file (lunarviz.instrument.spec)")


def _parser_measure(sub):
    p = _add_scene_command(sub, "measure", "measure the Earth's apparent albedo p* from frames in counts, or "
                           "simulate measurements end to end with their error budget", SCENE_GROUPS, brdfs="dhg")
    p.add_argument("frames", nargs="?", default=None, help="a FITS file of lunarviz image --instrument")
    p.add_argument("--expected", action="store_true", help="measure the file's noise-free EXPECTED_COUNTS")
    p.add_argument("--simulate", type=int, default=None, metavar="N", help="simulate N measurements instead")
    _add_instrument_option(p)
    _add_theta(p, default=None, help=f"with --simulate: {THETA_WORDS} [deg]")
    p.add_argument("--exposure", type=_seconds, default=None,
                   help="with --simulate: exposure [s], or with a unit: 8ms (the instrument's)")
    p.add_argument("--plan", default=None, metavar="PLAN.json",
                   help="with --simulate: the instrument, exposure and θ or time of a lunarviz plan --out file")
    p.add_argument("--frames-per-measurement", type=int, default=1,
                   help="with --simulate: frames averaged; measurement i, frame j from "
                        "default_rng([SEED, i, j]) (--seed)")
    p.add_argument("--lunar-fit", default=None, metavar="FIT.json",
                   help="a lunarviz fit result whose covariance is the lunar model's uncertainty "
                        "(default: the packaged fit of the BRDF to ROLO)")
    p.add_argument("--out", default=None, help=".json (rows: p_star, p_star_sigma, the error budget) or .csv")
    p.add_argument("--quiet", action="store_true", help="no progress bar and no summary on the terminal")


def _parser_plan(sub):
    p = _add_scene_command(sub, "plan", "the exposure that reaches an SNR on the earthlit patch without "
                           "saturating", SCENE_GROUPS, brdfs="dhg")
    _add_instrument_option(p, required=True)
    p.add_argument("--snr", type=float, required=True, help="signal-to-noise ratio in one frame (--snr-of)")
    p.add_argument("--snr-of", default="patch", choices=["patch", "pixel"],
                   help="the SNR of the earthlit patch's mean charge (what measure uses) or of one of its pixels")
    _add_theta(p, default=None, help=f"{THETA_WORDS} [deg] (or --time)")
    p.add_argument("--out", default=None, help=".json: a plan file that image --plan and measure --plan take")
    p.add_argument("--quiet", action="store_true", help="no summary on the terminal")


def _parser_study(sub):
    p = sub.add_parser("study", help="mesh-resolution study")
    p.add_argument("kind", choices=["mesh"], help="what to study: mesh (the resolution of one body's mesh)")
    p.add_argument("--levels", default="2:6:1", help="icosphere levels (integers)")
    _add_theta(p, many=True, default="30,90,150",
               help=f"{THETA_WORDS} list [deg]: a,b,c or start:stop:step")
    p.add_argument("--body", default="moon", choices=list(BODIES), help="the body whose mesh varies")
    p.add_argument("--shape", default="sphere", choices=["sphere", "ellipsoid", "craters"],
                   help="the shape refined level by level: the exact sphere, an ellipsoid (--axes) or a cratered Moon")
    p.add_argument("--axes", default="1.15,1.0,0.85", help="ellipsoid semi-axes in body radii")
    p.add_argument("--meshes", default=None, help="user meshes F1,F2,... coarse to fine (replaces --levels)")
    add_arguments(p, names=("brdfs", "mesh_units", "shading"))
    _add_executor_options(p, "with --executor dask and no scheduler: local cluster processes")
    p.add_argument("--out", required=True, help=".json or .csv (a .png plot is written beside it)")
    p.add_argument("--quiet", action="store_true", help="no progress bar and no summary on the terminal")


def _parser_mesh(sub):
    p = sub.add_parser("mesh", help="make a body mesh (ellipsoid, DEM, craters, patch) for --moon-mesh etc.")
    p.add_argument("action", choices=["make"], help="make: write a new mesh file")
    p.add_argument("shape", choices=["sphere", "ellipsoid", "dem", "craters", "patch"],
                   help="an icosphere, a triaxial ellipsoid, topography from a DEM map, seeded craters, or a sphere "
                        "refined around a point (--patch)")
    p.add_argument("--body", default="moon", choices=list(BODIES),
                   help="sets the nominal radius (R) the other options scale with")
    p.add_argument("--level", type=_nonneg_int("--level"), default=6,
                   help="icosphere subdivision level (20·4^L facets)")
    p.add_argument("--axes", default="1.15,1.0,0.85", help="ellipsoid semi-axes a,b,c in units of R")
    p.add_argument("--dem", default=None, help="DEM map (.npy/.png/.tif, equirectangular, row 0 = +90°)")
    p.add_argument("--height-scale", type=float, default=1.0, help="metres per DEM map unit")
    p.add_argument("--count", type=_int_at_least("--count", 0, MAX_CRATERS), default=40,
                   help=f"number of craters (at most {MAX_CRATERS:,})")
    p.add_argument("--diameters-km", default="60:300", help="crater diameter range min:max [km]")
    p.add_argument("--region", default=None, help="craters only in the cap LAT,LON,RADIUS_DEG")
    p.add_argument("--crater-seed", type=_nonneg_int("--crater-seed"), default=0, help="seed of the crater draw")
    p.add_argument("--patch", default=None, help="refine toward LAT,LON by a conformal zoom factor K: LAT,LON,K")
    p.add_argument("--out", required=True, help=".ply (float64), .obj, .stl, .off or .glb; vertices in metres")


def _parser_fit(sub):
    p = sub.add_parser("fit", help="fit a BRDF to disk-integrated lunar reflectance (ROLO or a table)")
    p.add_argument("--model", default="dhg", help="the lunar BRDF fitted: one of lambert, shg, dhg")
    p.add_argument("--source", default="rolo",
                   help="rolo (the ROLO model via the optional rimopy package) or a CSV with phase_deg,reflectance"
                        "[,waxing]")
    p.add_argument("--rolo-band", default="400-750",
                   help="ROLO's wavelength [nm] or band LO-HI of the fit's target (the paper's 400-750)")
    p.add_argument("--phases", default="2:96:2", help="ROLO phase angles [deg] (each waxing and waning)")
    p.add_argument("--free", default=None, help="parameters to fit, e.g. w,b,c,B0,h,theta_bar (default per BRDF)")
    add_arguments(p, names=("dhg_convention", "h_function", "moon_albedo_map", "order"), defaults={"order": 24})
    p.add_argument("--out", required=True, help=".json (a residual plot .png is written beside it)")


def _parser_bench_paper(sub):
    p = sub.add_parser("bench", help="run time against error for every method")
    p.add_argument("--quick", action="store_true", help="a reduced run (fewer phases, orders and rays)")
    p.add_argument("--out", required=True, help=".json (a .csv table and a .png Pareto plot beside it)")
    p.add_argument("--quiet", action="store_true", help="no progress bar and no summary on the terminal")
    p = sub.add_parser("paper", help="reproduce the paper end to end")
    p.add_argument("--out", required=True, help="output directory")
    p.add_argument("--quick", action="store_true", help="reduced run for CI and a first look")
    p.add_argument("--executor", default="local", choices=list(EXECUTORS),
                   help="local worker processes, or a Dask distributed cluster")
    p.add_argument("--scheduler", default=None, help="with --executor dask: scheduler address")
    p.add_argument("--quiet", action="store_true", help="no progress bar and no summary on the terminal")


#: a few examples per command, shown at the end of its --help
EXAMPLES = {
    "sweep": ["lunarviz sweep --method analytic --out paper.json",
              "lunarviz sweep --method raytrace --phases 0:180:30 --brdf lambert,dhg --out raytrace.csv",
              "lunarviz sweep --method reference --phases 30,90,150 --out reference.json",
              "lunarviz sweep --method raytrace --time-range 2026-06-01,2026-06-02,6h "
              "--observer site:34.26,-116.92,2067 --out sky.nc",
              "lunarviz sweep --moon-model rolo-fit-map --brdf dhg --wavelengths 400:1000:50 --out spectrum.json",
              "lunarviz sweep --method raytrace --band B,V,S2A-B4 --earth-surface landocean --clouds zonal "
              "--out colour.nc"],
    "brdf": ["lunarviz brdf --model dhg --incidence 75 --emission 0:85:5 --azimuth 0,180 --out brdf.csv",
             "lunarviz brdf --body earth --surface ocean --param earth.wind_speed=7 --wavelengths 450,550,865 "
             "--incidence 30 --emission 0:70:10 --azimuth 0,90,180 --out ocean.csv"],
    "trace": ["lunarviz trace --phase 120 --brdf dhg,lambert --out moon.vtp",
              "lunarviz trace --time 2025-03-14T06:58Z --out scene.vtm"],
    "render": ["lunarviz render --phase 120 --out moon.png",
               "lunarviz render --phase 0:180:30 --view moon --out frames.png --gif orbit.gif"],
    "view": ["lunarviz view --phase 120", "lunarviz view --web --port 8080"],
    "explore": ["lunarviz explore --phase 120",
                "lunarviz explore --web --lunation 2026-03-19 --observer site:34.26,-116.92,2067m",
                "lunarviz explore --state view.json --screenshot view.png"],
    "plot": ["lunarviz plot sweep.json --out sweep.png", "lunarviz plot study.json --out study.png"],
    "image": ["lunarviz image --phase 120 --pixels 512 --out moon.fits",
              "lunarviz image --phase 120 --psf gaussian:2 --halo 0.01,3 --out moon.png",
              "lunarviz image --phase 120 --band B,V,R --moon-model rolo-fit-map --out moon_bvr.fits",
              "lunarviz image --phase 120 --instrument salex --exposure 0.01 --frames 20 --out frames.fits"],
    "measure": ["lunarviz measure frames.fits --out m.json",
                "lunarviz measure --simulate 200 --instrument salex --phase 120 --exposure 0.01 --seed 1 --out m.json"],
    "plan": ["lunarviz plan --instrument salex --snr 100 --phase 120",
             "lunarviz plan --instrument bbso --snr 100 --time 2026-03-25T04:00Z --observer site:34.26,-116.92,2067"],
    "study": ["lunarviz study mesh --levels 2:5 --phases 30,90,150 --out study.json",
              "lunarviz study mesh --body earth --levels 3:6 --out earth_study.csv"],
    "mesh": ["lunarviz mesh make craters --level 6 --count 40 --out craters.ply",
             "lunarviz mesh make ellipsoid --axes 1.1,1.0,0.9 --level 5 --out ellipsoid.ply"],
    "fit": ["lunarviz fit --model dhg --source rolo --out fit.json",
            "lunarviz fit --model lambert --source table.csv --out fit_table.json"],
    "bench": ["lunarviz bench --quick --out bench.json"],
    "paper": ["lunarviz paper --out paper_out", "lunarviz paper --quick --out paper_quick"],
}


def build_parser() -> argparse.ArgumentParser:
    """The ``lunarviz`` command's parser: scene options come from :mod:`lunarviz.options`."""
    from lunarviz import __version__
    ap = _Parser(prog="lunarviz", description="Real-scale ray-traced earthshine and moonshine.",
                 epilog="examples:\n" + "\n".join(f"  {EXAMPLES[c][0]}" for c in ("sweep", "trace", "render", "image",
                                                                                  "paper"))
                 + "\n\nlunarviz COMMAND --help shows each command's options and more examples")
    ap.add_argument("--version", action="version", version=f"lunarviz {__version__}")
    sub = ap.add_subparsers(dest="command", required=True, parser_class=_Parser)
    for add in (_parser_sweep, _parser_brdf, _parser_trace, _parser_pictures, _parser_image, _parser_measure,
                _parser_plan, _parser_study,
                _parser_mesh, _parser_fit, _parser_bench_paper, _parser_explore, _parser_plot):
        add(sub)
    for name, command in sub.choices.items():
        command.epilog = "examples:\n" + "\n".join(f"  {e}" for e in EXAMPLES[name])
    return ap


def _scene(a, phases, times=None):
    """The :class:`lunarviz.Scene` the options describe (the CLI is a thin layer over the API)."""
    from lunarviz.api import Scene
    opts = scene_options(a, {"brdfs": lambda text, _: tuple(_brdf_list(text)),
                             "params": lambda items, args: parse_params(items, _brdf_list(args.brdf)),
                             "detector": lambda text, _: _detector(text)})
    return Scene(phases=None if times is not None else phases, time=times, **opts)


def cmd_sweep(a):
    import lunarviz.api as api
    from lunarviz.options import METHODS
    from lunarviz.outputs.writers import write_results
    a.method = any_case(a.method, METHODS) or a.method
    if a.method not in METHODS:
        raise UsageError(str(unknown_choice("method", a.method, METHODS)))
    if a.state is not None:  # the explorer's row: its scene, ray traced
        _state_alone(a, "sweep")
        if a.method not in ("analytic", "raytrace"):  # (analytic: the flag's default, not given)
            raise UsageError("sweep --state gives the explorer's ray-traced row: drop --method")
        a.method = "raytrace"
    times = _times(a)
    if times is not None and a.phases is not None:
        raise UsageError("give --phases (the θ scene) or --time/--time-range (the real sky), not both")
    phases = parse_float_list(a.phases or "0:180:5", "phase", 0.0, 360.0)
    if a.out is None and not a.dry_run:
        raise UsageError("sweep needs --out FILE (.json, .csv or .nc; - for CSV on standard output), or --dry-run")
    to_stdout = a.out == "-"  # (the rows as CSV on standard output, nothing else there)
    out = None if a.dry_run or to_stdout else _check_out(a.out, (".json", ".csv", ".nc"))
    plot = _check_out(a.plot, (".png", ".pdf", ".svg")) if a.plot is not None and not a.dry_run else None
    scene = _scene(a, phases, times) if a.state is None else _load_state(a.state).scene()
    settings = scene.settings(a.method)  # method-specific checks before any work
    if a.scheduler is not None and a.executor != "dask":
        raise UsageError("--scheduler goes with --executor dask")
    if a.dry_run:
        from lunarviz.workflows.dry_run import describe, dry_run
        print("\n".join(describe(dry_run(settings, a.workers))))
        return
    res = api.run(scene, a.method, workers=a.workers, progress=not a.quiet, executor=a.executor,
                  scheduler=a.scheduler)
    if to_stdout:
        from lunarviz.outputs.writers import rows_csv
        sys.stdout.write(rows_csv(res))
    elif out.suffix.lower() == ".nc":
        from lunarviz.outputs.tables import write_netcdf
        write_netcdf(out, res)
    else:
        write_results(out, res)
    if plot is not None:
        from lunarviz.outputs.sweep_plot import plot_sweep
        plot_sweep(res, plot)
    if not a.quiet and not to_stdout:
        print("\n".join(row_table(res["rows"])))
        print("\n".join(albedo_lines(res)))
        print(f"wrote {out}" + (f" and {plot}" if plot is not None else ""))


def albedo_lines(res: dict) -> list[str]:
    """The run's Eq. 17 estimates of the Bond albedo (over the sampled phases, per BRDF and
    method) and the model Earth's own spherical and geometric albedo and phase integral."""
    def shown(v):
        if isinstance(v, dict):  # a spectral run: one per wavelength or band
            return "  ".join(f"{lab}: {x:.4f}" for lab, x in v.items() if x is not None and math.isfinite(x))
        return f"{v:.4f}" if v is not None and math.isfinite(v) else ""
    lines = []
    for b, m in res["bond_albedo"].items():
        for meth, v in m.items():
            lines.append(f"Bond albedo, Eq. 17 over the sampled phases  {b:8s} {meth:10s} " + (
                shown(v) or "undefined: Eq. 17 integrates p* over the Earth's phases (sweep θ across 0-180°, or "
                            "dates that span them)"))
    if "earth_spherical_albedo" in res:
        lines.append(f"the model Earth's own: spherical albedo {shown(res['earth_spherical_albedo'])}   geometric "
                     f"albedo {shown(res['earth_geometric_albedo'])}   phase integral "
                     f"{shown(res['earth_phase_integral'])}")
    return lines


def row_table(rows: list[dict], most: int = 12) -> list[str]:
    """The rows as a short table for the terminal (the first and last of many): θ or time, BRDF,
    band or wavelength (where the run has them), moonshine, earthshine [W m⁻², per nm for a
    wavelength], p* and its bound."""
    banded = any(r.get("band") or r.get("wavelength_nm") is not None for r in rows)

    def cell(r):
        key = r["time_utc"][:16] if r.get("time_utc") else f"{r['theta_deg']:g}"
        label = r.get("band") or (f"{r['wavelength_nm']:g}nm" if r.get("wavelength_nm") is not None else "")
        ms, es = (r.get(k, r.get(k + "_nm")) for k in ("moonshine_W_m2", "earthshine_W_m2"))
        p, tol = r.get("apparent_albedo"), r.get("rtol")
        def num(v, f):
            return "-" if v is None or (isinstance(v, float) and not math.isfinite(v)) else format(v, f)
        why = r.get("skip_reason") or ""
        band = f" {label:>8}" if banded else ""
        return (f"{key:>16} {r.get('brdf', ''):7}{band} {num(ms, '.4e'):>11} {num(es, '.4e'):>11} "
                f"{num(p, '.4f'):>7} {num(tol, '.1e'):>8} {why}").rstrip()
    head = f"{'time' if rows and rows[0].get('time_utc') else 'θ [deg]':>16} {'brdf':7}" \
           + (f" {'band':>8}" if banded else "") + f" {'moon W/m²':>11} {'earth W/m²':>11} {'p*':>7} {'rtol':>8}"
    shown = rows if len(rows) <= most else rows[:most // 2] + [None] + rows[-most // 2:]
    return [head] + [f"{'...':>16} ({len(rows) - most} more rows in the file)" if r is None else cell(r)
                     for r in shown]


def cmd_brdf(a):
    from lunarviz.outputs.writers import write_results
    from lunarviz.workflows.brdf_tables import earth_rows, lunar_rows
    inc = parse_float_list(a.incidence, "incidence", 0.0, 90.0)
    emi = parse_float_list(a.emission, "emission", 0.0, 90.0)
    azi = parse_float_list(a.azimuth, "azimuth", -360.0, 360.0)
    out = _check_out(a.out, (".json", ".csv"))
    if a.body == "earth":
        if a.model is not None:
            raise UsageError("--model names a lunar BRDF: the Earth takes --surface")
        if a.surface is None:
            raise UsageError("--body earth needs --surface (black, lambert:A, ocean, land, vegetation, desert, snow "
                             "or cloud)")
        from lunarviz.options import BY_NAME
        for name in ("moon_model", "h_function", "dhg_convention"):
            if getattr(a, name) not in (None, BY_NAME[name].default):
                raise UsageError(f"{BY_NAME[name].cli_flag} is the Moon's: --body earth does not take it")
        lam = parse_float_list(a.wavelengths, "wavelengths", 300.0, 2500.0)
        rows, settings = earth_rows(a.surface, lam, inc, emi, azi, atmosphere=not a.no_atmosphere,
                                    params=parse_params(a.param, ["earth"]).get("earth", {}), stokes=a.stokes)
    else:
        from lunarviz.photometry.brdf import make_brdf
        if a.model is None:
            raise UsageError("the Moon's table needs --model (lambert, shg, dhg or hapke-style presets)")
        if a.surface is not None or a.no_atmosphere or a.stokes:
            raise UsageError("--surface, --no-atmosphere and --stokes are the Earth's: add --body earth")
        model_name = _brdf_list(a.model)
        if len(model_name) != 1:
            raise UsageError(f"--model takes one BRDF, got {a.model!r}")
        parsed = parse_params(a.param, model_name)
        if "earth" in parsed:
            raise UsageError("--param earth.NAME is the Earth's: add --body earth (and --surface)")
        params = parsed.get(model_name[0], {})
        model = make_brdf(model_name[0], dhg_convention=a.dhg_convention, h_function=a.h_function, params=params,
                          moon_model=a.moon_model)
        rows = lunar_rows(model, inc, emi, azi)
        settings = {"model": model_name[0], "dhg_convention": a.dhg_convention, "h_function": a.h_function,
                    "params": model.params}
    write_results(out, {"settings": settings, "rows": rows})
    if not getattr(a, "quiet", False):
        print(f"wrote {out} ({len(rows)} rows)")


def cmd_trace(a):
    import lunarviz.api as api
    from lunarviz.viz.meshio import check_vtm_target, write_facet_mesh
    times = _times(a)
    if times is not None:
        if a.phase is not None:
            raise UsageError("give --phase or --time, not both")
        if len(times) != 1:
            raise UsageError(f"trace takes one time, got {len(times)}")
        key = times[0]
    else:
        if a.phase is None:
            raise UsageError("trace needs --phase θ or --time")
        if not (0.0 <= a.phase <= 360.0) or not math.isfinite(a.phase):
            raise UsageError(f"phase {a.phase:g} is out of range [0, 360]")
        key = a.phase
    out = _check_out(a.out, (".vtp", ".vtk", ".ply", ".vtm"))
    if str(out).lower().endswith(".vtm"):
        check_vtm_target(out)
    res = api.trace(_scene(a, [a.phase if a.phase is not None else 0.0], times), key)
    from lunarviz.caches import release_caches
    release_caches()  # the meshes and Embree scenes are done with: ~1 GB at 5 M facets before the write
    write_facet_mesh(out, res)
    if not getattr(a, "quiet", False):
        for b in res.info["brdfs"]:
            print(f"{b}: moonshine {res.totals[f'moonshine_W_m2_{b}']:.6e} W m-2, earthshine "
                  f"{res.totals[f'earthshine_W_m2_{b}']:.6e} W m-2 at the detector")
        print(f"wrote {out} ({res.n_faces} facets; unsuffixed arrays: {res.info['brdf']})")


def _state_alone(a, command: str, own: tuple = ()) -> None:
    """Refuse scene options, dates and θ given beside ``--state`` (the state holds the scene)."""
    from lunarviz.api import SCENE_DEFAULTS
    from lunarviz.options import BY_NAME
    given = [BY_NAME[k].cli_flag for k, v in scene_options(a).items() if k != "brdfs" and v != SCENE_DEFAULTS[k]]
    given += ["--" + n.replace("_", "-") for n in DATE_OPTIONS + ("phase", "phases") if getattr(a, n, None) is not None]
    given += [flag for dest, flag in own if getattr(a, dest, None) not in (None, False)]
    if a.brdf not in ("dhg", ",".join(SCENE_DEFAULTS["brdfs"])):
        given.append("--brdf")
    if given:
        raise UsageError(f"{command} --state takes the scene from the state file: drop {given[0]}")


def _load_state(path):
    from lunarviz.explore.state import ExploreState
    try:
        return ExploreState.load(path)
    except LunarvizError as exc:
        raise UsageError(str(exc)) from None


def cmd_render(a, interactive=False):
    if not interactive:  # a bad output path is refused before anything is loaded or computed
        out = _check_out(a.out, (".png",))
        gif = _check_out(a.gif, (".gif",)) if a.gif else None
        if a.state is not None:
            _state_alone(a, "render", (("gif", "--gif"),))
            if a.view != "composite":
                raise UsageError("render --state draws the explorer's picture: drop --view")
            from lunarviz.explore.engine import state_picture
            from lunarviz.outputs.writers import write_picture
            state = _load_state(a.state)
            if a.size != "1600x900":  # (a size asked for: the state's picture at that size)
                state = state.with_(size=_size(a.size))
            write_picture(out, state_picture(state))
            if not a.quiet:
                print(f"wrote {out}")
            return
    from lunarviz.viz import views
    phases = parse_float_list(a.phase or "90", "phase", 0.0, 360.0)
    try:
        w, h = (int(x) for x in a.size.lower().split("x"))
        if w < 64 or h < 64 or w > 8192 or h > 8192:
            raise ValueError
    except ValueError:
        raise UsageError(f"malformed --size {a.size!r}: use WxH, each 64..8192") from None
    if a.view not in views.VIEWS:
        raise UsageError(str(unknown_choice("view", a.view, views.VIEWS)))
    times = _times(a)
    if times is not None and a.phase is not None:
        raise UsageError("give --phase (the θ scene) or --time/--time-range (the real sky), not both")
    brdf = _brdf_list(a.brdf)
    if len(brdf) != 1:
        raise UsageError(f"--brdf takes one BRDF here, got {a.brdf!r}")
    scene = _scene(a, phases, times)
    if interactive:
        import lunarviz.api as api
        web = getattr(a, "web", False)
        if times is None and len(phases) > 1:
            raise UsageError("view starts at one phase (its slider moves through the others): give one --phase")
        if not web and (getattr(a, "port", None) is not None or getattr(a, "host", None) is not None):
            raise UsageError("--port and --host go with --web")
        if web:
            port = 0 if a.port is None else a.port
            if not 0 <= port <= 65535:
                raise UsageError(f"--port {port} is not a TCP port (0-65535; 0 picks a free one)")
            api.view(scene, brdf=brdf[0], size=(w, h), web=True, port=port, host=a.host or "127.0.0.1")
            return
        import os
        if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
            raise UsageError("lunarviz view needs a display (DISPLAY is not set); use lunarviz view --web "
                             "(a browser) or lunarviz render (pictures)")
        api.view(scene, brdf=brdf[0], size=(w, h))
        return
    from functools import partial

    from lunarviz.workflows.tasks import view_data
    files = views.render_frames(partial(view_data, scene.settings("raytrace")), scene.keys, brdf[0], out,
                                view=a.view, size=(w, h), gif=gif, progress=not a.quiet)
    if not a.quiet:
        for f in files:
            print(f"wrote {f}")


CAMERA_DEFAULTS = {"fov_deg": 0.75, "pixels": "256", "supersample": 4, "pointing": "moon", "psf": "none",
                   "halo": "none"}


def _phases_or_times(a, default: str = "90"):
    times = _times(a)
    if times is not None and a.phase is not None:
        raise UsageError("give --phase (the θ scene) or --time/--time-range (the real sky), not both")
    return parse_float_list(a.phase or default, "phase", 0.0, 360.0), times


def _apply_plan(a) -> None:
    """``--plan FILE``: its instrument, exposure and θ or time, where the command line gives none
    (a different one given is an error)."""
    if getattr(a, "plan", None) is None:
        return
    from lunarviz.instrument.spec import instrument_spec_text
    from lunarviz.workflows.measurement import read_plan
    p = read_plan(a.plan)
    if a.instrument is not None and instrument_spec_text(a.instrument) != p["instrument_spec"]:
        raise UsageError(f"--instrument {a.instrument!r} differs from the plan's {p['instrument_spec']!r}: drop one")
    if a.exposure is not None and not math.isclose(a.exposure, p["exposure_s"], rel_tol=1e-9):
        raise UsageError(f"--exposure {a.exposure!r} s differs from the plan's {p['exposure_s']!r} s: drop one")
    a.instrument, a.exposure = p["instrument_spec"], p["exposure_s"]
    if a.phase is not None or _times(a) is not None:
        raise UsageError(f"--plan {a.plan!r} gives the θ or time its exposure was planned at ({p['key']}): drop "
                         f"--phase/--time")
    if p["key"].endswith("Z"):
        a.time = p["key"]
    else:
        a.phase = p["key"]


def cmd_image(a):
    import lunarviz.api as api
    from lunarviz.methods.camera import Camera, parse_pixels
    _apply_plan(a)
    phases, times = _phases_or_times(a)
    given = [k for k in CAMERA_DEFAULTS if getattr(a, k) is not None]
    camera, out_suffixes = None, (".fits", ".npy", ".png")
    if a.instrument is not None:
        if given:
            raise UsageError(f"--instrument sets the camera and its optics: drop --{given[0].replace('_', '-')}")
        out_suffixes = (".fits",)
    else:
        if a.exposure is not None:
            raise UsageError("--exposure goes with --instrument")
        if a.frames != 1:
            raise UsageError("--frames goes with --instrument")
        for k, v in CAMERA_DEFAULTS.items():
            setattr(a, k, v if getattr(a, k) is None else getattr(a, k))
        w, h = parse_pixels(a.pixels)
        camera = Camera(fov_deg=a.fov_deg, width=w, height=h, supersample=a.supersample, pointing=a.pointing)
    out = _check_out(a.out, out_suffixes)
    gif = _check_out(a.gif, (".gif",)) if a.gif else None
    scene = _scene(a, phases, times)
    if gif is not None and len(scene.keys) < 2:
        raise UsageError("--gif needs several frames (several phases or times)")
    files = api.image(scene, keys=scene.keys, camera=camera, psf=a.psf, halo=a.halo, out=out, gif=gif,
                      progress=not a.quiet, instrument=a.instrument, exposure=a.exposure, frames=a.frames)
    if not a.quiet:
        for f in files:
            print(f"wrote {f}")


def cmd_measure(a):
    import lunarviz.api as api
    from lunarviz.outputs.writers import write_results
    out = _check_out(a.out, (".json", ".csv")) if a.out is not None else None
    if a.plan is not None and a.simulate is None:
        raise UsageError("--plan goes with --simulate (a file of frames carries its own instrument and exposure)")
    _apply_plan(a)
    if a.simulate is None:
        if a.frames is None:
            raise UsageError("give a FITS file of lunarviz image --instrument, or --simulate N")
        for k in ("instrument", "phase", "exposure", "time", "time_range"):
            if getattr(a, k) is not None:
                raise UsageError(f"--{k.replace('_', '-')} goes with --simulate (a file carries its own)")
        defaults = vars(build_parser().parse_args(["measure", a.frames]))
        scene_keys = {o.dest for o in OPTIONS} | set(DATE_OPTIONS) | {"brdf", "param", "seed"}
        changed = sorted(k for k in scene_keys & set(vars(a)) if getattr(a, k) != defaults.get(k))
        if changed:
            raise UsageError(f"--{changed[0].replace('_', '-')} goes with --simulate: a file of frames carries its "
                             f"own scene")
        res = api.measure(a.frames, expected=a.expected, lunar_fit=a.lunar_fit)
    else:
        if a.frames is not None:
            raise UsageError("give a FITS file or --simulate N, not both")
        if a.instrument is None:
            raise UsageError("--simulate needs --instrument")
        if a.phase is None and _times(a) is None:
            raise UsageError("--simulate needs --phase DEG or --time ISO")
        phases, times = _phases_or_times(a)
        if len(times or phases) != 1:
            raise UsageError("--simulate takes one --phase or one --time")
        scene = _scene(a, phases, times)
        res = api.measure(scene=scene, simulate=a.simulate, instrument=a.instrument, exposure=a.exposure,
                          frames=a.frames_per_measurement, lunar_fit=a.lunar_fit,
                          progress=not a.quiet)
    if out is not None:
        write_results(out, res)
    if not a.quiet:
        r = res["rows"][0] if a.simulate is None else res["summary"]
        if a.simulate is None:
            print(f"p* = {r['p_star']:.5f} ± {r['p_star_sigma']:.5f} (random) ± {r['p_star_sigma_systematic']:.5f} "
                  f"(systematic); U(k=2) = {r['p_star_U_k2']:.5f}")
            terms = [(k[len("sigma_"):].replace("_", " "), v) for k, v in r.items()
                     if k.startswith("sigma_") and isinstance(v, (int, float)) and math.isfinite(v)]
            if terms:  # the error budget, largest first (σ of p*, in the units of p*, as the rows give them)
                print("error budget (σ of p*): " + ", ".join(
                    f"{name} {v:.2e}" for name, v in sorted(terms, key=lambda t: -t[1])))
        else:
            print(f"{r['measurements']} measurements: sweep p* = {r['p_star_sweep']:.5f}, noiseless "
                  f"{r['p_star_noiseless']:.5f}; standardised error mean {r['standardised_error_mean']:+.3f}, "
                  f"variance {r['standardised_error_variance']:.3f}")
        if out is not None:
            print(f"wrote {out}")


def cmd_plan(a):
    import json

    import lunarviz.api as api
    from lunarviz.outputs.writers import write_results
    out = _check_out(a.out, (".json",)) if a.out is not None else None
    if a.phase is None and _times(a) is None:
        raise UsageError("plan needs --phase DEG or --time ISO")
    phases, times = _phases_or_times(a)
    if len(times or phases) != 1:
        raise UsageError("plan takes one --phase or one --time")
    res = api.plan(_scene(a, phases, times), instrument=a.instrument, snr=a.snr, per=a.snr_of)
    if out is not None:
        write_results(out, res)
    if not a.quiet:
        of = "the earthlit patch" if a.snr_of == "patch" else "an earthlit pixel"
        if res["feasible"]:
            print(f"exposure {res['exposure_s']:.6g} s reaches SNR {res['snr_target']:g} on {of}")
        else:
            print(f"no exposure reaches SNR {res['snr_target']:g} on {of} unsaturated: the longest safe exposure "
                  f"{res['saturation_exposure_s']:.6g} s gives {res['snr_at_saturation_exposure']:.3g}; "
                  f"{res['frames_needed_at_saturation_exposure']} such frames averaged would reach it")
        print(f"  SNR per frame: patch ({res['earthlit_pixels']} pixels) {res['snr_patch_at_exposure']:.3g}, pixel "
              f"{res['snr_pixel_at_exposure']:.3g}; the brightest pixel holds {res['brightest_pixel_e']:.0f} e- "
              f"({100 * res['brightest_pixel_fraction_of_full_well']:.0f} % of the {res['full_well_e']:.0f} e- full "
              f"well)")
        if out is not None and res["feasible"]:
            print(f"wrote {out}: lunarviz image --plan {out} ... and measure --simulate N --plan {out} take it")
        elif out is not None:
            print(f"wrote {out} (no exposure to plan with: image --plan refuses it)")
        if out is None:
            print(json.dumps(res, indent=1))


def cmd_study(a):
    from lunarviz.workflows import study
    levels = parse_float_list(a.levels, "level", 0, 8)
    bad = [v for v in levels if v != int(v)]
    if bad:
        raise UsageError(f"--levels {bad[0]:g} is not an integer")
    levels = [int(v) for v in levels]
    phases = parse_float_list(a.phases, "phase", 0.0, 180.0)
    out = _check_out(a.out, (".json", ".csv"))
    _check_out(out.with_suffix(".png"), (".png",))  # the plot beside it, before any work
    meshes = [m.strip() for m in a.meshes.split(",") if m.strip()] if a.meshes else None
    if meshes is not None:
        from lunarviz.bodies.meshes import load_user_mesh
        if len(meshes) < 2:
            raise UsageError("--meshes needs at least two meshes, coarse to fine")
        for m in meshes:
            load_user_mesh(m, a.body, units=a.mesh_units)
    if meshes is None and any(b <= a_ for a_, b in zip(levels, levels[1:])):
        raise UsageError(f"--levels {a.levels!r} must increase (coarse to fine)")
    if meshes is not None and len(set(meshes)) != len(meshes):
        raise UsageError("--meshes lists a mesh twice")
    if a.scheduler is not None and a.executor != "dask":
        raise UsageError("--scheduler goes with --executor dask")
    study.mesh(levels, phases, _brdf_list(a.brdf), out=out, plot=out.with_suffix(".png"), shading=a.shading,
               progress=not a.quiet, body=a.body, shape=a.shape, axes=tuple(_check_axes(a.axes)), meshes=meshes,
               mesh_units=a.mesh_units, executor=a.executor, scheduler=a.scheduler, workers=a.workers)
    print(f"wrote {out}")


def _floats(text, name, n, colon=True):
    """``n`` finite numbers separated by commas (or colons, where ``colon``)."""
    text = str(text).replace(":", ",") if colon else str(text)
    try:
        v = [float(x) for x in text.split(",")]
    except ValueError:
        raise UsageError(f"malformed {name} {text!r}: expected {n} numbers") from None
    if len(v) != n or not all(math.isfinite(x) for x in v):
        raise UsageError(f"malformed {name} {text!r}: expected {n} numbers")
    return v


def _check_axes(text):
    ax = _floats(text, "--axes", 3, colon=False)
    if not all(0.3 <= x <= 3.0 for x in ax):
        raise UsageError(f"--axes {text!r}: each semi-axis must be 0.3–3 body radii (a body mesh must stay plausible)")
    return ax


def cmd_mesh(a):
    from lunarviz.bodies import shapes
    from lunarviz.bodies.meshes import NOMINAL_RADII
    R = NOMINAL_RADII[a.body]
    if a.level > MAX_LEVEL:
        raise UsageError(f"--level {a.level} is too fine (at most {MAX_LEVEL}: {20 * 4**MAX_LEVEL / 1e6:.1f} M facets; "
                         f"--patch refines where it matters)")
    out = _check_out(a.out, (".ply", ".obj", ".stl", ".off", ".glb"))
    patch = None
    if a.patch:
        lat, lon, k = _floats(a.patch, "--patch", 3)
        if not (-90 <= lat <= 90) or not (-360 <= lon <= 360) or k < 1:
            raise UsageError(f"--patch {a.patch!r}: latitude must be in [-90, 90], longitude in [-360, 360], K ≥ 1")
        patch = (lat, lon, k)
    if a.shape == "sphere":
        m = shapes.base_sphere(a.level, patch)
        m.vertices = m.vertices * R
    elif a.shape == "ellipsoid":
        ax = _check_axes(a.axes)
        m = shapes.ellipsoid(*(x * R for x in ax), level=a.level, patch=patch)
    elif a.shape == "dem":
        if not a.dem:
            raise UsageError("mesh make dem needs --dem FILE")
        m = shapes.dem(a.dem, R, a.height_scale, a.level, patch)
    elif a.shape == "craters":
        d0, d1 = _floats(a.diameters_km, "--diameters-km", 2)
        if not (0 < d0 <= d1 <= 0.5 * R / 1e3):
            raise UsageError(f"--diameters-km {a.diameters_km!r}: need 0 < min ≤ max ≤ {0.5 * R / 1e3:g} km "
                             f"(half the {a.body}'s radius)")
        region = tuple(_floats(a.region, "--region", 3)) if a.region else None
        if region and not (-90 <= region[0] <= 90 and -360 <= region[1] <= 360 and 0 < region[2] <= 180):
            raise UsageError(f"--region {a.region!r}: need LAT in [-90, 90], LON in [-360, 360], 0 < RADIUS_DEG ≤ 180")
        m = shapes.craters(R, a.level, a.count, d0 * 1e3, d1 * 1e3, a.crater_seed, region, patch)
    else:
        if patch is None:
            raise UsageError("mesh make patch needs --patch LAT,LON,K")
        m = shapes.patch(R, a.level, *patch)
    from lunarviz.bodies.meshes import validate_mesh
    validate_mesh(m, f"{a.shape} mesh")
    shapes.write_mesh(m, out)
    print(f"wrote {out} ({len(m.faces)} facets, vertices in metres, {a.body} frame)")


def cmd_fit(a):
    from lunarviz.outputs.writers import write_results
    from lunarviz.workflows.fit import DEFAULT_FREE, plot_fit, run_fit
    brdf = _brdf_list(a.model)
    if len(brdf) != 1:
        raise UsageError(f"--model takes one BRDF, got {a.model!r}")
    free = tuple(x.strip() for x in a.free.split(",") if x.strip()) if a.free else DEFAULT_FREE[brdf[0]]
    if a.source != "rolo" and not Path(a.source).is_file():
        raise UsageError(f"--source {a.source!r} is neither rolo nor a CSV file")
    out = _check_out(a.out, (".json",))
    _check_out(out.with_suffix(".png"), (".png",))  # the residual plot beside it, before any work
    if a.moon_albedo_map is not None:
        from lunarviz.surfaces.moon_map import MoonAlbedoMap
        MoonAlbedoMap.parse(a.moon_albedo_map)  # a bad map: one line, before any work
    res = run_fit(brdf[0], a.source, a.rolo_band, a.phases, free, dhg_convention=a.dhg_convention,
                  h_function=a.h_function, moon_map=a.moon_albedo_map, order=a.order)
    d = res.to_dict()
    d["settings"] = {"source": a.source, "band_nm": a.rolo_band, "phases_deg": a.phases,
                     "dhg_convention": a.dhg_convention, "h_function": a.h_function,
                     "moon_albedo_map": a.moon_albedo_map, "order": a.order}
    plot_fit(res, out.with_suffix(".png"))  # the plot first: a failure leaves neither file
    write_results(out, d)
    for k in res.free:
        flag = "constrained" if res.constrained[k] else "NOT constrained (degenerate or at a bound)"
        print(f"{k:10s} = {res.params[k]:.5g} ± {res.sigma[k]:.2g}   {flag}")
    print(f"rms log residual {res.rms_log_residual:.4f}; wrote {out}")


def cmd_bench(a):
    from lunarviz.workflows.bench import run_bench
    out = _check_out(a.out, (".json",))
    run_bench(out, quick=a.quick, progress=not a.quiet)
    print(f"wrote {out}")


def cmd_paper(a):
    from lunarviz.workflows.paper import run_paper
    out = Path(a.out)
    if out.exists() and not out.is_dir():
        raise UsageError(f"--out {a.out!r} exists and is not a directory")
    parent = out.resolve().parent
    if not parent.is_dir():
        raise UsageError(f"--out {a.out!r}: parent directory does not exist")
    if a.scheduler is not None and a.executor != "dask":
        raise UsageError("--scheduler goes with --executor dask")
    run_paper(out, quick=a.quick, progress=not a.quiet, executor=a.executor, scheduler=a.scheduler)


def cmd_explore(a):
    from lunarviz.explore.state import state_from_scene
    size = _size(a.size)
    shot = _check_out(a.screenshot, (".png",)) if a.screenshot else None
    keep = _check_out(a.save_state, (".json",)) if a.save_state else None
    if not a.web and (a.port is not None or a.host is not None):
        raise UsageError("--port and --host go with --web")
    if a.state is not None:
        _state_alone(a, "explore", (("explore_band", "--band"), ("explore_instrument", "--instrument")))
        if a.explore_panel != "brdf":
            raise UsageError("explore --state takes the scene from the state file: drop --panel")
        state = _load_state(a.state)
        if a.size != "1280x800":  # (a size asked for: the state's picture at that size)
            state = state.with_(size=size)
    else:
        times = _times(a)
        if times is not None and a.phases is not None:
            raise UsageError("give --phase (the θ scene) or --time/--time-range/--nights/--lunation, not both")
        brdf = _brdf_list(a.brdf)
        if len(brdf) != 1:
            raise UsageError(f"--brdf takes one BRDF here (the menu changes it), got {a.brdf!r}")
        phases = parse_float_list(a.phases or "0:180:5", "phase", 0.0, 360.0)
        scene = _scene(a, phases, times)
        key = phases[0] if times is None and a.phases is not None else None
        state = state_from_scene(scene, key=key, brdf=brdf[0], band=a.explore_band, size=size)
        try:
            state = state.with_(instrument=a.explore_instrument, panel=a.explore_panel)
        except LunarvizError as exc:
            raise UsageError(str(exc)) from None
        state.scene()  # the band and the rest checked now
    if shot is not None:  # the picture first: a state that cannot be drawn leaves no file behind
        from lunarviz.explore.engine import state_picture
        from lunarviz.outputs.writers import write_picture
        picture = state_picture(state)
        if keep is not None:
            state.save(keep)
        write_picture(shot, picture)
        print(f"wrote {shot}")
        return
    if keep is not None:
        state.save(keep)
    if a.web:
        port = 0 if a.port is None else a.port
        if not 0 <= port <= 65535:
            raise UsageError(f"--port {port} is not a TCP port (0-65535; 0 picks a free one)")
        from lunarviz.explore.web_app import serve
        serve(state, host=a.host or "127.0.0.1", port=port)
        return
    import os
    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise UsageError("lunarviz explore needs a display (DISPLAY is not set); use lunarviz explore --web "
                         "(a browser) or --screenshot FILE.png")
    from lunarviz.explore.desktop import run_desktop
    run_desktop(state)


def _size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(x) for x in text.lower().split("x"))
        if not (960 <= w <= 4096 and 600 <= h <= 4096):
            raise ValueError
    except ValueError:
        raise UsageError(f"malformed --size {text!r}: use WxH, width 960-4096 and height 600-4096") from None
    return w, h


def cmd_plot(a):
    from lunarviz.workflows.plot_file import plot_file
    out = _check_out(a.out, (".png", ".pdf", ".svg"))
    kind = plot_file(a.file, out)
    print(f"wrote {out} (a {kind})")


COMMANDS = {"sweep": cmd_sweep, "brdf": cmd_brdf, "trace": cmd_trace, "render": cmd_render,
            "view": lambda a: cmd_render(a, interactive=True), "study": cmd_study,
            "bench": cmd_bench, "paper": cmd_paper, "mesh": cmd_mesh, "fit": cmd_fit, "image": cmd_image,
            "measure": cmd_measure, "plan": cmd_plan, "explore": cmd_explore, "plot": cmd_plot}


#: warnings already printed in this run: the same one (settings are checked more than once) is shown once
_SHOWN: set = set()


def _show_warning(message, category, filename, lineno, file=None, line=None):
    text = f"lunarviz: warning: {message}"
    if text not in _SHOWN:
        _SHOWN.add(text)
        print(text, file=sys.stderr)


def _terminate_as_interrupt() -> None:
    """SIGTERM ends a run the way Ctrl-C does: temporary files are removed, worker processes
    ended, and the command exits 130 with one line (in the main thread only: a library
    caller's own handlers are left alone)."""
    import signal
    import threading
    if threading.current_thread() is not threading.main_thread():
        return

    def interrupt(signum, frame):
        raise KeyboardInterrupt
    signal.signal(signal.SIGTERM, interrupt)


def main(argv=None) -> int:
    import warnings

    from lunarviz.errors import LunarvizWarning
    shown = warnings.showwarning
    if not sys.warnoptions:
        warnings.filterwarnings("once", category=LunarvizWarning)  # one line per distinct warning
    warnings.showwarning = lambda m, c, *a, **k: (_show_warning(m, c, *a, **k) if issubclass(c, LunarvizWarning)
                                                  else shown(m, c, *a, **k))
    parser = build_parser()
    _terminate_as_interrupt()
    try:
        with command_line_words():
            return _run(parser, argv)
    finally:
        warnings.showwarning = shown


def _run(parser, argv) -> int:
    """Parse ``argv`` and run its command: the exit status, each error in one line."""
    try:
        args = parser.parse_args(argv)
        COMMANDS[args.command](args)
    except UsageError as exc:
        print(f"lunarviz: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except LunarvizError as exc:  # validation errors from the core (parameters, meshes, dates); other
        # exceptions are bugs and keep their traceback
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        print(f"lunarviz: error: {msg}", file=sys.stderr)
        return EXIT_USAGE
    except OSError as exc:  # a file the system refused (a name too long, a vanished folder): input/output
        print(f"lunarviz: error: {exc.strerror or exc}: {exc.filename or ''}".rstrip(": "), file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("lunarviz: interrupted", file=sys.stderr)
        return 130
    return 0


if __name__ == "__main__":
    sys.exit(main())
